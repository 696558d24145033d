"""JAUS 3.3 codec core: errors, the 16-byte header, scaled integers, encode/decode dispatch.

Sans-IO: bytes in, typed records out (and back); no sockets, no clocks. The wire facts come
from ``shared/reference/jaus-3.3-wire-format.md`` (cited below as "reference §n").

Every record is a frozen ``msgspec.Struct`` (about 6x cheaper to build than a frozen slotted
dataclass, measured on the Set Wrench Effort record) that carries its :class:`Header`; the
message type fixes the command code and the experimental flag. Concrete records live in
:mod:`overdrive.jaus.messages` and register themselves here with :func:`register`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from enum import IntEnum
from typing import TYPE_CHECKING, Any, ClassVar, Final, Literal, Self, TypeVar

import msgspec

from overdrive.jaus.addresses import DEFAULT_CLIENT_ID, XGV_PRIMITIVE_DRIVER, JausId

# --------------------------------------------------------------------------- errors


class JausError(ValueError):
    """Base of the codec's errors."""


class JausDecodeError(JausError):
    """The bytes are not a well-formed JAUS message or JUDP datagram.

    The only exception :func:`decode` and :func:`overdrive.jaus.judp.decode_datagram` raise,
    whatever the input (truncated, oversized, wrong length, unknown flag, garbage).
    """


class JausEncodeError(JausError):
    """A record cannot be put on the wire: NaN/infinite value, raw field out of range, wrong
    type, payload too large. The only exception :func:`encode` raises."""


# --------------------------------------------------------------------------- header

HEADER_SIZE: Final = 16  # reference §1: "Message header (16 bytes)"
MAX_PAYLOAD_SIZE: Final = 4080  # reference §1: bytes 12-13 bits 0-11, "max 4080"
DEFAULT_PRIORITY: Final = 6  # reference §1: byte 0 bits 0-3, "default 6"
VERSION_3_3: Final = 2  # reference §1: byte 1, "2 = 3.2/3.3"
_MAX_PRIORITY: Final = 15  # reference §1: 4 bits
_MAX_ACK_NAK: Final = 3  # reference §1: 2 bits
_MAX_VERSION: Final = 63  # reference §1: 6 bits
_RESERVED_VERSION_BITS: Final = 0xC0  # reference §1: byte 1 bits 6-7 reserved
_SIZE_MASK: Final = 0x0FFF  # reference §1: bytes 12-13 bits 0-11
_FLAG_SHIFT: Final = 12  # reference §1: bytes 12-13 bits 12-15
_MAX_SEQUENCE: Final = 0xFFFF  # reference §1: uint16

# byte 0 = priority | ack_nak << 4 | service connection << 6 | experimental << 7; the IDs
# (instance, component, node, subsystem) read as a little-endian u32 are
# subsystem << 24 | node << 16 | component << 8 | instance.
_HEADER: Final = struct.Struct("<BBHIIHH")


class AckNak(IntEnum):
    """Header byte 0 bits 4-5 (reference §1)."""

    NONE = 0
    REQUEST = 1
    NAK = 2
    ACK = 3


class DataFlag(IntEnum):
    """Header bytes 12-13 bits 12-15 (reference §1). Only SINGLE is decoded; see docs/jaus.md."""

    SINGLE = 0
    FIRST = 1
    NORMAL = 2
    RETRANSMITTED = 4
    LAST = 8


_DATA_FLAGS: Final = frozenset(int(f) for f in DataFlag)
_SINGLE: Final = int(DataFlag.SINGLE)


class Header(msgspec.Struct, frozen=True):
    """The 16-byte header minus what the message type fixes (command code, experimental flag,
    payload size). Defaults: a client (1.2.4.1) talking to the XGV Primitive Driver (1.1.33.1)."""

    destination: JausId = XGV_PRIMITIVE_DRIVER
    source: JausId = DEFAULT_CLIENT_ID
    priority: int = DEFAULT_PRIORITY
    ack_nak: int = AckNak.NONE
    service_connection: bool = False
    version: int = VERSION_3_3
    data_flag: int = DataFlag.SINGLE
    sequence: int = 0

    def replace(self, **changes: Any) -> Header:
        """A copy with some fields changed."""
        return msgspec.structs.replace(self, **changes)


_ID_CACHE: dict[int, JausId] = {}
_ID_CACHE_LIMIT: Final = 4096  # bounds memory under garbage input; real systems use a handful


