"""AutonomouStuff / Hexagon PACMod 3: CAN frames <-> typed commands and reports. Sans-IO.

The layout comes from a DBC file read with cantools, never from offsets typed here:

- **shipped**: ``as_pacmod_v3.4.0.dbc``, from the MIT-licensed pacmod3 driver's history
  (github.com/astuff/pacmod3, commit cfce19c of 2018-11-15, the last one holding it; sha256 in
  ``SHIPPED_DBC_SHA256``). It is the ``"v3"`` dialect: every system command carries its own
  ``CLEAR_FAULTS`` bit and there is no global command.
- **the newer kits** (DBC 12 to 14, ``"v14"`` dialect) add ``GLOBAL_CMD`` (0x80: clear faults,
  clear overrides, a 4-bit counter and its complement), ``SUPERVISORY_CTRL`` (0x81: allow
  enable, with counter and complement) and ``GLOBAL_RPT``'s ``SUPERVISORY_ENABLE_REQUIRED`` bit,
  and change the layout of messages the codec uses: shorter frames (ACCEL_CMD 3 bytes,
  STEERING_CMD 5, SHIFT_CMD 2, SHIFT_RPT 4, VEHICLE_SPEED_RPT 3, YAW_RATE_RPT 2), no
  ``CLEAR_FAULTS`` in the system commands (it moved to ``GLOBAL_CMD``), a ``COMMAND_TIMEOUT``
  bit in the system reports, and a signed front-left wheel speed. The newest DBC (pacmod_dbc
  v14) carries no licence and is not shipped; those messages are in
  ``overdrive_pacmod3_v14_global.dbc``, written for overdrive from the byte layout of the MIT
  pacmod3_common library (``src/autogen/pacmod12.c`` / ``pacmod12.h``).
- **a user's own DBC** (``Pacmod3Codec(dbc_path=...)``) replaces the shipped one; it must define
  every message and signal the codec uses, checked when it is loaded.

Every command is validated before encoding (``KitEncodeError``: NaN, infinities, out of
range: nothing is clamped silently); every frame is checked on decoding (``KitDecodeError``:
wrong length, a counter whose complement does not match; ``UnknownFrame``: an id the dialect
does not use). ``docs/pacmod3.md`` lists the messages and the choices made.
"""

from __future__ import annotations

import hashlib
import math
import struct
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from typing import Any, Final, Literal

import cantools
import msgspec

from overdrive.kits.frames import CanFrame, KitDecodeError, KitEncodeError, KitError, UnknownFrame

Dialect = Literal["v3", "v14"]
DBC_DIR: Final = Path(__file__).resolve().parent / "dbc"
SHIPPED_DBC: Final = DBC_DIR / "as_pacmod_v3.4.0.dbc"
SHIPPED_DBC_SHA256: Final = "6003eb74fb9b1475321705942186950592a86d09850a020008e7537f0bb9c9f7"
V14_GLOBAL_DBC: Final = DBC_DIR / "overdrive_pacmod3_v14_global.dbc"

RATIO_MAX: Final = 1.0
"""ACCEL_CMD / BRAKE_CMD: 0..1 of the pedal's travel (DBC range [0|1], 0.001 per bit)."""
STEERING_POSITION_MAX_RAD: Final = 32.767
"""STEERING_CMD POSITION: signed 16 bits at 0.001 rad (DBC range [-32.768|32.767])."""
STEERING_RATE_MAX_RADPS: Final = 65.535
"""STEERING_CMD ROTATION_RATE: unsigned 16 bits at 0.001 rad/s."""
COUNTER_MODULO: Final = 16
"""GLOBAL_CMD / SUPERVISORY_CTRL COUNTER: 4 bits, 0 on the first frame, wrapping after 15."""


class Gear(IntEnum):
    """SHIFT_CMD values (DBC ``VAL_ 296``); 5 and 6 appear only in reports."""

    PARK = 0
    REVERSE = 1
    NEUTRAL = 2
    FORWARD = 3     # "FORWARD/HIGH": also HIGH on vehicles with LOW/HIGH
    LOW = 4
    BETWEEN_GEARS = 5
    ERROR = 6
    NONE = 7


