"""Property tests: what encode -> decode -> encode keeps (headers, raw fields, non-negative
scaled raws) and what it moves (a negative signed scaled raw, one step toward zero); decoded
values within 1.5 steps of what was sent; NaN, infinities and out-of-range raw fields are
refused with JausEncodeError."""

from __future__ import annotations

import math
import struct
from typing import Any

import msgspec
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from jaus_strategies import ALL_TYPES, any_message, message_strategy

from overdrive.jaus import (
    CreateServiceConnection,
    Header,
    JausEncodeError,
    JausTimestamp,
    Message,
    Motion,
    ReportCurvature,
    ReportErrorCount,
    ReportVelocityState,
    ScaledInt,
    SetDiscreteDevices,
    SetMotionProfile,
    SetWrenchEffort,
    UnknownMessage,
    decode,
    decode_datagram,
    encode,
    encode_datagram,
    messages,
)
from overdrive.jaus.layout import FixedLayout, PresenceLayout, ScaledWire, Wire


def _signed_scaled_raws(message: Message, wire: bytes) -> list[tuple[int, int, bool]]:
    """(offset, raw, signed-scaled?) of each field of a layout message's payload."""
    layout = getattr(type(message), "layout", None)
    payload = wire[16:]
    if isinstance(layout, PresenceLayout):
        pv = int.from_bytes(payload[: layout.pv_size], "little")
        fields = [w for i, (_, w) in enumerate(layout.fields) if pv >> i & 1]
        fmt = "<" + layout.pv_fmt + "".join(w.fmt for w in fields)
        fields = [Wire(layout.pv_fmt), *fields]
    elif isinstance(layout, FixedLayout):
        fields = [w for _, w in layout.fields]
        fmt = "<" + "".join(w.fmt for w in fields)
    else:
        return []
    raws = struct.unpack(fmt, payload)
    return [(i, raw, isinstance(w, ScaledWire) and w.scaled.kind in ("short", "integer"))
            for i, (raw, w) in enumerate(zip(raws, fields, strict=True))]


@pytest.mark.parametrize("cls", ALL_TYPES, ids=lambda cls: cls.__name__)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_what_round_trips(cls: type[Message], data: st.DataObject) -> None:
    """decode then encode gives the same bytes, except that a negative raw of a signed scaled
    field comes back one step toward zero (OpenJAUS's decode/encode pair, docs/jaus.md);
    headers, raw fields and non-negative raws are fixed points."""
    message = data.draw(message_strategy(cls))
    wire = encode(message)
    again = decode(wire)
    assert type(again) is cls
    assert again.header == message.header
    rewire = encode(again)
    assert rewire[:16] == wire[:16]
    before, after = _signed_scaled_raws(message, wire), _signed_scaled_raws(again, rewire)
    if not before:
        assert rewire == wire
    for (_, raw, signed), (_, raw_again, _) in zip(before, after, strict=True):
        assert raw_again == (raw + 1 if signed and raw < 0 else raw)
    assert decode(rewire) == again or any(s and r < 0 for _, r, s in before)


def _scaled_fields(cls: type[Message]) -> list[tuple[str, ScaledWire]]:
    layout = getattr(cls, "layout", None)
    if not isinstance(layout, FixedLayout | PresenceLayout):
        return []
    return [(name, wire) for name, wire in layout.fields if isinstance(wire, ScaledWire)]


SCALED_TYPES = [cls for cls in ALL_TYPES if _scaled_fields(cls)]


@pytest.mark.parametrize("cls", SCALED_TYPES, ids=lambda cls: cls.__name__)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_decoded_values_within_one_step(cls: type[Message], data: st.DataObject) -> None:
    message = data.draw(message_strategy(cls))
    again = decode(encode(message))
    for name, wire in _scaled_fields(cls):
        sent, got = getattr(message, name), getattr(again, name)
        if sent is None:
            assert got is None
            continue
        scaled = wire.scaled
        clamped = min(max(sent, scaled.lo), scaled.hi)
        assert scaled.lo <= got <= scaled.hi
        assert abs(got - clamped) <= 1.5 * scaled.scale, name


@settings(max_examples=150, deadline=None)
@given(messages=st.lists(any_message, min_size=1, max_size=5))
def test_datagram_round_trip(messages: list[Message]) -> None:
    datagram = encode_datagram(messages)
    again = decode_datagram(datagram)
    assert [type(m) for m in again] == [type(m) for m in messages]
    assert [decode(encode(m)) for m in messages] == again


@given(kind=st.sampled_from(["byte", "short", "ushort", "integer", "uinteger"]), data=st.data())
def test_generated_code_agrees_with_scaled_int(kind: str, data: st.DataObject) -> None:
    """The layouts inline ScaledInt's arithmetic; both must give the same numbers."""
    lo = data.draw(st.floats(-1e4, 1e4))
    hi = lo + data.draw(st.floats(1e-2, 1e4))
    scaled = ScaledInt(kind, lo, hi)  # type: ignore[arg-type]
    layout = FixedLayout([("x", ScaledWire(scaled))])
    value = data.draw(st.floats(lo - (hi - lo), hi + (hi - lo)))
    raw = scaled.to_raw(value)
    assert layout.encode((value,)) == layout.struct.pack(raw)
    assert layout.decode(layout.struct.pack(raw), "x") == (scaled.from_raw(raw),)
    wire_raw = data.draw(st.integers(*_raw_bounds(layout.struct.format[-1])))
    assert layout.decode(layout.struct.pack(wire_raw), "x") == (scaled.from_raw(wire_raw),)


