"""JAUS 3.3 message records and their payload layouts.

One frozen record per message of reference §4 (core), §5 (platform) and §6 (TORC
experimental). Quantities are SI with the unit in the name; enumerations and bit fields stay
integers, with ``IntEnum``/``IntFlag`` helpers for their values. Presence-vector messages
take ``None`` for an absent field and compute the presence vector when encoded.

Every record ends with a ``header`` whose default addresses the component that normally
receives it (commands, queries) or sends it (reports), per reference §6-7; pass your own
``Header`` (or use ``with_header``/the transport) to address anything else.
"""

from __future__ import annotations

import math
import struct
from datetime import datetime
from enum import IntEnum, IntFlag
from typing import Any, ClassVar, Final, Self, TypeVar

import msgspec

from overdrive.jaus.addresses import (
    DEFAULT_AUTHORITY,
    DEFAULT_CLIENT_ID,
    XGV_ERROR_MANAGER,
    XGV_MOTION_PROFILE_DRIVER,
    XGV_NODE_MANAGER,
    XGV_PRIMITIVE_DRIVER,
    XGV_SIGNALS_DRIVER,
    JausId,
)
from overdrive.jaus.codec import (
    Header,
    JausDecodeError,
    JausEncodeError,
    Message,
    ScaledInt,
    register,
)
from overdrive.jaus.layout import ENCODE_FAILURES, FixedLayout, PresenceLayout, ScaledWire, Wire

# --------------------------------------------------------------------------- default headers

TO_PRIMITIVE_DRIVER: Final = Header(destination=XGV_PRIMITIVE_DRIVER, source=DEFAULT_CLIENT_ID)
TO_MOTION_PROFILE_DRIVER: Final = Header(
    destination=XGV_MOTION_PROFILE_DRIVER, source=DEFAULT_CLIENT_ID
)
TO_SIGNALS_DRIVER: Final = Header(destination=XGV_SIGNALS_DRIVER, source=DEFAULT_CLIENT_ID)
FROM_PRIMITIVE_DRIVER: Final = Header(destination=DEFAULT_CLIENT_ID, source=XGV_PRIMITIVE_DRIVER)
FROM_MOTION_PROFILE_DRIVER: Final = Header(
    destination=DEFAULT_CLIENT_ID, source=XGV_MOTION_PROFILE_DRIVER
)
FROM_NODE_MANAGER: Final = Header(destination=DEFAULT_CLIENT_ID, source=XGV_NODE_MANAGER)
FROM_SIGNALS_DRIVER: Final = Header(destination=DEFAULT_CLIENT_ID, source=XGV_SIGNALS_DRIVER)
FROM_ERROR_MANAGER: Final = Header(destination=DEFAULT_CLIENT_ID, source=XGV_ERROR_MANAGER)
# reference §4: service-connection messages carry the service-connection flag
SERVICE_TO_PRIMITIVE_DRIVER: Final = TO_PRIMITIVE_DRIVER.replace(service_connection=True)
SERVICE_FROM_PRIMITIVE_DRIVER: Final = FROM_PRIMITIVE_DRIVER.replace(service_connection=True)

# --------------------------------------------------------------------------- wire field types

U8: Final = Wire("B")
U16: Final = Wire("H")
U32: Final = Wire("I")
I32: Final = Wire("i")


def _checked(wire: Wire, value: int) -> int:
    """``value`` after checking it fits ``wire`` (for the hand-written payloads)."""
    wire.check(value)
    return value


def _atan_scaled(scaled: ScaledInt) -> Wire:
    """Curvature carried as atan(curvature) in a scaled integer (reference §6)."""
    half_pi = math.pi / 2

    def to_raw(curvature_1pm: float) -> int:
        if not math.isfinite(curvature_1pm):
            raise JausEncodeError(f"cannot encode non-finite value {curvature_1pm!r}")
        return scaled.to_raw(math.atan(curvature_1pm))

    def from_raw(raw: int) -> float:
        # from_raw already clamps to [-pi/2, pi/2]; the float pi/2 is just below the true
        # value, so tan stays positive at the top end
        return math.tan(max(-half_pi, min(half_pi, scaled.from_raw(raw))))

    return Wire(scaled.fmt, to_raw, from_raw)


_MS_PER_S: Final = 1000.0


def _millis_to_raw(duration_s: float) -> int:
    if not math.isfinite(duration_s):
        raise JausEncodeError(f"cannot encode non-finite value {duration_s!r}")
    millis = round(duration_s * _MS_PER_S)
    if not 0 <= millis <= 0xFFFF:
        raise JausEncodeError(f"must be 0..65.535 s, got {duration_s!r}")
    return millis


MILLIS_U16: Final = Wire("H", _millis_to_raw, lambda raw: raw / _MS_PER_S)
"""A duration in seconds carried as raw milliseconds in a u16 (reference §6)."""


# --------------------------------------------------------------------------- timestamp


class JausTimestamp(msgspec.Struct, frozen=True):
    """The u32 timestamp of reference §5: bits 0-9 ms, 10-15 s, 16-21 min, 22-26 h, 27-31 day.

    Values are checked against the bit widths only (ms up to 1023, s up to 63, ...) so any
    timestamp read off the wire re-encodes unchanged.
    """

    day: int = 0
    hour: int = 0
    minute: int = 0
    second: int = 0
    millisecond: int = 0

    @classmethod
    def from_datetime(cls, moment: datetime) -> JausTimestamp:
        """The timestamp of a given moment (the caller picks the clock)."""
        return cls(
            moment.day, moment.hour, moment.minute, moment.second, moment.microsecond // 1000
        )

    def to_raw(self) -> int:
        """The packed u32; raises JausEncodeError when a part overflows its bits."""
        return _timestamp_to_raw(self)

    @classmethod
    def from_raw(cls, raw: int) -> JausTimestamp:
        return cls(
            raw >> 27, (raw >> 22) & 0x1F, (raw >> 16) & 0x3F, (raw >> 10) & 0x3F, raw & 0x3FF
        )


def _timestamp_to_raw(value: JausTimestamp) -> int:
    if type(value) is not JausTimestamp:
        raise JausEncodeError(f"must be a JausTimestamp, got {type(value).__name__}")
    day, hour, minute, second, ms = msgspec.structs.astuple(value)
    try:
        # bit widths of reference §5: ms 10, s 6, min 6, h 5, day 5; a negative part
        # shifted right stays non-zero, a float part fails the shift
        if not (ms >> 10 | second >> 6 | minute >> 6 | hour >> 5 | day >> 5):
            return ms | second << 10 | minute << 16 | hour << 22 | day << 27
    except TypeError:
        pass
    raise JausEncodeError(f"timestamp parts must be integers within their bits, got {value!r}")