GEAR_COMMANDS: Final = frozenset({Gear.PARK, Gear.REVERSE, Gear.NEUTRAL, Gear.FORWARD, Gear.LOW,
                                  Gear.NONE})


class _Command(msgspec.Struct, frozen=True, kw_only=True):
    """The bits every system command carries (DBC: ENABLE, IGNORE_OVERRIDES, CLEAR_OVERRIDE,
    CLEAR_FAULTS). ``enable`` false disables the system; the kit enables it only on a
    false -> true edge (``docs/pacmod3.md``)."""

    enable: bool
    ignore_overrides: bool = False
    clear_override: bool = False
    clear_faults: bool = False


class AccelCmd(_Command, frozen=True, kw_only=True):
    """ACCEL_CMD (0x100): the accelerator, 0..1 of its travel."""

    accel_ratio: float


class BrakeCmd(_Command, frozen=True, kw_only=True):
    """BRAKE_CMD (0x104): the brake pedal, 0..1 of its travel."""

    brake_ratio: float


class SteeringCmd(_Command, frozen=True, kw_only=True):
    """STEERING_CMD (0x12C): the steering-wheel angle (left positive) and its rate limit."""

    position_rad: float
    rotation_rate_radps: float


class ShiftCmd(_Command, frozen=True, kw_only=True):
    """SHIFT_CMD (0x128): the gear to select."""

    gear: Gear


class GlobalCmd(msgspec.Struct, frozen=True, kw_only=True):
    """GLOBAL_CMD (0x80, v14 dialect): clear faults / overrides; the counter's complement is
    computed on encoding and checked on decoding."""

    counter: int
    clear_faults: bool = False
    clear_overrides: bool = False
    sanity_check_required: bool = True


class SupervisoryCtrl(msgspec.Struct, frozen=True, kw_only=True):
    """SUPERVISORY_CTRL (0x81, v14 dialect): ``enable`` false disables every system."""

    counter: int
    enable: bool


class GlobalRpt(msgspec.Struct, frozen=True, kw_only=True):
    """GLOBAL_RPT (0x10): the kit as a whole."""

    enabled: bool
    override_active: bool
    usr_can_timeout: bool
    str_can_timeout: bool
    brk_can_timeout: bool
    subsystem_timeout: bool
    veh_can_timeout: bool
    fault_active: bool
    config_fault_active: bool
    usr_can_read_errors: int
    supervisory_enable_required: bool = False   # v14 only; always false in v3


class _SystemRpt(msgspec.Struct, frozen=True, kw_only=True):
    """The status bits every system report carries."""

    enabled: bool
    override_active: bool
    command_output_fault: bool = False
    input_output_fault: bool = False
    output_reported_fault: bool = False
    pacmod_fault: bool = False
    vehicle_fault: bool = False
    command_timeout: bool = False   # v14 only: the system's commands stopped (always false in v3)

    @property
    def faulted(self) -> bool:
        """Any of the report's five fault bits."""
        return (self.command_output_fault or self.input_output_fault
                or self.output_reported_fault or self.pacmod_fault or self.vehicle_fault)


class AccelRpt(_SystemRpt, frozen=True, kw_only=True):
    """ACCEL_RPT (0x200): values as ratios of the pedal's travel."""

    manual_input: float
    commanded_value: float
    output_value: float


class BrakeRpt(_SystemRpt, frozen=True, kw_only=True):
    """BRAKE_RPT (0x204): values as ratios of the pedal's travel."""

    manual_input: float
    commanded_value: float
    output_value: float


class SteeringRpt(_SystemRpt, frozen=True, kw_only=True):
    """STEERING_RPT (0x22C): steering-wheel angles, rad, left positive."""

    manual_input: float
    commanded_value: float
    output_value: float


class ShiftRpt(_SystemRpt, frozen=True, kw_only=True):
    """SHIFT_RPT (0x228): gears (``Gear`` values; 5 between gears, 6 error)."""

    manual_input: int
    commanded_value: int
    output_value: int


class VehicleSpeedRpt(msgspec.Struct, frozen=True, kw_only=True):
    """VEHICLE_SPEED_RPT (0x400): signed speed, m/s, and whether it is valid."""

    speed_mps: float
    valid: bool