def _raw_bounds(fmt: str) -> tuple[int, int]:
    return {"B": (0, 255), "h": (-32768, 32767), "H": (0, 65535), "i": (-(2**31), 2**31 - 1),
            "I": (0, 2**32 - 1)}[fmt]  # fmt: skip


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize(
    "build",
    [
        lambda v: SetWrenchEffort.xgv(throttle_pct=v),
        lambda v: SetWrenchEffort(resistive_rotational_z_pct=v),
        lambda v: CreateServiceConnection(command_code=0x4404, rate_hz=v),
        lambda v: SetMotionProfile.single(speed_mps=v, max_accel_mps2=1.0),
        lambda v: SetMotionProfile.single(speed_mps=1.0, max_accel_mps2=1.0, curvature_1pm=v),
        lambda v: SetMotionProfile.single(speed_mps=1.0, max_accel_mps2=1.0, duration_s=v),
        lambda v: ReportVelocityState(yaw_rate_radps=v),
        lambda v: ReportCurvature(curvature_1pm=v),
    ],
)
def test_non_finite_values_are_refused(build: Any, bad: float) -> None:
    with pytest.raises(JausEncodeError, match="non-finite"):
        encode(build(bad))


@pytest.mark.parametrize(
    ("message", "field"),
    [
        (SetDiscreteDevices(gear=256), "gear"),
        (SetDiscreteDevices(gear=-1), "gear"),
        (SetDiscreteDevices(gear=2.0), "gear"),  # type: ignore[arg-type]
        (SetWrenchEffort.xgv(throttle_pct="50"), "propulsive_linear_x_pct"),  # type: ignore[arg-type]
        (CreateServiceConnection(command_code=0x10000, rate_hz=1.0), "command_code"),
        (ReportVelocityState(timestamp=JausTimestamp(millisecond=1024)), "timestamp"),
        (SetMotionProfile.single(1.0, 1.0, duration_s=65.536), "duration_s"),
        (SetMotionProfile.single(1.0, 1.0, duration_s=-0.1), "duration_s"),
        (ReportErrorCount(counts=(2**31,)), "must be an integer"),
        (SetMotionProfile(motions=(Motion(),) * 256), "255"),
    ],
)
def test_out_of_range_raw_fields_are_refused(message: Message, field: str) -> None:
    with pytest.raises(JausEncodeError, match=field):
        encode(message)


@pytest.mark.parametrize(
    "header",
    [
        Header(priority=16),
        Header(priority=-1),
        Header(ack_nak=4),
        Header(version=64),
        Header(sequence=0x10000),
        Header(data_flag=3),
        Header(priority=6.0),  # type: ignore[arg-type]
    ],
)
def test_bad_headers_are_refused(header: Header) -> None:
    with pytest.raises(JausEncodeError, match="header"):
        encode(SetWrenchEffort.xgv(throttle_pct=1.0), header)


def test_oversized_payload_is_refused() -> None:
    assert len(encode(UnknownMessage(0x9999, bytes(4080)))) == 16 + 4080
    with pytest.raises(JausEncodeError, match="4080"):
        encode(UnknownMessage(0x9999, bytes(4081)))


def test_clamping_out_of_range_scaled_values() -> None:
    high = decode(encode(SetWrenchEffort.xgv(throttle_pct=1e6, brake_pct=-5.0)))
    assert isinstance(high, SetWrenchEffort)
    assert high.throttle_pct == 100.0
    assert high.brake_pct == 0.0


def test_records_are_immutable() -> None:
    message = SetWrenchEffort.xgv(throttle_pct=10.0)
    with pytest.raises(AttributeError):
        message.propulsive_linear_x_pct = 20.0  # type: ignore[misc]
    assert message.with_header(sequence=4).header.sequence == 4
    assert msgspec.structs.replace(message, propulsive_linear_x_pct=20.0).throttle_pct == 20.0


SCALED_INTS = {
    name: value for name, value in vars(messages).items() if isinstance(value, ScaledInt)
}


@pytest.mark.parametrize("name", sorted(SCALED_INTS))
def test_every_encoder_output_decodes_back_to_itself(name: str) -> None:
    """Exhaustive for 8/16-bit fields, the ends and a sample for 32-bit ones: every raw the
    encoder can produce decodes inside [lo, hi] and re-encodes to itself (raw >= 0) or one
    step toward zero (raw < 0); raws no encoder produces decode to the clamped ends."""
    scaled = SCALED_INTS[name]
    bits = {"B": 8, "h": 16, "H": 16, "i": 32, "I": 32}[scaled.fmt]
    low, high = (
        (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if scaled.fmt.islower() else (0, 2**bits - 1)
    )
    if bits <= 16:
        raws: Any = range(low, high + 1)
    else:
        step = (high - low) // 40_000
        raws = [
            *range(low, low + 50),
            *range(low, high, step),
            *range(-50, 50),
            *range(high - 50, high + 1),
        ]
    first, last = scaled.to_raw(scaled.lo), scaled.to_raw(scaled.hi)
    for raw in raws:
        value = scaled.from_raw(raw)
        assert scaled.lo <= value <= scaled.hi
        again = scaled.to_raw(value)
        if first <= raw <= last:
            assert again == (raw + 1 if raw < 0 else raw), (raw, value)
        else:
            assert value in (scaled.lo, scaled.hi)