class _TimestampWire(Wire):
    """The timestamp field, with its unpacking inlined into the generated decoders."""

    __slots__ = ()

    def decode_source(self, var: str, ns: dict[str, Any], tag: str) -> list[str]:
        ns["JausTimestamp"] = JausTimestamp
        return [
            f"{var} = JausTimestamp({var} >> 27, {var} >> 22 & 0x1F, {var} >> 16 & 0x3F, "
            f"{var} >> 10 & 0x3F, {var} & 0x3FF)"  # JausTimestamp.from_raw
        ]


TIMESTAMP: Final = _TimestampWire("I", _timestamp_to_raw, JausTimestamp.from_raw)

# --------------------------------------------------------------------------- scaled field types

_PI: Final = math.pi
PCT_PROPULSIVE: Final = ScaledInt("short", -100.0, 100.0)  # §5 wrench bits 0-5
PCT_RESISTIVE: Final = ScaledInt("byte", 0.0, 100.0)  # §5 wrench bits 6-11
RATE_HZ: Final = ScaledInt("ushort", 0.0, 1092.0)  # §4 Create/Confirm Service Connection
VELOCITY_MPS: Final = ScaledInt("integer", -65.534, 65.534)  # §5 velocity state bits 0-2
VELOCITY_RMS_MPS: Final = ScaledInt("uinteger", 0.0, 100.0)  # §5 velocity state bit 3
RATE_RADPS: Final = ScaledInt("short", -32.767, 32.767)  # §5 velocity state bits 4-6
RATE_RMS_RADPS: Final = ScaledInt("ushort", 0.0, _PI)  # §5 velocity state bit 7
LATITUDE_DEG: Final = ScaledInt("integer", -90.0, 90.0)  # §5 global pose bit 0
LONGITUDE_DEG: Final = ScaledInt("integer", -180.0, 180.0)  # §5 global pose bit 1
ELEVATION_M: Final = ScaledInt("integer", -10000.0, 35000.0)  # §5 global/local pose bit 2
POSITION_RMS_M: Final = ScaledInt("uinteger", 0.0, 100.0)  # §5 pose bit 3
LOCAL_XY_M: Final = ScaledInt("integer", -100000.0, 100000.0)  # §5 local pose bits 0-1
ATTITUDE_RAD: Final = ScaledInt("short", -_PI, _PI)  # §5 pose bits 4-6
ATTITUDE_RMS_RAD: Final = ScaledInt("ushort", 0.0, _PI)  # §5 pose bit 7
PROFILE_SPEED_MPS: Final = ScaledInt("ushort", -65.535, 65.535)  # §6 Set Motion Profile
PROFILE_ACCEL_MPS2: Final = ScaledInt("ushort", 0.0, 100.0)  # §6 Set Motion Profile
CURVATURE_ANGLE_RAD: Final = ScaledInt("ushort", -_PI / 2, _PI / 2)  # §6 atan(curvature)
CURVATURE_RATE_1PMS: Final = ScaledInt("ushort", 0.0, 10.0)  # §6 Set Motion Profile
WHEEL_SPEED_MPS: Final = ScaledInt("ushort", -65.535, 65.535)  # §6 Report Wheels Speed

_CURVATURE: Final = _atan_scaled(CURVATURE_ANGLE_RAD)

# --------------------------------------------------------------------------- layouts


class _LayoutMessage(Message, frozen=True):
    """A record whose payload is its fields, in declaration order, per ``layout``."""

    layout: ClassVar[FixedLayout | PresenceLayout]

    def encode_payload(self) -> bytes:
        values = msgspec.structs.astuple(self)
        try:
            return self.layout.encode_values(values)
        except ENCODE_FAILURES:
            raise JausEncodeError(self.layout.problem(values)) from None

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        return cls(*cls.layout.decode(payload, cls.name), header)


def _fixed(*fields: tuple[str, Wire]) -> FixedLayout:
    return FixedLayout(fields)


def _presence(pv_fmt: str, *fields: tuple[str, Wire]) -> PresenceLayout:
    return PresenceLayout(pv_fmt, fields)


_EMPTY: Final = _fixed()

_M = TypeVar("_M", bound=type[Message])


def _message(cls: _M) -> _M:
    """Register a record, checking that a layout covers its fields in order then ``header``."""
    fields = cls.__struct_fields__
    if fields[-1] != "header":
        raise TypeError(f"{cls.__name__}: the last field must be 'header'")
    layout = getattr(cls, "layout", None)
    if layout is not None and layout.names != fields[:-1]:
        raise TypeError(
            f"{cls.__name__}: layout {layout.names} does not match fields {fields[:-1]}"
        )
    return register(cls)


# =========================================================================== §4 core messages


@_message
class SetComponentAuthority(_LayoutMessage, frozen=True):
    """0x0001: set the receiving component's authority."""

    code = 0x0001
    name = "set-component-authority"
    layout = _fixed(("authority", U8))
    authority: int = DEFAULT_AUTHORITY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class Shutdown(_LayoutMessage, frozen=True):
    """0x0002: component status to shutdown."""

    code = 0x0002
    name = "shutdown"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class Standby(_LayoutMessage, frozen=True):
    """0x0003: component status to standby (the XGV's software pause, reference §7)."""

    code = 0x0003
    name = "standby"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class Resume(_LayoutMessage, frozen=True):
    """0x0004: component status back to ready."""

    code = 0x0004
    name = "resume"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class Reset(_LayoutMessage, frozen=True):
    """0x0005: reinitialise the component."""

    code = 0x0005
    name = "reset"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class SetEmergency(_LayoutMessage, frozen=True):
    """0x0006: raise an emergency (u16 emergency code, bit 0 = set)."""

    code = 0x0006
    name = "set-emergency"
    layout = _fixed(("emergency_code", U16))
    emergency_code: int = 1
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ClearEmergency(_LayoutMessage, frozen=True):
    """0x0007: clear an emergency (u16 emergency code, bit 0 = clear)."""

    code = 0x0007
    name = "clear-emergency"
    layout = _fixed(("emergency_code", U16))
    emergency_code: int = 1
    header: Header = TO_PRIMITIVE_DRIVER


class ServiceConnectionResponse(IntEnum):
    """Confirm Service Connection response codes (reference §4)."""

    CREATED = 0
    NODE_NOT_CAPABLE = 1
    COMPONENT_NOT_CAPABLE = 2
    INSUFFICIENT_AUTHORITY = 3
    REFUSED = 4
    INVALID_PARAMETER = 5
    NOT_SUPPORTED = 6


@_message
class CreateServiceConnection(_LayoutMessage, frozen=True):
    """0x0008: ask for ``command_code`` reports at ``rate_hz`` with ``presence_vector``."""

    code = 0x0008
    name = "create-service-connection"
    layout = _fixed(
        ("command_code", U16), ("rate_hz", ScaledWire(RATE_HZ)), ("presence_vector", U32)
    )
    command_code: int
    rate_hz: float
    presence_vector: int = 0
    header: Header = SERVICE_TO_PRIMITIVE_DRIVER


