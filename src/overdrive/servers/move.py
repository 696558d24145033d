"""The move server (seed 004): the only thing the planner talks to.

It accepts MOVE / REVERSE / STOP (``MoveCommand``), answers every one (``MoveReply``: accepted,
or rejected with ``invalid`` / ``infeasible`` / ``not_ready`` / ``busy``, see
``move_feasibility``), and executes the accepted ones through the driving module (seed 003),
never the speed server directly:

- ``DriveMode``: the speed-server state to reach (``run`` to move; the driving module
  sequences parked -> paused -> idle -> run and the gear changes), the direction, and a
  nonzero fault for an emergency stop;
- ``AdvanceAuthorization`` (source ``move``): the distance left of the command, from where the
  vehicle is now, every period; 0 to stop;
- ``MaxSpeed`` (source ``move``): the command's maximum speed after the speed reductions
  (``move_conditions``) and the adaptive caps (``adaptive``);
- ``SteeringRequest``: the command's curvature.

A new command replaces the current one at once; without one the vehicle stops at the end of
the distance (the authorization runs out). Progress is signed along the command's direction
and conservative: the larger of the trusted GPS/INS odometer and integrated wheel speed
(``safety.plausibility``, issue 16), so a rollback is not progress. Command
ids must increase: a command not newer than one already seen (a reordered or repeated message)
is rejected as ``stale``, so a STOP is never overtaken by an earlier MOVE. A command's distance
counts from where the vehicle was when the planner issued it (``issued_s``; the travel since is
subtracted on arrival, ``servers.anchoring``); one too old or future-dated is ``stale`` too.

Interruptions are latched: when the vehicle leaves drive-by-wire (a SafeStop pause, a software
pause, a manual override, an e-stop disable) or the computer loses speed control, the active
command is discarded and the speed server is asked to pause (or to park, when the engine is
off: it is never restarted without a command that needs it). Nothing moves when the
interruption ends; the next command (a new id) starts again through the speed server's runwait.

Independently of the planner, the forward radar is checked every period through its corridor
(``move_radar``: targets remembered in the world frame until passed, judged along the arcs of
the commanded and the steered curvature, as wide as the vehicle plus a margin): a target whose
path distance is shorter than the stopping distance (dynamics, with the brake estimate) plus a
margin is an emergency stop (fault to the speed server through the driving module,
authorization 0, ``Notice(kind="estop")``). The stop latches until a new command is accepted.
A silent or frozen radar is fault 1151 / 1152 and caps the forward authorization at the range
last seen clear. Reversing has no radar: a REVERSE is clamped to 1.5 m/s and to the vehicle's
own forward track plus 1 m (the reply says so). See docs/move-server.md for the rules.

Outputs every period: the four driving inputs above, ``MoveStatus``; ``MoveReply`` per
command; ``ActuatorEstimates`` on ``move/estimates`` every ``estimates_period_s``; ``Notice``
for e-stops, speed reductions (when they start) and rejected inputs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import msgspec

from overdrive.dynamics.control import MAX_CONTROL_STEP_S
from overdrive.dynamics.ellipse import (
    DEFAULT_ENVELOPE,
    BrakingCache,
    Ellipse,
    EnvelopeConfig,
    ellipse_for,
    lateral_speed_limit_mps,
    max_safe_speed_mps,
)
from overdrive.dynamics.grip_estimate import GripConfig, GripEstimator
from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.dynamics.validation import finite, valid_sigma
from overdrive.dynamics.vehicle_params import G_MPS2, GearTable, VehicleParams
from overdrive.messages import (
    ENGINE_CUT_MODES,
    PAUSE_STOP_MODES,
    AdvanceAuthorization,
    DriveMode,
    DrivingStatus,
    GpsIns,
    Imu,
    MaxSpeed,
    MoveCommand,
    MoveReply,
    MoveStatus,
    Notice,
    Radar,
    SpeedState,
    SteerCommand,
    SteeringRequest,
    Topic,
    VehicleStatus,
    WheelSpeed,
    slippery_ground,
    tyres_at_limit,
)
from overdrive.safety.plausibility import MotionPlausibility, plausibility_config
from overdrive.servers.adaptive import ESTIMATES_TOPIC, ActuatorModel, AdaptiveConfig
from overdrive.servers.anchoring import OdometerHistory
from overdrive.servers.dispatch import TypeDispatch
from overdrive.servers.move_arrivals import sample_times
from overdrive.servers.move_clock import FAULT_AFTER_REFUSALS, PlannerClock, PlannerMachine
from overdrive.servers.move_conditions import ConditionConfig, ConditionMonitor, InputGaps
from overdrive.servers.move_feasibility import (
    Situation,
    Verdict,
    check_command,
    direction_change_note,
    direction_of,
)
from overdrive.servers.move_radar import RadarConfig, RadarCorridor
from overdrive.servers.speed_table import ESTOP_CAUSES, FaultCode, estop_cause

SOURCE = "move"
TIME_EPS_S = 1e-9
SENSOR_TOPICS = frozenset({Topic.GPS_INS, Topic.IMU, Topic.WHEEL_SPEED})
"""Periodic sensors whose samples queued during a stall are dated at their own time
(``move_arrivals``): the integrals over them (wheel odometer, IMU) never credit a stall to one."""
SHORTEST_DECEL_MPS2 = 0.1   # floor of the hardest deceleration (a slope steeper than the tyres hold)

# --------------------------------------------------------------------------- phases (table)

PHASES = ("idle", "starting", "shifting", "moving", "stopping", "estopped", "interrupted",
          "failed")
"""``MoveStatus.phase`` values."""

EVENTS: dict[str, str] = {
    "command_start": "MOVE/REVERSE accepted; the speed server is not in run yet",
    "command_shift": "MOVE/REVERSE accepted in the other direction: stop, shift through idle",
    "command_run": "MOVE/REVERSE accepted; the speed server is in run in that direction",
    "stop_cmd": "STOP accepted",
    "ready": "the speed server reached run in the command's direction",
    "lost": "the speed server left run (or the gear changed direction) during a move",
    "done": "the distance is used up and the vehicle stands",
    "stopped": "the vehicle stands after a STOP",
    "estop": "radar target inside the stopping distance plus margin",
    "interrupt": "the vehicle left drive-by-wire or speed control, the speed server stopped it "
                 "on its own (watchdog, a timeout), the driving module stopped it for loss of "
                 "command traffic, or this server stalled: the command is discarded",
    "failed": "the speed server holds the vehicle after a direction fault (rollback, a grade the "
              "gear cannot climb, issue 16): the command is abandoned, never done",
}

_COMMANDS = {"command_start": "starting", "command_shift": "shifting", "command_run": "moving"}

_INTERRUPT = {"interrupt": "interrupted"}
_FAILED = {"failed": "failed"}

TRANSITIONS: dict[str, dict[str, str]] = {
    "idle": {**_COMMANDS, "stop_cmd": "stopping", "estop": "estopped", **_INTERRUPT},
    "starting": {**_COMMANDS, "ready": "moving", "stop_cmd": "stopping", "estop": "estopped",
                 **_INTERRUPT, **_FAILED},
    "shifting": {**_COMMANDS, "ready": "moving", "stop_cmd": "stopping", "estop": "estopped",
                 **_INTERRUPT, **_FAILED},
    "moving": {**_COMMANDS, "lost": "starting", "done": "idle", "stop_cmd": "stopping",
               "estop": "estopped", **_INTERRUPT, **_FAILED},
    "stopping": {**_COMMANDS, "stopped": "idle", "estop": "estopped", **_INTERRUPT},
    "estopped": dict(_COMMANDS),
    "interrupted": {**_COMMANDS, "stop_cmd": "interrupted", "estop": "estopped"},
    "failed": {**_COMMANDS, "stop_cmd": "stopping", "estop": "estopped", **_INTERRUPT},
}
"""``TRANSITIONS[phase][event] -> phase``; an event a phase does not list leaves it as is."""


def next_phase(phase: str, event: str | None) -> str:
    if event is None:
        return phase
    return TRANSITIONS[phase].get(event, phase)


def mermaid_diagram() -> str:
    lines = ["stateDiagram-v2", "    [*] --> idle"]
    for phase in PHASES:
        for event, target in TRANSITIONS[phase].items():
            lines.append(f"    {phase} --> {target} : {event}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- config

class MoveServerConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Tuning of the move server; every default says where it comes from."""

    friction: float = 0.8              # assumed tyre-road friction at start (scenario default);
                                       # re-estimated online (dynamics.grip_estimate, issue 31)
    friction_max: float | None = None  # the estimate never loosens above this (None: friction)
    grip: GripConfig = GripConfig()
    envelope: EnvelopeConfig = DEFAULT_ENVELOPE
    reaction_s: float = 0.7            # the driving module's latency allowance (same figure)
    plan_decel_fraction: float = 0.6   # the driving module's braking plan's share (same figure)
    stop_margin_m: float = 0.05        # the driving module aims this far before the end
    creep_speed_mps: float = 0.3       # the driving module's terminal phase
    gear_speed_fraction: float = 0.9   # speeds above this share of a gear's top are unreachable
    standstill_mps: float = 0.05       # plant's shift threshold; 2.5 sigma of GPS speed noise
    stopped_hold_s: float = 0.3        # standing this long counts as stopped
    done_tolerance_m: float = 0.5      # a move is done standing within this of its end
    estop_margin_m: float = 2.0        # radar range beyond the stopping distance that must stay free
    estop_reaction_s: float = 0.25     # SPSS period 0.1 + brake lag 0.08 + 2 ticks, with margin
    estop_fault_code: int = 40         # client fault code (1..999) forwarded to the speed server
    turn_in_m: float = 3.0             # slow steering: travel at most this while it catches up
    turn_in_min_mps: float = 1.0       # ... but never demand less than this for it
    estimates_period_s: float = 0.1
    lag_explained_mps2: float = 0.3      # acceleration this close to the throttle estimate's
                                         # prediction explains a lag (allowance for the speed
                                         # state's filtered acceleration and the pedal's lag; mud
                                         # at 0.5 of the drive takes more)
    throttle_reserve_mps2: float = 0.05  # a weak throttle's reachable speed keeps this much
                                        # acceleration in hand (the speed loop's margin to
                                        # hold a speed; the condition monitor's lag test)
    adaptive: AdaptiveConfig = AdaptiveConfig()
    conditions: ConditionConfig = ConditionConfig()
    radar: RadarConfig = RadarConfig()   # corridor, radar health, reverse limits (move_radar)
    planner_machine: PlannerMachine = "same"   # the planner's clock: this machine's or another's
                                               # (move_clock; docs/move-server.md)
    stall_s: float = 0.2               # a step gap beyond this is a stall of this server: the
                                       # driving module's command_silence_s (same figure: seed
                                       # 001's 200 ms budget), after which it has stopped the
                                       # vehicle for loss of command traffic


