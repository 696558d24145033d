"""Wire format of bus messages between processes: a small versioned msgpack envelope.

A frame is the msgpack array ``[schema_version, type_name, sender, payload, sent_s]`` where
``payload`` is the message struct encoded as a msgpack map (field names kept, so a frame is
self-describing and readable by any msgpack tool). ``sender`` is the publishing node's name,
checked by the receiving bus against its publisher policy. ``sent_s`` is the send time on the
publisher's CLOCK_MONOTONIC (one clock for every process on a host; docs/multiprocess.md), put
there by the bus at publication; frames without it (4 elements, older writers) decode with NaN. Decoding is two-step: the envelope
first (payload kept raw), then the payload with the decoder of the named type, so an unknown
type or a frame from another schema version is refused before its payload is looked at.

Every way a frame can be bad raises ``WireError`` with a short ``reason``; the bus counts and
drops such frames, so a malformed frame never reaches a node.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec

from overdrive.messages import (
    ALL_MESSAGES,
    SCHEMA_VERSION,
    AdvanceAuthorization,
    CanTraffic,
    ClockEstimate,
    Display,
    DriveMode,
    DrivingStatus,
    GpsIns,
    Imu,
    MaxSpeed,
    Message,
    MoveCommand,
    MoveReply,
    MoveStatus,
    NodeTick,
    Notice,
    PedalCommand,
    PowertrainCommand,
    Radar,
    SafetyDevices,
    SetSpeed,
    SpeedState,
    SteerCommand,
    SteeringRequest,
    Topic,
    Truth,
    VehicleStatus,
    WheelSpeed,
)

MAX_FRAME_BYTES = 64 * 1024  # far above any message (largest, Truth, is ~250 B); refuses junk early

TOPIC_TYPES: dict[str, type] = {
    Topic.MOVE_COMMAND: MoveCommand, Topic.MOVE_REPLY: MoveReply, Topic.MOVE_STATUS: MoveStatus,
    Topic.PLANNER_CLOCK: ClockEstimate,
    Topic.STEERING: SteeringRequest, Topic.MAX_SPEED: MaxSpeed, Topic.ADVANCE: AdvanceAuthorization,
    Topic.DRIVE_MODE: DriveMode, Topic.DRIVING_STATUS: DrivingStatus, Topic.SET_SPEED: SetSpeed,
    Topic.SPEED_STATE: SpeedState, Topic.PEDALS: PedalCommand, Topic.STEER: SteerCommand,
    Topic.POWERTRAIN: PowertrainCommand, Topic.SAFETY: SafetyDevices,
    Topic.VEHICLE_STATUS: VehicleStatus, Topic.WHEEL_SPEED: WheelSpeed, Topic.GPS_INS: GpsIns,
    Topic.IMU: Imu, Topic.RADAR: Radar, Topic.TRUTH: Truth, Topic.NOTICE: Notice,
    Topic.TICK: NodeTick, Topic.DISPLAY: Display, Topic.CAN_FRAMES: CanTraffic,
}
"""The one message type each stack topic carries (messages.py's topic comments)."""


class Frame(msgspec.Struct, array_like=True, frozen=True):
    version: int
    type: str
    sender: str
    payload: msgspec.Raw
    sent_s: float = float("nan")


class WireError(ValueError):
    """A frame that cannot be delivered; ``reason`` is a short stable code for counting."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


def _message_classes() -> list[type]:
    found, todo = [], list(Message.__subclasses__())
    while todo:
        cls = todo.pop()
        found.append(cls)
        todo.extend(cls.__subclasses__())
    return found


class Registry:
    """Message types known on the wire, by class name, and the type each topic must carry.

    With ``discover`` (the default), every subclass of ``overdrive.messages.Message`` defined in
    an imported module is known too (servers add their own, e.g. the move server's
    ``ActuatorEstimates``); the class tree is re-read when a name is missed.
    """

    def __init__(self, types: tuple[type, ...] = ALL_MESSAGES,
                 topic_types: dict[str, type] | None = None, discover: bool = True) -> None:
        self._types: dict[str, type] = {}
        self._decoders: dict[str, msgspec.msgpack.Decoder] = {}
        self.topic_types: dict[str, type] = dict(TOPIC_TYPES if topic_types is None else topic_types)
        self._encoder = msgspec.msgpack.Encoder()
        self._frame_decoder = msgspec.msgpack.Decoder(Frame)
        self.discover = discover
        self._seen_classes = 0
        for cls in types:
            self.register(cls)
        self._discover()

    def _discover(self) -> bool:
        """Register Message subclasses imported since the last look; True if any was new."""
        if not self.discover:
            return False
        classes = _message_classes()
        if len(classes) == self._seen_classes:
            return False
        self._seen_classes = len(classes)
        added = False
        for cls in classes:
            if cls.__name__ not in self._types:
                self.register(cls)
                added = True
        return added

    def register(self, cls: type, topic: str | None = None) -> None:
        """Make ``cls`` (a msgspec Struct) decodable; with ``topic``, bind it as that topic's type."""
        if not (isinstance(cls, type) and issubclass(cls, msgspec.Struct)):
            raise TypeError(f"{cls!r} is not a msgspec.Struct")
        known = self._types.get(cls.__name__)
        if known is not None and known is not cls:
            raise ValueError(f"another type is already registered as {cls.__name__!r}")
        self._types[cls.__name__] = cls
        self._decoders[cls.__name__] = msgspec.msgpack.Decoder(cls)
        if topic is not None:
            self.topic_types[topic] = cls

    def __contains__(self, name: str) -> bool:
        return name in self._types

    def type_named(self, name: str) -> type:
        return self._types[name]

    def encode(self, msg: Any, sender: str, sent_s: float = float("nan")) -> bytes:
        name = type(msg).__name__
        if self._types.get(name) is not type(msg) and not (
                self._discover() and self._types.get(name) is type(msg)):
            raise TypeError(f"{name} is not a registered message type")
        return self._encoder.encode((SCHEMA_VERSION, name, sender, msg, sent_s))

    def decode(self, data: bytes | bytearray | memoryview, topic: str | None = None) -> tuple[str, Any]:
        """Return ``(sender, message)``; raise ``WireError`` for anything that is not a valid frame."""
        sender, msg, _sent_s = self.decode_stamped(data, topic)
        return sender, msg

    def decode_stamped(self, data: bytes | bytearray | memoryview,
                       topic: str | None = None) -> tuple[str, Any, float]:
        """``decode`` plus the frame's send time (NaN when absent or not finite)."""
        if len(data) > MAX_FRAME_BYTES:
            raise WireError("too_large", f"{len(data)} bytes")
        try:
            frame = self._frame_decoder.decode(data)
        except (msgspec.MsgspecError, ValueError) as exc:   # incl. invalid UTF-8 in a str
            raise WireError("malformed", str(exc)) from None
        if frame.version != SCHEMA_VERSION:
            raise WireError("version", f"schema {frame.version}, expected {SCHEMA_VERSION}")
        decoder = self._decoders.get(frame.type)
        if decoder is None and self._discover():
            decoder = self._decoders.get(frame.type)
        if decoder is None:
            raise WireError("unknown_type", frame.type[:64])
        expected = self.topic_types.get(topic) if topic is not None else None
        if expected is not None and expected.__name__ != frame.type:
            raise WireError("topic_type", f"{frame.type[:64]} on {topic}, expected {expected.__name__}")
        try:
            msg = decoder.decode(frame.payload)
        except (msgspec.MsgspecError, ValueError) as exc:   # incl. invalid UTF-8 in a str
            raise WireError("payload", str(exc)) from None
        sent_s = frame.sent_s if math.isfinite(frame.sent_s) else math.nan
        return frame.sender, msg, sent_s


__all__ = ["MAX_FRAME_BYTES", "TOPIC_TYPES", "Frame", "Registry", "WireError"]