@_message
class ConfirmServiceConnection(_LayoutMessage, frozen=True):
    """0x0009: answer to Create Service Connection (``response``: ServiceConnectionResponse)."""

    code = 0x0009
    name = "confirm-service-connection"
    layout = _fixed(
        ("command_code", U16),
        ("instance_id", U8),
        ("rate_hz", ScaledWire(RATE_HZ)),
        ("response", U8),
    )
    command_code: int
    instance_id: int
    rate_hz: float
    response: int = ServiceConnectionResponse.CREATED
    header: Header = SERVICE_FROM_PRIMITIVE_DRIVER


@_message
class ActivateServiceConnection(_LayoutMessage, frozen=True):
    """0x000A: resume a suspended service connection."""

    code = 0x000A
    name = "activate-service-connection"
    layout = _fixed(("command_code", U16), ("instance_id", U8))
    command_code: int
    instance_id: int
    header: Header = SERVICE_TO_PRIMITIVE_DRIVER


@_message
class SuspendServiceConnection(_LayoutMessage, frozen=True):
    """0x000B: pause a service connection."""

    code = 0x000B
    name = "suspend-service-connection"
    layout = _fixed(("command_code", U16), ("instance_id", U8))
    command_code: int
    instance_id: int
    header: Header = SERVICE_TO_PRIMITIVE_DRIVER


@_message
class TerminateServiceConnection(_LayoutMessage, frozen=True):
    """0x000C: end a service connection."""

    code = 0x000C
    name = "terminate-service-connection"
    layout = _fixed(("command_code", U16), ("instance_id", U8))
    command_code: int
    instance_id: int
    header: Header = SERVICE_TO_PRIMITIVE_DRIVER


@_message
class RequestComponentControl(_LayoutMessage, frozen=True):
    """0x000D: ask to control the receiving component with ``authority``."""

    code = 0x000D
    name = "request-component-control"
    layout = _fixed(("authority", U8))
    authority: int = DEFAULT_AUTHORITY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReleaseComponentControl(_LayoutMessage, frozen=True):
    """0x000E: give control back (the XGV then enters software pause, reference §7)."""

    code = 0x000E
    name = "release-component-control"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


class ControlResponse(IntEnum):
    """Confirm Component Control response codes (reference §4)."""

    ACCEPTED = 0
    NOT_SUPPORTED = 1
    NOT_ACCEPTED = 2


@_message
class ConfirmComponentControl(_LayoutMessage, frozen=True):
    """0x000F: answer to Request Component Control (``response``: ControlResponse)."""

    code = 0x000F
    name = "confirm-component-control"
    layout = _fixed(("response", U8))
    response: int = ControlResponse.ACCEPTED
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class RejectComponentControl(_LayoutMessage, frozen=True):
    """0x0010: control taken away (or refused)."""

    code = 0x0010
    name = "reject-component-control"
    layout = _EMPTY
    header: Header = FROM_PRIMITIVE_DRIVER


class ComponentStatus(IntEnum):
    """Report Component Status primary status (reference §4)."""

    INITIALIZE = 0
    READY = 1
    STANDBY = 2
    SHUTDOWN = 3
    FAILURE = 4
    EMERGENCY = 5


_STATUS_NAMES: Final = {int(s): s.name.lower() for s in ComponentStatus}


class XgvSecondaryStatus(IntFlag):
    """XGV bits of Report Component Status' secondary status (reference §4).

    Bits 19-20 hold the SafeStop link status (0 no link, 1 bypass, 2 link good); read them
    with ``(secondary_status >> LINK_STATUS_SHIFT) & 0b11``.
    """

    MANUAL_OVERRIDE = 1 << 16
    SAFESTOP_PAUSE = 1 << 17
    SAFESTOP_STOP = 1 << 18
    LINK_STATUS = 0b11 << 19
    EXTERNAL_ESTOP = 1 << 21
    COMPUTER_STEERING = 1 << 22
    COMPUTER_SPEED = 1 << 23
    DOOR_PAUSE = 1 << 24
    ERROR_PAUSE = 1 << 25
    EMERGENCY_MANUAL_OVERRIDE = 1 << 26
    STEERING_NEEDS_INIT = 1 << 27
    STEERING_INIT_NEEDS_USER_INPUT = 1 << 28


LINK_STATUS_SHIFT: Final = 19  # reference §4: secondary status bits 19-20


@_message
class QueryComponentStatus(_LayoutMessage, frozen=True):
    """0x2002."""

    code = 0x2002
    name = "query-component-status"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportComponentStatus(_LayoutMessage, frozen=True):
    """0x4002: ``primary_status`` (ComponentStatus) and ``secondary_status`` (XgvSecondaryStatus)."""

    code = 0x4002
    name = "report-component-status"
    layout = _fixed(("primary_status", U8), ("secondary_status", U32))
    primary_status: int = ComponentStatus.READY
    secondary_status: int = 0
    header: Header = FROM_PRIMITIVE_DRIVER

    def fields_dict(self) -> dict[str, Any]:
        fields = super().fields_dict()
        if self.primary_status in _STATUS_NAMES:
            fields["primary_status_name"] = _STATUS_NAMES[self.primary_status]
        return fields


@_message
class QueryComponentControl(_LayoutMessage, frozen=True):
    """0x200D."""

    code = 0x200D
    name = "query-component-control"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


_CONTROLLER: Final = struct.Struct(
    "<BBBBB"
)  # reference §4: subsystem, node, component, instance, authority


@_message
class ReportComponentControl(Message, frozen=True):
    """0x400D: who controls the component (0.0.0.0 when nobody) and with what authority."""

    code = 0x400D
    name = "report-component-control"
    controller: JausId = JausId(0, 0, 0, 0)
    authority: int = 0
    header: Header = FROM_PRIMITIVE_DRIVER

    def encode_payload(self) -> bytes:
        c = self.controller
        if not isinstance(c, JausId):
            raise JausEncodeError(f"controller must be a JausId, got {type(c).__name__}")
        return _CONTROLLER.pack(
            c.subsystem, c.node, c.component, c.instance, _checked(U8, self.authority)
        )

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        if len(payload) != _CONTROLLER.size:
            raise JausDecodeError(
                f"{cls.name}: payload is {len(payload)} bytes, expected {_CONTROLLER.size}"
            )
        subsystem, node, component, instance, authority = _CONTROLLER.unpack(payload)
        return cls(JausId(subsystem, node, component, instance), authority, header)