class WheelSpeedRpt(msgspec.Struct, frozen=True, kw_only=True):
    """WHEEL_SPEED_RPT (0x407): wheel angular speeds, rad/s. The shipped DBC declares the front
    left one unsigned (the others signed): decoded as the DBC says."""

    front_left_radps: float
    front_right_radps: float
    rear_left_radps: float
    rear_right_radps: float


class YawRateRpt(msgspec.Struct, frozen=True, kw_only=True):
    """YAW_RATE_RPT (0x40D): yaw rate, rad/s, left positive."""

    yaw_rate_radps: float


Command = AccelCmd | BrakeCmd | SteeringCmd | ShiftCmd | GlobalCmd | SupervisoryCtrl
Report = (GlobalRpt | AccelRpt | BrakeRpt | SteeringRpt | ShiftRpt | VehicleSpeedRpt
          | WheelSpeedRpt | YawRateRpt)

_FLAGS: Final = (("enable", "ENABLE"), ("ignore_overrides", "IGNORE_OVERRIDES"),
                 ("clear_override", "CLEAR_OVERRIDE"), ("clear_faults", "CLEAR_FAULTS"))
_RPT_FLAGS: Final = (("enabled", "ENABLED"), ("override_active", "OVERRIDE_ACTIVE"),
                     ("command_output_fault", "COMMAND_OUTPUT_FAULT"),
                     ("input_output_fault", "INPUT_OUTPUT_FAULT"),
                     ("output_reported_fault", "OUTPUT_REPORTED_FAULT"),
                     ("pacmod_fault", "PACMOD_FAULT"), ("vehicle_fault", "VEHICLE_FAULT"),
                     ("command_timeout", "COMMAND_TIMEOUT"))
_RPT_VALUES: Final = (("manual_input", "MANUAL_INPUT"), ("commanded_value", "COMMANDED_VALUE"),
                      ("output_value", "OUTPUT_VALUE"))
_GLOBAL_RPT: Final = (("enabled", "PACMOD_SYSTEM_ENABLED"),
                      ("override_active", "PACMOD_SYSTEM_OVERRIDE_ACTIVE"),
                      ("usr_can_timeout", "USR_CAN_TIMEOUT"), ("str_can_timeout", "STR_CAN_TIMEOUT"),
                      ("brk_can_timeout", "BRK_CAN_TIMEOUT"),
                      ("subsystem_timeout", "PACMOD_SUBSYSTEM_TIMEOUT"),
                      ("veh_can_timeout", "VEH_CAN_TIMEOUT"),
                      ("fault_active", "PACMOD_SYSTEM_FAULT_ACTIVE"),
                      ("config_fault_active", "CONFIG_FAULT_ACTIVE"),
                      ("usr_can_read_errors", "USR_CAN_READ_ERRORS"))


@dataclass(frozen=True)
class _Map:
    """One typed message <-> one DBC message: (field, signal) pairs."""

    cls: type
    message: str
    fields: tuple[tuple[str, str], ...]


