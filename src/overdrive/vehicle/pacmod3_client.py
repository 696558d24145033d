"""The stack's side of a PACMod 3 drive-by-wire kit, standing where ``XgvClient`` stands. Sans-IO.

``Pacmod3Client`` turns the stack's actuator commands into PACMod 3 commands and the kit's
reports into the stack's sensor messages. It never touches a bus or a clock:
``receive(frame, read_s)`` takes a frame that arrived, ``sensor_outputs(now_s)`` gives the bus
messages to publish, ``command_frames(now_s)`` the frames to send now (every
``command_period_s``, 1/30 s: the PACMod user protocol's 30 Hz), and ``request_engage(now_s)``
is the operator's act (``overdrive.runtime.can_link`` does the I/O).

Commands (docs/pacmod3-stack.md):

- ACCEL_CMD ``accel_ratio`` = the speed server's throttle % / 100, BRAKE_CMD ``brake_ratio`` =
  brake % / 100 (through ``gate_pedals``: never both); the pedal-to-acceleration gains are the
  kit's, learnt by the adaptive loops (seed 004).
- STEERING_CMD: ``steer_pct`` (% of full lock, positive right, rate limited by ``gate_steer`` at
  the vehicle's ``steer_rate_rps``) -> road-wheel angle (``max_steer_rad``) -> steering-WHEEL
  angle through the vehicle file's ``steering_ratio`` (constant or variable), left positive;
  ROTATION_RATE the wheel rate that turns the road wheels at ``steer_rate_rps``.
- SHIFT_CMD: the speed server's gear, sent only at a standstill with the brake held (commanded
  and reported at ``ENGAGE_BRAKE_RATIO`` or more); otherwise the gear the kit reports is held
  and a ``shift_refused`` notice says why.
- ``enable`` per system from the engage workflow (``vehicle.pacmod3_engage``): the planner
  never engages. A stack whose pedal commands go stale (``PEDAL_STALE_S``) is braked to a stop
  while the kit stays engaged.

Reports: ``VehicleStatus`` (safety mode ``drive-by-wire`` engaged; ``manual-override`` for an
operator override, the kit's command timeout or a fault: the kit hands the vehicle back to its
driver, the interruption the driving module latches; ``software-pause`` while disengaged or
engaging), ``WheelSpeed`` and ``GpsIns`` (solution ``dead_reckoning``: position and heading
integrated from VEHICLE_SPEED_RPT and YAW_RATE_RPT, the odometer the speed integrated), ``Imu``
(acceleration differentiated from the speed, lateral from the yaw rate). A report silent for
more than ``REPORT_TIMEOUT_S`` (three report periods and a half) is a fault and the sensors stop,
so the speed server's sensor watchdog stops the stack, as the XGV client does. Frames that do
not decode (wrong length, unknown id, a bad complement) are counted and said once, never acted
on; a command frame from anyone else on the bus is counted and said once.
"""

from __future__ import annotations

import math
from typing import Any, Final, Literal

import msgspec