@_message
class QueryHeartbeatPulse(_LayoutMessage, frozen=True):
    """0x2202."""

    code = 0x2202
    name = "query-heartbeat-pulse"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportHeartbeatPulse(_LayoutMessage, frozen=True):
    """0x4202: the XGV sends it unprompted at about 1 Hz (reference §2)."""

    code = 0x4202
    name = "report-heartbeat-pulse"
    layout = _EMPTY
    header: Header = FROM_NODE_MANAGER


@_message
class QueryComponentAuthority(_LayoutMessage, frozen=True):
    """0x2001 (OpenJAUS's core services list it, jausService.c)."""

    code = 0x2001
    name = "query-component-authority"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportComponentAuthority(_LayoutMessage, frozen=True):
    """0x4001: the component's authority (what Set Component Authority set)."""

    code = 0x4001
    name = "report-component-authority"
    layout = _fixed(("authority", U8))
    authority: int = 0
    header: Header = FROM_PRIMITIVE_DRIVER


# ----------------------------------------------------------------- dynamic configuration
# Discovery, as OpenJAUS 3.3's node manager does it (libjaus dynamicConfiguration messages):
# it queries Identification, then Configuration, then each component's Services.


class QueryField(IntEnum):
    """Query Identification's query field (OpenJAUS queryIdentificationMessage.h)."""

    SYSTEM = 1
    SUBSYSTEM = 2
    NODE = 3
    COMPONENT = 4


@_message
class QueryIdentification(_LayoutMessage, frozen=True):
    """0x2B00: who are you (``query_field``: QueryField)."""

    code = 0x2B00
    name = "query-identification"
    layout = _fixed(("query_field", U8))
    query_field: int = QueryField.SUBSYSTEM
    header: Header = TO_PRIMITIVE_DRIVER


IDENTIFICATION_SIZE: Final = 80  # OpenJAUS JAUS_IDENTIFICATION_LENGTH_BYTES: NUL-padded text
_IDENTIFICATION_HEAD: Final = struct.Struct("<BBH")  # query type, authority, type


@_message
class ReportIdentification(Message, frozen=True):
    """0x4B00: ``identification`` text (at most 79 bytes, latin-1) and the JAUS ``type``."""

    code = 0x4B00
    name = "report-identification"
    query_type: int = QueryField.SUBSYSTEM
    authority: int = 0
    type: int = 0
    identification: str = ""
    header: Header = FROM_NODE_MANAGER

    def encode_payload(self) -> bytes:
        try:
            text = self.identification.encode("latin-1")
        except (AttributeError, UnicodeEncodeError):
            raise JausEncodeError("identification must be latin-1 text") from None
        if len(text) >= IDENTIFICATION_SIZE or b"\0" in text:
            raise JausEncodeError(f"identification must be < {IDENTIFICATION_SIZE} bytes, no NUL")
        head = _IDENTIFICATION_HEAD.pack(_checked(U8, self.query_type),
                                         _checked(U8, self.authority), _checked(U16, self.type))
        return head + text.ljust(IDENTIFICATION_SIZE, b"\0")

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        size = _IDENTIFICATION_HEAD.size
        if not size <= len(payload) <= size + IDENTIFICATION_SIZE:
            raise JausDecodeError(f"{cls.name}: payload of {len(payload)} bytes, expected "
                                  f"{size}..{size + IDENTIFICATION_SIZE}")
        query_type, authority, kind = _IDENTIFICATION_HEAD.unpack_from(payload)
        text = payload[size:].split(b"\0", 1)[0][: IDENTIFICATION_SIZE - 1]
        return cls(query_type, authority, kind, text.decode("latin-1"), header)


@_message
class QueryConfiguration(_LayoutMessage, frozen=True):
    """0x2B01: ``query_field`` 2 subsystem, 3 node (OpenJAUS queryConfigurationMessage.h)."""

    code = 0x2B01
    name = "query-configuration"
    layout = _fixed(("query_field", U8))
    query_field: int = QueryField.SUBSYSTEM
    header: Header = TO_PRIMITIVE_DRIVER


class ConfigurationNode(msgspec.Struct, frozen=True):
    """One node of Report Configuration: its id and its (component, instance) pairs."""

    node: int
    components: tuple[tuple[int, int], ...] = ()


def _counted(items: Any, what: str) -> int:
    if not isinstance(items, tuple | list) or len(items) > 0xFF:
        raise JausEncodeError(f"{what} must be a tuple of at most 255 items")
    return len(items)


class _Reader:
    """Sequential little-endian reads with a decode error naming the message on overrun."""

    __slots__ = ("offset", "payload", "what")

    def __init__(self, payload: bytes, what: str) -> None:
        self.payload, self.what, self.offset = payload, what, 0

    def read(self, fmt: struct.Struct) -> tuple[Any, ...]:
        if self.offset + fmt.size > len(self.payload):
            raise JausDecodeError(f"{self.what}: payload of {len(self.payload)} bytes is truncated")
        values = fmt.unpack_from(self.payload, self.offset)
        self.offset += fmt.size
        return values

    def done(self) -> None:
        if self.offset != len(self.payload):
            raise JausDecodeError(f"{self.what}: {len(self.payload) - self.offset} bytes after "
                                  "the last item")


_B: Final = struct.Struct("<B")
_BB: Final = struct.Struct("<BB")
_SERVICE_MESSAGE: Final = struct.Struct("<HI")  # command code, presence vector


@_message
class ReportConfiguration(Message, frozen=True):
    """0x4B01: the nodes of the subsystem and their components (OpenJAUS layout)."""

    code = 0x4B01
    name = "report-configuration"
    nodes: tuple[ConfigurationNode, ...] = ()
    header: Header = FROM_NODE_MANAGER

    def encode_payload(self) -> bytes:
        parts = [_B.pack(_counted(self.nodes, "nodes"))]
        for node in self.nodes:
            if not isinstance(node, ConfigurationNode):
                raise JausEncodeError(f"nodes must hold ConfigurationNode records, got {node!r}")
            parts.append(_BB.pack(_checked(U8, node.node),
                                  _counted(node.components, "components")))
            parts += [_BB.pack(_checked(U8, c), _checked(U8, i)) for c, i in node.components]
        return b"".join(parts)

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        reader = _Reader(payload, cls.name)
        nodes = []
        for _ in range(reader.read(_B)[0]):
            node, count = reader.read(_BB)
            nodes.append(ConfigurationNode(node, tuple(reader.read(_BB) for _ in range(count))))
        reader.done()
        return cls(tuple(nodes), header)


@_message
class QueryServices(_LayoutMessage, frozen=True):
    """0x2B03: which messages do you take and give."""

    code = 0x2B03
    name = "query-services"
    layout = _EMPTY
    header: Header = TO_PRIMITIVE_DRIVER