_MAPS: Final = (
    _Map(AccelCmd, "ACCEL_CMD", (*_FLAGS, ("accel_ratio", "ACCEL_CMD"))),
    _Map(BrakeCmd, "BRAKE_CMD", (*_FLAGS, ("brake_ratio", "BRAKE_CMD"))),
    _Map(SteeringCmd, "STEERING_CMD", (*_FLAGS, ("position_rad", "POSITION"),
                                       ("rotation_rate_radps", "ROTATION_RATE"))),
    _Map(ShiftCmd, "SHIFT_CMD", (*_FLAGS, ("gear", "SHIFT_CMD"))),
    _Map(AccelRpt, "ACCEL_RPT", (*_RPT_FLAGS, *_RPT_VALUES)),
    _Map(BrakeRpt, "BRAKE_RPT", (*_RPT_FLAGS, *_RPT_VALUES)),
    _Map(SteeringRpt, "STEERING_RPT", (*_RPT_FLAGS, *_RPT_VALUES)),
    _Map(ShiftRpt, "SHIFT_RPT", (*_RPT_FLAGS, *_RPT_VALUES)),
    _Map(VehicleSpeedRpt, "VEHICLE_SPEED_RPT", (("speed_mps", "VEHICLE_SPEED"),
                                                ("valid", "VEHICLE_SPEED_VALID"))),
    _Map(WheelSpeedRpt, "WHEEL_SPEED_RPT", (("front_left_radps", "WHEEL_SPD_FRONT_LEFT"),
                                            ("front_right_radps", "WHEEL_SPD_FRONT_RIGHT"),
                                            ("rear_left_radps", "WHEEL_SPD_REAR_LEFT"),
                                            ("rear_right_radps", "WHEEL_SPD_REAR_RIGHT"))),
    _Map(YawRateRpt, "YAW_RATE_RPT", (("yaw_rate_radps", "YAW_RATE"),)),
    _Map(GlobalRpt, "GLOBAL_RPT", _GLOBAL_RPT),
)
_V14_MAPS: Final = (
    _Map(GlobalCmd, "GLOBAL_CMD", (("clear_faults", "CLEAR_FAULTS"),
                                   ("sanity_check_required", "SANITY_CHECK_REQUIRED"),
                                   ("clear_overrides", "CLEAR_OVERRIDES"),
                                   ("counter", "COUNTER"))),
    _Map(SupervisoryCtrl, "SUPERVISORY_CTRL", (("enable", "ENABLE"), ("counter", "COUNTER"))),
    _Map(GlobalRpt, "GLOBAL_RPT", (*_GLOBAL_RPT,
                                   ("supervisory_enable_required", "SUPERVISORY_ENABLE_REQUIRED"))),
)
_COUNTED: Final = frozenset({"GLOBAL_CMD", "SUPERVISORY_CTRL"})
_OPTIONAL_SIGNALS: Final = frozenset({"CLEAR_FAULTS", "COMMAND_TIMEOUT"})
"""Signals one dialect lacks (v14 commands have no CLEAR_FAULTS; v3 reports no COMMAND_TIMEOUT):
absent from the DBC in use, the field decodes as False and encoding it True is refused."""


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def complement4(counter: int) -> int:
    """The 4-bit complement of a GLOBAL_CMD / SUPERVISORY_CTRL counter (0b1011 -> 0b0100)."""
    return ~counter & 0xF


