"""Wire frames: every message round-trips; anything else is refused with a reason, never raised."""

from __future__ import annotations

import contextlib

import msgspec
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from overdrive.bus.wire import TOPIC_TYPES, Registry, WireError
from overdrive.messages import ALL_MESSAGES, SCHEMA_VERSION, Message, SetSpeed, Topic

REGISTRY = Registry()
SPSS = SetSpeed(speed_mps=5.0, accel_mps2=1.0, gear="drive", state="run")
ANY_MESSAGE = st.sampled_from(ALL_MESSAGES).flatmap(st.from_type)


def _same(a: object, b: object) -> bool:
    """Equal as encoded (NaN-safe)."""
    return type(a) is type(b) and msgspec.msgpack.encode(a) == msgspec.msgpack.encode(b)


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(msg=ANY_MESSAGE, sender=st.text(max_size=20))
def test_every_message_round_trips_with_its_sender(msg: Message, sender: str) -> None:
    try:
        frame = REGISTRY.encode(msg, sender)
    except OverflowError:          # ints beyond 64 bits cannot be msgpack; the bus counts these
        assume(False)
    got_sender, got = REGISTRY.decode(frame)
    assert got_sender == sender and _same(got, msg)


def test_topic_types_cover_every_stack_topic_and_are_enforced() -> None:
    topics = {v for k, v in vars(Topic).items() if k.isupper()}
    assert topics == set(TOPIC_TYPES)
    frame = REGISTRY.encode(SPSS, "driving")
    assert REGISTRY.decode(frame, Topic.SET_SPEED)[1] == SPSS
    with pytest.raises(WireError) as exc:
        REGISTRY.decode(frame, Topic.PEDALS)
    assert exc.value.reason == "topic_type"


@pytest.mark.parametrize(("frame", "reason"), [
    (b"", "malformed"),
    (b"\xc1", "malformed"),
    (msgspec.msgpack.encode((SCHEMA_VERSION + 1, "SetSpeed", "driving", {})), "version"),
    (msgspec.msgpack.encode((SCHEMA_VERSION, "Nope", "driving", {})), "unknown_type"),
    (msgspec.msgpack.encode((SCHEMA_VERSION, "SetSpeed", "driving", {"speed_mps": "fast"})), "payload"),
    (msgspec.msgpack.encode((SCHEMA_VERSION, "SetSpeed", "driving", {"extra": 1})), "payload"),
    (msgspec.msgpack.encode((SCHEMA_VERSION, "SetSpeed", 7, {})), "malformed"),
    (msgspec.msgpack.encode([SCHEMA_VERSION, "SetSpeed"]), "malformed"),
    (b"\x94" + b"\x00" * 70_000, "too_large"),
])
def test_bad_frames_are_refused_with_a_reason(frame: bytes, reason: str) -> None:
    with pytest.raises(WireError) as exc:
        REGISTRY.decode(frame, Topic.SET_SPEED)
    assert exc.value.reason == reason


@settings(max_examples=500)
@given(data=st.binary(max_size=300))
def test_random_bytes_never_escape_as_anything_but_wire_error(data: bytes) -> None:
    with contextlib.suppress(WireError):
        REGISTRY.decode(data, Topic.SET_SPEED)


@settings(max_examples=500)
@given(msg=ANY_MESSAGE, flips=st.lists(st.tuples(st.integers(0, 10_000), st.integers(1, 255)),
                                       min_size=1, max_size=4),
       cut=st.integers(0, 10_000))
def test_mutated_frames_decode_to_a_valid_message_or_wire_error(msg: Message, flips, cut: int) -> None:
    try:
        frame = bytearray(REGISTRY.encode(msg, "x"))
    except OverflowError:
        assume(False)
    for pos, xor in flips:
        frame[pos % len(frame)] ^= xor
    frame = frame[: max(1, cut % (len(frame) + 1))]
    try:
        _sender, got = REGISTRY.decode(bytes(frame))
    except WireError:
        return
    assert isinstance(got, Message)


def test_registry_discovers_message_subclasses_and_refuses_name_clashes() -> None:
    class LateMessage(Message, frozen=True):
        value_m: float

    registry = Registry()
    frame = registry.encode(LateMessage(value_m=1.5), "x")
    assert registry.decode(frame)[1] == LateMessage(value_m=1.5)
    assert Registry(discover=False).type_named("SetSpeed") is SetSpeed
    with pytest.raises(TypeError):
        Registry(discover=False).encode(LateMessage(value_m=1.0), "x")

    class SetSpeed2(msgspec.Struct):
        x: int
    SetSpeed2.__name__ = "SetSpeed"
    with pytest.raises(ValueError, match="already registered"):
        registry.register(SetSpeed2)
