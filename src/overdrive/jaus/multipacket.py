"""Multi-packet JAUS messages (header data flags, reference §1): split and reassemble. Sans-IO.

A message whose payload exceeds one packet's 4080 bytes travels as packets flagged FIRST, then
NORMAL ones, then LAST, with consecutive sequence numbers (wrapping at 65536); a packet sent
again carries RETRANSMITTED and replaces the one with its sequence number. :class:`Reassembler`
joins them per (origin, source, destination, command code, experimental flag) and refuses, with a
:class:`JausDecodeError` saying why, what cannot be joined: a NORMAL/LAST/RETRANSMITTED packet
with no FIRST, a sequence number outside the message, a message larger than
``MAX_MESSAGE_SIZE`` or ``MAX_PACKETS``, too many messages in progress (``MAX_OPEN``). Messages not completed within
``timeout_s`` are dropped by :meth:`Reassembler.expire` (and when a new FIRST needs room).
None of the XGV's messages needs more than one packet; this is for peers that send such.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final

from overdrive.jaus.codec import (
    HEADER_SIZE,
    MAX_PAYLOAD_SIZE,
    DataFlag,
    JausDecodeError,
    JausEncodeError,
    Message,
    UnknownMessage,
    decode,
    decode_header,
    encode_header,
    message_type,
)

MAX_MESSAGE_SIZE: Final = 65536   # our bound on a reassembled payload (16 full packets); the
                                  # reference sets none, OpenJAUS's large-message handler neither
MAX_PACKETS: Final = 256         # packets per message: bounds the bookkeeping of tiny packets
MAX_OPEN: Final = 8               # messages being reassembled at once, per receiver
TIMEOUT_S: Final = 1.0            # a message's packets all arrive within this (our choice)
_MODULUS: Final = 0x10000         # reference §1: u16 sequence number


def split(message: Message, packet_payload: int = MAX_PAYLOAD_SIZE) -> list[bytes]:
    """``message`` as JAUS packets (header + payload each): one SINGLE packet when it fits,
    else FIRST, NORMAL..., LAST from the header's sequence number on."""
    if not 1 <= packet_payload <= MAX_PAYLOAD_SIZE:
        raise JausEncodeError(f"packet payload must be 1..{MAX_PAYLOAD_SIZE} bytes")
    payload = message.encode_payload()
    if len(payload) > MAX_MESSAGE_SIZE:
        raise JausEncodeError(f"payload of {len(payload)} bytes exceeds {MAX_MESSAGE_SIZE}")
    chunks = [payload[i:i + packet_payload] for i in range(0, len(payload), packet_payload)]
    header = message.header
    if len(chunks) <= 1:
        return [encode_header(header, message.code, message.experimental, len(payload))
                + payload]
    packets = []
    for index, chunk in enumerate(chunks):
        flag = (DataFlag.FIRST if index == 0 else
                DataFlag.LAST if index == len(chunks) - 1 else DataFlag.NORMAL)
        part = header.replace(data_flag=int(flag), sequence=(header.sequence + index) % _MODULUS)
        packets.append(encode_header(part, message.code, message.experimental, len(chunk))
                       + chunk)
    return packets


@dataclass
class _Open:
    first_sequence: int
    started_s: float
    parts: dict[int, bytes] = field(default_factory=dict)   # offset from first -> payload
    last_offset: int | None = None
    size: int = 0


Key = tuple[object, object, object, int, bool]


class Reassembler:
    """Joins multi-packet messages (see the module docstring); one per receiver."""

    def __init__(self, timeout_s: float = TIMEOUT_S) -> None:
        self.timeout_s = timeout_s
        self.open: dict[Key, _Open] = {}
        self.dropped = 0          # messages abandoned: replaced, timed out or refused

    def expire(self, now_s: float) -> None:
        for key in [k for k, o in self.open.items() if now_s - o.started_s >= self.timeout_s]:
            del self.open[key]
            self.dropped += 1

    def feed(self, raw: bytes, now_s: float, origin: object = None) -> Message | None:
        """The message ``raw`` completes (a SINGLE one at once), or None while incomplete.

        ``origin`` (e.g. the sender's address) is part of the key, so packets claiming the same
        ids from another sender can neither complete nor replace a message in progress."""
        header, code, experimental, size = decode_header(raw)
        if header.data_flag == DataFlag.SINGLE:
            return decode(raw)
        if len(raw) != HEADER_SIZE + size:
            raise JausDecodeError(
                f"wrong length: header says {size} payload bytes, got {len(raw) - HEADER_SIZE}")
        key: Key = (origin, header.source, header.destination, code, experimental)
        flag = header.data_flag
        if flag == DataFlag.FIRST:
            self.expire(now_s)
            if key in self.open:
                self.dropped += 1          # a new message replaces an unfinished one
            elif len(self.open) >= MAX_OPEN:
                self.dropped += 1
                raise JausDecodeError(f"multi-packet: {MAX_OPEN} messages already in progress")
            self.open[key] = _Open(header.sequence, now_s)
        current = self.open.get(key)
        if current is None:
            raise JausDecodeError(f"multi-packet: {DataFlag(flag).name} packet (sequence "
                                  f"{header.sequence}) with no FIRST packet before it")
        offset = (header.sequence - current.first_sequence) % _MODULUS
        last = current.last_offset
        if offset >= MAX_PACKETS or (last is not None and (
                offset > last or (flag == DataFlag.LAST and offset != last))):
            del self.open[key]
            self.dropped += 1
            raise JausDecodeError(f"multi-packet: sequence {header.sequence} outside the message")
        previous = current.parts.get(offset)
        if previous is not None and flag != DataFlag.RETRANSMITTED:
            del self.open[key]
            self.dropped += 1
            raise JausDecodeError(f"multi-packet: sequence {header.sequence} sent twice")
        current.size += size - (len(previous) if previous is not None else 0)
        if current.size > MAX_MESSAGE_SIZE:
            del self.open[key]
            self.dropped += 1
            raise JausDecodeError(f"multi-packet: message exceeds {MAX_MESSAGE_SIZE} bytes")
        current.parts[offset] = raw[HEADER_SIZE:]
        if flag == DataFlag.LAST:
            current.last_offset = offset
        if current.last_offset is None or len(current.parts) != current.last_offset + 1:
            return None
        del self.open[key]
        payload = b"".join(current.parts[i] for i in range(current.last_offset + 1))
        whole = header.replace(data_flag=int(DataFlag.SINGLE), sequence=current.first_sequence)
        cls = message_type(code, experimental)
        if cls is None:
            return UnknownMessage(code, payload, experimental, whole)
        return cls.decode_payload(payload, whole)


__all__ = ["MAX_MESSAGE_SIZE", "MAX_OPEN", "MAX_PACKETS", "TIMEOUT_S", "Reassembler", "split"]