class Service(msgspec.Struct, frozen=True):
    """One service of Report Services: its JAUS type (0 core) and its input and output
    messages as (command code, presence vector) pairs."""

    type: int
    inputs: tuple[tuple[int, int], ...] = ()
    outputs: tuple[tuple[int, int], ...] = ()


@_message
class ReportServices(Message, frozen=True):
    """0x4B03: the component's services (OpenJAUS layout)."""

    code = 0x4B03
    name = "report-services"
    services: tuple[Service, ...] = ()
    header: Header = FROM_PRIMITIVE_DRIVER

    def encode_payload(self) -> bytes:
        parts = [_B.pack(_counted(self.services, "services"))]
        for service in self.services:
            if not isinstance(service, Service):
                raise JausEncodeError(f"services must hold Service records, got {service!r}")
            parts.append(struct.pack("<H", _checked(U16, service.type)))
            for messages in (service.inputs, service.outputs):
                parts.append(_B.pack(_counted(messages, "service messages")))
                parts += [_SERVICE_MESSAGE.pack(_checked(U16, c), _checked(U32, pv))
                          for c, pv in messages]
        return b"".join(parts)

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        reader = _Reader(payload, cls.name)
        services = []
        for _ in range(reader.read(_B)[0]):
            (kind,) = reader.read(struct.Struct("<H"))
            inputs = tuple(reader.read(_SERVICE_MESSAGE) for _ in range(reader.read(_B)[0]))
            outputs = tuple(reader.read(_SERVICE_MESSAGE) for _ in range(reader.read(_B)[0]))
            services.append(Service(kind, inputs, outputs))
        reader.done()
        return cls(tuple(services), header)


# =========================================================================== §5 platform messages

_WRENCH_FIELDS: Final = (
    ("propulsive_linear_x_pct", ScaledWire(PCT_PROPULSIVE)),
    ("propulsive_linear_y_pct", ScaledWire(PCT_PROPULSIVE)),
    ("propulsive_linear_z_pct", ScaledWire(PCT_PROPULSIVE)),
    ("propulsive_rotational_x_pct", ScaledWire(PCT_PROPULSIVE)),
    ("propulsive_rotational_y_pct", ScaledWire(PCT_PROPULSIVE)),
    ("propulsive_rotational_z_pct", ScaledWire(PCT_PROPULSIVE)),
    ("resistive_linear_x_pct", ScaledWire(PCT_RESISTIVE)),
    ("resistive_linear_y_pct", ScaledWire(PCT_RESISTIVE)),
    ("resistive_linear_z_pct", ScaledWire(PCT_RESISTIVE)),
    ("resistive_rotational_x_pct", ScaledWire(PCT_RESISTIVE)),
    ("resistive_rotational_y_pct", ScaledWire(PCT_RESISTIVE)),
    ("resistive_rotational_z_pct", ScaledWire(PCT_RESISTIVE)),
)

WRENCH_ALL: Final = 0x0FFF  # reference §5: bits 0-11
WRENCH_XGV: Final = 0x0061  # reference §5: throttle, steering, brake


class _WrenchEffort(_LayoutMessage, frozen=True):
    """Fields shared by Set and Report Wrench Effort, with the XGV names as properties."""

    layout = _presence("H", *_WRENCH_FIELDS)

    propulsive_linear_x_pct: float | None = None
    propulsive_linear_y_pct: float | None = None
    propulsive_linear_z_pct: float | None = None
    propulsive_rotational_x_pct: float | None = None
    propulsive_rotational_y_pct: float | None = None
    propulsive_rotational_z_pct: float | None = None
    resistive_linear_x_pct: float | None = None
    resistive_linear_y_pct: float | None = None
    resistive_linear_z_pct: float | None = None
    resistive_rotational_x_pct: float | None = None
    resistive_rotational_y_pct: float | None = None
    resistive_rotational_z_pct: float | None = None

    @classmethod
    def xgv(
        cls,
        throttle_pct: float | None = None,
        steering_pct: float | None = None,
        brake_pct: float | None = None,
        **kwargs: Any,
    ) -> Self:
        """Build from the XGV's names (reference §5 XGV mapping); None leaves a field out."""
        return cls(
            propulsive_linear_x_pct=throttle_pct,
            propulsive_rotational_z_pct=steering_pct,
            resistive_linear_x_pct=brake_pct,
            **kwargs,
        )

    @property
    def throttle_pct(self) -> float | None:
        """XGV throttle, 0..100 (propulsive linear X)."""
        return self.propulsive_linear_x_pct

    @property
    def steering_pct(self) -> float | None:
        """XGV steering, -100..100 (propulsive rotational Z)."""
        return self.propulsive_rotational_z_pct

    @property
    def brake_pct(self) -> float | None:
        """XGV brake, 0..100 (resistive linear X)."""
        return self.resistive_linear_x_pct


@_message
class SetWrenchEffort(_WrenchEffort, frozen=True):
    """0x0405: command efforts; on the XGV throttle, steering and brake (see ``xgv``)."""

    code = 0x0405
    name = "set-wrench-effort"
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportWrenchEffort(_WrenchEffort, frozen=True):
    """0x4405: the efforts being applied."""

    code = 0x4405
    name = "report-wrench-effort"
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class QueryWrenchEffort(_LayoutMessage, frozen=True):
    """0x2405: ask for the efforts selected by ``presence_vector``."""

    code = 0x2405
    name = "query-wrench-effort"
    layout = _fixed(("presence_vector", U16))
    presence_vector: int = WRENCH_ALL
    header: Header = TO_PRIMITIVE_DRIVER


class Propulsion(IntFlag):
    """Discrete devices propulsion byte (reference §5)."""

    MAIN_POWER = 1 << 0
    MAIN_FUEL = 1 << 1
    AUXILIARY_FUEL = 1 << 2
    AUXILIARY_POWER = 1 << 3
    STARTER = 1 << 4
    COLD_START = 1 << 5
    AUTO_START = 1 << 6
    AUTO_SHUTDOWN = 1 << 7


class ParkingHorn(IntFlag):
    """Discrete devices parking brake / horn byte (reference §5)."""

    PARKING_BRAKE = 1 << 0
    HORN = 1 << 1


class Gear(IntEnum):
    """Discrete devices gear byte (reference §5): 0 park, 1-127 forward, 128 neutral,
    129-255 reverse; the XGV uses 1 low and 2 drive."""

    PARK = 0
    LOW = 1
    DRIVE = 2
    NEUTRAL = 128
    REVERSE = 129


_DISCRETE_FIELDS: Final = (
    ("propulsion_flags", U8),
    ("parking_horn_flags", U8),
    ("gear", U8),
    ("transfer_case", U8),
)
DISCRETE_ALL: Final = 0x0F  # reference §5: bits 0-3


