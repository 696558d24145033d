"""Multi-packet messages (issue 19): split, reassembled in any order after FIRST, and refused
with a reason when they cannot be joined."""

from __future__ import annotations

import contextlib
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive.jaus import (
    DataFlag,
    Header,
    JausDecodeError,
    JausId,
    ReportErrorCount,
    UnknownMessage,
    decode,
    decode_header,
)
from overdrive.jaus.judp import decode_datagram, frame
from overdrive.jaus.multipacket import MAX_MESSAGE_SIZE, MAX_OPEN, Reassembler, split

BIG = ReportErrorCount(counts=tuple(range(-100, 155)), header=Header(sequence=65530))


def flags(packets: list[bytes]) -> list[int]:
    return [decode_header(p)[0].data_flag for p in packets]


def test_split_flags_and_sequences() -> None:
    packets = split(BIG, packet_payload=100)
    assert flags(packets) == [1] + [2] * (len(packets) - 2) + [8]
    assert [decode_header(p)[0].sequence for p in packets[:8]] == [
        65530, 65531, 65532, 65533, 65534, 65535, 0, 1]   # wraps at 65536
    assert split(ReportErrorCount(counts=(1,))) == [split(ReportErrorCount(counts=(1,)))[0]]
    assert flags(split(ReportErrorCount(counts=(1,)))) == [0]


@settings(max_examples=60, deadline=None)
@given(size=st.integers(4, 1100), seed=st.integers(0, 2**32))   # <= 256 packets
def test_reassembled_in_any_order_after_first(size: int, seed: int) -> None:
    message = BIG
    packets = split(message, packet_payload=size)
    rest = packets[1:]
    random.Random(seed).shuffle(rest)
    reassembler = Reassembler()
    results = [reassembler.feed(p, 0.0) for p in [packets[0], *rest]]
    assert results[:-1] == [None] * (len(packets) - 1) or len(packets) == 1
    assert results[-1] == message
    assert reassembler.open == {}


def test_retransmitted_packet_replaces_and_datagrams_carry_packets() -> None:
    packets = split(BIG, packet_payload=300)
    reassembler = Reassembler()
    again = bytearray(packets[1])
    again[13] = (again[13] & 0x0F) | DataFlag.RETRANSMITTED << 4
    datagrams = [frame([packets[0], packets[1]]), frame([bytes(again)]),
                 frame(packets[2:])]
    got = [m for d in datagrams for m in decode_datagram(d, reassembler, 0.0)]
    assert got == [BIG]
    with pytest.raises(JausDecodeError, match="multi-packet"):
        decode_datagram(datagrams[0])          # without a reassembler: refused, as before


@pytest.mark.parametrize(("attack", "reason"), [
    (lambda p: [p[1]], "no FIRST"),
    (lambda p: [p[0], p[-1], p[-1]], "sent twice"),
    (lambda p: [p[0], p[1], p[1]], "sent twice"),
    (lambda p: split(BIG, packet_payload=1), "outside the message"),   # > MAX_PACKETS
])
def test_what_cannot_be_reassembled_is_refused(attack: object, reason: str) -> None:
    packets = split(BIG, packet_payload=300)
    reassembler = Reassembler()
    with pytest.raises(JausDecodeError, match=reason):
        for packet in attack(packets):  # type: ignore[operator]
            reassembler.feed(packet, 0.0)
    assert reassembler.open == {}


def test_oversized_and_too_many_and_stale_messages_are_refused() -> None:
    huge = UnknownMessage(0x1234, bytes(MAX_MESSAGE_SIZE), header=Header())
    packets = split(huge)
    reassembler = Reassembler()
    extra = bytearray(packets[1])                        # one more NORMAL past the limit
    extra[14:16] = ((decode_header(packets[-1])[0].sequence + 1) % 65536).to_bytes(2, "little")
    with pytest.raises(JausDecodeError, match="exceeds"):
        for packet in [*packets[:-1], bytes(extra)]:
            reassembler.feed(packet, 0.0)
    for i in range(MAX_OPEN):
        message = ReportErrorCount(counts=(1,) * 200, header=Header(source=JausId(1, 9, i + 1)))
        assert reassembler.feed(split(message, 100)[0], 0.0) is None
    late = ReportErrorCount(counts=(1,) * 200, header=Header(source=JausId(1, 9, 99)))
    with pytest.raises(JausDecodeError, match="in progress"):
        reassembler.feed(split(late, 100)[0], 0.0)
    assert reassembler.feed(split(late, 100)[0], 5.0) is None   # the stale ones expired
    assert len(reassembler.open) == 1 and reassembler.dropped >= MAX_OPEN


def test_single_packets_pass_straight_through() -> None:
    wire = split(ReportErrorCount(counts=(7,)))[0]
    assert Reassembler().feed(wire, 0.0) == decode(wire)


@settings(max_examples=200, deadline=None)
@given(seed=st.integers(0, 2**32))
def test_mutated_packet_streams_raise_only_decode_errors(seed: int) -> None:
    """Flipped bits, dropped, duplicated and reordered packets of several messages."""
    from overdrive.fuzzing import mutate

    rng = random.Random(seed)
    packets = [p for i in range(3) for p in split(
        ReportErrorCount(counts=(i,) * 100, header=Header(source=JausId(1, 9, i + 1))), 64)]
    rng.shuffle(packets)
    reassembler = Reassembler()
    for packet in packets:
        data = mutate(packet, rng) if rng.random() < 0.3 else packet
        with contextlib.suppress(JausDecodeError):
            reassembler.feed(data, rng.random())
    assert len(reassembler.open) <= MAX_OPEN


def test_packets_from_another_origin_neither_complete_nor_replace() -> None:
    """A spoofer claiming the same ids from elsewhere cannot hijack a message."""
    packets = split(BIG, packet_payload=300)
    reassembler = Reassembler()
    assert reassembler.feed(packets[0], 0.0, origin="real") is None
    assert reassembler.feed(packets[0], 0.0, origin="spoofer") is None   # its own stream
    for packet in packets[1:-1]:
        assert reassembler.feed(packet, 0.0, origin="real") is None
    with pytest.raises(JausDecodeError, match="no FIRST"):
        reassembler.feed(packets[1], 0.0, origin="elsewhere")
    assert reassembler.feed(packets[-1], 0.0, origin="real") == BIG
    assert reassembler.dropped == 0