from overdrive.dynamics.control import first_order_lag
from overdrive.dynamics.steering_ratio import road_wheel_rad, steering_wheel_rad
from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.kits.frames import CanFrame, KitError, UnknownFrame
from overdrive.kits.pacmod3 import (
    STEERING_RATE_MAX_RADPS,
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
from overdrive.messages import (
    GpsIns,
    Imu,
    Notice,
    PedalCommand,
    PowertrainCommand,
    Topic,
    Truth,
    VehicleStatus,
    WheelSpeed,
)
from overdrive.safety.gate import GateLimits, gate_pedals, gate_steer
from overdrive.vehicle.kit_reports import ReportGuard
from overdrive.vehicle.modes import computer_axes
from overdrive.vehicle.pacmod3_engage import (
    DISABLE_FRAMES,
    ENGAGE_BRAKE_RATIO,
    ENGAGE_STANDSTILL_MPS,
    LATCHED,
    STANDSTILL_HOLD_S,
    STOP_BRAKE_RATIO,
    Conditions,
    classify_event,
    next_state,
    refusal,
    stop_bound_s,
)

COMMAND_PERIOD_S: Final = 1.0 / 30.0   # PACMod user CAN protocol: commands at 30 Hz
REPORT_PERIOD_S: Final = 1.0 / 30.0    # the kit's reports at 30 Hz (docs/pacmod3.md)
REPORT_TIMEOUT_S: Final = 3.5 * REPORT_PERIOD_S   # more than 3 report periods silent: a fault
                                       # (the half period: the 10 ms receive step's jitter)
EDGE_GRACE_S: Final = 3.5 * REPORT_PERIOD_S   # after an enable edge, override and timeout bits
                                       # still latched from before are the kit's old state:
                                       # counted only once it had this long to clear them
FOREIGN_HOLD_S: Final = REPORT_TIMEOUT_S   # another node's command frame read within this: a
                                       # fault while engaged, an engage refused
PEDAL_STALE_S: Final = 0.1             # pedal commands older than this (10 of the speed
                                       # server's periods): the stack is lost, brake to a stop
STALE_BRAKE_PCT: Final = 100.0         # as the XGV client's command-timeout brake
GEAR_STANDSTILL_MPS: Final = ENGAGE_STANDSTILL_MPS   # SHIFT_CMD only below this speed
SHIFT_BRAKE_OUTPUT_MIN: Final = 0.3    # and with the kit reporting the hold commanded and its
                                       # brake output at least this (the pedal is down; a kit's
                                       # pedal map shapes the output, 0.496 for 0.6 measured on
                                       # the emulated kit)
RATIO_STEP: Final = 0.001              # the pedal ratios' resolution on the wire (DBC)
BRING_UP_ACCEL_RATIO_MAX: Final = 0.2  # bring-up caps (docs/drive-your-own-vehicle.md):
BRING_UP_STEERING_RATE_RADPS: Final = 0.5   # a fifth of the pedal, a slow wheel, walking pace
BRING_UP_SPEED_MPS: Final = 2.0        # above this in bring-up: throttle 0 and the brake held
BringUp = Literal["throttle", "brake", "steering"]
SYSTEMS: Final = ("brake", "accel", "steering", "shift")
WORKFLOW_SYSTEMS: Final[dict[str | None, tuple[str, ...]]] = {
    None: SYSTEMS,
    "brake": ("brake",),
    "throttle": ("brake", "accel", "shift"),
    "steering": ("brake", "steering"),
}
"""The systems each mode enables (bring-up keeps the brake for stopping); brake first. The
throttle's takes the gear too (shifted, as always, only at a standstill with the brake held):
without it a kit in park never moves (red team, 2026-11-26)."""

_REPORTS: Final[dict[type, str]] = {AccelRpt: "accel", BrakeRpt: "brake", SteeringRpt: "steering",
                                    ShiftRpt: "shift"}
_REQUIRED: Final = ("global", "accel", "brake", "steering", "shift", "speed", "yaw")
"""Reports that must keep coming (``REPORT_TIMEOUT_S``); the wheel speeds are not used."""
_GUARDED_REPORTS: Final = (GlobalRpt, *_REPORTS, VehicleSpeedRpt, YawRateRpt, WheelSpeedRpt)
"""The kit's reports, checked for a second sender (``vehicle.kit_reports``)."""


class Pacmod3ClientConfig(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """Rates and modes of the client."""

    dialect: Dialect = "v3"
    command_period_s: float = COMMAND_PERIOD_S
    report_timeout_s: float = REPORT_TIMEOUT_S
    bring_up: BringUp | None = None
    publish_truth: bool = False           # overdrive drive: the run's trace from the reports
    accel_filter_s: float = 0.05          # on the differentiated speed
    limits: GateLimits | None = None      # who may command (default: VehicleSim's sources)

    def __post_init__(self) -> None:
        for name in ("command_period_s", "report_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"Pacmod3ClientConfig.{name}: a finite number above 0, got "
                                 f"{value!r}")
        if self.command_period_s * 3 > 0.1 + 1e-9:
            raise ValueError("Pacmod3ClientConfig.command_period_s: three periods must fit the "
                             "kit's 100 ms command timeout")
        if not (math.isfinite(self.accel_filter_s) and self.accel_filter_s >= 0.0):
            raise ValueError("Pacmod3ClientConfig.accel_filter_s: finite, 0 or more")
        if self.bring_up not in WORKFLOW_SYSTEMS:
            raise ValueError(f"Pacmod3ClientConfig.bring_up: one of throttle, brake, steering, "
                             f"got {self.bring_up!r}")


class Pacmod3Stats(msgspec.Struct, kw_only=True):
    """Counts for ``summary.json`` ``can``."""

    frames_in: int = 0
    frames_out: int = 0
    malformed: int = 0
    unknown: int = 0
    foreign_commands: int = 0
    report_conflicts: int = 0   # reports refused as a second sender's (rate, impossible speed)
    rejected_commands: int = 0
    shifts_refused: int = 0
    engage_refused: int = 0


def gear_names(params: VehicleParams) -> dict[str, Gear]:
    """The vehicle's gear names -> SHIFT_CMD values, by role: park, reverse, drive (FORWARD),
    low (LOW, when it is not the drive gear); any other gear that does not drive is NEUTRAL."""
    table = {g.name: Gear.NEUTRAL for g in params.gears if g.direction == 0}
    table[params.park_gear] = Gear.PARK
    table[params.reverse_gear] = Gear.REVERSE
    if params.low_gear != params.drive_gear:
        table[params.low_gear] = Gear.LOW
    table[params.drive_gear] = Gear.FORWARD
    return table


class Pacmod3Client:
    """PACMod 3 client logic (see the module docstring)."""

    def __init__(self, params: VehicleParams, config: Pacmod3ClientConfig | None = None,
                 codec: Pacmod3Codec | None = None, name: str = "pacmod3-client") -> None:
        if params.steering_ratio is None:
            raise ValueError(f"vehicle {params.preset}: no steering_ratio; a PACMod 3 commands "
                             f"the steering wheel's angle, so the vehicle file must state it")
        self.params = params
        self.config = cfg = config or Pacmod3ClientConfig()
        self.codec = codec or Pacmod3Codec(cfg.dialect)
        self.name = name
        self.limits = cfg.limits or GateLimits(
            steer_rate_pct_per_s=100.0 * params.steer_rate_rps / params.max_steer_rad)
        self.gear_of = gear_names(params)
        self.name_of = {Gear.PARK: params.park_gear, Gear.REVERSE: params.reverse_gear,
                        Gear.FORWARD: params.drive_gear, Gear.LOW: params.low_gear}
        neutral = [g for g, v in self.gear_of.items() if v == Gear.NEUTRAL]
        if neutral:
            self.name_of[Gear.NEUTRAL] = neutral[0]
        self.systems = WORKFLOW_SYSTEMS[cfg.bring_up]
        ratio = params.steering_ratio
        max_ratio = ratio if isinstance(ratio, float) else max(r for _, r in ratio)
        self.wheel_rate_radps = min(params.steer_rate_rps * max_ratio, STEERING_RATE_MAX_RADPS)
        if cfg.bring_up is not None:
            self.wheel_rate_radps = min(self.wheel_rate_radps, BRING_UP_STEERING_RATE_RADPS)
        self.stats = Pacmod3Stats()
        self.report_guard = ReportGuard(REPORT_PERIOD_S)
        self.notices: list[Notice] = []
        self._told: set[str] = set()
        self._command_ids = frozenset(self.codec.frame_id(c) for c in (
            AccelCmd, BrakeCmd, SteeringCmd, ShiftCmd))
        # engage workflow
        self.state = "disengaged"
        self.state_s = 0.0
        self.engage_pending = False
        self.disable_frames = 0        # enable=0 frames sent since engaging began
        self.edge_s: dict[str, float] = {}   # when each system's enable edge went out
        self.transitions: list[tuple[float, str, str, str]] = []   # (t, from, event, to)
        self.counter = 0               # v14 GLOBAL_CMD / SUPERVISORY_CTRL
        self.next_send_s = -math.inf
        self.last_send_s: float | None = None
        # stack inputs
        self.pedals = PedalCommand(throttle_pct=0.0, brake_pct=100.0, source=name)
        self.pedals_s: float | None = None   # when the last pedal command was taken
        self.steer_cmd_pct = 0.0
        self.steer_sent_pct: float | None = None   # rate limiter's memory (None: not yet)
        self.powertrain: PowertrainCommand | None = None
        self.shift_refusal: str | None = None
        self.rejecting: dict[str, str] = {}   # code -> the reason last said (said once)
        # reports
        self.seen_s: dict[str, float] = {}   # report -> when last read
        self.global_rpt: GlobalRpt | None = None
        self.system_rpt: dict[str, Any] = {}
        self.rpt_s: dict[str, float] = {}
        self.speed_mps = 0.0
        self.speed_s: float | None = None
        self.yaw_radps = 0.0
        self.accel_mps2 = 0.0
        self.x_m = self.y_m = self.heading_rad = 0.0
        self.odometer_m = 0.0
        self.fresh = False
        self.silent: str | None = None       # the report silent now (no sensors meanwhile)
        self.silence_seen: str | None = None   # a silence seen, until an engage clears it
        self.bus_errors: list[str] = []
        self.foreign_s = -math.inf           # when another node's command frame was last read
        self.standstill_s: float | None = None   # reported below standstill since (None: moving)
        self.stop_deadline_s = math.inf      # stopping: disable by then whatever the reports say
        self.ending = False                  # the drive is ending (``end_drive``)
        self.stop_cause = ""                 # the event that entered stopping

    # ------------------------------------------------------------------ wire in

    def receive(self, frame: CanFrame, read_s: float) -> None:
        """Take one frame read at ``read_s``; garbage is counted, never acted on."""
        self.stats.frames_in += 1
        if frame.arbitration_id in self._command_ids and not frame.is_extended:
            self._foreign(read_s, f"a PACMod command frame {frame} from another node on the "
                                  f"bus: a second controller?")
            return
        try:
            msg = self.codec.decode(frame)
        except UnknownFrame:
            self.stats.unknown += 1
            return   # other ECUs share a vehicle bus: counted, not a fault
        except KitError as e:
            self.stats.malformed += 1
            self._notice("malformed", f"PACMod frame refused: {e}")
            return
        if isinstance(msg, _GUARDED_REPORTS) and not self._plausible(frame, msg, read_s):
            return
        if isinstance(msg, GlobalRpt):
            self.global_rpt = msg
            self.seen_s["global"] = read_s
        elif type(msg) in _REPORTS:
            system = _REPORTS[type(msg)]
            self.system_rpt[system] = msg
            self.rpt_s[system] = read_s
            self.seen_s[system] = read_s
        elif isinstance(msg, VehicleSpeedRpt):
            if msg.valid and math.isfinite(msg.speed_mps):
                self._speed(msg.speed_mps, read_s)
        elif isinstance(msg, YawRateRpt):
            if math.isfinite(msg.yaw_rate_radps):
                self.yaw_radps = msg.yaw_rate_radps
                self.seen_s["yaw"] = read_s
        elif isinstance(msg, WheelSpeedRpt):
            pass   # the vehicle speed report is used (the tyre radius is not in the vehicle file)
        else:   # a command type decoded from an id not ours (v14 global/supervisory)
            self._foreign(read_s, f"{type(msg).__name__} from another node")

    def _plausible(self, frame: CanFrame, msg: Any, read_s: float) -> bool:
        """A report from the kit, as far as its rate and physics tell (``kit_reports``): a
        second sender's is refused, counted, and a fault the client detects (it brakes)."""
        guard = self.report_guard
        ok = guard.arrived(frame.arbitration_id, read_s)
        if ok and isinstance(msg, VehicleSpeedRpt) and msg.valid and math.isfinite(msg.speed_mps):
            ok = guard.speed_plausible(msg.speed_mps, read_s)
        if not ok:
            self.stats.report_conflicts += 1
            self._notice("report_conflict", guard.conflict or "report refused")
        return ok

    def _foreign(self, read_s: float, reason: str) -> None:
        """Another node commands the kit: a fault while it is seen (``FOREIGN_HOLD_S``)."""
        self.stats.foreign_commands += 1
        self.foreign_s = max(self.foreign_s, read_s)
        self._notice("foreign_command", reason)

    def _speed(self, v: float, read_s: float) -> None:
        """Dead reckoning: position, heading and odometer integrated between speed reports,
        over the reports' own read times (a gap longer than the report timeout is not
        integrated: the sensors stop then)."""
        if self.speed_s is not None:
            dt = read_s - self.speed_s
            if 0.0 < dt <= self.config.report_timeout_s:
                mean = 0.5 * (v + self.speed_mps)
                heading_mid = self.heading_rad + 0.5 * self.yaw_radps * dt
                self.x_m += mean * math.cos(heading_mid) * dt
                self.y_m += mean * math.sin(heading_mid) * dt
                self.heading_rad = math.remainder(self.heading_rad + self.yaw_radps * dt, math.tau)
                self.odometer_m += abs(mean) * dt
                self.accel_mps2 = first_order_lag((v - self.speed_mps) / dt, self.accel_mps2,
                                                  self.config.accel_filter_s, dt)
        self.speed_mps, self.speed_s = v, read_s
        if abs(v) >= ENGAGE_STANDSTILL_MPS:
            self.standstill_s = None
        elif self.standstill_s is None:
            self.standstill_s = read_s
        self.seen_s["speed"] = read_s
        self.fresh = True

    def bus_error(self, text: str) -> None:
        """A bus error the edge reported (bus-off, no acknowledgement, a full buffer): a fault."""
        self.bus_errors.append(text)

    # ------------------------------------------------------------------ engage workflow

    def _all_enabled(self, now_s: float) -> bool:
        return all(getattr(self.system_rpt.get(s), "enabled", False)
                   and self.rpt_s.get(s, -math.inf) > self.edge_s.get(s, math.inf)
                   for s in self.systems)

    def _after_grace(self, system: str, now_s: float) -> bool:
        """An override/timeout bit on ``system`` counts (engaging: only once the kit had
        ``EDGE_GRACE_S`` after the system's edge to clear what it latched before)."""
        if self.state != "engaging":
            return True
        edge = self.edge_s.get(system)
        return edge is not None and now_s - edge > EDGE_GRACE_S

    def _conditions(self, now_s: float) -> Conditions:
        g = self.global_rpt
        client_reason = self._client_fault_reason(now_s)
        kit_reason = self._kit_fault_reason(now_s)
        override = any(getattr(self.system_rpt.get(s), "override_active", False)
                       and self._after_grace(s, now_s) for s in self.systems)
        every = all(self._after_grace(s, now_s) for s in self.systems)   # GLOBAL_RPT's bits:
        if g is not None and g.override_active and every:   # once every edge had its grace
            override = True
        kit_timeout = bool(g is not None and g.usr_can_timeout and every)
        return Conditions(
            engage_request=self.engage_pending, fault=kit_reason is not None,
            client_fault=client_reason is not None, stopped=self._stopped(now_s),
            drive_end=self.ending and (self.state != "stopping" or self.stop_cause == "drive_end"),
            override=override, kit_timeout=kit_timeout, all_enabled=self._all_enabled(now_s),
            engage_elapsed_s=now_s - self.state_s, speed_mps=self.speed_mps,
            reports_fresh=self._silent(now_s) is None and self._heard())

    def _stopped(self, now_s: float) -> bool:
        """Stopping is over: the kit reports a standstill held ``STANDSTILL_HOLD_S`` (reports
        fresh), or the stop's time bound ran out."""
        if self.state != "stopping":
            return False
        if now_s >= self.stop_deadline_s:
            return True
        return (self.standstill_s is not None and self._silent(now_s) is None
                and now_s - self.standstill_s >= STANDSTILL_HOLD_S)

    def end_drive(self, now_s: float) -> None:
        """The drive ends (duration over, Ctrl-C, SIGTERM): engaged, the next frames brake to a
        standstill (``stopping``) before the kit is let go; otherwise nothing to wait for."""
        self.ending = True

    @property
    def releasing(self) -> bool:
        """Still braking to a stop: the kit must not be let go yet."""
        return self.state == "stopping" or (self.ending and self.state == "engaged")

    def _heard(self) -> bool:
        return all(k in self.seen_s for k in _REQUIRED)

    @property
    def heard(self) -> bool:
        """Every required report arrived at least once: the kit is there."""
        return self._heard()

    def _silent(self, now_s: float) -> str | None:
        """The first required report silent too long (once every one was heard)."""
        if not self._heard():
            return None
        for key in _REQUIRED:
            if now_s - self.seen_s[key] > self.config.report_timeout_s:
                return key
        return None

    def _fault_reason(self, now_s: float, *, kit_faults: bool = True) -> str | None:
        """Why the kit cannot be driven now (None: no fault): the client's reason first."""
        return self._client_fault_reason(now_s) or self._kit_fault_reason(now_s,
                                                                          kit_faults=kit_faults)

    def _client_fault_reason(self, now_s: float) -> str | None:
        """A fault the CLIENT detects (the kit may still drive: engaged, it brakes to a stop):
        a report silent, a bus error, another node's command frames, a gear ERROR report."""
        silent = self._silent(now_s) or self.silence_seen
        if silent is not None:
            self.silence_seen = silent   # seen between two frames: kept for the workflow
            return f"{silent} report silent for more than {self.config.report_timeout_s:.3f} s"
        if self.bus_errors:
            return f"CAN bus error: {self.bus_errors[-1]}"
        if now_s - self.foreign_s <= FOREIGN_HOLD_S:
            return "command frames from another node on the bus (a second controller?)"
        if self.report_guard.conflict is not None:
            return f"reports from a second sender: {self.report_guard.conflict}"
        shift = self.system_rpt.get("shift")
        if shift is not None and shift.output_value == Gear.ERROR:
            return "shift report: gear ERROR"
        if self._brake_answers():
            # a fault on another system while the brake still answers: stop with the brake
            # (disabling at speed would coast; a stuck steering rolled 46 m, red team 2026-11-26)
            g = self.global_rpt
            if g is not None and g.fault_active:
                return "GLOBAL_RPT: fault active (braking to a stop with the brake)"
            for s in self.systems:
                r = self.system_rpt.get(s)
                if s != "brake" and r is not None and (r.faulted or (
                        not r.enabled and not r.override_active)):
                    why = "claims a fault" if r.faulted else "was disabled by the kit"
                    return f"{s} report {why} (braking to a stop with the brake)"
        return None

    def _brake_answers(self) -> bool:
        """Engaged (or stopping) with the kit's brake enabled and not faulted: whatever else
        failed, the client can still stop the vehicle itself."""
        brake = self.system_rpt.get("brake")
        return (self.state in ("engaged", "stopping") and brake is not None and brake.enabled
                and not brake.faulted and not brake.override_active)

    def _kit_fault_reason(self, now_s: float, *, kit_faults: bool = True) -> str | None:
        """A fault the KIT reports (it has let go of the vehicle). Its own fault bits
        (clearable with ``clear_faults``) count unless ``kit_faults`` is False (the operator's
        engage, whose sequence sends ``clear_faults``), and while engaging only once the edges
        had their grace (a fault that stays after the clear is a fault again)."""
        g = self.global_rpt
        if g is not None and g.config_fault_active:
            return "GLOBAL_RPT: config fault (the kit's configuration: not cleared by commands)"
        every = all(self._after_grace(s, now_s) for s in self.systems)
        brake_answers = self._brake_answers()   # then another system's loss is the client's
        # while the brake answers, GLOBAL_RPT's fault bit is the client's to stop on (it may
        # arrive a report before the system's own fault bit in the same period)
        if (kit_faults and g is not None and g.fault_active and every
                and not brake_answers):
            return "GLOBAL_RPT: fault active"
        for s in self.systems:
            r = self.system_rpt.get(s)
            if (kit_faults and r is not None and r.faulted and self._after_grace(s, now_s)
                    and not (brake_answers and s != "brake")):
                return f"{s} report claims a fault"
        if self.state in ("engaged", "stopping") and not (g is not None and g.usr_can_timeout):
            for s in (["brake"] if brake_answers else self.systems):
                r = self.system_rpt.get(s)
                if r is not None and not r.enabled and not r.override_active:
                    return f"the kit disabled {s} while engaged"
        return None

    def request_engage(self, now_s: float) -> str | None:
        """The operator's act: engage (or re-engage after an override, a timeout or a fault).
        Returns why it is refused (None: the engage sequence starts at the next frame). A
        silence or bus error that is over is the operator's to acknowledge here."""
        if self._silent(now_s) is None:
            self.silence_seen = None
        self.bus_errors.clear()
        self.report_guard.clear()
        c = self._conditions(now_s)
        c = msgspec.structs.replace(c, fault=self._kit_fault_reason(now_s, kit_faults=False)
                                    is not None)
        why = refusal(self.state, c)
        detail = self._fault_reason(now_s, kit_faults=False)
        if why is not None and (c.fault or c.client_fault) and detail is not None:
            why = f"{why}: {detail}"
        if why is not None:
            self.stats.engage_refused += 1
            self.notices.append(Notice(kind="rejected", source=self.name, code="engage_refused",
                                       reason=why))
            return why
        self.engage_pending = True
        return None

    def _step_workflow(self, now_s: float) -> None:
        c = self._conditions(now_s)
        if self.engage_pending:   # the operator's engage clears the kit's own fault bits
            c = msgspec.structs.replace(c, fault=self._kit_fault_reason(now_s, kit_faults=False)
                                        is not None)
        event = classify_event(self.state, c)
        self.engage_pending = False
        if event is None:
            return
        before = self.state
        self.state = next_state(before, event)
        if self.state == before:
            return
        self.state_s = now_s
        self.transitions.append((now_s, before, event, self.state))
        if self.state == "engaging":
            self.disable_frames = 0
            self.edge_s.clear()
            self.bus_errors.clear()
            self.silence_seen = None
            self._told.discard("state")
        if self.state == "stopping":
            self.stop_deadline_s = now_s + stop_bound_s(self.speed_mps)
            self.stop_cause = event
        reason = {"override": "operator override: the kit hands the vehicle to its driver",
                  "kit_timeout": "the kit timed out our commands (usr_can_timeout)",
                  "fault": self._fault_reason(now_s) or "fault",
                  "client_fault": f"{self._client_fault_reason(now_s) or 'fault'}: braking to "
                                  f"a standstill engaged, then letting go",
                  "drive_end": "the drive ends: braking to a standstill engaged, then letting go",
                  "stopped": "stopped (or the stop's time bound ran out): letting go",
                  "released": "the drive ended stopped: the kit let go",
                  "engage_timeout": "the kit did not enable every system in time"}.get(event)
        kind = "engage"
        if self.state == "overridden":
            kind = "interruption"
        elif self.state in ("faulted", "timed_out", "stopping") and not self.ending:
            kind = "fault"
        self.notices.append(Notice(kind=kind, source=self.name, code=f"pacmod3_{self.state}",
                                   reason=reason or f"{before} -> {self.state} ({event})"))

    # ------------------------------------------------------------------ stack side

    def take_inputs(self, inbox: Any, now_s: float) -> list[tuple[str, Any]]:
        """The stack's commands; those from sources without control are rejected."""
        lim = self.limits
        out: list[tuple[str, Any]] = []
        for topic, msg in inbox:
            if topic == Topic.PEDALS and isinstance(msg, PedalCommand):
                if self._allowed(msg, lim.pedal_sources, out):
                    self.pedals, self.pedals_s = msg, now_s
                    _, _, why = gate_pedals(msg.throttle_pct, msg.brake_pct)
                    if why and why != "throttle while braking":   # that one is the rule
                        self._reject("pedals_gated", f"pedal command {why}: gated (a NaN "
                                                     f"throttle 0, brake 100; clamped)", out)
                    else:
                        self.rejecting.pop("pedals_gated", None)
            elif topic == Topic.STEER:
                if not self._allowed(msg, lim.steer_sources, out):
                    continue
                if math.isfinite(msg.steer_pct):
                    self.steer_cmd_pct = min(max(msg.steer_pct, -100.0), 100.0)
                    self.rejecting.pop("steer_not_finite", None)
                else:
                    self._reject("steer_not_finite", f"steer_pct {msg.steer_pct!r}: the last "
                                                     f"command held", out)
            elif (topic == Topic.POWERTRAIN and isinstance(msg, PowertrainCommand)
                  and self._allowed(msg, lim.powertrain_sources, out)):
                if msg.gear in self.gear_of:
                    self.powertrain = msg
                    self.rejecting.pop("unknown_gear", None)
                else:
                    self._reject("unknown_gear", f"gear {msg.gear!r}: not a gear of "
                                                 f"{self.params.preset}; the last request held",
                                 out)
        return out

    def _reject(self, code: str, reason: str, out: list | None = None) -> None:
        """A command the client refused (in part): counted every time; a rejection notice when
        the reason changes (a stream of the same bad command is said once)."""
        self.stats.rejected_commands += 1
        if self.rejecting.get(code) == reason:
            return
        self.rejecting[code] = reason
        notice = Notice(kind="rejected", source=self.name, code=code, reason=reason)
        if out is None:
            self.notices.append(notice)
        else:
            out.append((Topic.NOTICE, notice))

    def _allowed(self, msg: Any, sources: frozenset[str], out: list) -> bool:
        if getattr(msg, "source", None) in sources:
            return True
        self.stats.rejected_commands += 1
        out.append((Topic.NOTICE, Notice(kind="rejected", source=self.name, code="no_control",
                                         reason=f"{type(msg).__name__} from "
                                                f"{getattr(msg, 'source', None)!r}")))
        return False

    # ------------------------------------------------------------------ wire out

    def command_frames(self, now_s: float) -> list[CanFrame]:
        """The frames to send now: every ``command_period_s`` one command per system (and the
        v14 global/supervisory frames), the engage workflow stepped first."""
        if now_s < self.next_send_s - 1e-9:
            return []
        period = self.config.command_period_s
        self.next_send_s = max(self.next_send_s + period, now_s + 0.5 * period) \
            if math.isfinite(self.next_send_s) else now_s + period
        dt = period if self.last_send_s is None else max(now_s - self.last_send_s, 0.0)
        self.last_send_s = now_s
        self._step_workflow(now_s)
        messages = self._commands(now_s, dt)
        frames = []
        for m in messages:
            try:
                frames.append(self.codec.encode(m))
            except KitError as e:   # cannot happen with the values built below; never crash
                self._notice("encode", f"a command could not be encoded: {e}")
                return []
        self.stats.frames_out += len(frames)
        return frames

    def release_frames(self) -> list[CanFrame]:
        """One frame per system with ``enable=0`` (the drive ending hands the kit back; the
        workflow's state is left as it is)."""
        gear = self._gear(ENGAGE_BRAKE_RATIO)
        messages = [BrakeCmd(enable=False, brake_ratio=ENGAGE_BRAKE_RATIO),
                    AccelCmd(enable=False, accel_ratio=0.0),
                    SteeringCmd(enable=False, position_rad=0.0,
                                rotation_rate_radps=self.wheel_rate_radps),
                    ShiftCmd(enable=False, gear=gear)]
        return [self.codec.encode(m) for m in messages]

    def _enable(self, now_s: float) -> dict[str, bool]:
        """``enable`` per system for this frame, recording each system's edge."""
        enable = dict.fromkeys(SYSTEMS, False)
        if self.state in ("engaged", "stopping"):
            for s in self.systems:
                enable[s] = True
        elif self.state == "engaging":
            if self.disable_frames < DISABLE_FRAMES:
                self.disable_frames += 1
                return enable
            brake_on = (getattr(self.system_rpt.get("brake"), "enabled", False)
                        and self.rpt_s.get("brake", -math.inf) > self.edge_s.get("brake", math.inf))
            for s in self.systems:
                if s == "brake" or brake_on:
                    enable[s] = True
                    self.edge_s.setdefault(s, now_s)
        return enable

    def _commands(self, now_s: float, dt: float) -> list[Any]:
        cfg = self.config
        enable = self._enable(now_s)
        engaged = self.state == "engaged"
        clear = self.state == "engaging"
        throttle_pct, brake_pct, _ = gate_pedals(self.pedals.throttle_pct, self.pedals.brake_pct)
        if self.pedals_s is None or now_s - self.pedals_s > PEDAL_STALE_S:
            throttle_pct, brake_pct = 0.0, STALE_BRAKE_PCT   # a lost stack: brake, engaged
            if engaged:
                self._notice("stack_stale", f"no pedal command for more than {PEDAL_STALE_S} s: "
                                            f"braking to a stop, still engaged")
        accel = throttle_pct / 100.0
        brake = brake_pct / 100.0
        if not engaged:
            accel, brake = 0.0, max(brake, ENGAGE_BRAKE_RATIO)
        if self.state == "stopping":   # the client's own stop: full brake, still enabled
            accel, brake = 0.0, STOP_BRAKE_RATIO
        if cfg.bring_up is not None:
            accel = min(accel, BRING_UP_ACCEL_RATIO_MAX)
            if abs(self.speed_mps) > BRING_UP_SPEED_MPS:
                accel, brake = 0.0, max(brake, ENGAGE_BRAKE_RATIO)
        steer = self._steering(now_s, dt, engaged)
        gear = self._gear(brake)
        v3_clear = clear and cfg.dialect == "v3"   # v14 clears faults in GLOBAL_CMD
        out: list[Any] = [
            BrakeCmd(enable=enable["brake"], clear_override=clear, clear_faults=v3_clear,
                     brake_ratio=brake),
            AccelCmd(enable=enable["accel"], clear_override=clear, clear_faults=v3_clear,
                     accel_ratio=accel),
            SteeringCmd(enable=enable["steering"], clear_override=clear, clear_faults=v3_clear,
                        position_rad=steer, rotation_rate_radps=self.wheel_rate_radps),
            ShiftCmd(enable=enable["shift"], clear_override=clear, clear_faults=v3_clear,
                     gear=gear),
        ]
        if cfg.dialect == "v14":
            on = self.state in ("engaging", "engaged", "stopping")   # v14: 0 disables all
            out.insert(0, GlobalCmd(counter=self.counter, clear_overrides=clear,
                                    clear_faults=clear))
            out.insert(1, SupervisoryCtrl(counter=self.counter, enable=on))
            self.counter = (self.counter + 1) % 16
        return out

    def _steering(self, now_s: float, dt: float, engaged: bool) -> float:
        """STEERING_CMD position (steering-wheel angle, left positive): the stack's steer %
        rate limited from the last position sent; not engaged, the measured position held."""
        p = self.params
        measured = self.system_rpt.get("steering")
        measured_pct = (self._pct_of_wheel(measured.output_value)
                        if measured is not None and math.isfinite(measured.output_value) else 0.0)
        holding = self.state == "stopping" and self.steer_sent_pct is not None
        if not holding and (not engaged or self.steer_sent_pct is None):
            self.steer_sent_pct = measured_pct   # stopping: the last position sent is held
        if engaged:
            self.steer_sent_pct, _ = gate_steer(self.steer_cmd_pct, self.steer_sent_pct,
                                                self.limits, dt)
        road_left = -self.steer_sent_pct / 100.0 * p.max_steer_rad
        return steering_wheel_rad(p.steering_ratio, road_left)

    def _pct_of_wheel(self, wheel_rad: float) -> float:
        """A steering-wheel angle (left positive) as the stack's % of lock (right positive)."""
        p = self.params
        pct = -road_wheel_rad(p.steering_ratio, wheel_rad) / p.max_steer_rad * 100.0
        return min(max(pct, -100.0), 100.0)

    def _gear(self, brake_ratio: float) -> Gear:
        """The gear to command: the stack's, only at a standstill with the brake held; else
        the gear the kit reports (a refusal said once per request)."""
        shift = self.system_rpt.get("shift")
        current = Gear.NONE
        if shift is not None and shift.output_value in (0, 1, 2, 3, 4):
            current = Gear(shift.output_value)
        pt = self.powertrain
        if pt is None or self.state == "stopping":
            return current
        if pt.gear not in self.gear_of:   # refused in take_inputs; never stored
            return current
        wanted = self.gear_of[pt.gear]
        if wanted == current:
            self.shift_refusal = None
            return current
        brake_rpt = self.system_rpt.get("brake")
        held = (brake_ratio >= ENGAGE_BRAKE_RATIO and brake_rpt is not None
                and brake_rpt.commanded_value >= ENGAGE_BRAKE_RATIO - RATIO_STEP
                and brake_rpt.output_value >= SHIFT_BRAKE_OUTPUT_MIN)
        why = None
        if not abs(self.speed_mps) <= GEAR_STANDSTILL_MPS:
            why = f"moving at {self.speed_mps:.2f} m/s"
        elif not held:
            why = f"brake not held at {ENGAGE_BRAKE_RATIO:.0%} or more"
        if why is None:
            self.shift_refusal = None
            return wanted
        if why != self.shift_refusal and self.state == "engaged":   # disabled: SHIFT idle
            self.shift_refusal = why
            self.stats.shifts_refused += 1
            self.notices.append(Notice(kind="rejected", source=self.name, code="shift_refused",
                                       reason=f"{pt.gear}: {why}; holding {current.name}"))
        return current

    # ------------------------------------------------------------------ sensors

    def safety_mode(self) -> str:
        if self.state == "engaged":
            return "drive-by-wire"
        if self.state in LATCHED:
            return "manual-override"
        return "software-pause"

    def vehicle_status(self) -> VehicleStatus:
        mode = self.safety_mode()
        computer_steering, computer_speed = computer_axes(mode, "full")
        shift = self.system_rpt.get("shift")
        reported = shift.output_value if shift is not None else None
        gear = self.name_of.get(Gear(reported)) if reported in (0, 1, 2, 3, 4) else None
        wanted = self.powertrain.gear if self.powertrain is not None else None
        shifting = reported == Gear.BETWEEN_GEARS or (wanted is not None and gear is not None
                                                      and wanted != gear
                                                      and self.shift_refusal is None)
        accel = self.system_rpt.get("accel")
        brake = self.system_rpt.get("brake")
        steering = self.system_rpt.get("steering")

        def pct(r: Any) -> float:
            v = r.output_value * 100.0 if r is not None else 0.0
            return min(max(v, 0.0), 100.0) if math.isfinite(v) else 0.0

        return VehicleStatus(
            gear=gear or self.params.park_gear, shifting=shifting, engine="running",
            engine_rpm=self.params.idle_rpm, start_failed=False, traction_control=False,
            steer_pct=(self._pct_of_wheel(steering.output_value)
                       if steering is not None and math.isfinite(steering.output_value) else 0.0),
            throttle_pct=pct(accel), brake_pct=pct(brake), safety_mode=mode,
            computer_speed=computer_speed, computer_steering=computer_steering)

    def sensor_outputs(self, now_s: float) -> list[tuple[str, Any]]:
        """Bus messages for what arrived since the last call (nothing once a report is silent)."""
        silent = self._silent(now_s)
        if silent is not None and self.silent is None:
            self.silent = self.silence_seen = silent
            self._notice("silent", f"PACMod {silent} report silent for more than "
                                   f"{self.config.report_timeout_s:.3f} s: no more sensors")
        elif silent is None:
            self.silent = None
            self._told.discard("silent")
        out: list[tuple[str, Any]] = [(Topic.NOTICE, n) for n in self.notices]
        self.notices.clear()
        fresh, self.fresh = self.fresh, False
        if not fresh or silent is not None or not self._heard():
            return out
        out.append((Topic.VEHICLE_STATUS, self.vehicle_status()))
        v, yaw = self.speed_mps, self.yaw_radps
        out.append((Topic.WHEEL_SPEED, WheelSpeed(speed_mps=v)))
        out.append((Topic.GPS_INS, GpsIns(
            x_m=self.x_m, y_m=self.y_m, heading_rad=self.heading_rad, speed_mps=v,
            pitch_rad=0.0, roll_rad=0.0, odometer_m=self.odometer_m,
            solution="dead_reckoning")))
        out.append((Topic.IMU, Imu(accel_x_mps2=self.accel_mps2, accel_y_mps2=v * yaw,
                                   accel_z_mps2=G_MPS2, yaw_rate_rps=yaw)))
        if self.config.publish_truth:
            curvature = -yaw / v if abs(v) >= 0.1 else 0.0
            out.append((Topic.TRUTH, Truth(
                x_m=self.x_m, y_m=self.y_m, heading_rad=self.heading_rad, speed_mps=v,
                accel_mps2=self.accel_mps2, lat_accel_mps2=-v * yaw, curvature_1pm=curvature,
                pitch_rad=0.0, roll_rad=0.0, odometer_m=self.odometer_m, slip=False,
                contact=False)))
        return out

    def _notice(self, key: str, reason: str) -> None:
        if key not in self._told:
            self._told.add(key)
            self.notices.append(Notice(kind="fault", source=self.name, code=f"pacmod3_{key}",
                                       reason=reason))

    def report(self) -> dict[str, Any]:
        """``summary.json`` ``can``: counts, the engage state and its transitions."""
        return {"stats": msgspec.to_builtins(self.stats), "engage_state": self.state,
                "transitions": [{"t_s": round(t, 3), "from": a, "event": e, "to": b}
                                for t, a, e, b in self.transitions]}


__all__ = ["BRING_UP_ACCEL_RATIO_MAX", "BRING_UP_SPEED_MPS", "BRING_UP_STEERING_RATE_RADPS",
           "COMMAND_PERIOD_S", "PEDAL_STALE_S", "REPORT_TIMEOUT_S", "WORKFLOW_SYSTEMS",
           "Pacmod3Client", "Pacmod3ClientConfig", "Pacmod3Stats", "gear_names"]