class _DiscreteDevices(_LayoutMessage, frozen=True):
    """Fields shared by Set and Report Discrete Devices; ``transfer_case`` is raw (meaning
    unknown, reference §5)."""

    layout = _presence("B", *_DISCRETE_FIELDS)

    propulsion_flags: int | None = None
    parking_horn_flags: int | None = None
    gear: int | None = None
    transfer_case: int | None = None

    @property
    def propulsion(self) -> Propulsion | None:
        """The propulsion byte's named bits (issue 19: it read as a bare number)."""
        return None if self.propulsion_flags is None else Propulsion(self.propulsion_flags)

    @property
    def parking_horn(self) -> ParkingHorn | None:
        return None if self.parking_horn_flags is None else ParkingHorn(self.parking_horn_flags)

    def fields_dict(self) -> dict[str, Any]:
        """The raw bytes, plus their named bits and the gear's name (``overdrive jaus decode``)."""
        fields = super().fields_dict()
        for name, flags in (("propulsion", self.propulsion), ("parking_horn", self.parking_horn)):
            if flags is not None:
                fields[name] = {_flag_name(bit): bool(flags & bit) for bit in type(flags)}
        if self.gear is not None:
            fields["gear_name"] = gear_name(self.gear)
        return fields


def _flag_name(bit: IntFlag) -> str:
    return (bit.name or "").lower()


def gear_name(code: int) -> str:
    """Reference §5: 0 park, 1-127 forward, 128 neutral, 129-255 reverse."""
    if code == Gear.PARK:
        return "park"
    if code == Gear.NEUTRAL:
        return "neutral"
    return "forward" if code < Gear.NEUTRAL else "reverse"


@_message
class SetDiscreteDevices(_DiscreteDevices, frozen=True):
    """0x0406: engine, parking brake/horn, gear (e.g. ``gear=Gear.DRIVE``)."""

    code = 0x0406
    name = "set-discrete-devices"
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportDiscreteDevices(_DiscreteDevices, frozen=True):
    """0x4406."""

    code = 0x4406
    name = "report-discrete-devices"
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class QueryDiscreteDevices(_LayoutMessage, frozen=True):
    """0x2406: the reference gives no payload; a u8 presence vector is assumed, matching the
    u8 presence vector of the set/report messages (docs/jaus.md)."""

    code = 0x2406
    name = "query-discrete-devices"
    layout = _fixed(("presence_vector", U8))
    presence_vector: int = DISCRETE_ALL
    header: Header = TO_PRIMITIVE_DRIVER


POSE_ALL: Final = 0x01FF  # reference §5: bits 0-8 for velocity state and both poses


@_message
class ReportVelocityState(_LayoutMessage, frozen=True):
    """0x4404. No XGV component is named for it in the reference: set the source."""

    code = 0x4404
    name = "report-velocity-state"
    layout = _presence(
        "H",
        ("velocity_x_mps", ScaledWire(VELOCITY_MPS)),
        ("velocity_y_mps", ScaledWire(VELOCITY_MPS)),
        ("velocity_z_mps", ScaledWire(VELOCITY_MPS)),
        ("velocity_rms_mps", ScaledWire(VELOCITY_RMS_MPS)),
        ("roll_rate_radps", ScaledWire(RATE_RADPS)),
        ("pitch_rate_radps", ScaledWire(RATE_RADPS)),
        ("yaw_rate_radps", ScaledWire(RATE_RADPS)),
        ("rate_rms_radps", ScaledWire(RATE_RMS_RADPS)),
        ("timestamp", TIMESTAMP),
    )
    velocity_x_mps: float | None = None
    velocity_y_mps: float | None = None
    velocity_z_mps: float | None = None
    velocity_rms_mps: float | None = None
    roll_rate_radps: float | None = None
    pitch_rate_radps: float | None = None
    yaw_rate_radps: float | None = None
    rate_rms_radps: float | None = None
    timestamp: JausTimestamp | None = None
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class QueryVelocityState(_LayoutMessage, frozen=True):
    """0x2404."""

    code = 0x2404
    name = "query-velocity-state"
    layout = _fixed(("presence_vector", U16))
    presence_vector: int = POSE_ALL
    header: Header = TO_PRIMITIVE_DRIVER


_ATTITUDE_FIELDS: Final = (
    ("position_rms_m", ScaledWire(POSITION_RMS_M)),
    ("roll_rad", ScaledWire(ATTITUDE_RAD)),
    ("pitch_rad", ScaledWire(ATTITUDE_RAD)),
    ("yaw_rad", ScaledWire(ATTITUDE_RAD)),
    ("attitude_rms_rad", ScaledWire(ATTITUDE_RMS_RAD)),
    ("timestamp", TIMESTAMP),
)


@_message
class ReportGlobalPose(_LayoutMessage, frozen=True):
    """0x4402. No XGV component is named for it in the reference: set the source."""

    code = 0x4402
    name = "report-global-pose"
    layout = _presence(
        "H",
        ("latitude_deg", ScaledWire(LATITUDE_DEG)),
        ("longitude_deg", ScaledWire(LONGITUDE_DEG)),
        ("elevation_m", ScaledWire(ELEVATION_M)),
        *_ATTITUDE_FIELDS,
    )
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    elevation_m: float | None = None
    position_rms_m: float | None = None
    roll_rad: float | None = None
    pitch_rad: float | None = None
    yaw_rad: float | None = None
    attitude_rms_rad: float | None = None
    timestamp: JausTimestamp | None = None
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class QueryGlobalPose(_LayoutMessage, frozen=True):
    """0x2402."""

    code = 0x2402
    name = "query-global-pose"
    layout = _fixed(("presence_vector", U16))
    presence_vector: int = POSE_ALL
    header: Header = TO_PRIMITIVE_DRIVER


@_message
class ReportLocalPose(_LayoutMessage, frozen=True):
    """0x4403. No XGV component is named for it in the reference: set the source."""

    code = 0x4403
    name = "report-local-pose"
    layout = _presence(
        "H",
        ("x_m", ScaledWire(LOCAL_XY_M)),
        ("y_m", ScaledWire(LOCAL_XY_M)),
        ("z_m", ScaledWire(ELEVATION_M)),
        *_ATTITUDE_FIELDS,
    )
    x_m: float | None = None
    y_m: float | None = None
    z_m: float | None = None
    position_rms_m: float | None = None
    roll_rad: float | None = None
    pitch_rad: float | None = None
    yaw_rad: float | None = None
    attitude_rms_rad: float | None = None
    timestamp: JausTimestamp | None = None
    header: Header = FROM_PRIMITIVE_DRIVER


@_message
class QueryLocalPose(_LayoutMessage, frozen=True):
    """0x2403."""

    code = 0x2403
    name = "query-local-pose"
    layout = _fixed(("presence_vector", U16))
    presence_vector: int = POSE_ALL
    header: Header = TO_PRIMITIVE_DRIVER