class Pacmod3Codec:
    """Frames <-> typed PACMod 3 messages for one ``dialect`` over one DBC file.

    ``dbc_path`` None: the shipped v3.4.0 DBC. ``dbc_version`` and ``dbc_sha256`` name what was
    read, for the run folder.
    """

    def __init__(self, dialect: Dialect = "v3", dbc_path: str | Path | None = None) -> None:
        if dialect not in ("v3", "v14"):
            raise ValueError(f"PACMod 3 dialect {dialect!r}: expected 'v3' or 'v14'")
        self.dialect: Dialect = dialect
        self.dbc_path = Path(dbc_path) if dbc_path is not None else SHIPPED_DBC
        try:
            db = cantools.database.load_file(str(self.dbc_path), strict=True)
        except (OSError, ValueError, cantools.database.UnsupportedDatabaseFormatError,
                cantools.database.errors.Error) as e:   # ValueError: a suffix cantools lacks
            raise KitError(f"{self.dbc_path}: cannot read as a DBC: {e}") from e
        self.dbc_sha256 = _sha256(self.dbc_path)
        self.dbc_version = db.version or self.dbc_path.stem
        self.dbc_files: tuple[tuple[str, str], ...] = ((str(self.dbc_path), self.dbc_sha256),)
        """Every DBC file read, ``(path, sha256)``: the v14 fragment too, for the run folder."""
        maps = list(_MAPS)
        sources = [(m, db) for m in maps]
        if dialect == "v14":
            # A user's v14 DBC defines every message itself; with the shipped v3.4.0 DBC, the
            # fragment supplies the messages added or changed since (and GLOBAL_RPT's new bit).
            ext = cantools.database.load_file(str(V14_GLOBAL_DBC), strict=True)
            self.dbc_files += ((str(V14_GLOBAL_DBC), _sha256(V14_GLOBAL_DBC)),)
            own = {x.name for x in db.messages} if self.dbc_path != SHIPPED_DBC else set()
            ext_names = {x.name for x in ext.messages}
            v14 = [*(m for m in maps if m.message != "GLOBAL_RPT"), *_V14_MAPS]
            sources = [(m, db if m.message in own or m.message not in ext_names else ext)
                       for m in v14]
        self._by_type: dict[type, tuple[_Map, Any]] = {}
        self._by_id: dict[int, tuple[_Map, Any]] = {}
        self._fields: dict[type, tuple[tuple[str, str], ...]] = {}
        self._converters: dict[type, tuple[tuple[str, str, Any, int | None], ...]] = {}
        self._limits: dict[type, tuple[tuple[str, float, float, frozenset[int], str], ...]] = {}
        for m, source in sources:
            try:
                message = source.get_message_by_name(m.message)
            except KeyError as e:
                raise KitError(f"{self.dbc_path}: no message {m.message}") from e
            names = {s.name for s in message.signals}
            missing = [sig for _, sig in m.fields
                       if sig not in names and sig not in _OPTIONAL_SIGNALS]
            if missing:
                raise KitError(f"{self.dbc_path}: {m.message} lacks {', '.join(missing)}")
            if message.frame_id in self._by_id:   # cantools only warns about a shared id
                raise KitError(f"{self.dbc_path}: {m.message} and "
                               f"{self._by_id[message.frame_id][0].message} share CAN id "
                               f"0x{message.frame_id:X}: one frame cannot be both")
            self._by_type[m.cls] = (m, message)
            self._by_id[message.frame_id] = (m, message)
            fields = tuple((f, sig) for f, sig in m.fields if sig in names)
            self._fields[m.cls] = fields
            types = {f.name: f.type for f in msgspec.structs.fields(m.cls)}
            self._converters[m.cls] = tuple(
                (field, signal, types[field],
                 _decimals(message.get_signal_by_name(signal).scale) if types[field] is float
                 else None)
                for field, signal in fields)
            self._limits[m.cls] = tuple(_limits(message.get_signal_by_name(signal))
                                        for _, signal in fields)

    @property
    def frame_ids(self) -> frozenset[int]:
        """Every identifier this codec reads or writes."""
        return frozenset(self._by_id)

    def frame_id(self, cls: type) -> int:
        """The CAN id of the message ``cls``."""
        return self._by_type[cls][1].frame_id

    def encode(self, msg: Command | Report) -> CanFrame:
        """``msg`` as a frame. Raises ``KitEncodeError`` for a value the DBC cannot carry."""
        try:
            m, message = self._by_type[type(msg)]
        except KeyError:
            raise KitEncodeError(f"{type(msg).__name__} is not a PACMod 3 "
                                 f"{self.dialect} message") from None
        values: dict[str, Any] = {}
        for field, signal in m.fields:
            value = getattr(msg, field)
            if (field, signal) not in self._fields[m.cls]:   # a signal this dialect lacks
                if value:
                    hint = " (v14 clears faults with GlobalCmd)" if signal == "CLEAR_FAULTS" else ""
                    raise KitEncodeError(f"{m.message}.{signal}: not in the {self.dialect} "
                                         f"protocol{hint}")
                continue
            if isinstance(value, bool):
                value = int(value)
            elif isinstance(value, float) and not math.isfinite(value):
                raise KitEncodeError(f"{m.message}.{signal}: {value} is not finite")
            values[signal] = value
        _check_command(msg, m.message)
        if m.message in _COUNTED:
            values["COMPLEMENT"] = complement4(values["COUNTER"])
        try:
            data = message.encode(values, scaling=True, strict=True)
        except (cantools.database.errors.EncodeError, ValueError, KeyError, OverflowError,
                struct.error) as e:
            # OverflowError / struct.error: a value inside the DBC's stated range that its bits
            # cannot hold (v3.4.0's unsigned WHEEL_SPD_FRONT_LEFT given a negative speed).
            raise KitEncodeError(f"{m.message}: {e}") from e
        return CanFrame(arbitration_id=message.frame_id, data=bytes(data))

    def decode(self, frame: CanFrame) -> Command | Report:
        """The typed message in ``frame``. Raises ``UnknownFrame`` for an id this dialect does
        not use, ``KitDecodeError`` for a wrong length, a bad complement, or a value outside the
        range the DBC states (unless the DBC names it: gears 5 to 7), so no report out of its
        range (an accelerator at 65 times its travel) reaches the stack."""
        if frame.is_extended:
            raise UnknownFrame(f"extended id 0x{frame.arbitration_id:X}: PACMod 3 uses 11-bit ids")
        try:
            m, message = self._by_id[frame.arbitration_id]
        except KeyError:
            raise UnknownFrame(f"CAN id 0x{frame.arbitration_id:X} is not a PACMod 3 "
                               f"{self.dialect} frame this codec reads") from None
        if len(frame.data) != message.length:
            raise KitDecodeError(f"{m.message}: {len(frame.data)} bytes, expected "
                                 f"{message.length}")
        try:
            signals = message.decode(frame.data, decode_choices=False, scaling=True)
        except (cantools.database.errors.DecodeError, ValueError) as e:
            raise KitDecodeError(f"{m.message}: {e}") from e
        if m.message in _COUNTED and signals["COMPLEMENT"] != complement4(signals["COUNTER"]):
            raise KitDecodeError(f"{m.message}: complement {signals['COMPLEMENT']} does not "
                                 f"match counter {signals['COUNTER']}")
        for signal, low, high, choices, stated in self._limits[m.cls]:
            value = signals[signal]
            if not low <= value <= high and value not in choices:
                raise KitDecodeError(f"{m.message}.{signal}: {value:g} outside the DBC's range "
                                     f"{stated}")
        kwargs = {field: convert(signals[signal] if digits is None
                                 else round(signals[signal], digits))
                  for field, signal, convert, digits in self._converters[m.cls]}
        try:
            msg = m.cls(**kwargs)
            # a command frame must hold what a command may carry: the encoder's own ranges
            # (position -32.768 rad is in the DBC's range but not in the symmetric +-32.767)
            _check_command(msg, m.message)
        except ValueError as e:   # a gear the enum does not have; KitEncodeError
            raise KitDecodeError(f"{m.message}: {e}") from e
        return msg


