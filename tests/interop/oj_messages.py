"""Generated JAUS 3.3 messages for the codec comparison with OpenJAUS's libjaus (ojcodec).

Every standard message type ojcodec knows: every presence-vector subset of the presence-vector
messages, the ends of every scaled range, values beyond them (the encoders clamp), zero,
values a hair either side of a step, and random values; random headers. Values are limited to
what OpenJAUS's structs can hold (noted where that narrows a field).
"""

from __future__ import annotations

import random
from collections.abc import Iterator
from typing import Any

from overdrive.jaus import Header, JausId, JausTimestamp, Message, message_types
from overdrive.jaus.layout import FixedLayout, PresenceLayout, ScaledWire, Wire
from overdrive.jaus.messages import TIMESTAMP

INT_BOUNDS = {"B": (0, 0xFF), "H": (0, 0xFFFF), "I": (0, 0xFFFFFFFF), "i": (-(2**31), 2**31 - 1)}
# OpenJAUS keeps only bit 0 of the emergency code and the parking-brake and horn bits of the
# second discrete-devices byte (its structs have one field per defined bit).
NARROWED = {"emergency_code": (0, 1), "parking_horn_flags": (0, 3)}
# ojcodec encodes and decodes these (its strcmp list); the discovery messages, which it only
# partly decodes, have their own test, and it knows neither Component Authority message
NOT_GENERAL = {0x2001, 0x4001, 0x2B00, 0x2B01, 0x2B03, 0x4B00, 0x4B01, 0x4B03}
STANDARD = [cls for cls in message_types() if not cls.experimental and cls.code not in NOT_GENERAL]


def scaled_value(rng: random.Random, wire: ScaledWire) -> float:
    s = wire.scaled
    span = s.hi - s.lo
    step = s.scale
    choice = rng.randrange(10)
    if choice == 0:
        return rng.choice([s.lo, s.hi])
    if choice == 1:
        return rng.choice([s.lo - span * rng.random(), s.hi + span * rng.random()])
    if choice == 2:
        return 0.0 if s.lo <= 0.0 <= s.hi else s.lo
    if choice == 3:  # just either side of a step boundary
        n = rng.randrange(-1000, 1000)
        return s.lo + (n + rng.choice([0.4999, 0.5, 0.5001])) * step
    return rng.uniform(s.lo, s.hi)


def field_value(rng: random.Random, name: str, wire: Wire) -> Any:
    if isinstance(wire, ScaledWire):
        return scaled_value(rng, wire)
    if wire is TIMESTAMP:
        return JausTimestamp(rng.randrange(32), rng.randrange(32), rng.randrange(64),
                             rng.randrange(64), rng.randrange(1024))
    low, high = NARROWED.get(name, INT_BOUNDS[wire.fmt])
    return rng.choice([low, high, rng.randint(low, high)])


def header(rng: random.Random) -> Header:
    def jaus_id() -> JausId:
        return JausId(*(rng.randrange(1, 256) for _ in range(4)))

    return Header(destination=jaus_id(), source=jaus_id(), priority=rng.randrange(16),
                  ack_nak=rng.randrange(4), service_connection=rng.random() < 0.5,
                  version=rng.randrange(64), sequence=rng.randrange(0x10000))


def build(rng: random.Random, cls: type[Message], pv: int | None = None) -> Message:
    layout = getattr(cls, "layout", None)
    values: dict[str, Any] = {}
    if isinstance(layout, PresenceLayout | FixedLayout):
        for i, (name, wire) in enumerate(layout.fields):
            if pv is None or pv >> i & 1:
                values[name] = field_value(rng, name, wire)
    elif cls.name == "report-component-control":
        values = {"controller": JausId(*(rng.randrange(256) for _ in range(4))),
                  "authority": rng.randrange(256)}
    return cls(**values, header=header(rng))


def generate(seed: int = 19, per_fixed_type: int = 120) -> Iterator[Message]:
    """Every presence subset once per presence-vector type, ``per_fixed_type`` of the others."""
    rng = random.Random(seed)
    for cls in STANDARD:
        layout = getattr(cls, "layout", None)
        if isinstance(layout, PresenceLayout):
            for pv in range(1 << len(layout.fields)):
                yield build(rng, cls, pv)
        else:
            count = per_fixed_type if getattr(layout, "fields", True) else 4
            for _ in range(count):
                yield build(rng, cls)


def to_ojcodec(message: Message, pv: int | None = None) -> str:
    """The ``E`` line that makes ojcodec build the same message with libjaus."""
    h = message.header
    parts = ["E", message.name, f"pri={h.priority}", f"ack={h.ack_nak}",
             f"sc={int(h.service_connection)}", f"exp={int(message.experimental)}",
             f"ver={h.version}", f"seq={h.sequence}", f"dst={h.destination}", f"src={h.source}"]
    if pv is not None:
        parts.append(f"pv={pv}")
    for name, value in message.fields_dict().items():
        parts.append(f"{name}={_text(value)}")
    return " ".join(parts)


def _text(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict):  # a timestamp
        return ":".join(str(value.get(k, 0)) for k in ("day", "hour", "minute", "second",
                                                       "millisecond"))
    return str(value)