def _jaus_id(value: int) -> JausId:
    jaus_id = _ID_CACHE.get(value)
    if jaus_id is None:
        jaus_id = JausId(value >> 24, (value >> 16) & 0xFF, (value >> 8) & 0xFF, value & 0xFF)
        if len(_ID_CACHE) < _ID_CACHE_LIMIT:
            _ID_CACHE[value] = jaus_id
    return jaus_id


def _header_problem(header: Header, code: int, payload_size: int) -> str:
    """Why a header cannot be encoded (the slow path, run only after the fast one failed)."""
    if not isinstance(header, Header):
        return f"header must be a Header, got {type(header).__name__}"
    for name, top in (
        ("priority", _MAX_PRIORITY),
        ("ack_nak", _MAX_ACK_NAK),
        ("version", _MAX_VERSION),
        ("sequence", _MAX_SEQUENCE),
    ):
        value = getattr(header, name)
        if not isinstance(value, int) or not 0 <= value <= top:
            return f"header {name} must be an integer 0..{top}, got {value!r}"
    if header.data_flag not in _DATA_FLAGS:
        return f"header data_flag must be one of {sorted(_DATA_FLAGS)}, got {header.data_flag!r}"
    for name in ("destination", "source"):
        if not isinstance(getattr(header, name), JausId):
            return f"header {name} must be a JausId"
    if payload_size > MAX_PAYLOAD_SIZE:
        return f"payload of {payload_size} bytes exceeds the {MAX_PAYLOAD_SIZE}-byte maximum"
    return f"command code must be an integer 0..0xFFFF, got {code!r}"


def encode_header(header: Header, code: int, experimental: bool, payload_size: int) -> bytes:
    """The 16 header bytes (reference §1); raises JausEncodeError for out-of-range fields."""
    try:
        priority = header.priority
        ack_nak = header.ack_nak
        version = header.version
        data_flag = header.data_flag
        dst = header.destination
        src = header.source
        if (
            priority >> 4  # 4 bits
            or ack_nak >> 2  # 2 bits
            or version >> 6  # 6 bits
            or data_flag not in _DATA_FLAGS
            or payload_size > MAX_PAYLOAD_SIZE
            or type(dst) is not JausId
            or type(src) is not JausId
        ):
            raise JausEncodeError(_header_problem(header, code, payload_size))
        return _HEADER.pack(
            priority
            | ack_nak << 4
            | (0x40 if header.service_connection else 0)
            | (0x80 if experimental else 0),
            version,
            code,
            dst.subsystem << 24 | dst.node << 16 | dst.component << 8 | dst.instance,
            src.subsystem << 24 | src.node << 16 | src.component << 8 | src.instance,
            payload_size | data_flag << _FLAG_SHIFT,
            header.sequence,
        )
    except (AttributeError, TypeError, struct.error):
        raise JausEncodeError(_header_problem(header, code, payload_size)) from None


def decode_header(data: bytes | bytearray | memoryview) -> tuple[Header, int, bool, int]:
    """Parse the first 16 bytes: ``(header, command code, experimental, payload size)``.

    Accepts every defined data flag (multi-packet ones included) so tools can show them;
    :func:`decode` is the one that insists on single-packet messages.
    """
    if len(data) < HEADER_SIZE:
        raise JausDecodeError(
            f"truncated: {len(data)} bytes, a JAUS message needs the {HEADER_SIZE}-byte header"
        )
    byte0, byte1, code, dst, src, size_flags, sequence = _HEADER.unpack_from(data)
    if byte1 & _RESERVED_VERSION_BITS:
        raise JausDecodeError(f"reserved bits 6-7 of header byte 1 are set (0x{byte1:02X})")
    data_flag = size_flags >> _FLAG_SHIFT
    if data_flag not in _DATA_FLAGS:
        raise JausDecodeError(f"unknown data flag {data_flag} in header")
    size = size_flags & _SIZE_MASK
    if size > MAX_PAYLOAD_SIZE:
        raise JausDecodeError(f"payload size {size} exceeds the {MAX_PAYLOAD_SIZE}-byte maximum")
    header = Header(
        _ID_CACHE.get(dst) or _jaus_id(dst),
        _ID_CACHE.get(src) or _jaus_id(src),
        byte0 & 0x0F,
        (byte0 >> 4) & 0x03,
        byte0 & 0x40 != 0,
        byte1,
        data_flag,
        sequence,
    )
    return header, code, byte0 & 0x80 != 0, size


# --------------------------------------------------------------------------- scaled integers

ScaledKind = Literal["byte", "short", "ushort", "integer", "uinteger"]

