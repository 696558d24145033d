"""The emulated PACMod 3 kit: a PACMod 3 as seen from its user CAN bus, overdrive's plant behind it.

Sans-IO: ``receive(frame, now_s)`` takes one command frame, ``step(now_s)`` advances the vehicle,
``report_frames(now_s)`` gives the reports due, ``truth(now_s)`` the ground truth for the judge.
Nothing here reads a clock or opens a bus (``overdrive kit-sim pacmod3`` does: run/kit_sim.py).

The kit's rules (docs/pacmod3-kit.md; issue 32):

- **Systems** ACCEL, BRAKE, STEERING, SHIFT, each with its own command stream. A system enables
  only on a DISABLE -> ENABLE edge of its command's ``enable`` bit: the previous accepted frame
  said 0, this one says 1. A stream that starts with 1, or a stream still saying 1 after the kit
  disabled the system (timeout, override, fault, supervisory disable), does not enable it.
- **Command timeout**: ``COMMAND_TIMEOUT_S`` (3 periods of 1/30 s) without an accepted frame of
  a system that has had one -> that system is timed out (``GLOBAL_RPT.usr_can_timeout``) and
  disabled. A real PACMod then hands the vehicle back to the driver: in simulation nobody presses
  a pedal, so the vehicle rolls to a stop by drag and engine braking. A stack must never rely on
  the timeout to stop. Frames resuming clear the timeout flag; enabling again needs an edge.
- **Override**: an operator input (accelerator or brake pedal pressed beyond its threshold, the
  steering wheel held with more than its torque threshold, a gear selected by hand) latches
  ``override_active`` on that system's report and disables it; ``GLOBAL_RPT.override_active``
  while any system is latched. A latch clears only once the operator has let go AND the stream
  sends ``clear_override`` with a DISABLE -> ENABLE edge (or, v14, GLOBAL_CMD clear_overrides,
  after which an edge still enables). ``ignore_overrides`` is honoured as a real kit does
  (counted: a stack must never set it).
- **Faults**: a stuck actuator (a scenario's actuator fault or an injected ``stuck``) reports
  ``output_reported_fault`` on its system and disables it; the fault stays latched until the
  actuator works again and ``clear_faults`` is sent (per command in v3, GLOBAL_CMD in v14).
- **Reports** every ``REPORT_PERIOD_S`` (30 Hz): GLOBAL_RPT, the four system reports,
  VEHICLE_SPEED_RPT (signed), WHEEL_SPEED_RPT (magnitudes), YAW_RATE_RPT (left positive).
  ``silence`` faults stop all of them for a while.
- **v14 dialect**: GLOBAL_CMD and SUPERVISORY_CTRL carry a 4-bit counter: each must be the last
  one seen plus 1 (mod 16); a repeated or skipped counter is counted and the frame ignored (the
  next consecutive one is accepted again). ``supervisory_enable_required`` is reported; no
  system enables unless SUPERVISORY_CTRL enable=1 frames are current, and enable=0 (or its
  stream timing out) disables every system.
- **Bad input**: unknown ids, wrong lengths, bad complements, values outside the DBC's or the
  vehicle's range (a steering-wheel angle past full lock, a report-only gear): counted by
  reason, never acted on, and not a command (they do not feed the timeout).

Steering: ``STEERING_CMD.position_rad`` is the steering-WHEEL angle, left positive; the kit moves
its wheel target toward it at no more than ``rotation_rate_radps`` and turns it into the road-wheel
angle through the vehicle's ``steering_ratio`` (``dynamics.steering_ratio``); the plant (right
positive) adds its own actuator rate limit and lag. Pedals: ``accel_ratio`` and ``brake_ratio``
go through the kit's own nonlinear maps (``accel_effort``, ``brake_effort``: a dead band and a
progressive curve, as pedal-by-wire feels) that the stack is not told: its adaptive loops must
find them.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass, field
from typing import Any, Final, Literal

import msgspec

from overdrive.dynamics.steering_ratio import road_wheel_rad, steering_wheel_rad
from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.kits.frames import CanFrame, KitEncodeError, UnknownFrame
from overdrive.kits.pacmod3 import (
    COUNTER_MODULO,
    GEAR_COMMANDS,
    RATIO_MAX,
    AccelCmd,
    AccelRpt,
    BrakeCmd,
    BrakeRpt,
    Dialect,
    Gear,
    GlobalCmd,
    GlobalRpt,
    Pacmod3Codec,
    ShiftCmd,
    ShiftRpt,
    SteeringCmd,
    SteeringRpt,
    SupervisoryCtrl,
    VehicleSpeedRpt,
    WheelSpeedRpt,
    YawRateRpt,
)
from overdrive.messages import SafetyDevices
from overdrive.vehicle.plant import STOPPED_MPS, ActuatorFaults, Plant, World

System = Literal["accel", "brake", "steering", "shift"]
SYSTEMS: Final[tuple[System, ...]] = ("accel", "brake", "steering", "shift")

COMMAND_PERIOD_S: Final = 1.0 / 30.0
"""PACMod user CAN protocol: commands expected at 30 Hz."""
COMMAND_TIMEOUT_S: Final = 3.0 * COMMAND_PERIOD_S
"""3 missed periods (100 ms) without a command -> the system disables (issue 32)."""
REPORT_PERIOD_S: Final = 1.0 / 30.0
"""Every report at 30 Hz (a real kit's rates vary by vehicle; this is ours: docs/pacmod3-kit.md)."""
PLANT_STEP_S: Final = 0.01
"""The plant is integrated in steps of at most 10 ms, as in the lock-step runs."""
TIME_EPS_S: Final = 1e-9
"""Float slack on time comparisons (a frame exactly at the timeout is still in time)."""

ACCEL_OVERRIDE_RATIO: Final = 0.1
"""Accelerator pressed by the operator beyond 10 % of its travel latches an override
(engineering estimate: above a resting foot, below any deliberate press)."""
BRAKE_OVERRIDE_RATIO: Final = 0.1
"""Brake pedal pressed beyond 10 % of its travel latches an override (engineering estimate)."""
STEERING_OVERRIDE_NM: Final = 3.0
"""Operator torque on the steering wheel beyond 3 N.m latches an override (engineering estimate:
a deliberate grab; a hand resting on the rim gives ~1 N.m)."""
STEERING_POSITION_SLACK_RAD: Final = 0.002
"""A wheel angle up to 2 DBC steps (0.001 rad) past full lock is full lock (rounding of the
client's inverse); beyond, the frame is refused."""

ACCEL_DEAD_BAND: Final = 0.06
"""The kit's own accelerator map (hidden from the stack): nothing below 6 % of travel, ..."""
ACCEL_EXPONENT: Final = 1.6
"""... then a progressive curve (pedal-by-wire maps are soft at first). Engineering estimate."""
BRAKE_DEAD_BAND: Final = 0.04
"""The kit's own brake map: pedal free play of 4 % of travel, ..."""
BRAKE_EXPONENT: Final = 1.3
"""... then a progressive curve (booster and pad bite). Engineering estimate."""

TYRE_RADIUS_M: Final = 0.381
"""Rolling radius for WHEEL_SPEED_RPT: the RX 450h's 235/65R18 (228.6 mm rim + 152.75 mm wall)."""


def accel_effort(ratio: float) -> float:
    """The plant's throttle (0..1) for an accelerator ratio: dead band, then ``x^1.6``."""
    if ratio <= ACCEL_DEAD_BAND:
        return 0.0
    return min(((ratio - ACCEL_DEAD_BAND) / (1.0 - ACCEL_DEAD_BAND)) ** ACCEL_EXPONENT, 1.0)


def brake_effort(ratio: float) -> float:
    """The plant's brake (0..1) for a brake-pedal ratio: free play, then ``x^1.3``."""
    if ratio <= BRAKE_DEAD_BAND:
        return 0.0
    return min(((ratio - BRAKE_DEAD_BAND) / (1.0 - BRAKE_DEAD_BAND)) ** BRAKE_EXPONENT, 1.0)


class KitFault(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """A fault injected into the kit, on the kit's clock (``now_s`` as passed in).

    ``override``: the operator presses ``system``'s pedal to ``value`` (a ratio), holds the wheel
    with ``value`` N.m, or selects gear ``value`` by hand, from ``start_s`` to ``end_s``.
    ``silence``: no report at all in the window (``system`` unused). ``stuck``: ``system``'s
    actuator (accel, brake, steering) freezes where it is for the window.
    """

    kind: Literal["override", "silence", "stuck"]
    start_s: float
    end_s: float | None = None
    system: System | None = None
    value: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and self.start_s >= 0.0):
            raise ValueError(f"fault start {self.start_s} s must be a finite time >= 0")
        if self.end_s is not None and not (math.isfinite(self.end_s) and self.end_s > self.start_s):
            raise ValueError(f"fault end {self.end_s} s must be a finite time after its start")
        if self.kind in ("override", "stuck") and self.system is None:
            raise ValueError(f"a {self.kind} fault names its system ({', '.join(SYSTEMS)})")
        if self.kind == "stuck" and self.system == "shift":
            raise ValueError("a stuck actuator is accel, brake or steering")
        if not math.isfinite(self.value):
            raise ValueError(f"fault value {self.value} must be finite")
        if self.kind == "override" and self.system in ("accel", "brake") \
                and not 0.0 <= self.value <= RATIO_MAX:
            raise ValueError(f"a pedal press is a ratio 0..1, got {self.value}")
        if self.kind == "override" and self.system == "shift" and \
                self.value not in {float(g) for g in GEAR_COMMANDS - {Gear.NONE}}:
            raise ValueError(f"a gear selected by hand is a Gear value, got {self.value}")

    def active(self, now_s: float) -> bool:
        return self.start_s - TIME_EPS_S <= now_s and (self.end_s is None
                                                         or now_s < self.end_s - TIME_EPS_S)


@dataclass
class SystemState:
    """One system's state as the kit holds it."""

    enabled: bool = False
    last_enable_bit: bool | None = None   # None: no frame since the kit last disabled it
    last_command_s: float | None = None   # the last accepted command frame
    timed_out: bool = False
    override: bool = False                # latched
    fault: bool = False                   # latched
    ignore_overrides: bool = False
    command: Any = None                   # the last accepted command message


@dataclass
class KitEvents:
    """What happened, with times, for the summary and the tests."""

    enable_edges: list[tuple[str, float]] = field(default_factory=list)
    disables: list[tuple[str, float, str]] = field(default_factory=list)
    timeouts: list[tuple[str, float]] = field(default_factory=list)
    overrides: list[tuple[str, float]] = field(default_factory=list)
    override_clears: list[tuple[str, float]] = field(default_factory=list)
    faults: list[tuple[str, float]] = field(default_factory=list)
    refused_edges: list[tuple[str, float, str]] = field(default_factory=list)
    # at each enable edge: the brake the kit was applying then (enabled brake command, else 0)
    brake_at_edges: list[float] = field(default_factory=list)
    first_throttle_s: float | None = None   # first step an enabled accel command gave throttle


class Truth(msgspec.Struct, frozen=True):
    """Ground truth: the simulated vehicle's own state (not what the reports say)."""

    t_s: float
    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float
    odometer_m: float
    road_wheel_rad: float        # right positive (the plant's)
    steering_wheel_rad: float    # left positive (PACMod's)
    gear: str
    throttle: float
    brake: float
    enabled: tuple[str, ...]


_NAMES: Final = {AccelCmd: "accel", BrakeCmd: "brake", SteeringCmd: "steering", ShiftCmd: "shift"}


class Pacmod3Kit:
    """The emulated kit (module docstring). ``params`` must state a ``steering_ratio``."""

    def __init__(self, params: VehicleParams, world: World | None = None, seed: int = 1, *,
                 dialect: Dialect = "v3", codec: Pacmod3Codec | None = None,
                 faults: tuple[KitFault, ...] = ()) -> None:
        if params.steering_ratio is None:
            raise ValueError(f"vehicle {params.preset!r} states no steering_ratio: a PACMod 3 "
                             f"steers by the steering-wheel angle")
        self.params = params
        self.codec = codec if codec is not None else Pacmod3Codec(dialect)
        self.dialect: Dialect = self.codec.dialect
        self.plant = Plant(params, world or World(), random.Random(f"{seed}/engine"),
                           engine_running=True, gear=params.park_gear)
        self.max_wheel_rad = steering_wheel_rad(params.steering_ratio, params.max_steer_rad)
        self.systems: dict[str, SystemState] = {s: SystemState() for s in SYSTEMS}
        self.events = KitEvents()
        self.faults: list[KitFault] = list(faults)
        self.bad_frames: dict[str, int] = {}
        self.frames_seen: dict[str, int] = {}
        self.ignore_overrides_frames = 0
        self.clear_override_frames = 0
        # kit-side actuator targets
        self.wheel_target_rad = 0.0        # the rate-limited steering-wheel target, left +
        self.scenario_operator: dict[str, float] = {}   # from SafetyDevices (manual override)
        # v14
        self.supervisory_enable_required = self.dialect == "v14"
        self.supervisory_enabled = False
        self.supervisory_last_s: float | None = None
        self.supervisory_timed_out = False
        self.counters: dict[str, int | None] = {"GLOBAL_CMD": None, "SUPERVISORY_CTRL": None}
        # time
        self.last_step_s: float | None = None
        self.next_report_s: float | None = None
        self.now_s = 0.0
        self.last_frame_s: dict[str, float] = {}

    # ------------------------------------------------------------------ world and faults

    def set_world(self, world: World) -> None:
        self.plant.world = world

    def apply_actuator_faults(self, faults: ActuatorFaults) -> None:
        """A scenario's actuator fault (weak, slow, stuck) for the plant."""
        self.plant.faults = faults

    def set_devices(self, devices: SafetyDevices) -> None:
        """A scenario's safety devices, as a PACMod vehicle has them: a manual override (or its
        emergency form, or a partial mode) is the safety driver braking and holding the wheel."""
        operator: dict[str, float] = {}
        takes_speed = devices.manual_override or devices.emergency_manual_override \
            or devices.partial_mode == "manual-speed"
        takes_wheel = devices.manual_override or devices.emergency_manual_override \
            or devices.partial_mode == "manual-steering"
        if takes_speed:
            operator["brake"] = SCENARIO_DRIVER_BRAKE_RATIO
        if takes_wheel:
            operator["steering"] = SCENARIO_DRIVER_TORQUE_NM
        self.scenario_operator = operator

    def inject(self, fault: KitFault) -> None:
        self.faults.append(fault)

    def _operator_input(self, system: str, now_s: float) -> float:
        """The operator's input on ``system`` now (pedal ratio, wheel torque, gear): 0 if none."""
        value = self.scenario_operator.get(system, 0.0)
        for f in self.faults:
            if f.kind == "override" and f.system == system and f.active(now_s):
                value = f.value
        return value

    def _operator_overrides(self, system: str, now_s: float) -> bool:
        value = self._operator_input(system, now_s)
        if system == "accel":
            return value >= ACCEL_OVERRIDE_RATIO
        if system == "brake":
            return value >= BRAKE_OVERRIDE_RATIO
        if system == "steering":
            return abs(value) >= STEERING_OVERRIDE_NM
        return any(f.kind == "override" and f.system == "shift" and f.active(now_s)
                   for f in self.faults)

    def _stuck(self, system: str, now_s: float) -> bool:
        plant_faults = self.plant.faults
        if system == "accel" and plant_faults.throttle_stuck:
            return True
        if system == "brake" and plant_faults.brake_stuck:
            return True
        if system == "steering" and plant_faults.steering_stuck:
            return True
        return any(f.kind == "stuck" and f.system == system and f.active(now_s) for f in self.faults)

    def silenced(self, now_s: float) -> bool:
        return any(f.kind == "silence" and f.active(now_s) for f in self.faults)

    # ------------------------------------------------------------------ input

    def _bad(self, reason: str) -> None:
        self.bad_frames[reason] = self.bad_frames.get(reason, 0) + 1

    def receive(self, frame: CanFrame, now_s: float) -> None:
        """One frame from the bus. Anything not a valid command of this dialect is counted in
        ``bad_frames`` by reason and otherwise ignored."""
        self._check_timeouts(now_s)
        try:
            msg = self.codec.decode(frame)
        except UnknownFrame:
            self._bad("unknown_id")
            return
        except ValueError as e:   # KitDecodeError, or anything else a decoder may raise
            self._bad("bad_complement" if "complement" in str(e) else "malformed")
            return
        name = type(msg).__name__
        if name.endswith("Rpt"):
            self._bad("report_id")     # another node reporting on our ids: not a command
            return
        self.frames_seen[name] = self.frames_seen.get(name, 0) + 1
        if isinstance(msg, GlobalCmd):
            if self._counter_ok("GLOBAL_CMD", msg.counter):
                self._global(msg, now_s)
            return
        if isinstance(msg, SupervisoryCtrl):
            if self._counter_ok("SUPERVISORY_CTRL", msg.counter):
                self._supervisory(msg, now_s)
            return
        reason = self._invalid(msg)
        if reason:
            self._bad(reason)
            return
        self._command(_NAMES[type(msg)], msg, now_s)

    def _counter_ok(self, message: str, counter: int) -> bool:
        last = self.counters[message]
        self.counters[message] = counter   # a skip resynchronises: the next one in turn is good
        if last is None or counter == (last + 1) % COUNTER_MODULO:
            return True
        self._bad("repeated_counter" if counter == last else "bad_counter")
        return False

    def _invalid(self, msg: Any) -> str:
        """Why a decoded command is not one the kit acts on ("" if it is)."""
        if isinstance(msg, AccelCmd) and not 0.0 <= msg.accel_ratio <= RATIO_MAX:
            return "out_of_range"
        if isinstance(msg, BrakeCmd) and not 0.0 <= msg.brake_ratio <= RATIO_MAX:
            return "out_of_range"
        if isinstance(msg, SteeringCmd) and \
                abs(msg.position_rad) > self.max_wheel_rad + STEERING_POSITION_SLACK_RAD:
            return "out_of_range"
        if isinstance(msg, ShiftCmd) and msg.gear not in GEAR_COMMANDS:
            return "out_of_range"
        return ""

    def _command(self, system: str, msg: Any, now_s: float) -> None:
        st = self.systems[system]
        st.last_command_s = now_s
        self.last_frame_s[system] = now_s
        st.timed_out = False
        st.ignore_overrides = msg.ignore_overrides
        if msg.ignore_overrides:
            self.ignore_overrides_frames += 1
        if msg.clear_override:
            self.clear_override_frames += 1
        if msg.clear_faults and self.dialect == "v3":
            self._clear_fault(system, now_s)
        edge = st.last_enable_bit is False and msg.enable
        st.last_enable_bit = msg.enable
        if not msg.enable:
            if st.enabled:
                self._disable(system, now_s, "enable=0")
        elif edge:
            if st.override and msg.clear_override and not self._operator_overrides(system, now_s):
                st.override = False
                self.events.override_clears.append((system, now_s))
            why = self._cannot_enable(system, now_s)
            if why:
                self.events.refused_edges.append((system, now_s, why))
            else:
                brake = self.systems["brake"]
                self.events.brake_at_edges.append(   # before this edge takes effect
                    brake.command.brake_ratio if brake.enabled and brake.command is not None
                    else 0.0)
                st.enabled = True
                self.events.enable_edges.append((system, now_s))
        st.command = msg

    def _cannot_enable(self, system: str, now_s: float) -> str:
        st = self.systems[system]
        if st.override:
            return "override latched (release, then clear_override with the edge)"
        if self._operator_overrides(system, now_s) and not st.ignore_overrides:
            return "operator input"
        if st.fault:
            return "fault latched (clear_faults)"
        if self.supervisory_enable_required and not self.supervisory_enabled:
            return "supervisory enable required"
        return ""

    def _disable(self, system: str, now_s: float, why: str) -> None:
        st = self.systems[system]
        if st.enabled:
            self.events.disables.append((system, now_s, why))
        st.enabled = False
        st.last_enable_bit = None   # a new DISABLE -> ENABLE edge is needed

    def _clear_fault(self, system: str, now_s: float) -> None:
        st = self.systems[system]
        if st.fault and not self._stuck(system, now_s):
            st.fault = False

    def _global(self, msg: GlobalCmd, now_s: float) -> None:
        if msg.clear_faults:
            for system in SYSTEMS:
                self._clear_fault(system, now_s)
        if msg.clear_overrides:
            for system in SYSTEMS:
                st = self.systems[system]
                if st.override and not self._operator_overrides(system, now_s):
                    st.override = False
                    self.events.override_clears.append((system, now_s))

    def _supervisory(self, msg: SupervisoryCtrl, now_s: float) -> None:
        self.supervisory_last_s = now_s
        self.supervisory_timed_out = False
        self.supervisory_enabled = msg.enable
        if not msg.enable:
            for system in SYSTEMS:
                self._disable(system, now_s, "supervisory enable=0")

    # ------------------------------------------------------------------ rules in time

    def _check_timeouts(self, now_s: float) -> None:
        for system, st in self.systems.items():
            if (st.last_command_s is not None and not st.timed_out
                    and now_s - st.last_command_s > COMMAND_TIMEOUT_S + TIME_EPS_S):
                st.timed_out = True
                self.events.timeouts.append((system, now_s))
                self._disable(system, now_s, "command timeout")
        if (self.supervisory_last_s is not None and not self.supervisory_timed_out
                and now_s - self.supervisory_last_s > COMMAND_TIMEOUT_S + TIME_EPS_S):
            self.supervisory_timed_out = True
            self.supervisory_enabled = False
            self.events.timeouts.append(("supervisory", now_s))
            for system in SYSTEMS:
                self._disable(system, now_s, "supervisory timeout")

    def _check_operator(self, now_s: float) -> None:
        for system, st in self.systems.items():
            if self._stuck(system, now_s) and not st.fault:
                st.fault = True
                self.events.faults.append((system, now_s))
                self._disable(system, now_s, "actuator fault")
            if st.ignore_overrides and st.enabled:
                continue
            if self._operator_overrides(system, now_s) and not st.override:
                st.override = True
                self.events.overrides.append((system, now_s))
                self._disable(system, now_s, "operator override")

    # ------------------------------------------------------------------ step

    def step(self, now_s: float) -> None:
        """Apply the kit's rules at ``now_s`` and advance the vehicle to it."""
        self.now_s = now_s
        self._check_timeouts(now_s)
        self._check_operator(now_s)
        last = self.last_step_s
        self.last_step_s = now_s
        if last is None or now_s <= last:
            return
        dt_total = now_s - last
        n = max(1, math.ceil(dt_total / PLANT_STEP_S - 1e-9))
        dt = dt_total / n
        for _ in range(n):
            self._plant_step(dt, now_s)

    def _plant_step(self, dt_s: float, now_s: float) -> None:
        p, plant, systems = self.params, self.plant, self.systems
        throttle = brake = 0.0
        accel, brk, steer, shift = (systems[s] for s in SYSTEMS)
        if accel.enabled and accel.command is not None:
            throttle = accel_effort(accel.command.accel_ratio)
            if throttle > 0.0 and self.events.first_throttle_s is None:
                self.events.first_throttle_s = now_s
        if brk.enabled and brk.command is not None:
            brake = brake_effort(brk.command.brake_ratio)
        operator_accel = self._operator_input("accel", now_s)
        operator_brake = self._operator_input("brake", now_s)
        if not accel.enabled or not accel.ignore_overrides:
            throttle = max(throttle, accel_effort(operator_accel))
        if not brk.enabled or not brk.ignore_overrides:
            brake = max(brake, brake_effort(operator_brake))
        # steering: the kit's wheel target follows the command at its rotation rate; disabled,
        # the wheel stays where it is (nobody turns it in simulation)
        if steer.enabled and steer.command is not None:
            goal = max(-self.max_wheel_rad, min(self.max_wheel_rad, steer.command.position_rad))
            max_step = steer.command.rotation_rate_radps * dt_s
            self.wheel_target_rad += max(-max_step, min(max_step, goal - self.wheel_target_rad))
        else:
            self.wheel_target_rad = self.steering_wheel_now()
        road_left = road_wheel_rad(p.steering_ratio, self.wheel_target_rad)
        steer_pct = -100.0 * road_left / p.max_steer_rad
        gear = plant.gear if plant.shift_target is None else plant.shift_target
        if shift.enabled and shift.command is not None and shift.command.gear != Gear.NONE:
            gear = self._gear_name(shift.command.gear) or gear
        hand = [f for f in self.faults if f.kind == "override" and f.system == "shift"
                and f.active(now_s)]
        if hand and not (shift.enabled and shift.ignore_overrides):
            gear = self._gear_name(Gear(int(hand[-1].value))) or gear
        saved = plant.faults
        stuck = {f"{'throttle' if s == 'accel' else s}_stuck": True for s in ("accel", "brake",
                                                                              "steering")
                 if any(f.kind == "stuck" and f.system == s and f.active(now_s)
                        for f in self.faults)}
        if stuck:
            plant.faults = msgspec.structs.replace(saved, **stuck)
        plant.step(dt_s, 100.0 * throttle, 100.0 * brake, steer_pct, gear, True, False)
        plant.faults = saved

    def _gear_name(self, gear: Gear) -> str | None:
        """The vehicle's gear for a SHIFT_CMD value (None: the vehicle has none such)."""
        p = self.params
        if gear == Gear.PARK:
            return p.park_gear
        if gear == Gear.REVERSE:
            return p.reverse_gear
        if gear == Gear.FORWARD:
            return p.drive_gear
        if gear == Gear.LOW:
            return p.low_gear
        if gear == Gear.NEUTRAL:
            return next((g.name for g in p.gears if g.direction == 0 and not g.holds), None)
        return None

    def _gear_code(self, name: str | None) -> int:
        p = self.params
        codes = {p.park_gear: Gear.PARK, p.reverse_gear: Gear.REVERSE, p.drive_gear: Gear.FORWARD,
                 p.low_gear: Gear.LOW}
        neutral = self._gear_name(Gear.NEUTRAL)
        if neutral is not None:
            codes[neutral] = Gear.NEUTRAL
        return int(codes.get(name, Gear.NONE)) if name is not None else int(Gear.NONE)

    def steering_wheel_now(self) -> float:
        """The steering-wheel angle the road wheels stand at (left positive)."""
        return steering_wheel_rad(self.params.steering_ratio, -self.plant.road_wheel_rad)

    # ------------------------------------------------------------------ reports

    def report_frames(self, now_s: float) -> list[CanFrame]:
        """The reports due at ``now_s`` (every ``REPORT_PERIOD_S``; none while silenced)."""
        if self.next_report_s is None:
            self.next_report_s = now_s
        if now_s < self.next_report_s - TIME_EPS_S:
            return []
        self.next_report_s += REPORT_PERIOD_S
        if self.next_report_s < now_s:      # a stalled caller: restart the schedule from now
            self.next_report_s = now_s + REPORT_PERIOD_S
        if self.silenced(now_s):
            return []
        frames = []
        for msg in self.reports(now_s):
            try:
                frames.append(self.codec.encode(msg))
            except KitEncodeError:
                self._bad("report_unencodable")   # a value the DBC cannot carry: not sent
        return frames

    def reports(self, now_s: float) -> list[Any]:
        """The typed reports describing the kit now."""
        plant, systems = self.plant, self.systems
        accel, brk, steer, shift = (systems[s] for s in SYSTEMS)

        def status(st: SystemState, system: str) -> dict[str, bool]:
            return {"enabled": st.enabled, "override_active": st.override,
                    "output_reported_fault": st.fault or self._stuck(system, now_s)}

        def commanded(st: SystemState, attr: str) -> float:
            return float(getattr(st.command, attr)) if st.command is not None else 0.0

        gear_out = int(Gear.BETWEEN_GEARS) if plant.shift_target is not None \
            else self._gear_code(plant.gear)
        speed = plant.speed_mps
        wheel_radps = abs(plant.wheel_speed_mps) / TYRE_RADIUS_M
        usr_timeout = any(st.timed_out for st in systems.values()) or self.supervisory_timed_out
        fault = any(st.fault for st in systems.values())
        return [
            GlobalRpt(enabled=any(st.enabled for st in systems.values()),
                      override_active=any(st.override for st in systems.values()),
                      usr_can_timeout=usr_timeout, str_can_timeout=False, brk_can_timeout=False,
                      subsystem_timeout=False, veh_can_timeout=False, fault_active=fault,
                      config_fault_active=False,
                      usr_can_read_errors=min(sum(self.bad_frames.values()), 0xFFFF),
                      supervisory_enable_required=self.supervisory_enable_required),
            AccelRpt(**status(accel, "accel"),
                     manual_input=min(self._operator_input("accel", now_s), RATIO_MAX),
                     commanded_value=commanded(accel, "accel_ratio"),
                     output_value=min(plant.throttle, RATIO_MAX)),
            BrakeRpt(**status(brk, "brake"),
                     manual_input=min(self._operator_input("brake", now_s), RATIO_MAX),
                     commanded_value=commanded(brk, "brake_ratio"),
                     output_value=min(plant.brake, RATIO_MAX)),
            SteeringRpt(**status(steer, "steering"), manual_input=self.steering_wheel_now(),
                        commanded_value=commanded(steer, "position_rad"),
                        output_value=self.steering_wheel_now()),
            ShiftRpt(**status(shift, "shift"), manual_input=self._gear_code(plant.gear),
                     commanded_value=int(shift.command.gear) if shift.command is not None
                     else int(Gear.NONE), output_value=gear_out),
            VehicleSpeedRpt(speed_mps=speed, valid=True),
            WheelSpeedRpt(front_left_radps=wheel_radps, front_right_radps=wheel_radps,
                          rear_left_radps=wheel_radps, rear_right_radps=wheel_radps),
            YawRateRpt(yaw_rate_radps=-plant.speed_mps * plant.curvature_1pm),
        ]

    # ------------------------------------------------------------------ truth

    def truth(self, now_s: float) -> Truth:
        plant = self.plant
        return Truth(t_s=now_s, x_m=plant.x_m, y_m=plant.y_m, heading_rad=plant.heading_rad,
                     speed_mps=plant.speed_mps, odometer_m=plant.odometer_m,
                     road_wheel_rad=plant.road_wheel_rad,
                     steering_wheel_rad=self.steering_wheel_now(), gear=plant.gear,
                     throttle=plant.throttle, brake=plant.brake,
                     enabled=tuple(s for s, st in self.systems.items() if st.enabled))

    def summary(self, now_s: float) -> dict[str, Any]:
        """The kit's record: truth, frames seen, edges, timeouts, overrides, bad frames."""
        ev = self.events
        return {
            "dialect": self.dialect, "vehicle": self.params.preset,
            "dbc_version": self.codec.dbc_version, "dbc_sha256": self.codec.dbc_sha256,
            "truth": msgspec.to_builtins(self.truth(now_s)),
            "odometer_m": self.plant.odometer_m,
            "frames_seen": dict(sorted(self.frames_seen.items())),
            "bad_frames": dict(sorted(self.bad_frames.items())),
            "enable_edges": [{"system": s, "t_s": t, "brake_ratio": b}
                             for (s, t), b in zip(ev.enable_edges, ev.brake_at_edges,
                                                  strict=True)],
            "first_throttle_s": ev.first_throttle_s,
            "refused_edges": [{"system": s, "t_s": t, "why": w} for s, t, w in ev.refused_edges],
            "disables": [{"system": s, "t_s": t, "why": w} for s, t, w in ev.disables],
            "timeouts": [{"system": s, "t_s": t} for s, t in ev.timeouts],
            "overrides": [{"system": s, "t_s": t} for s, t in ev.overrides],
            "override_clears": [{"system": s, "t_s": t} for s, t in ev.override_clears],
            "faults": [{"system": s, "t_s": t} for s, t in ev.faults],
            "last_command_s": dict(sorted(self.last_frame_s.items())),
            "ignore_overrides_frames": self.ignore_overrides_frames,
            "stopped": abs(self.plant.speed_mps) < STOPPED_MPS,
        }


SCENARIO_DRIVER_BRAKE_RATIO: Final = 0.3
"""A scenario's manual override: the safety driver presses the brake to 30 % of its travel (a
firm, controlled stop, as ``sim_node.DRIVER_BRAKE_PCT``)."""
SCENARIO_DRIVER_TORQUE_NM: Final = 5.0
"""... and holds the wheel with 5 N.m (a firm grip, above ``STEERING_OVERRIDE_NM``)."""


__all__ = ["COMMAND_PERIOD_S", "COMMAND_TIMEOUT_S", "REPORT_PERIOD_S", "SYSTEMS", "KitFault",
           "Pacmod3Kit", "Truth", "accel_effort", "brake_effort"]