def _decimals(scale: float) -> int | None:
    """Decimal places of a power-of-ten scale (0.001 -> 3): a decoded value is rounded to them,
    so raw 3300 at 0.001 reads 3.3, not 3300 * 0.001 = 3.3000000000000003. None otherwise."""
    if not 0 < scale < 1:
        return None
    digits = round(-math.log10(scale))
    return digits if math.isclose(10.0 ** -digits, scale) else None


def _limits(signal: Any) -> tuple[str, float, float, frozenset[int], str]:
    """A signal's DBC range, widened by half a step (the scaled raw values at its ends), the
    values its ``VAL_`` table names, and the range as the DBC states it (for errors)."""
    half_step = abs(signal.scale) / 2
    low = -math.inf if signal.minimum is None else signal.minimum - half_step
    high = math.inf if signal.maximum is None else signal.maximum + half_step
    return (signal.name, low, high, frozenset(signal.choices or ()),
            f"[{signal.minimum}|{signal.maximum}]")


def _check_command(msg: Any, name: str) -> None:
    """Ranges the DBC states, checked here so a bad value is refused, never wrapped or clamped."""
    if isinstance(msg, AccelCmd | BrakeCmd):
        ratio = msg.accel_ratio if isinstance(msg, AccelCmd) else msg.brake_ratio
        if not 0.0 <= ratio <= RATIO_MAX:
            raise KitEncodeError(f"{name}: ratio {ratio} outside 0..{RATIO_MAX}")
    elif isinstance(msg, SteeringCmd):
        if abs(msg.position_rad) > STEERING_POSITION_MAX_RAD:
            raise KitEncodeError(f"{name}: position {msg.position_rad} rad outside "
                                 f"+-{STEERING_POSITION_MAX_RAD}")
        if not 0.0 <= msg.rotation_rate_radps <= STEERING_RATE_MAX_RADPS:
            raise KitEncodeError(f"{name}: rotation rate {msg.rotation_rate_radps} rad/s "
                                 f"outside 0..{STEERING_RATE_MAX_RADPS}")
    elif isinstance(msg, ShiftCmd):
        if msg.gear not in GEAR_COMMANDS:
            raise KitEncodeError(f"{name}: {msg.gear!r} is a report value, not a command")
    elif isinstance(msg, GlobalCmd | SupervisoryCtrl) and not 0 <= msg.counter < COUNTER_MODULO:
        raise KitEncodeError(f"{name}: counter {msg.counter} outside 0..15")