# reference §3: RANGE per type, and which types are signed (bias = centre) or not (bias = min)
_RANGES: Final[dict[str, tuple[float, bool, str]]] = {
    "byte": (255.0, False, "B"),
    "short": (65534.0, True, "h"),
    "ushort": (65535.0, False, "H"),
    "integer": (4294967294.0, True, "i"),
    "uinteger": (4294967294.0, False, "I"),
}

_isfinite = math.isfinite


class ScaledInt:
    """A real number carried as an integer on [lo, hi] (reference §3), coded as OpenJAUS does.

    Encode: clamp, then ``int((v - bias) / scale + 0.5)`` (``int`` truncates toward zero), in
    the same double-precision order as OpenJAUS's ``jausXxxFromDouble``. NaN and infinities
    are rejected with :class:`JausEncodeError` instead of clamped: on a drive-by-wire link a
    non-finite command is a bug upstream, never "full throttle".

    Decode: OpenJAUS's ``raw * scale + bias`` (``jausXxxToDouble``), the same double for every
    raw any encoder produces, then clamped to [lo, hi]. The clamp only touches raws no encoder
    emits (int16 -32768/-32767 on a symmetric range, u32 0xFFFFFFFF): they are hostile or
    broken input, and a value outside [lo, hi] is never handed on.

    What round-trips (property-tested): ``to_raw(from_raw(n)) == n`` for n >= 0, and
    ``n + 1`` for n < 0 (the truncation toward zero moves a negative value's raw up by one);
    ``from_raw(to_raw(v))`` is within 0.5 step of the clamped ``v`` when ``v - bias >= 0``
    and within 1.5 steps (never further from zero) below it.
    """

    __slots__ = ("bias", "fmt", "from_raw", "hi", "kind", "lo", "scale", "to_raw")

    def __init__(self, kind: ScaledKind, lo: float, hi: float) -> None:
        value_range, signed, fmt = _RANGES[kind]
        self.kind = kind
        self.lo = lo = float(lo)
        self.hi = hi = float(hi)
        self.scale = scale = (hi - lo) / value_range
        self.bias = bias = (hi + lo) / 2.0 if signed else lo
        self.fmt = fmt

        # closures over locals: these run per field per message, so no attribute lookups
        def to_raw(value: float) -> int:
            """Encode one value (clamped to [lo, hi]); NaN and infinities raise."""
            if not _isfinite(value):
                raise JausEncodeError(f"cannot encode non-finite value {value!r}")
            if value < lo:
                value = lo
            elif value > hi:
                value = hi
            return int((value - bias) / scale + 0.5)

        def from_raw(raw: int) -> float:
            """Decode one raw integer (OpenJAUS's formula), clamped to [lo, hi]."""
            value = raw * scale + bias
            if value < lo:
                return lo
            if value > hi:
                return hi
            return value

        self.to_raw: Callable[[float], int] = to_raw
        self.from_raw: Callable[[int], float] = from_raw

    def __repr__(self) -> str:
        return f"ScaledInt({self.kind!r}, {self.lo!r}, {self.hi!r})"


# --------------------------------------------------------------------------- records and dispatch


class Message(msgspec.Struct, frozen=True):
    """Base of every JAUS message record.

    Subclasses set ``code``, ``experimental`` and ``name`` as class attributes, declare their
    payload fields, and end with a ``header: Header`` field whose default addresses the
    component that normally receives (or sends) that message.
    """

    code: ClassVar[int]
    experimental: ClassVar[bool] = False
    name: ClassVar[str]

    if TYPE_CHECKING:  # declared per subclass so it can come last and carry its own default
        header: Header

    def encode_payload(self) -> bytes:
        """The payload bytes (everything after the header)."""
        raise NotImplementedError

    @classmethod
    def decode_payload(cls, payload: bytes, header: Header) -> Self:
        """Build the record from its payload; raises JausDecodeError."""
        raise NotImplementedError

    def with_header(self, **changes: Any) -> Self:
        """A copy whose header has some fields changed, e.g. ``msg.with_header(sequence=3)``."""
        return msgspec.structs.replace(self, header=msgspec.structs.replace(self.header, **changes))

    def fields_dict(self) -> dict[str, Any]:
        """The payload fields as JSON-ready builtins, absent (None) fields left out."""
        return {
            name: _to_builtin(value)
            for name in self.__struct_fields__
            if name != "header" and (value := getattr(self, name)) is not None
        }


