"""JUDP (SAE AS5669) datagram framing, reference §2. Sans-IO.

A datagram is the transport version byte ``0x01`` then one or more messages, each behind a
4-byte frame header: header compression number (0), compression flags (0), and a big-endian
u16 holding 16 + payload size. A frame length of 0 ends the datagram; anything after it is
ignored. Header compression is not supported (non-zero compression bytes are rejected).
Multi-packet messages are rejected, as by :func:`codec.decode`, unless the receiver passes a
:class:`~overdrive.jaus.multipacket.Reassembler` to :func:`decode_datagram`.

Sending: one message per datagram by default (:func:`datagrams`), because OpenJAUS's receiver
(``JudpInterface.cpp``, ``recvThreadRun``) takes only the first message of a datagram and drops
the rest (shared/interop/openjaus README); packing (:func:`pack`) is an explicit option for
peers known to accept it. Receiving accepts any number of messages per datagram.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from typing import Final

from overdrive.jaus.codec import (
    HEADER_SIZE,
    MAX_PAYLOAD_SIZE,
    JausDecodeError,
    JausEncodeError,
    Message,
    decode,
    encode,
)
from overdrive.jaus.multipacket import Reassembler

TRANSPORT_VERSION: Final = 0x01  # reference §2: "one byte 0x01 (transport version)"
JUDP_PORT: Final = 3794  # reference §2: "port 3794"
MAX_DATAGRAM_SIZE: Final = 4101  # reference §2: "Max datagram 4101 bytes"
_FRAME: Final = struct.Struct(">BBH")  # reference §2: compression number, flags, BE length
_MAX_FRAME_LENGTH: Final = HEADER_SIZE + MAX_PAYLOAD_SIZE
_END: Final = 0  # reference §2: "A length of 0 ends the datagram"


def frame(encoded_messages: Iterable[bytes]) -> bytes:
    """Wrap already-encoded JAUS messages into one datagram."""
    parts = [bytes((TRANSPORT_VERSION,))]
    for message in encoded_messages:
        if not HEADER_SIZE <= len(message) <= _MAX_FRAME_LENGTH:
            raise JausEncodeError(
                f"a JAUS message is 16..{_MAX_FRAME_LENGTH} bytes, got {len(message)}"
            )
        parts.append(_FRAME.pack(0, 0, len(message)))
        parts.append(message)
    if len(parts) == 1:
        raise JausEncodeError("a datagram needs at least one message")
    datagram = b"".join(parts)
    if len(datagram) > MAX_DATAGRAM_SIZE:
        raise JausEncodeError(
            f"datagram of {len(datagram)} bytes exceeds the {MAX_DATAGRAM_SIZE}-byte maximum"
        )
    return datagram


def encode_datagram(messages: Message | Iterable[Message]) -> bytes:
    """One datagram holding ``messages`` (a record or several), encoded with their headers."""
    if isinstance(messages, Message):
        messages = (messages,)
    return frame(encode(message) for message in messages)


def split(data: bytes | bytearray | memoryview) -> list[bytes]:
    """The raw JAUS messages of a datagram, checked for framing only."""
    size = len(data)
    if size == 0:
        raise JausDecodeError("empty datagram")
    if size > MAX_DATAGRAM_SIZE:
        raise JausDecodeError(
            f"datagram of {size} bytes exceeds the {MAX_DATAGRAM_SIZE}-byte maximum"
        )
    if data[0] != TRANSPORT_VERSION:
        raise JausDecodeError(
            f"not a JUDP datagram: transport version 0x{data[0]:02X}, expected 0x01"
        )
    messages = []
    offset = 1
    while offset < size:
        if size - offset < _FRAME.size:
            raise JausDecodeError(
                f"truncated frame header at byte {offset}: {size - offset} bytes left"
            )
        compression, flags, length = _FRAME.unpack_from(data, offset)
        if length == _END:
            break
        if compression or flags:
            raise JausDecodeError(
                f"header compression (0x{compression:02X}, 0x{flags:02X}) at byte {offset} "
                "is not supported"
            )
        if not HEADER_SIZE <= length <= _MAX_FRAME_LENGTH:
            raise JausDecodeError(
                f"frame length {length} at byte {offset} is outside 16..{_MAX_FRAME_LENGTH}"
            )
        start = offset + _FRAME.size
        end = start + length
        if end > size:
            raise JausDecodeError(
                f"truncated message at byte {start}: frame says {length} bytes, {size - start} left"
            )
        messages.append(bytes(data[start:end]))
        offset = end
    if not messages:
        raise JausDecodeError("datagram holds no message")
    return messages


def decode_datagram(data: bytes | bytearray | memoryview,
                    reassembler: Reassembler | None = None, now_s: float = 0.0,
                    origin: object = None) -> list[Message]:
    """Every message of a datagram; raises :class:`JausDecodeError` (only) if any is malformed.

    Multi-packet packets are refused unless a ``reassembler`` is given: then they go to it and
    a message they complete is returned in their place (``now_s`` times them out; ``origin``,
    e.g. the sender's address, keeps different senders' packets apart).
    """
    return decode_messages(split(data), reassembler, now_s, origin)


def decode_messages(raws: Iterable[bytes], reassembler: Reassembler | None = None,
                    now_s: float = 0.0, origin: object = None) -> list[Message]:
    """:func:`decode_datagram` on messages already :func:`split` (a receiver can bound how
    many of a datagram's messages it decodes)."""
    messages = []
    for index, raw in enumerate(raws):
        try:
            if reassembler is None:
                messages.append(decode(raw))
            elif (message := reassembler.feed(raw, now_s, origin)) is not None:
                messages.append(message)
        except JausDecodeError as exc:
            raise JausDecodeError(f"message {index + 1}: {exc}") from None
    return messages


def pack(messages: Iterable[Message], max_size: int = MAX_DATAGRAM_SIZE) -> list[bytes]:
    """As few datagrams as hold ``messages`` in order, each at most ``max_size`` bytes."""
    datagrams: list[bytes] = []
    batch: list[bytes] = []
    used = 1
    for message in messages:
        raw = encode(message)
        if batch and used + _FRAME.size + len(raw) > max_size:
            datagrams.append(frame(batch))
            batch, used = [], 1
        batch.append(raw)
        used += _FRAME.size + len(raw)
    if batch:
        datagrams.append(frame(batch))
    return datagrams


def datagrams(messages: Iterable[Message], packed: bool = False) -> list[bytes]:
    """The datagrams carrying ``messages`` in order: one each (the default, what OpenJAUS
    sends and can receive), or as few as they fit in when ``packed``."""
    if packed:
        return pack(messages)
    return [frame((encode(message),)) for message in messages]