# =========================================================================== §6 TORC experimental

MOTION_DURATION_S: Final = 0.4  # reference §6: "clients send 400 ms and refresh it"


class Motion(msgspec.Struct, frozen=True):
    """One motion of Set Motion Profile (reference §6). Curvature: the XGV's sign convention."""

    speed_mps: float = 0.0
    max_accel_mps2: float = 0.0
    curvature_1pm: float = 0.0
    curvature_rate_1pms: float = 0.0
    duration_s: float = MOTION_DURATION_S


MOTION_LAYOUT: Final = FixedLayout(
    (
        ("speed_mps", ScaledWire(PROFILE_SPEED_MPS)),
        ("max_accel_mps2", ScaledWire(PROFILE_ACCEL_MPS2)),
        ("curvature_1pm", _CURVATURE),
        ("curvature_rate_1pms", ScaledWire(CURVATURE_RATE_1PMS)),
        ("duration_s", MILLIS_U16),
    )
)
_VERSION_COUNT: Final = struct.Struct("<BB")
MOTION_PROFILE_VERSION: Final = 1  # reference §6: "u8 version = 1"


@_message
class SetMotionProfile(Message, frozen=True):
    """0xE328 (experimental): speed and curvature commands for the Motion Profile Driver.

    XGV clients send one motion (``SetMotionProfile.single(...)``); the format allows up to 255.
    """

    code = 0xE328
    experimental = True
    name = "set-motion-profile"
    motions: tuple[Motion, ...] = ()
    version: int = MOTION_PROFILE_VERSION
    header: Header = TO_MOTION_PROFILE_DRIVER

    @classmethod
    def single(
        cls,
        speed_mps: float,
        max_accel_mps2: float,
        curvature_1pm: float = 0.0,
        curvature_rate_1pms: float = 0.0,
        duration_s: float = MOTION_DURATION_S,
        header: Header = TO_MOTION_PROFILE_DRIVER,
    ) -> Self:
        """A one-motion profile, as XGV clients send it."""
        motion = Motion(speed_mps, max_accel_mps2, curvature_1pm, curvature_rate_1pms, duration_s)
        return cls((motion,), header=header)

    def encode_payload(self) -> bytes:
        motions = self.motions
        if not isinstance(motions, tuple | list) or len(motions) > 0xFF:
            raise JausEncodeError("motions must be a tuple of at most 255 Motion records")
        parts = [_VERSION_COUNT.pack(_checked(U8, self.version), len(motions))]
        for motion in motions:
            if not isinstance(motion, Motion):
                raise JausEncodeError(f"motions must hold Motion records, got {motion!r}")
            parts.append(MOTION_LAYOUT.encode(msgspec.structs.astuple(motion)))
        return b"".join(parts)

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        if len(payload) < _VERSION_COUNT.size:
            raise JausDecodeError(f"{cls.name}: payload of {len(payload)} bytes is truncated")
        version, count = _VERSION_COUNT.unpack_from(payload)
        size = MOTION_LAYOUT.size
        expected = _VERSION_COUNT.size + count * size
        if len(payload) != expected:
            raise JausDecodeError(
                f"{cls.name}: payload is {len(payload)} bytes, {count} motions need {expected}"
            )
        motions = tuple(
            Motion(*MOTION_LAYOUT.decode(payload[start : start + size], cls.name))
            for start in range(_VERSION_COUNT.size, expected, size)
        )
        return cls(motions, version, header)


class ControlMode(IntEnum):
    """Report Vehicle Mode control mode (seed 000, field 2)."""

    UNKNOWN = 0
    SOFTWARE_PAUSE = 1
    WRENCH_EFFORTS = 2
    MOTION_PROFILES = 3


class ReadyMode(IntEnum):
    """Report Vehicle Mode ready mode (seed 000, field 3)."""

    UNKNOWN = 0
    SOFTWARE_PAUSE = 1
    READY = 2


class SafetyMode(IntEnum):
    """Report Vehicle Mode safety mode (seed 000, field 4); 2-7 all mean software pause."""

    UNKNOWN = 0
    DRIVE_BY_WIRE = 1
    SOFTWARE_PAUSE = 2
    ESTOP_PAUSE = 8
    MANUAL_OVERRIDE = 9
    EMERGENCY_MANUAL_OVERRIDE = 10
    ESTOP_DISABLE = 11


_SOFTWARE_PAUSE_CODES: Final = range(2, 8)  # seed 000: "2-7: software pause"


_SAFETY_MODE_NAMES: Final = {int(m): m.name.lower().replace("_", "-") for m in SafetyMode}


def safety_mode_name(value: int) -> str:
    """The contract's name for a safety mode value ("drive-by-wire", "software-pause", ...)."""
    if value in _SOFTWARE_PAUSE_CODES:
        return "software-pause"
    return _SAFETY_MODE_NAMES.get(value, "reserved")


class PartialModeOverride(IntFlag):
    """Report Vehicle Mode partial mode overrides (seed 000, field 5): set = manual."""

    STEERING = 1 << 0
    SPEED = 1 << 1


class SafetyDevices(IntFlag):
    """Report Vehicle Mode safety devices (seed 000, field 6). Bits 3-4 hold the SafeStop link
    status (0 no link, 1 bypass, 2 link good): ``(value >> SAFESTOP_LINK_SHIFT) & 0b11``."""

    MANUAL_OVERRIDE = 1 << 0
    SAFESTOP_PAUSE = 1 << 1
    SAFESTOP_STOP = 1 << 2
    SAFESTOP_LINK = 0b11 << 3
    EXTERNAL_ESTOP = 1 << 5
    DOOR_PAUSE = 1 << 6
    ERRORS = 1 << 7
    EMERGENCY_MANUAL_OVERRIDE = 1 << 8
    STEERING_NEEDS_INIT = 1 << 9
    STEERING_INIT_AWAITING_USER = 1 << 10


SAFESTOP_LINK_SHIFT: Final = 3  # seed 000: safety devices bits 3-4


@_message
class ReportVehicleMode(_LayoutMessage, frozen=True):
    """0xE456 (experimental) from the Node Manager: the XGV's modes (seed 000)."""

    code = 0xE456
    experimental = True
    name = "report-vehicle-mode"
    layout = _fixed(
        ("version", U8),
        ("control_mode", U8),
        ("ready_mode", U8),
        ("safety_mode", U8),
        ("partial_mode_overrides", U8),
        ("safety_devices", U16),
    )
    version: int = 0
    control_mode: int = ControlMode.UNKNOWN
    ready_mode: int = ReadyMode.UNKNOWN
    safety_mode: int = SafetyMode.UNKNOWN
    partial_mode_overrides: int = 0
    safety_devices: int = 0
    header: Header = FROM_NODE_MANAGER

    def fields_dict(self) -> dict[str, Any]:
        fields = super().fields_dict()
        fields["safety_mode_name"] = safety_mode_name(self.safety_mode)
        return fields