def _to_builtin(value: Any) -> Any:
    if isinstance(value, JausId):
        return str(value)
    if isinstance(value, msgspec.Struct):
        return {
            name: _to_builtin(v)
            for name in value.__struct_fields__
            if (v := getattr(value, name)) is not None
        }
    if isinstance(value, tuple | list):
        return [_to_builtin(v) for v in value]
    if isinstance(value, bytes):
        return value.hex()
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return int(value)
    return value


class UnknownMessage(Message, frozen=True):
    """A message whose (experimental flag, command code) pair has no record here.

    Keeps the raw payload so it re-encodes byte for byte.
    """

    code: int  # type: ignore[misc]  # an instance field here, a class attribute elsewhere
    payload: bytes = b""
    experimental: bool = False  # type: ignore[misc]
    header: Header = Header()
    name: ClassVar[str] = "unknown"  # type: ignore[misc]

    def encode_payload(self) -> bytes:
        return bytes(self.payload)

    def fields_dict(self) -> dict[str, Any]:
        return {"payload_hex": bytes(self.payload).hex()}


_REGISTRY: dict[int, type[Message]] = {}
_EXPERIMENTAL_KEY: Final = 0x10000  # registry key = code, plus this for experimental codes


def _key(code: int, experimental: bool) -> int:
    return code | _EXPERIMENTAL_KEY if experimental else code


_M = TypeVar("_M", bound=type[Message])


def register(cls: _M) -> _M:
    """Class decorator: make :func:`decode` produce ``cls`` for its (experimental, code)."""
    key = _key(cls.code, cls.experimental)
    if key in _REGISTRY:
        raise ValueError(
            f"{cls.__name__} and {_REGISTRY[key].__name__} share code 0x{cls.code:04X}"
        )
    _REGISTRY[key] = cls
    return cls


def message_types() -> tuple[type[Message], ...]:
    """Every registered record type, in registration order."""
    return tuple(_REGISTRY.values())


def message_type(code: int, experimental: bool = False) -> type[Message] | None:
    """The record type for a command code, or None when it would decode as UnknownMessage."""
    return _REGISTRY.get(_key(code, experimental))


def encode(message: Message, header: Header | None = None) -> bytes:
    """Header + payload bytes of ``message``; ``header`` replaces ``message.header`` if given.

    Raises :class:`JausEncodeError` (only) when the record cannot be put on the wire.
    """
    if not isinstance(message, Message):
        raise JausEncodeError(f"expected a JAUS message record, got {type(message).__name__}")
    try:
        payload = message.encode_payload()
    except JausEncodeError as exc:
        raise JausEncodeError(f"{message.name}: {exc}") from None
    except (TypeError, ValueError, OverflowError, struct.error) as exc:
        raise JausEncodeError(f"{message.name}: {exc}") from None
    return (
        encode_header(
            message.header if header is None else header,
            message.code,
            message.experimental,
            len(payload),
        )
        + payload
    )


def decode(data: bytes | bytearray | memoryview) -> Message:
    """Decode exactly one single-packet JAUS message (header + payload, nothing more).

    Raises :class:`JausDecodeError` (only) on anything malformed, including multi-packet data
    flags, which this codec rejects rather than reassembles (see docs/jaus.md).
    """
    header, code, experimental, size = decode_header(data)
    if header.data_flag != _SINGLE:
        raise JausDecodeError(
            f"multi-packet data flag {header.data_flag} ({DataFlag(header.data_flag).name}) "
            "is not supported; only single-packet messages are decoded"
        )
    if len(data) != HEADER_SIZE + size:
        raise JausDecodeError(
            f"wrong length: header says {size} payload bytes, got {len(data) - HEADER_SIZE}"
        )
    payload = data[HEADER_SIZE:] if type(data) is bytes else bytes(data[HEADER_SIZE:])
    cls = _REGISTRY.get(code | _EXPERIMENTAL_KEY if experimental else code)
    if cls is None:
        return UnknownMessage(code, payload, experimental, header)
    return cls.decode_payload(payload, header)


def to_dict(message: Message) -> dict[str, Any]:
    """The JSON object ``overdrive jaus decode`` prints for one message (see docs/jaus.md)."""
    header = message.header
    return {
        "code": message.code,
        "name": message.name,
        "priority": header.priority,
        "ack_nak": header.ack_nak,
        "service_connection": header.service_connection,
        "experimental": bool(message.experimental),
        "version": header.version,
        "destination": str(header.destination),
        "source": str(header.source),
        "data_flag": header.data_flag,
        "sequence": header.sequence,
        "fields": message.fields_dict(),
    }