class ActiveCommand(msgspec.Struct, frozen=True):
    command: MoveCommand
    direction: str
    odometer0_m: float


LAG_TOPICS = (Topic.GPS_INS, Topic.SPEED_STATE)
"""The state whose late arrival or loss lowers the speed (issue 31; move_conditions ``lag``)."""

THROTTLE_REACH_STEPS = 24
"""Bisection steps for a weak throttle's reachable speed: 2^-24 of the max speed (< 1 um/s)."""

MAX_SESSIONS_KEPT = 64
"""Planner sessions remembered as earlier ones (a planner restarting every second for a minute)."""


# --------------------------------------------------------------------------- node

class MoveServer:
    """Seed-004 move server node (see the module docstring)."""

    name = "move"
    period_s = 0.01
    subscriptions = (Topic.MOVE_COMMAND, Topic.SPEED_STATE, Topic.DRIVING_STATUS, Topic.GPS_INS,
                     Topic.IMU, Topic.RADAR, Topic.VEHICLE_STATUS, Topic.WHEEL_SPEED, Topic.STEER)

    def __init__(self, params: VehicleParams, *, config: MoveServerConfig | None = None) -> None:
        self.params = params
        self.config = cfg = config or MoveServerConfig()
        if not (math.isfinite(cfg.friction) and cfg.friction > 0.0):
            raise ValueError(f"friction: must be a positive finite number, got {cfg.friction}")
        if not (math.isfinite(cfg.stall_s) and cfg.stall_s > 0.0):
            raise ValueError(f"stall_s: must be a positive finite number, got {cfg.stall_s}")
        self.grip = GripEstimator(params, cfg.friction, cfg.friction_max, cfg.grip)
        self.ellipse = ellipse_for(params, self.grip.estimate, cfg.envelope)
        self.gears = GearTable(params)
        self.model = ActuatorModel(params, cfg.adaptive)
        self.monitor = ConditionMonitor(params, cfg.conditions)
        self.gaps = InputGaps(LAG_TOPICS, cfg.conditions.lag_window_s)   # issue 31: late inputs
        self.corridor = RadarCorridor(params, cfg.radar)
        self.phase = "idle"
        self.active: ActiveCommand | None = None
        self.last_command_id = 0
        self.newest_command_id: int | None = None   # the current session's newest command
        self.session: int | None = None             # the planner's current session
        self.sessions_seen: dict[int, None] = {}    # every session seen (insertion order, bounded)
        self.newest_issued_s: float | None = None   # newest command taken, on this clock
        self.stale_session_in_row = 0               # commands of earlier sessions in a row
        self.history = OdometerHistory()   # odometer by time: a command counts from its issue
        self.planner_clock = PlannerClock(cfg.planner_machine)   # when, on this clock, it was
        # issue 16: motion sensing cross-checked; progress is signed along each direction and
        # conservative (forward in ``history``, reverse here)
        self.motion = MotionPlausibility(SOURCE, plausibility_config(params))
        self.history_reverse = OdometerHistory()
        self.direction = "forward"
        self.curvature_1pm = 0.0
        self.engaged = False            # a MOVE/REVERSE has been accepted: keep the engine up
        self.hold_state: str | None = None
        self.away_mode = ""     # a safety mode other than drive-by-wire seen since the last step
        self.back_s: float | None = None   # when the vehicle came back after the newest
                                           # interruption (inf while away): what was issued
                                           # before is not a new command (_issued_before_back)
        # e-stop
        self.latched = False
        self.fault_active = False
        self.estop_reason = ""
        self.failure_reason = ""   # why the last command failed (phase "failed")
        # inputs
        self.gps: GpsIns | None = None
        self.gps_s = -math.inf
        self.imu: Imu | None = None
        self.radar: Radar | None = None
        self.status: VehicleStatus | None = None
        self.speed_state: SpeedState | None = None
        self.speed_stop_code = 0   # an e-stop the speed server latched on its own, since last step
        self.speed_stop_cause = ""   # its name (the interruption's code), since last step
        self.speed_seen: tuple[float, int] | None = None   # (started_s, unasked_stops) last seen
        self.driving_seen: tuple[float, int] | None = None   # the same of the driving module
        self.driving_stops = 0     # its unasked stops (loss of command traffic, grip lost) since
                                   # last step
        self.stall_gap_s = 0.0     # this server's own step gap beyond stall_s, this step
        self.hold_clear_since_accept = False   # a non-failed direction hold seen since accepted
        self.driving: DrivingStatus | None = None
        self.wheel_mps: float | None = None
        self.steer_cmd_pct: float | None = None
        self.last_now_s: float | None = None
        self.stopped_since_s: float | None = None
        self.next_estimates_s = -math.inf
        self.limit_mps = 0.0
        self.remaining_m = 0.0
        self._reductions_noticed: set[str] = set()   # reductions in force already noticed
        self.pause_end_m: float | None = None   # a pause's stop: the discarded command's end
                                                # (progress along ``direction``), kept as the
                                                # authorization until the vehicle stands
        self._sensor_rejection = ""
        self._brake_ell_cache: tuple[float, Ellipse, Ellipse] | None = None
        self._brakings = BrakingCache()
        self._brake_ell = self._brake_ellipse()    # _brake_ellipse() of the current period
        self._lateral_key: tuple[Any, ...] | None = None   # last lateral_speed_limit_mps call
        self._lateral_mps = math.inf
        self._dispatch = TypeDispatch(   # every input but MOVE commands, by its type
            ((GpsIns, self._gps), (Imu, self._imu), (Radar, self._radar),
             (VehicleStatus, self._status), (WheelSpeed, self._wheel),
             (SpeedState, self._speed_state), (DrivingStatus, self._driving),
             (SteerCommand, self._steer_cmd)), self._ignore)

    # ------------------------------------------------------------------ helpers

    @property
    def speed_mps(self) -> float:
        """The trusted speed (issue 16); the GPS/INS's when none is trusted (the speed server
        stops the vehicle then)."""
        trusted = self.motion.speed_mps
        if trusted is not None:
            return trusted
        return self.gps.speed_mps if self.gps is not None else 0.0

    @property
    def odometer_m(self) -> float:
        """The GPS/INS path length as received (progress is ``progress_m``, never this)."""
        return self.gps.odometer_m if self.gps is not None else 0.0

    def progress_m(self, direction: str) -> float:
        """Signed, conservative progress along ``direction`` (issue 16: never path length)."""
        return self.motion.progress_m(-1 if direction == "reverse" else 1)

    def _stopped(self, now_s: float) -> bool:
        return (self.stopped_since_s is not None
                and now_s - self.stopped_since_s >= self.config.stopped_hold_s - TIME_EPS_S)

    def _server_direction(self) -> int:
        """Direction of the gear the speed server reports (0: none / not in run)."""
        ss = self.speed_state
        return 0 if ss is None else self.gears.direction(ss.gear)

    def _ready(self, direction: str) -> bool:
        ss = self.speed_state
        want = -1 if direction == "reverse" else 1
        return ss is not None and ss.state == "run" and self._server_direction() == want

    def _vehicle_direction(self) -> int:
        status = self.status
        return 0 if status is None else self.gears.direction(status.gear)

    def _brake_ellipse(self) -> Ellipse:
        """The planning ellipse with its longitudinal axis no larger than the brakes now give."""
        e = self.ellipse
        brake = self.model.brake_decel_mps2 * (1.0 - self.config.envelope.derate)
        cached = self._brake_ell_cache
        if cached is not None and cached[0] == brake and cached[1] is e:
            return cached[2]   # the brake estimate rarely changes: the same ellipse
        ell = Ellipse(lon_mps2=min(e.lon_mps2, brake), lat_mps2=e.lat_mps2)
        self._brake_ell_cache = (brake, e, ell)
        return ell

    def _grade_roll(self) -> tuple[float, float]:
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        roll = self.gps.roll_rad if self.gps is not None else 0.0
        return (-pitch if self.direction == "reverse" else pitch), roll

    # ------------------------------------------------------------------ inputs

    def _finite_sensor(self, ok: bool, reason: str, out: list) -> bool:
        if ok:
            return True
        if reason != self._sensor_rejection:
            self._sensor_rejection = reason
            out.append((Topic.NOTICE, Notice(kind="rejected", source=SOURCE, code="sensor",
                                             reason=reason)))
        return False

    def _gps(self, now_s: float, msg: GpsIns, out: list) -> None:
        if finite(msg.x_m, msg.y_m, msg.heading_rad, msg.speed_mps, msg.odometer_m, msg.pitch_rad,
                  msg.roll_rad) and valid_sigma(msg.position_sigma_m):
            self.gps, self.gps_s = msg, now_s
            self.motion.gps(now_s, msg)
        else:
            self._finite_sensor(False, "gps_ins: not finite", out)

    def _imu(self, now_s: float, msg: Imu, out: list) -> None:
        if finite(msg.accel_x_mps2, msg.accel_z_mps2, msg.yaw_rate_rps):
            self.imu = msg
            self.motion.imu(now_s, msg)
        else:
            self._finite_sensor(False, "imu: not finite", out)

    def _radar(self, now_s: float, msg: Radar, out: list) -> None:
        if finite(msg.range_m) and (msg.bearing_rad is None or finite(msg.bearing_rad)):
            self.radar = msg
            self.corridor.receive(now_s, msg)
        else:
            self._finite_sensor(False, "radar: range not finite", out)

    def _status(self, now_s: float, msg: VehicleStatus, out: list) -> None:
        if finite(msg.steer_pct, msg.throttle_pct, msg.brake_pct):
            self.status = msg
            # each status on its own: a pause and its end read in one step still interrupt
            if not (msg.safety_mode == "drive-by-wire" and msg.computer_speed):
                if not self.away_mode:
                    self.away_mode = msg.safety_mode if msg.computer_speed \
                        else f"{msg.safety_mode}, no computer speed control"
                self.back_s = math.inf
            elif self.back_s == math.inf:
                self.back_s = now_s
        else:
            self._finite_sensor(False, "vehicle_status: not finite", out)

    def _wheel(self, now_s: float, msg: WheelSpeed, out: list) -> None:
        if finite(msg.speed_mps):
            self.wheel_mps = msg.speed_mps
            self.motion.wheel(now_s, msg)
        else:
            self._finite_sensor(False, "wheel_speed: not finite", out)

    def _speed_state(self, now_s: float, msg: SpeedState, out: list) -> None:
        seen = self.speed_seen
        if seen is not None and msg.started_s == seen[0] and msg.unasked_stops < seen[1]:
            # older than one already seen (reordered): not the state now, but a stop it
            # reports is obeyed all the same (what stops is never stale)
            if msg.estop and estop_cause(msg.estop_code):
                self._speed_stop(msg.estop_code)
            return
        last_fault = self.speed_state.fault if self.speed_state is not None else 0
        self.speed_state = msg
        self.speed_seen = (msg.started_s, msg.unasked_stops)
        if seen is not None and msg.started_s != seen[0]:
            # a restarted speed server: nothing it latched survived, it may drive the old
            # command on; a stop the stack did not ask for all the same. Any change counts
            # (a clock behind the old one's too): a late report of the old server only
            # interrupts again, the safe side
            self._speed_stop(0, "restart")
        elif msg.estop and estop_cause(msg.estop_code):
            self._speed_stop(msg.estop_code)   # any report of the step counts (issue 38)
        elif msg.fault == FaultCode.ENGINE_STALLED and last_fault != msg.fault:
            # the engine stopped: the server restarts it (seed 001), but the vehicle stopped
            # unasked, so the command in force is discarded like an e-stop's
            self._speed_stop(msg.fault)
        elif seen is not None and msg.unasked_stops > seen[1]:
            # the count rose (by one or more) though no report of the stop itself arrived
            # (SpeedState is droppable): the stop happened all the same
            code = msg.fault if msg.fault in ESTOP_CAUSES else 0
            self._speed_stop(code, "unasked_stop" if not code else "")
        if msg.direction_hold != "failed":
            self.hold_clear_since_accept = True

    def _speed_stop(self, code: int, cause: str = "") -> None:
        """Note a stop the speed server made on its own (its fault ``code``, 0 if unknown); the
        first of a step names the interruption (a restart, before the stop it then reports)."""
        if not self.speed_stop_cause:
            self.speed_stop_code = code
            self.speed_stop_cause = cause or estop_cause(code)

    def _seen_end_of(self, msg: DrivingStatus, rise: int) -> bool:
        """True when a rise of one is the driving module's latch of an interruption this server
        saw end itself (the vehicle came back at ``back_s``, after the latch): that interruption
        already ended the command it interrupted, and its report, delivered late, must not end
        the new one (a 10 m MOVE accepted after a 20 ms pause drove 0.36 m). Clocks of two
        nodes may differ: the error only ends a command (the safe side)."""
        stop_s, back_s = msg.last_unasked_stop_s, self.back_s
        return (rise == 1 and msg.last_unasked_stop == "interrupted" and finite(stop_s)
                and back_s is not None and back_s != math.inf and stop_s <= back_s)

    def _driving(self, now_s: float, msg: DrivingStatus, out: list) -> None:
        count, started_s = msg.unasked_stops, msg.started_s
        if (not isinstance(count, int) or isinstance(count, bool) or count < 0
                or not finite(started_s)):
            self._finite_sensor(False, "driving_status: unasked_stops or started_s invalid", out)
            return
        seen = self.driving_seen
        if seen is not None and started_s == seen[0] and count < seen[1]:
            return   # older than one already seen (reordered): it reports no new stop
        self.driving = msg
        self.driving_seen = (started_s, count)
        if seen is None:
            return   # the count before this server knew the module: nothing it drove was stopped
        # a rise (by one or more: the reports between may be lost) is a stop the driving module
        # made on its own; a restarted module (another start) counts from 0
        base = seen[1] if started_s == seen[0] else 0
        if count > base and not self._seen_end_of(msg, count - base):
            self.driving_stops += count - base

    def _steer_cmd(self, now_s: float, msg: SteerCommand, out: list) -> None:
        if finite(msg.steer_pct):
            self.steer_cmd_pct = msg.steer_pct

    def _ignore(self, now_s: float, msg: Any, out: list) -> None:
        pass

    # ------------------------------------------------------------------ step

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        commands: list[Any] = []
        dispatch = self._dispatch
        # a sensor sample counts at its own time, not at its arrival: after a stall the queue is
        # read at once, and one reading must not be credited for the whole gap (issue 38)
        times = sample_times(inbox, SENSOR_TOPICS, self.last_now_s, now_s)
        for (topic, msg), at_s in zip(inbox, times, strict=True):
            if topic == Topic.MOVE_COMMAND:
                commands.append(msg)
                continue
            dispatch(at_s, msg, out)
        dt_s = 0.0 if self.last_now_s is None else max(0.0, now_s - self.last_now_s)
        self.last_now_s = now_s
        self.gaps.arrived(now_s, {topic for topic, _ in inbox})
        cfg = self.config
        # this server did not run for longer than the driving module waits for its stream: a
        # stall (the vehicle was stopped meanwhile, a STOP waited unread); judged in _classify
        self.stall_gap_s = dt_s if dt_s > cfg.stall_s + TIME_EPS_S else 0.0
        out.extend((Topic.NOTICE, n) for n in self.motion.step(
            now_s, -1 if self.direction == "reverse" else 1))
        if self.hold_state is None and self.status is not None:
            # before the first command, keep the vehicle as it was found (engine off: parked)
            self.hold_state = "run" if self.status.engine == "running" else "parked"
        if abs(self.speed_mps) < cfg.standstill_mps:
            if self.stopped_since_s is None:
                self.stopped_since_s = now_s
        else:
            self.stopped_since_s = None

        if self.gps is not None:
            self.history.record(now_s, self.progress_m("forward"))
            self.history_reverse.record(now_s, self.progress_m("reverse"))
            if self.motion.trusted("gps_ins"):   # the own track only from a trusted pose
                self.corridor.record_trail(self.gps,
                                           1 if self.speed_mps > cfg.standstill_mps else 0)
        # review of issue 16: the corridor's memory and its clear range follow the conservative
        # signed progress (a frozen GPS/INS odometer must not stop the clear range shrinking)
        out.extend((Topic.NOTICE, n) for n in self.corridor.update(
            now_s, self.gps, self._path_curvatures(), self.direction == "forward",
            progress_m=self.progress_m("forward"), yaw_rate_rps=self._yaw_rate_rps()))
        self._learn(min(dt_s, MAX_CONTROL_STEP_S))   # a stall is not one long learning step
        self._brake_ell = self._brake_ellipse()   # the estimates are fixed until the next period
        for cmd in commands:
            self._command(now_s, cmd, out)
        if commands:
            estimate = self.planner_clock.report(now_s)
            if estimate is not None:
                out.append((Topic.PLANNER_CLOCK, estimate))

        event = self._classify(now_s, out)
        self._set_phase(next_phase(self.phase, event))
        self._end_pause_stop(now_s)
        self._limits(now_s, out)
        self._outputs(now_s, out)
        return out

    def _yaw_rate_rps(self) -> float:
        """The radar frame's yaw rate (issue 30): the gyro's while trusted, else the measured
        steering's curvature at the trusted speed (the GPS/INS heading can step)."""
        if self.imu is not None and self.motion.trusted("imu"):
            return self.imu.yaw_rate_rps
        return -self.speed_mps * self._path_curvatures()[-1]

    def _path_curvatures(self) -> tuple[float, ...]:
        """The radar corridor's arcs: the commanded curvature and the one the steering has."""
        status, p = self.status, self.params
        if status is None:
            return (self.curvature_1pm,)
        measured = math.tan(status.steer_pct / 100.0 * p.max_steer_rad) / p.wheelbase_m
        return (self.curvature_1pm, measured)

    def _learn(self, dt_s: float) -> None:
        status, gps, imu = self.status, self.gps, self.imu
        if status is not None:
            # issue 16: the actuator model learns only from trusted motion sensing
            trusted = self.motion.speed_mps is not None and self.motion.trusted("imu")
            if gps is not None and imu is not None and not status.shifting and trusted:
                direction = self._vehicle_direction()
                self.model.update_pedals(dt_s, direction, status.gear, self.speed_mps,
                                         imu.accel_x_mps2, gps.pitch_rad, status.throttle_pct,
                                         status.brake_pct, tyres_at_limit(status),
                                         status.engine == "running")
                self._learn_grip(dt_s, direction, status, gps, imu)
            self.model.update_steering(dt_s, self.steer_cmd_pct, status.steer_pct)
        if imu is not None:
            self.monitor.update_imu(dt_s, imu.accel_z_mps2)

    def _learn_grip(self, dt_s: float, direction: int, status: VehicleStatus, gps: GpsIns,
                    imu: Imu) -> None:
        """Friction online (issue 31, dynamics.grip_estimate); the ellipse follows it."""
        before = self.grip.estimate
        after = self.grip.update(self.last_now_s or 0.0, dt_s, speed_mps=self.speed_mps,
                                 accel_x_mps2=imu.accel_x_mps2, accel_y_mps2=imu.accel_y_mps2,
                                 pitch_rad=gps.pitch_rad, direction=direction,
                                 slipping=tyres_at_limit(status))
        if after != before:
            self.ellipse = ellipse_for(self.params, after, self.config.envelope)
            self._lateral_key = None   # the curve's speed limit was for the old ellipse

    # ------------------------------------------------------------------ commands

    def _situation(self, now_s: float) -> Situation:
        cfg = self.config
        status, ss = self.status, self.speed_state
        v = self.speed_mps
        moving = ""
        if abs(v) > cfg.standstill_mps * 2.0:
            moving = "forward" if v > 0.0 else "reverse"
        return Situation(
            have_position=self.gps is not None, speed_mps=v,
            pitch_rad=self.gps.pitch_rad if self.gps is not None else 0.0,
            safety_mode=status.safety_mode if status is not None else "drive-by-wire",
            computer_speed=status.computer_speed if status is not None else True,
            speed_server_estop=bool(ss is not None and ss.estop and not self.latched),
            speed_server_fault=ss.fault_message if ss is not None else "",
            moving_direction=moving,
            shifting_to=self.direction if self.phase == "shifting" else "",
            estop_braking=self.phase == "estopped" and self.fault_active,
            latched_estop=self.latched,
            radar_target=math.isfinite(self.corridor.nearest_m),
            radar_range_m=self.corridor.nearest_m,
            ellipse=self._brake_ell, standstill_mps=cfg.standstill_mps,
            obstacle_margin_m=cfg.estop_margin_m)

    def _command(self, now_s: float, cmd: Any, out: list) -> None:
        """``_answer`` with the command's session echoed in its reply."""
        first = len(out)
        self._answer(now_s, cmd, out)
        session = getattr(cmd, "session", 0)
        if isinstance(session, int) and not isinstance(session, bool) and session:
            for i in range(first, len(out)):
                topic, msg = out[i]
                if topic == Topic.MOVE_REPLY:
                    out[i] = (topic, msgspec.structs.replace(msg, session=session))

    def _answer(self, now_s: float, cmd: Any, out: list) -> None:
        """One planner command (rules: docs/move-server.md, "Sessions and staleness"): a STOP
        acts at once whatever its id, stamp or session; a MOVE / REVERSE that is new goes
        through the checks; a stale one (an id not newer within the session, or an earlier
        session) only restricts the command in force."""
        situation = self._situation(now_s)
        verdict = check_command(cmd, situation, self.params, self.config.gear_speed_fraction)
        command_id = getattr(cmd, "command_id", 0)
        kind = getattr(cmd, "kind", "stop")
        if not isinstance(command_id, int) or isinstance(command_id, bool):
            command_id = 0
        if kind not in ("move", "reverse", "stop"):
            kind = "stop"
        if verdict is not None and verdict.code == "invalid":
            if isinstance(cmd, MoveCommand) and cmd.kind == "stop":
                self._stop(command_id, f"a STOP is always obeyed ({verdict.message})", out)
                return
            out.append((Topic.MOVE_REPLY, MoveReply(command_id=command_id, kind=kind,
                                                    accepted=False, code="invalid",
                                                    message=verdict.message)))
            return
        bad_echo = self.planner_clock.echo_problem(now_s, cmd)
        if bad_echo:
            if cmd.kind == "stop":
                self._stop(command_id, f"a STOP is always obeyed ({bad_echo})", out)
                return
            self._time_refusal(command_id, kind, bad_echo, out)
            return
        stale = self._staleness(cmd, command_id, now_s)
        if stale.startswith("session ") and "not the planner's current session" in stale:
            self.stale_session_in_row += 1
            if self.stale_session_in_row == FAULT_AFTER_REFUSALS:   # no silent lock-out
                out.append((Topic.NOTICE, Notice(
                    kind="fault", source=SOURCE, code="planner_session",
                    reason=f"commands of an earlier planner session keep arriving: {stale}")))
        elif not stale:
            self.stale_session_in_row = 0
            self.planner_clock.observe(now_s, cmd)
        if kind == "stop":
            if not stale:
                self.last_command_id = command_id
            self._stop(command_id, f"{stale}: a STOP is always obeyed" if stale else "", out)
            return
        if stale:
            self._restrict(now_s, cmd, command_id, stale, out)
            return
        if verdict is None:
            verdict = self._issued_before_back(cmd, now_s) or self._too_steep_to_plan(cmd)
        odometer0_m = self.progress_m(direction_of(kind))
        if verdict is None and cmd.issued_s is not None:
            anchored, why, clock = self._anchor(kind, cmd, now_s)
            if anchored is None:
                # the planner's newest intent cannot be placed: it may have shortened the
                # distance, so the command in force is not kept either (fail-safe: stop)
                if clock:
                    self._time_refusal(command_id, kind, f"{why}; stopping", out)
                else:
                    out.append((Topic.MOVE_REPLY, MoveReply(
                        command_id=command_id, kind=kind, accepted=False, code="stale",
                        message=f"{why}; stopping")))
                if self.active is not None:
                    self.active = None
                    self._set_phase(next_phase(self.phase, "stop_cmd"))
                return
            odometer0_m = anchored
        if verdict is not None:
            out.append((Topic.MOVE_REPLY, MoveReply(command_id=command_id, kind=kind,
                                                    accepted=False, code=verdict.code,
                                                    message=verdict.message)))
            return
        cmd, clamped = self.corridor.clamp_reverse(cmd, self.gps)   # no rear sensor
        short = self._short_of_a_stop(cmd, odometer0_m, out)
        turn = direction_change_note(cmd, situation)
        out.append((Topic.MOVE_REPLY, MoveReply(
            command_id=command_id, kind=kind, accepted=True,
            message="; ".join(m for m in (turn, clamped, short) if m))))
        self.last_command_id = command_id
        self.planner_clock.placed()
        direction = direction_of(cmd.kind)
        if direction != self.direction:
            # the other direction's authorization is void from now on
            out.append((Topic.ADVANCE, AdvanceAuthorization(
                source=SOURCE, distance_m=0.0, reverse=self.direction == "reverse",
                issued_s=now_s)))
        if self._ready(direction):
            event = "command_run"
        elif self._vehicle_direction() not in (0, -1 if direction == "reverse" else 1) \
                or (self.phase == "shifting" and direction != self.direction):
            event = "command_shift"
        else:
            event = "command_start"
        self.direction = direction
        self.engaged = True
        self.latched = False
        self.fault_active = False
        self.estop_reason = ""
        self.curvature_1pm = float(cmd.curvature_1pm)
        self.active = ActiveCommand(cmd, direction, odometer0_m)
        self.pause_end_m = None
        self.hold_clear_since_accept = False   # a "failed" hold from before is not this command's
        self._set_phase(next_phase(self.phase, event))

    def _issued_before_back(self, cmd: MoveCommand, now_s: float) -> Verdict | None:
        """``not_ready`` for a MOVE / REVERSE issued before the vehicle came back from the newest
        interruption (before the stop, for a stop of the stack's own): sent during it and
        delivered late, it is not the new command that releases the latch (a MOVE issued 0.1 s
        before a release and delivered 0.3 s late drove its 40 m). An unstamped one cannot
        show when it was sent and is taken as new (docs/move-server.md)."""
        back_s = self.back_s
        if back_s is None or cmd.issued_s is None or back_s == math.inf:
            return None
        issued_s = self.planner_clock.placed_s(cmd, now_s)
        if issued_s is None or issued_s > back_s:
            return None
        return Verdict("not_ready", f"issued at t={issued_s:.3f} s, before the vehicle came back "
                                    f"from the interruption at t={back_s:.3f} s: not a new "
                                    "command; send it again")

    def _time_refusal(self, command_id: int, kind: str, why: str, out: list) -> None:
        """Refused for the planner's clock (code ``clock``); the fault when that persists."""
        out.append((Topic.MOVE_REPLY, MoveReply(command_id=command_id, kind=kind,  # type: ignore[arg-type]
                                                accepted=False, code="clock", message=why)))
        if self.planner_clock.refused(why):
            out.append((Topic.NOTICE, Notice(kind="fault", source=SOURCE, code="planner_clock",
                                             reason=f"commands refused for time reasons: {why}")))

    def _anchor(self, kind: str, cmd: MoveCommand, now_s: float
                ) -> tuple[float | None, str, bool]:
        """The odometer in ``kind``'s direction when ``cmd`` was issued, at its earliest
        plausible time on this clock; or (None, why, whether the reason is the planner's clock
        rather than the command's age)."""
        at_s, why = self.planner_clock.issue_time(cmd, now_s)
        if at_s is None:
            return None, why, True
        history = self.history_reverse if kind == "reverse" else self.history
        anchored, why = history.anchor(at_s, now_s)
        return anchored, why, False

    def _too_steep_to_plan(self, cmd: MoveCommand) -> Verdict | None:
        """Infeasible when the driving module's braking plan (a share of the ellipse's
        deceleration) cannot even hold the slope ahead: the MOVE would be accepted and never
        driven (red team, issue 17)."""
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        grade = -pitch if cmd.kind == "reverse" else pitch
        plan_mps2 = self._brake_ell.lon_mps2 * self.config.plan_decel_fraction
        downhill_mps2 = -G_MPS2 * math.sin(grade)
        if plan_mps2 > downhill_mps2:
            return None
        return Verdict("infeasible", f"the slope pulls at {downhill_mps2:.2f} m/s^2, more than the "
                                     f"braking plan's {plan_mps2:.2f} m/s^2 on this friction: "
                                     "the vehicle could not stop on it")

    def _staleness(self, cmd: Any, command_id: int, now_s: float) -> str:
        """Why ``cmd`` is stale ("" when it is new). A session not seen before becomes the
        current one (a restarted planner: its ids start again); an earlier session's commands
        and ids not newer than the current session's newest are stale. Sessions are ordered by
        when their commands were issued on this server's clock (``PlannerClock.placed_s``): a
        restarted planner may be on another machine's clock."""
        session = getattr(cmd, "session", 0)
        if not isinstance(session, int) or isinstance(session, bool):
            session = 0
        issued_s = getattr(cmd, "issued_s", None)
        if not isinstance(issued_s, float) or not math.isfinite(issued_s):
            issued_s = None
        elif isinstance(cmd, MoveCommand):
            issued_s = self.planner_clock.placed_s(cmd, now_s)
        if session != self.session:
            if session in self.sessions_seen:
                return f"session {session} is not the planner's current session {self.session}"
            self.sessions_seen[session] = None
            while len(self.sessions_seen) > MAX_SESSIONS_KEPT:
                del self.sessions_seen[next(iter(self.sessions_seen))]
            newest_s = self.newest_issued_s
            if issued_s is not None and newest_s is not None and issued_s < newest_s:
                # a session first heard of now, but issued before the current session's
                # newest command: an earlier run of the planner whose message came late
                return (f"session {session} issued at t={issued_s:.3f} s, before the current "
                        f"session {self.session}'s newest command (t={newest_s:.3f} s)")
            self.session, self.newest_command_id = session, None
            self.planner_clock.new_session()
        newest = self.newest_command_id
        if newest is not None and command_id <= newest:
            return f"command_id {command_id} is not newer than {newest}: reordered or repeated"
        self.newest_command_id = command_id
        if issued_s is not None:
            self.newest_issued_s = max(issued_s, self.newest_issued_s or issued_s)
        return ""

    def _stop(self, command_id: int, message: str, out: list) -> None:
        """STOP: accepted and acted on at once (a pause's stop too: authorization 0)."""
        out.append((Topic.MOVE_REPLY, MoveReply(command_id=command_id, kind="stop",
                                                accepted=True, message=message)))
        self.active = None
        self.pause_end_m = None
        self._set_phase(next_phase(self.phase, "stop_cmd"))

    def _restrict(self, now_s: float, cmd: MoveCommand, command_id: int, why: str,
                  out: list) -> None:
        """A stale MOVE / REVERSE: its end, if closer than the command in force's, and its max
        speed, if lower, apply; it never starts, extends or turns motion. Its end counts from
        where the vehicle was when it was issued; where that cannot be placed (older than the
        odometer history, or dated in the future) the vehicle stops."""
        active = self.active
        direction = direction_of(cmd.kind)
        if active is None or direction != active.direction:
            out.append((Topic.MOVE_REPLY, MoveReply(
                command_id=command_id, kind=cmd.kind, accepted=False, code="stale",
                message=f"{why}: not executed (a stale command only restricts the "
                        f"{'command in force' if active else 'motion'}; none in its direction)")))
            return
        odometer0_m = self.progress_m(direction)
        if cmd.issued_s is not None:
            anchored, when, _clock = self._anchor(cmd.kind, cmd, now_s)
            if anchored is None:
                # where it was issued is unknown, so how much closer its end is too: it may
                # shorten the command in force to anything: stop (fail-safe, as a new command)
                out.append((Topic.MOVE_REPLY, MoveReply(
                    command_id=command_id, kind=cmd.kind, accepted=False, code="stale",
                    restricted=True, message=f"{why}; {when}; stopping")))
                self.active = None
                self._set_phase(next_phase(self.phase, "stop_cmd"))
                return
            odometer0_m = anchored
        old = active.command
        end_m = min(active.odometer0_m + old.distance_m, odometer0_m + cmd.distance_m)
        distance_m = max(end_m - active.odometer0_m, 0.0)
        maxspeed_mps = min(old.maxspeed_mps, cmd.maxspeed_mps)
        changes = []
        if distance_m < old.distance_m:
            changes.append(f"end {old.distance_m - distance_m:.2f} m closer")
        if maxspeed_mps < old.maxspeed_mps:
            changes.append(f"max speed {maxspeed_mps:.2f} m/s")
        if changes:
            restricted = msgspec.structs.replace(old, distance_m=distance_m,
                                                 maxspeed_mps=maxspeed_mps)
            self.active = msgspec.structs.replace(active, command=restricted)
            self._short_of_a_stop(restricted, active.odometer0_m, out)
        out.append((Topic.MOVE_REPLY, MoveReply(
            command_id=command_id, kind=cmd.kind, accepted=False, code="stale",
            restricted=bool(changes),
            message=f"{why}: " + (f"restricted only: {', '.join(changes)}" if changes
                                  else "it restricts nothing of the command in force"))))

    def _short_of_a_stop(self, cmd: MoveCommand, odometer0_m: float, out: list) -> str:
        """Seed 004's "vehicle not in the expected position": a command whose distance (left of
        it now) is shorter than the hardest stop this vehicle can make from its speed. It is
        executed (hard braking) and the planner is told the overrun to expect."""
        v = abs(self.speed_mps)
        if v < self.config.standstill_mps or direction_of(cmd.kind) != self.direction:
            return ""
        p = self.params
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        grade = -pitch if cmd.kind == "reverse" else pitch
        decel = max(min(p.max_brake_decel_mps2, self.grip.estimate * G_MPS2 * math.cos(grade))
                    + G_MPS2 * math.sin(grade), SHORTEST_DECEL_MPS2)
        shortest_m = v * (self.period_s + p.brake_lag_s) + v * v / (2.0 * decel)
        left_m = cmd.distance_m - (self.progress_m(direction_of(cmd.kind)) - odometer0_m)
        if left_m >= shortest_m:
            return ""
        message = (f"vehicle not in the expected position: {left_m:.2f} m left at "
                   f"{v:.2f} m/s, the shortest stop is {shortest_m:.2f} m: expect an overrun "
                   f"of {shortest_m - left_m:.2f} m")
        out.append((Topic.NOTICE, Notice(kind="short_command", source=SOURCE,
                                         code=str(cmd.command_id), reason=message)))
        return message

    def _set_phase(self, phase: str) -> None:
        self.phase = phase

    # ------------------------------------------------------------------ per period

    def _remaining(self) -> float:
        if self.active is None:
            return 0.0
        used = self.progress_m(self.active.direction) - self.active.odometer0_m
        return max(0.0, self.active.command.distance_m - used)

    def _classify(self, now_s: float, out: list) -> str | None:
        """The period's event (after the commands), estop first."""
        cfg = self.config
        self.remaining_m = self._remaining()
        if self._collision_check(now_s, out):
            return "estop"
        if self._interruption(now_s, out):
            return "interrupt"
        phase = self.phase
        if phase == "estopped":
            if self.fault_active and self._stopped(now_s):
                self.fault_active = False     # brakes held by idle from now on; latch stays
            return None
        if phase in ("starting", "shifting", "moving") and self._direction_failed(out):
            return "failed"
        if phase in ("starting", "shifting") and self.active is not None:
            return "ready" if self._ready(self.active.direction) else None
        if phase == "moving" and self.active is not None:
            if self.remaining_m <= cfg.done_tolerance_m and self._stopped(now_s):
                self.active = None
                return "done"
            if not self._ready(self.active.direction):
                return "lost"
            return None
        if phase == "stopping" and self._stopped(now_s):
            return "stopped"
        return None

    def _end_pause_stop(self, now_s: float) -> None:
        """A pause's stop ends (authorization 0 from here) once the vehicle stands, is back in
        drive-by-wire (no command in force: stop now), or an e-stop latched."""
        if self.pause_end_m is None:
            return
        status = self.status
        back = status is not None and status.safety_mode == "drive-by-wire" \
            and status.computer_speed
        if back or self.phase == "estopped" or self._stopped(now_s):
            self.pause_end_m = None

    def _direction_failed(self, out: list) -> bool:
        """True when the speed server holds the vehicle after a direction fault (issue 16): the
        active command is abandoned and reported failed (never done), with the fault's words.
        Only a failure seen after a non-failed hold since the command was accepted counts: the
        speed server may still report the previous command's failure until it sees target 0."""
        ss = self.speed_state
        if (self.active is None or ss is None or ss.direction_hold != "failed"
                or not self.hold_clear_since_accept):
            return False
        command = self.active.command
        self.active = None
        self.failure_reason = (f"command {command.command_id} failed: "
                               f"{ss.fault_message or 'the speed server holds the vehicle'}")
        out.append((Topic.NOTICE, Notice(kind="move_failed", source=SOURCE,
                                         code=str(command.command_id),
                                         reason=self.failure_reason)))
        return True

    def _interruption(self, now_s: float, out: list) -> bool:
        """True on the period an engaged vehicle is interrupted: the command is discarded.

        An interruption is the vehicle leaving drive-by-wire or speed control (seed 000), or a
        stop the stack did not ask for: an emergency stop the speed server latched on its own
        (``SpeedState.estop_code`` above the client range: its SPSS watchdog, a sensor or
        vehicle command timeout, an actuator fault), a rise of ``SpeedState.unasked_stops``
        whose report was lost, a restarted speed server (``started_s`` later), a stop the
        driving module made for loss of command traffic (a rise of
        ``DrivingStatus.unasked_stops``), or a stall of this server (a step gap beyond
        ``stall_s``) while a command was in force or the vehicle moved. Either way nothing
        moves until a new command. A stall with nothing at stake is reported as a fault."""
        status = self.status
        stop_code, self.speed_stop_code = self.speed_stop_code, 0
        stop_cause, self.speed_stop_cause = self.speed_stop_cause, ""
        driving_stops, self.driving_stops = self.driving_stops, 0
        gap_s, self.stall_gap_s = self.stall_gap_s, 0.0
        away, self.away_mode = self.away_mode, ""
        at_stake = self.active is not None or abs(self.speed_mps) >= self.config.standstill_mps
        stalled = gap_s > 0.0 and at_stake
        if self._interrupted(status, away, stop_code, stop_cause, driving_stops, stalled, gap_s,
                             out):
            if self.back_s != math.inf:
                self.back_s = now_s   # a stop of the stack's own: what came before is old
            return True
        if gap_s > 0.0:   # no silent pass: a stall that interrupted nothing is still a fault
            out.append((Topic.NOTICE, Notice(
                kind="fault", source=SOURCE, code="move_stall",
                reason=f"the move server did not run for {gap_s:.2f} s (beyond "
                       f"{self.config.stall_s:.2f} s: stalled); nothing to interrupt "
                       f"(phase {self.phase}, {'a command in force' if self.active else 'no command'}"
                       f", {abs(self.speed_mps):.2f} m/s)")))
        return False

    def _interrupted(self, status: VehicleStatus | None, away: str, stop_code: int,
                     stop_cause: str, driving_stops: int, stalled: bool, gap_s: float,
                     out: list) -> bool:
        """``_interruption``'s decision and its notice (the causes taken from this step)."""
        if not self.engaged or self.phase == "estopped" or status is None:
            return False
        mode_ok = status.safety_mode == "drive-by-wire" and status.computer_speed and not away
        if mode_ok and not stop_cause and not driving_stops and not stalled:
            return False
        discarded = self.active
        self.active = None
        self.engaged = False
        if discarded is not None and not mode_ok and (status.safety_mode in PAUSE_STOP_MODES
                                                      or status.safety_mode == "drive-by-wire"):
            # seed 000: a pause "brings the vehicle to a stop using a constant (user set)
            # acceleration": the command's end stays the authorization while it stops (the
            # driving module stops at the pause rate inside it), never extended
            self.pause_end_m = self.progress_m(discarded.direction) + self.remaining_m
        engine_off = status.engine != "running" or status.safety_mode == "inactive" or (
            status.safety_mode in ENGINE_CUT_MODES and self.params.estop_engine_cut != "never")
        self.hold_state = "parked" if engine_off else "paused"
        what = (f"command {discarded.command.command_id} discarded" if discarded is not None
                else "no command active")
        if mode_ok:
            if stop_cause:
                ss = self.speed_state
                message = (ss.fault_message if ss is not None and stop_code
                           and ss.fault == stop_code else "")
                code = stop_cause
                what_stop = (f"speed server emergency stop (fault {stop_code}"
                             f"{': ' + message if message else ''})" if stop_code
                             else f"speed server stop ({stop_cause})")
            elif stalled:
                code = "move_stall"
                what_stop = (f"the move server did not run for {gap_s:.2f} s (beyond "
                             f"{self.config.stall_s:.2f} s: stalled; the driving module stops "
                             f"the vehicle when its stream goes quiet"
                             f"{', and did' if driving_stops else ''})")
            elif self.driving is not None and self.driving.last_unasked_stop == "grip_lost":
                code = "grip_lost"
                what_stop = ("the driving module stopped the vehicle: grip lost in a curve "
                             "(the curve no longer fits the shrunk ellipse)")
            elif self.driving is not None and self.driving.last_unasked_stop == "interrupted":
                code = "interrupted"
                what_stop = ("the driving module latched an interruption this server did not "
                             "see (the vehicle left drive-by-wire or speed control, or the "
                             "speed server stopped on its own, between two of its steps)")
            else:
                code = "command_silence"
                what_stop = ("the driving module stopped the vehicle for loss of command "
                             "traffic (this server's authorization stream went quiet"
                             + (f": it did not run for {gap_s:.2f} s" if gap_s > 0.0 else "")
                             + ")")
            out.append((Topic.NOTICE, Notice(
                kind="interrupted", source=SOURCE, code=code,
                reason=f"{what_stop}: {what}; nothing moves until a new command")))
            return True
        mode = away or (status.safety_mode if status.computer_speed
                        else f"{status.safety_mode}, no computer speed control")
        out.append((Topic.NOTICE, Notice(
            kind="interrupted", source=SOURCE, code=mode.split(",")[0],
            reason=f"safety mode {mode}: {what}; nothing moves until a new command")))
        return True

    def _collision_check(self, now_s: float, out: list) -> bool:
        """The VORAD failsafe on the radar corridor: True on the period an emergency stop starts."""
        cfg = self.config
        target_m = self.corridor.nearest_m     # path distance to a corridor target (move_radar)
        if self.phase == "estopped" or not math.isfinite(target_m):
            return False
        v = self.speed_mps
        forward_cmd = self.active is not None and self.active.direction == "forward"
        if not (v > cfg.standstill_mps or forward_cmd):
            return False
        grade = self.gps.pitch_rad if self.gps is not None else 0.0   # forward travel
        roll = self.gps.roll_rad if self.gps is not None else 0.0
        ell = self._brake_ell
        k = self.driving.curvature_1pm if self.driving is not None else self.curvature_1pm
        speed = max(v, self.corridor.closing_mps, 0.0)   # the radar's own closing speed too
        braking = self._brakings.get(ell, k, grade, roll).stopping_distance_m(speed,
                                                                          cfg.estop_reaction_s)
        if not math.isfinite(braking):
            braking = self._brakings.get(ell, 0.0, grade, roll).stopping_distance_m(
                speed, cfg.estop_reaction_s)
        reach = braking + cfg.estop_margin_m
        if target_m >= reach:
            return False
        self.latched = True
        self.fault_active = True
        self.active = None
        self.estop_reason = (f"radar: obstacle at {target_m:.1f} m inside stopping "
                             f"distance {braking:.1f} m + margin {cfg.estop_margin_m:.1f} m")
        out.append((Topic.NOTICE, Notice(kind="estop", source=SOURCE, code="radar",
                                         reason=self.estop_reason)))
        return True

    def _limits(self, now_s: float, out: list) -> None:
        """Speed limit for the driving module: command, reductions, adaptive caps."""
        active = self.active
        ss, status, driving = self.speed_state, self.status, self.driving
        maxspeed = active.command.maxspeed_mps if active is not None else 0.0
        grade, roll = self._grade_roll()
        k = self.curvature_1pm
        # the command's curve and the slope change rarely; the ellipse never (exact for +-0.0 too)
        key = (k, grade, roll)
        if key != self._lateral_key:
            self._lateral_key = key
            self._lateral_mps = lateral_speed_limit_mps(self.ellipse, k, grade, roll)
        v_lat = self._lateral_mps
        actuator_cap, why = self._actuator_cap(maxspeed, k, grade, roll)
        gap_s, gap_topic = self.gaps.worst(now_s)
        self.monitor.update(
            now_s, maxspeed_mps=maxspeed,
            pitch_rad=self.gps.pitch_rad if self.gps is not None else 0.0,
            speed_mps=self.speed_mps, wheel_speed_mps=self.wheel_mps,
            traction_control=bool(status is not None and slippery_ground(status)),
            abs_active=bool(status is not None and status.abs_active is True),
            hint=ss.hint if ss is not None else "none",
            goal_speed_mps=driving.goal_speed_mps if driving is not None else 0.0,
            throttle_pct=status.throttle_pct if status is not None else 0.0,
            safety_mode=status.safety_mode if status is not None else "drive-by-wire",
            speed_server_estop=bool(ss is not None and ss.estop and not self.latched),
            gps_age_s=now_s - self.gps_s if self.gps is not None else 0.0,
            lateral_cap_mps=v_lat, degraded=self.model.degraded(),
            actuator_cap_mps=actuator_cap, actuator_reason=why,
            input_gap_s=gap_s, input_gap_topic=gap_topic, lag_explained=self._lag_explained())
        self._reduction_notices(active is not None and self.phase not in ("stopping",
                                                                           "estopped"), out)
        limit = min(maxspeed, self.monitor.cap_mps())
        if active is not None and active.direction == "reverse":
            limit = min(limit, self._reverse_stop_cap_mps())
        self.limit_mps = max(limit, 0.0) if active is not None else 0.0

    def _reverse_stop_cap_mps(self) -> float:
        """No rear sensor (seed 004): a REVERSE no faster than a STOP (``estop_reaction_s``, the
        braking ellipse on the friction believed now, the slope behind) ends within the blind
        allowance. The fixed 2.5 m/s stopped in 0.47-0.68 m on dry ground but in 0.96-1.28 m at
        friction 0.2-0.3 (over the 1 m allowance): the cap follows the grip."""
        grade = -self.gps.pitch_rad if self.gps is not None else 0.0   # reverse travel
        roll = self.gps.roll_rad if self.gps is not None else 0.0
        braking = self._brakings.get(self._brake_ell, 0.0, grade, roll)
        return braking.max_safe_speed_mps(self.config.radar.reverse_blind_m,
                                          self.config.estop_reaction_s)

    def _reduction_notices(self, commanded: bool, out: list) -> None:
        """A ``speed_reduction`` notice for every reduction that slows a command and was not
        noticed yet: one that starts under a command, and one already in force when a command
        arrives (a steep slope before the MOVE, a reduction that began while stopping: issue
        31 item 8). Once per reduction while it lasts (commands replacing each other under it
        are not told again); one that ends and starts again is noticed again."""
        active = self.monitor.active
        self._reductions_noticed.intersection_update(active)
        if not commanded:
            return
        for code, r in active.items():
            if code not in self._reductions_noticed:
                self._reductions_noticed.add(code)
                out.append((Topic.NOTICE, Notice(kind="speed_reduction", source=SOURCE,
                                                 code=r.code, reason=r.reason)))

    def _actuator_cap(self, maxspeed: float, k: float, grade: float,
                      roll: float) -> tuple[float, str]:
        """Caps from the actuator estimates: weak brakes and slow steering."""
        cfg, p, model = self.config, self.params, self.model
        cap, reasons = math.inf, []
        e_b = model.brake.value
        if e_b < cfg.adaptive.degraded_brake:
            v = maxspeed * math.sqrt(e_b)   # same stopping distance at the reduced deceleration
            cap = min(cap, v)
            reasons.append(f"brake at {e_b:.0%}: speed x {math.sqrt(e_b):.2f}")
        brake_ell = self._brake_ell
        if brake_ell.lon_mps2 < self.ellipse.lon_mps2:
            d = self.remaining_m - cfg.stop_margin_m
            v = max_safe_speed_mps(brake_ell, d, k, grade, roll, cfg.reaction_s)
            if v <= cfg.creep_speed_mps:
                v = 0.0
            cap = min(cap, v)
        e_s = model.steering.value
        if e_s < cfg.adaptive.degraded_steering:
            catch_up_s = model.steer_time_s() - 3.0 * p.steer_lag_s
            if catch_up_s > 0.05:
                v = max(cfg.turn_in_min_mps, cfg.turn_in_m / catch_up_s)
                cap = min(cap, v)
            reasons.append(f"steering rate at {e_s:.0%}")
        e_t = model.throttle.value
        if e_t < cfg.adaptive.degraded_throttle:
            # issue 31: the weak throttle's envelope, as the brake's and the steering's: no
            # speed above what it can still reach on this grade in the gear engaged
            reach = self._throttle_reach_mps(e_t, grade, maxspeed)
            if reach is not None:
                cap = min(cap, reach)
                reasons.append(f"throttle at {e_t:.0%}: reaches {reach:.1f} m/s")
            else:
                reasons.append(f"throttle at {e_t:.0%}")
        return cap, ("actuator response degraded: " + "; ".join(reasons)) if reasons else ""

    def _lag_explained(self) -> bool:
        """The speed state's acceleration is what the throttle estimate predicts for the
        throttle reported (within ``lag_explained_mps2``): a weak throttle, not sticky ground
        (issue 31). Mud or soft ground decelerates beyond the prediction and stays sticky."""
        ss, status, p = self.speed_state, self.status, self.params
        e_t = self.model.throttle.value
        if ss is None or status is None or e_t >= self.config.adaptive.degraded_throttle:
            return False
        gear = self.gears.get(ss.gear)
        want = -1 if self.direction == "reverse" else 1
        if gear is None or gear.direction != want or not finite(ss.accel_mps2):
            return False
        v = abs(ss.speed_mps)
        grade, _ = self._grade_roll()
        expected = (e_t * 0.01 * status.throttle_pct * drive_authority_mps2(p, gear, v)
                    - resistance_mps2(p, v, math.sin(grade)))
        return want * ss.accel_mps2 >= expected - self.config.lag_explained_mps2

    def _throttle_reach_mps(self, effectiveness: float, grade: float,
                            maxspeed: float) -> float | None:
        """Highest speed up to ``maxspeed`` at which ``effectiveness`` x full throttle in the
        gear engaged still leaves ``throttle_reserve_mps2`` over rolling, drag and grade
        (bisection; the authority falls with speed). None: no gear of this direction engaged,
        or it cannot even start (the direction hold's business, not a speed cap)."""
        ss, p, cfg = self.speed_state, self.params, self.config
        gear = self.gears.get(ss.gear) if ss is not None else None
        want = -1 if self.direction == "reverse" else 1
        if gear is None or gear.direction != want:
            return None
        sin_g = math.sin(grade)

        def spare(v: float) -> float:
            return (effectiveness * drive_authority_mps2(p, gear, v)
                    - resistance_mps2(p, v, sin_g) - cfg.throttle_reserve_mps2)

        if spare(0.0) <= 0.0:
            return None
        lo, hi = 0.0, maxspeed
        if spare(hi) > 0.0:
            return hi
        for _ in range(THROTTLE_REACH_STEPS):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if spare(mid) > 0.0 else (lo, mid)
        return lo

    # ------------------------------------------------------------------ outputs

    def _drive_mode(self) -> DriveMode | None:
        cfg = self.config
        if self.phase == "estopped":
            if self.fault_active:
                return DriveMode(state="run", direction=self.direction,  # type: ignore[arg-type]
                                 fault=cfg.estop_fault_code, reason=self.estop_reason)
            return DriveMode(state="idle", direction=self.direction,  # type: ignore[arg-type]
                             reason="collision e-stop latched")
        if not self.engaged:
            if self.hold_state is None:
                return None
            return DriveMode(state=self.hold_state, direction="forward")  # type: ignore[arg-type]
        return DriveMode(state="run", direction=self.direction)  # type: ignore[arg-type]

    def _outputs(self, now_s: float, out: list) -> None:
        cfg = self.config
        mode = self._drive_mode()
        if mode is not None:
            out.append((Topic.DRIVE_MODE, mode))
        moving = self.phase in ("starting", "shifting", "moving") and self.active is not None
        authorized = self.remaining_m if moving else 0.0
        if self.pause_end_m is not None:   # a pause's stop: what was left, used up as it goes
            authorized = max(self.pause_end_m - self.progress_m(self.direction), 0.0)
        if self.direction == "forward":   # an untrusted radar: only the range last seen clear
            authorized = min(authorized, self.corridor.forward_cap_m(
                self.progress_m("forward"), cfg.estop_margin_m))
        out.append((Topic.ADVANCE, AdvanceAuthorization(
            source=SOURCE, distance_m=authorized, reverse=self.direction == "reverse",
            issued_s=now_s)))
        out.append((Topic.MAX_SPEED, MaxSpeed(source=SOURCE, issued_s=now_s,
                                              speed_mps=self.limit_mps if moving else 0.0)))
        out.append((Topic.STEERING, SteeringRequest(curvature_1pm=self.curvature_1pm)))
        reason = self.estop_reason if self.latched else "; ".join(
            [r.reason for r in self.monitor.active.values()]) if moving else ""
        if self.phase == "failed":
            reason = self.failure_reason
        elif not reason and self.planner_clock.fault_reason:
            reason = f"commands refused for time reasons: {self.planner_clock.fault_reason}"
        out.append((Topic.MOVE_STATUS, MoveStatus(
            command_id=self.last_command_id, phase=self.phase,
            remaining_m=self.remaining_m if self.active is not None else 0.0,
            latched_estop=self.latched, reason=reason, sent_s=now_s)))
        self.planner_clock.status_sent(now_s)
        if now_s + TIME_EPS_S >= self.next_estimates_s:
            out.append((ESTIMATES_TOPIC, self.model.message()))
            self.next_estimates_s += cfg.estimates_period_s
            if self.next_estimates_s <= now_s + TIME_EPS_S:
                self.next_estimates_s = now_s + cfg.estimates_period_s




__all__ = ["EVENTS", "PHASES", "TRANSITIONS", "MoveServer", "MoveServerConfig",
           "mermaid_diagram", "next_phase"]