@_message
class ReportCurvature(_LayoutMessage, frozen=True):
    """0xE455 (experimental) from the Motion Profile Driver."""

    code = 0xE455
    experimental = True
    name = "report-curvature"
    layout = _fixed(("version", U8), ("curvature_1pm", _CURVATURE), ("timestamp", TIMESTAMP))
    version: int = 1
    curvature_1pm: float = 0.0
    timestamp: JausTimestamp = JausTimestamp()
    header: Header = FROM_MOTION_PROFILE_DRIVER


@_message
class ReportWheelsSpeed(_LayoutMessage, frozen=True):
    """0xE42E (experimental) from the Primitive Driver. The reference gives no version value;
    0 is sent by default."""

    code = 0xE42E
    experimental = True
    name = "report-wheels-speed"
    layout = _fixed(
        ("version", U8),
        ("right_front_mps", ScaledWire(WHEEL_SPEED_MPS)),
        ("left_front_mps", ScaledWire(WHEEL_SPEED_MPS)),
        ("right_rear_mps", ScaledWire(WHEEL_SPEED_MPS)),
        ("left_rear_mps", ScaledWire(WHEEL_SPEED_MPS)),
        ("timestamp", TIMESTAMP),
    )
    version: int = 0
    right_front_mps: float = 0.0
    left_front_mps: float = 0.0
    right_rear_mps: float = 0.0
    left_rear_mps: float = 0.0
    timestamp: JausTimestamp = JausTimestamp()
    header: Header = FROM_PRIMITIVE_DRIVER


class TurnSignal(IntEnum):
    """Signals turn byte (reference §6)."""

    OFF = 0
    LEFT = 1
    RIGHT = 2
    FLASHERS = 3


class Horn(msgspec.Struct, frozen=True):
    """Signals horn group; the periods' unit is not given by the reference, so they stay raw."""

    status: int = 0
    period_on_raw: int = 0
    period_off_raw: int = 0


class Lights(msgspec.Struct, frozen=True):
    """Signals lights group: ``state`` bits 0-2 (0 off, 1 parking, 2 on), bit 3 high beam,
    bit 4 fog; periods raw as for :class:`Horn`."""

    state: int = 0
    period_on_raw: int = 0
    period_off_raw: int = 0


_SIGNALS_HEAD: Final = struct.Struct("<BB")  # reference §6: version, presence
_TRIPLE: Final = struct.Struct("<BBB")  # reference §6: horn and lights groups
_SIGNALS_VALID_BITS: Final = 0b111  # reference §6: bits 0 turn, 1 horn, 2 lights


class _Signals(Message, frozen=True):
    """Fields shared by Set and Report Signals (reference §6)."""

    version: int = 0
    turn_signal: int | None = None
    horn: Horn | None = None
    lights: Lights | None = None

    def encode_payload(self) -> bytes:
        presence = 0
        body = b""
        if self.turn_signal is not None:
            presence |= 1
            body += bytes((_checked(U8, self.turn_signal),))
        for bit, group, kind in ((1, self.horn, Horn), (2, self.lights, Lights)):
            if group is not None:
                if not isinstance(group, kind):
                    raise JausEncodeError(f"expected {kind.__name__}, got {group!r}")
                presence |= 1 << bit
                body += _TRIPLE.pack(*(_checked(U8, v) for v in msgspec.structs.astuple(group)))
        return _SIGNALS_HEAD.pack(_checked(U8, self.version), presence) + body

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        if len(payload) < _SIGNALS_HEAD.size:
            raise JausDecodeError(f"{cls.name}: payload of {len(payload)} bytes is truncated")
        version, presence = _SIGNALS_HEAD.unpack_from(payload)
        presence &= _SIGNALS_VALID_BITS  # undefined bits ignored, as for every presence vector
        expected = (
            _SIGNALS_HEAD.size
            + (presence & 1)
            + _TRIPLE.size * ((presence >> 1 & 1) + (presence >> 2 & 1))
        )
        if len(payload) != expected:
            raise JausDecodeError(
                f"{cls.name}: payload is {len(payload)} bytes, presence 0x{presence:02X} "
                f"needs {expected}"
            )
        offset = _SIGNALS_HEAD.size
        turn_signal = horn = lights = None
        if presence & 1:
            turn_signal = payload[offset]
            offset += 1
        if presence & 2:
            horn = Horn(*_TRIPLE.unpack_from(payload, offset))
            offset += _TRIPLE.size
        if presence & 4:
            lights = Lights(*_TRIPLE.unpack_from(payload, offset))
        return cls(version, turn_signal, horn, lights, header)


@_message
class SetSignals(_Signals, frozen=True):
    """0xE322 (experimental) to the Signals Driver: turn signals, horn, lights."""

    code = 0xE322
    experimental = True
    name = "set-signals"
    header: Header = TO_SIGNALS_DRIVER


@_message
class ReportSignals(_Signals, frozen=True):
    """0xE445 (experimental) from the Signals Driver."""

    code = 0xE445
    experimental = True
    name = "report-signals"
    header: Header = FROM_SIGNALS_DRIVER


_ERROR_HEAD: Final = struct.Struct("<BBB")  # reference §6: version, reserved, n
_ERROR_COUNT: Final = struct.Struct("<i")  # reference §6: n x int32


@_message
class ReportErrorCount(Message, frozen=True):
    """0xE451 (experimental) from the Error Manager: up to 255 int32 counters."""

    code = 0xE451
    experimental = True
    name = "report-error-count"
    version: int = 0
    reserved: int = 0
    counts: tuple[int, ...] = ()
    header: Header = FROM_ERROR_MANAGER

    def encode_payload(self) -> bytes:
        counts = self.counts
        if not isinstance(counts, tuple | list) or len(counts) > 0xFF:
            raise JausEncodeError("counts must be a tuple of at most 255 integers")
        head = _ERROR_HEAD.pack(
            _checked(U8, self.version), _checked(U8, self.reserved), len(counts)
        )
        return head + struct.pack(f"<{len(counts)}i", *(_checked(I32, c) for c in counts))

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        if len(payload) < _ERROR_HEAD.size:
            raise JausDecodeError(f"{cls.name}: payload of {len(payload)} bytes is truncated")
        version, reserved, count = _ERROR_HEAD.unpack_from(payload)
        expected = _ERROR_HEAD.size + count * _ERROR_COUNT.size
        if len(payload) != expected:
            raise JausDecodeError(
                f"{cls.name}: payload is {len(payload)} bytes, {count} counts need {expected}"
            )
        counts = struct.unpack_from(f"<{count}i", payload, _ERROR_HEAD.size)
        return cls(version, reserved, counts, header)
