"""The driving module (seed 003): authorizations, speed limits and steering in; SPSS and steering out.

Each 10 ms period it validates its inputs, uses up every authorization to advance by the
signed distance travelled (the larger of the trusted GPS/INS odometer and integrated wheel
speed, ``safety.plausibility``), computes the goal speed (the highest speed that can
still stop within the most restrictive authorization, under the acceleration ellipse, with a
reaction allowance for the speed server's latency, capped by the lowest live speed limit, the
gear and the lateral limit of the curve), rate-limits the curvature inside the ellipse, and
sequences the speed server (seed 001) as its only client. A streaming source (the move server)
silent beyond ``command_silence_s`` is loss of command traffic: the vehicle stops as for a
STOP, the stop is counted (``DrivingStatus.unasked_stops``) and the source held at 0 until it
sends 0. Tyres that slide in a curve (traction control and a yaw-rate deficit, issue 30) stop
the vehicle the same way, braking first with the curvature held. An interruption (the vehicle
leaving drive-by-wire or computer speed control: a pause, an override, an e-stop, a door; or an
emergency stop or restart of the speed server) latches here, for every client of this module,
as the move server latches it for its own: every authorization is held at 0, the speed server
is asked for ``paused`` (``parked`` once the engine is cut), and nothing moves until an
authorization arrives after the vehicle is back (issue 31). Design and formulas:
docs/driving-module.md; the ellipse: ``overdrive.dynamics.ellipse``.

Outputs: ``SteerCommand`` and ``DrivingStatus`` every period, ``SetSpeed`` every 100 ms,
``Notice(kind="rejected")`` for every rejected input.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import msgspec

from overdrive.dynamics.control import MAX_CONTROL_STEP_S, rate_limit
from overdrive.dynamics.ellipse import (
    DEFAULT_ENVELOPE,
    BrakingCache,
    Ellipse,
    EnvelopeConfig,
    Longitudinal,
    TractionMonitor,
    ellipse_for,
    lateral_available_mps2,
    lateral_demand_mps2,
    lateral_speed_limit_mps,
    load_axes_mps2,
    tyre_longitudinal_mps2,
)
from overdrive.dynamics.grip_estimate import GripConfig, GripEstimator
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
    Notice,
    SetSpeed,
    SpeedState,
    SteerCommand,
    SteeringRequest,
    Topic,
    VehicleStatus,
    WheelSpeed,
    slippery_ground,
    tyres_at_limit,
)
from overdrive.safety.actuators import SteeringMonitor
from overdrive.safety.plausibility import MotionPlausibility, plausibility_config
from overdrive.servers.anchoring import OdometerHistory
from overdrive.servers.gear_hints import GearHints
from overdrive.servers.move_arrivals import sample_times

SOURCE = "driving"
TIME_EPS_S = 1e-9   # slack when comparing simulated times built from integer ticks
END_EPS_M = 1e-6    # slack when comparing two authorizations' ends (float sums of odometers)

SENSOR_TOPICS = frozenset({Topic.GPS_INS, Topic.IMU, Topic.WHEEL_SPEED})
"""Periodic sensors whose samples queued during a stall are dated at their own time
(``move_arrivals``): the wheel odometer and the IMU integral never credit a stall to one."""

SPEED_STATES = ("parked", "reset", "starting", "startwait", "paused", "runwait", "idle",
                "shifting", "run")
REQUESTABLE = ("parked", "paused", "idle", "run")   # seed 001: only these can be requested


class DrivingConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Tuning of the driving module; every default says where it comes from."""

    envelope: EnvelopeConfig = DEFAULT_ENVELOPE
    monitor_actuators: bool = True     # False where the vehicle reports efforts, not positions
                                       # (JAUS 3.3: the XGV's wrench efforts; hazards H11, H14)
    reaction_s: float = 0.7            # speed-server latency allowance: SPSS period 0.1 + reference
                                       # ease-in 0.3 + brake lag 0.08 + loop, with margin (measured)
    plan_decel_fraction: float = 0.6   # the braking curve uses this share of the ellipse's A'
                                       # (the speed server must be able to follow it, measured)
    stop_margin_m: float = 0.10        # aim this far before the end of the authorization
    creep_speed_mps: float = 0.3       # terminal phase: approach the stop point at this speed ...
    creep_zone_m: float = 1.0          # ... over the last this many metres (kept, issue 31 item
                                       # 9: shorter, a brake found stuck at the stop overruns;
                                       # docs/driving-module.md)
    stop_tail_s: float = 0.6           # a vehicle commanded to stop travels ~ v x this (measured)
    cut_speed_mps: float = 0.6         # ... commanded only once the vehicle is this slow
    min_move_m: float = 0.1            # a stop point closer than this is not worth moving to
    max_speed_ttl_s: float = 0.5       # a limit not refreshed for this long lapses (5 refreshes
                                       # at the 100 ms rate the sources send)
    accel_mps2: float = 1.5            # comfort acceleration cap (~0.15 g)
    min_rate_mps2: float = 0.05        # SPSS accel is "Always positive" (seed 004): smallest sent
    max_rate_mps2: float = 9.0         # largest rate sent: the strongest preset brake (9 m/s^2)
    max_speed_cmd_mps: float = 70.0    # largest speed sent: the speed server's
                                       # max_request_speed_mps (the scenario file's bound)
    lateral_use_fraction: float = 0.9  # speed cap in a curve uses this share of the lateral axis,
                                       # leaving sqrt(1 - 0.9^2) = 44 % of A' for braking
    overload_decel_fraction: float = 0.3  # outside the ellipse: brake at this share of A'
    lat_jerk_mps3: float = 4.0         # lateral jerk limit on curvature changes (ride comfort)
    steer_rate_fraction: float = 0.8   # of the actuator's road-wheel rate (it needs headroom)
    spss_period_s: float = 0.1         # seed 001: an SPSS every 100 ms
    sensor_timeout_s: float = 0.2      # GPS/INS older than this: no goal speed (2 x SPSS budget)
    stopped_mps: float = 0.05          # standstill (plant's shift threshold; 2.5 sigma GPS noise)
    accel_band_mps: float = 0.05       # |goal - v| below this counts as holding speed
    low_gear_enter_fraction: float = 0.5   # limit <= this x low gear top speed: want low gear
    low_gear_exit_fraction: float = 0.7    # ... and leave it above this (hysteresis)
    low_gear_max_limit_mps: float = 3.0    # seed 003 "a very low speed limit": at most a jog
    low_gear_exit_limit_mps: float = 4.0   # ... and the absolute exit threshold (hysteresis)
    steep_pitch_fraction: float = 0.5  # |pitch| >= this x max_pitch: steep, want low gear
    steep_exit_ratio: float = 0.7      # ... not steep again below 0.7 x that
    slippery_hold_s: float = 30.0      # traction control seen within this: slippery, want low gear
                                       # (ABS reported apart is not: issue 31, docs)
    grip: GripConfig = GripConfig()    # friction re-estimated online (dynamics.grip_estimate)
    gear_dwell_s: float = 1.0          # a wish for another gear must last this long
    gear_speed_fraction: float = 0.9   # goal <= this x gear top speed (redline fade, seed 001 limits)
    lapse_decel_mps2: float = 2.5      # a lapsed limit source stops the vehicle this gently (when
                                       # nothing else needs braking): the XGV's pause deceleration
    hard_brake_min_mps: float = 0.15   # no hard braking below this: 7 sigma of the GPS speed noise
                                       # (a standing vehicle's noise is not motion)
    normal_stop_reaction_s: float = 0.3  # a stop on the normal path loses this much at speed: up to
                                         # one SPSS period, the reference ease-in, brake build-up
                                         # (issue 17: below it the end is met by hard braking)
    grip_min_deficit_mps2: float = 0.5  # turning short of the command by this much lateral
                                       # acceleration while traction control acts is grip lost
                                       # (issue 30): above the steering lag's share of a
                                       # jerk-limited ramp (4 m/s^3 x 0.05 s lag = 0.2), below
                                       # the physical lateral axis at friction 0.1 (0.6 m/s^2)
    grip_slip_fresh_s: float = 0.05    # traction control reported this recently: sliding now
                                       # (five of the vehicle's 10 ms status reports)
    grip_drift_m: float = 0.3          # a slow slide: this far outside the curve (dead-reckoned
                                       # from the yaw deficit) is grip lost; a fifth of the
                                       # 1.72 m a 1.78 m wide vehicle has in a 3.5 m lane
    grip_drift_rad: float = 0.03       # ... or this much heading lost to it (1.7 deg: the
                                       # steering lag's share of a jerk-limited curve entry,
                                       # 0.2 / v rad/s, stays below it at 4 m/s for 0.5 s)
    grip_drift_reset_s: float = 1.0    # the drift estimate restarts after this long without slip
    streaming_sources: tuple[str, ...] = ("move",)   # sources that send their authorization and
                                       # limit every period (the move server: every 10 ms); their
                                       # silence is loss of command traffic. Others (a lidar
                                       # authorizing once) keep their last word (docs)
    command_silence_s: float = 0.2     # silent this long (this module's own running time): lost.
                                       # Seed 001's 200 ms SPSS budget, 20 of the move server's
                                       # 10 ms periods; the speed server's watchdog, the sensor
                                       # and radar timeouts use the same figure


# --------------------------------------------------------------------------- validation



def validate_steering(msg: Any, params: VehicleParams,
                      max_curvature_1pm: float | None = None) -> str:
    """Reason to reject a SteeringRequest, or "" to accept it.

    ``max_curvature_1pm``: ``params.max_curvature_1pm`` when the caller has it (a property
    computing a tangent on every call).
    """
    if not isinstance(msg, SteeringRequest):
        return f"steering: not a SteeringRequest ({type(msg).__name__})"
    if not finite(msg.curvature_1pm):
        return f"steering: curvature_1pm {msg.curvature_1pm} is not finite"
    max_k = params.max_curvature_1pm if max_curvature_1pm is None else max_curvature_1pm
    if abs(msg.curvature_1pm) > max_k:
        return (f"steering: |curvature_1pm| {abs(msg.curvature_1pm):.6g} beyond the vehicle's "
                f"{max_k:.6g}")
    return ""


def _valid_source(source: Any) -> bool:
    return isinstance(source, str) and bool(source)


def validate_max_speed(msg: Any) -> str:
    if not isinstance(msg, MaxSpeed):
        return f"max_speed: not a MaxSpeed ({type(msg).__name__})"
    if not _valid_source(msg.source):
        return "max_speed: empty source"
    if msg.issued_s is not None and not finite(msg.issued_s):
        return f"max_speed: issued_s {msg.issued_s!r} from {msg.source!r} is not finite"
    if not finite(msg.speed_mps):
        return f"max_speed: speed_mps {msg.speed_mps} from {msg.source!r} is not finite"
    if msg.speed_mps < 0.0:
        return f"max_speed: speed_mps {msg.speed_mps} from {msg.source!r} is negative"
    return ""


def validate_advance(msg: Any) -> str:
    if not isinstance(msg, AdvanceAuthorization):
        return f"advance: not an AdvanceAuthorization ({type(msg).__name__})"
    if msg.issued_s is not None and not finite(msg.issued_s):
        return f"advance: issued_s {msg.issued_s!r} from {msg.source!r} is not finite"
    if not _valid_source(msg.source):
        return "advance: empty source"
    if not isinstance(msg.reverse, bool):
        return f"advance: reverse {msg.reverse!r} is not a bool"
    if not finite(msg.distance_m):
        return f"advance: distance_m {msg.distance_m} from {msg.source!r} is not finite"
    if msg.distance_m < 0.0:
        return f"advance: distance_m {msg.distance_m} from {msg.source!r} is negative"
    return ""


def validate_drive_mode(msg: Any) -> str:
    if not isinstance(msg, DriveMode):
        return f"drive_mode: not a DriveMode ({type(msg).__name__})"
    if msg.state not in REQUESTABLE:
        return f"drive_mode: state {msg.state!r} cannot be requested ({', '.join(REQUESTABLE)})"
    if msg.direction not in ("forward", "reverse"):
        return f"drive_mode: direction {msg.direction!r} is not forward or reverse"
    if not isinstance(msg.fault, int) or isinstance(msg.fault, bool) or msg.fault < 0:
        return f"drive_mode: fault {msg.fault!r} is not a non-negative integer"
    return ""


def validate_gps(msg: Any) -> str:
    if not isinstance(msg, GpsIns):
        return f"gps_ins: not a GpsIns ({type(msg).__name__})"
    if not finite(msg.x_m, msg.y_m, msg.heading_rad, msg.speed_mps, msg.pitch_rad, msg.roll_rad,
                  msg.odometer_m):
        return "gps_ins: pose, speed, attitude or odometer not finite"
    if not valid_sigma(msg.position_sigma_m):
        return "gps_ins: position_sigma_m not a finite number >= 0"
    return ""


def validate_speed_state(msg: Any) -> str:
    if not isinstance(msg, SpeedState):
        return f"speed_state: not a SpeedState ({type(msg).__name__})"
    if msg.state not in SPEED_STATES or not finite(msg.speed_mps):
        return f"speed_state: state {msg.state!r} unknown or speed not finite"
    return ""


# --------------------------------------------------------------------------- pure limiters

def curvature_bounds_1pm(e: Ellipse, speed_mps: float, lon_demand_mps2: float,
                         grade_rad: float = 0.0, roll_rad: float = 0.0) -> tuple[float, float]:
    """``(lo, hi)``: curvatures whose lateral demand fits beside ``lon_demand_mps2`` at ``speed_mps``.

    Lateral room ``L = B' sqrt(1 - (f_x/A')^2)``; ``v^2 k - g sin(roll)`` must lie in
    ``[-L, L]``, so ``hi = (L + c) / v^2``, ``lo = -(L - c) / v^2``. Unbounded at a standstill.
    """
    v2 = speed_mps * speed_mps
    if v2 < 1e-9:
        return -math.inf, math.inf
    room = lateral_available_mps2(e, lon_demand_mps2, grade_rad, roll_rad)
    c = G_MPS2 * math.sin(roll_rad)
    return -(room - c) / v2, (room + c) / v2


def limit_curvature(requested_1pm: float, last_1pm: float, lo_1pm: float, hi_1pm: float,
                    max_rate_1pmps: float, dt_s: float) -> float:
    """Move towards ``requested`` inside ``[lo, hi]``, at most ``max_rate * dt`` per step.

    Never steers further out of the ellipse than ``last``, and never back into it either
    (seed 003: "if it moves, we don't try to steer back into it. We let braking handle that"):
    a ``last`` already outside widens its own side of the bounds to itself.
    """
    lo = min(lo_1pm, last_1pm)
    hi = max(hi_1pm, last_1pm)
    target = min(max(requested_1pm, lo), hi)
    return rate_limit(target, last_1pm, max_rate_1pmps, dt_s)


def steer_pct_for(curvature_1pm: float, params: VehicleParams) -> float:
    """Kinematic bicycle: road-wheel angle ``atan(k L)`` as % of full lock, + right."""
    return math.atan(curvature_1pm * params.wheelbase_m) / params.max_steer_rad * 100.0


def longitudinal_command(goal_mps: float, speed_mps: float, limits: Longitudinal,
                         overload_decel_mps2: float | None,
                         config: DrivingConfig) -> tuple[float, float, float]:
    """``(speed, rate, signed accel)`` for the SPSS: reach ``goal`` inside the ellipse.

    Up: ``rate = min(comfort, accel available)``; when nothing is available the speed is held.
    Down: the whole deceleration available (the braking curve assumes it), or the overload
    rate when the vehicle is already outside the ellipse. The signed acceleration (0 within
    ``accel_band_mps`` of the goal) is what the steering allocation counts as in use.
    """
    band = config.accel_band_mps
    if goal_mps >= speed_mps:
        rate = min(config.accel_mps2, limits.accel_mps2)
        if rate < config.min_rate_mps2:
            return min(goal_mps, speed_mps), config.min_rate_mps2, 0.0
        rate = min(rate, config.max_rate_mps2)
        return goal_mps, rate, rate if goal_mps > speed_mps + band else 0.0
    rate = overload_decel_mps2 if overload_decel_mps2 is not None else limits.decel_mps2
    rate = min(max(rate, config.min_rate_mps2), config.max_rate_mps2)
    return goal_mps, rate, -rate if goal_mps < speed_mps - band else 0.0


def set_speed_message(speed_mps: float, accel_mps2: float, gear: str, state: str, fault: int,
                      config: DrivingConfig) -> SetSpeed:
    """The SPSS, valid by construction: the speed server rejects (fault 1003, then its
    watchdog e-stops) a speed outside ``[0, max_speed_cmd_mps]`` or a rate outside
    ``(0, 10]``. The rate is clamped to ``[min_rate_mps2, max_rate_mps2]``; a non-finite or
    negative speed asks for a stop (0) and a non-finite rate then brakes at ``max_rate_mps2``,
    else changes speed at the gentlest ``min_rate_mps2`` (issue 30: a curve that took the
    whole ellipse once sent a rate of 0)."""
    speed = speed_mps if math.isfinite(speed_mps) and speed_mps > 0.0 else 0.0
    speed = min(speed, config.max_speed_cmd_mps)
    if math.isfinite(accel_mps2):
        rate = min(max(accel_mps2, config.min_rate_mps2), config.max_rate_mps2)
    else:
        rate = config.max_rate_mps2 if speed == 0.0 else config.min_rate_mps2
    return SetSpeed(speed_mps=speed, accel_mps2=rate, gear=gear, state=state, fault=fault)


def stop_tail_m(speed_mps: float, grade_rad: float, tail_s: float) -> float:
    """Distance the vehicle rolls after a stop is commanded at ``speed_mps``.

    The speed server brings its reference to 0 and its speed loop decays the speed roughly
    exponentially (``v * tail_s``); uphill it only coasts, so gravity stops it sooner:
    ``min(v * tail_s, v^2 / (2 g sin(grade)))``.
    """
    v = abs(speed_mps)
    tail = v * tail_s
    g_along = G_MPS2 * math.sin(grade_rad)
    return min(tail, v * v / (2.0 * g_along)) if g_along > 0.0 else tail


# --------------------------------------------------------------------------- inputs kept per source

class SpeedLimits:
    """Per-source speed limits; the lowest applies.

    A source that stops refreshing for more than ``ttl_s`` has gone quiet: its limit becomes 0
    (hold) until it is heard again, so losing a limit source stops the vehicle rather than
    lifting the limit (fail-safe; e.g. a dead move-server process). With no source ever heard,
    there is no limit (``inf``: the gear's limit applies).
    """

    def __init__(self, ttl_s: float) -> None:
        self.ttl_s = ttl_s
        self.by_source: dict[str, tuple[float, float]] = {}   # source -> (speed, received_s)

    def update(self, source: str, speed_mps: float, now_s: float) -> None:
        self.by_source[source] = (speed_mps, now_s)

    def restrict(self, source: str, speed_mps: float) -> None:
        """A late message's limit: lowers the source's limit, never raises it nor refreshes it."""
        if source in self.by_source:
            limit, received_s = self.by_source[source]
            self.by_source[source] = (min(limit, speed_mps), received_s)

    def lapsed(self, now_s: float) -> bool:
        """A source has gone quiet (its limit counts as 0)."""
        return any(now_s - received_s > self.ttl_s + TIME_EPS_S
                   for _, received_s in self.by_source.values())

    def lowest_live_mps(self, now_s: float) -> float:
        """Lowest limit of the sources still heard (lapsed ones left out)."""
        return min((speed_mps for speed_mps, received_s in self.by_source.values()
                    if now_s - received_s <= self.ttl_s + TIME_EPS_S), default=math.inf)

    def lowest_mps(self, now_s: float) -> float:
        """Lowest limit, a lapsed source counting as 0; ``inf`` when no source was ever heard."""
        lowest = math.inf
        for speed_mps, received_s in self.by_source.values():
            if now_s - received_s > self.ttl_s + TIME_EPS_S:
                return 0.0
            lowest = min(lowest, speed_mps)
        return lowest


class Authorizations:
    """Per-(source, direction) authorizations, used up by the odometer; the shortest applies."""

    def __init__(self) -> None:
        self.by_source: dict[tuple[str, bool], tuple[float, float]] = {}  # -> (distance, odo0)

    def update(self, source: str, reverse: bool, distance_m: float, odometer_m: float) -> None:
        self.by_source[(source, reverse)] = (distance_m, odometer_m)

    def restrict(self, source: str, reverse: bool, end_m: float) -> None:
        """A late authorization's end (odometer): brings the source's end closer, never
        further."""
        if (source, reverse) in self.by_source:
            distance_m, odometer0_m = self.by_source[(source, reverse)]
            if end_m < odometer0_m + distance_m:
                self.by_source[(source, reverse)] = (max(end_m - odometer0_m, 0.0), odometer0_m)

    def remaining_m(self, reverse: bool, odometer_m: float) -> float:
        """Shortest remaining distance for the direction; NaN when no source authorized it."""
        shortest: float | None = None
        for (_, rev), (d, odo0) in self.by_source.items():
            if rev == reverse:
                left = max(0.0, d - (odometer_m - odo0))
                if shortest is None or left < shortest:   # min(): the first of equals
                    shortest = left
        return math.nan if shortest is None else shortest


# --------------------------------------------------------------------------- speed-server client

REQUEST_TOWARD: dict[str, dict[str, str | None]] = {
    # target state -> the speed server's state -> the state to request. None: keep the last
    # request (the server is on its way: starting an engine, waiting, shifting).
    "run": {"parked": "paused", "reset": None, "starting": None, "startwait": None,
            "paused": "run", "runwait": None, "idle": "run", "shifting": None, "run": "run"},
    "idle": {"parked": "paused", "reset": None, "starting": None, "startwait": None,
             "paused": "idle", "runwait": None, "idle": "idle", "shifting": None, "run": "idle"},
    "paused": {"parked": "paused", "reset": None, "starting": None, "startwait": None,
               "paused": "paused", "runwait": "paused", "idle": "paused", "shifting": "paused",
               "run": "paused"},
    "parked": {"parked": "parked", "reset": "parked", "starting": "parked", "startwait": "parked",
               "paused": "parked", "runwait": "paused", "idle": "paused", "shifting": "paused",
               "run": "paused"},
}
"""Seed 001's sequence as a table: parked -> paused -> run (one runwait), gear changes in idle;
back through idle. From paused, run is asked at once: the speed server goes paused -> runwait
-> shifting -> run, one runwait, where asking for idle first (the seed's "To come out of pause,
request idle") then run would wait twice (docs/speed-server.md, "Runwaits")."""


class Request(msgspec.Struct, frozen=True):
    state: str
    gear: str
    drive: bool = False     # the goal speed may be sent (else speed 0)


def _engine_off(status: VehicleStatus, params: VehicleParams) -> bool:
    """The vehicle's engine is off or about to be (seed 000: e-stop disable shuts it off "if
    configured to do so", ``estop_engine_cut`` not ``never``: at once or once it stands;
    inactive)."""
    if status.engine != "running" or status.safety_mode == "inactive":
        return True
    return status.safety_mode in ENGINE_CUT_MODES and params.estop_engine_cut != "never"


def _pause_stop_cause(cause: str) -> bool:
    """An interruption whose stop is a pause's, at the vehicle's pause rate: the vehicle left
    drive-by-wire for seed 000's pauses, the door, an override (``PAUSE_STOP_MODES``), or lost
    computer speed control; not an e-stop, nor a stop the speed server made on its own."""
    mode, _, rest = cause.partition(",")
    return mode in PAUSE_STOP_MODES or (mode == "drive-by-wire" and bool(rest))


def client_request(target: str, server_state: str, server_gear: str, want_gear: str,
                   stopped: bool, last: Request | None) -> Request:
    """What to ask the speed server for next, from ``REQUEST_TOWARD`` plus the gear rules.

    Gears change only in idle: in run with the wrong gear, stop (speed 0), then request idle in
    the current gear; in idle with the wrong gear, request idle with the new gear (a shift);
    in idle with the right gear, request run. Leaving run waits for a standstill.
    """
    state = REQUEST_TOWARD[target][server_state]
    if state is None:
        if last is not None:
            return Request(last.state, last.gear)
        return Request(target if target in ("run", "idle") else "paused", want_gear)
    if server_state == "run":
        if target == "run" and server_gear == want_gear:
            return Request("run", server_gear, drive=True)
        if not stopped:
            return Request("run", server_gear)
        return Request("idle" if target in ("run", "idle") else state, server_gear)
    if server_state == "idle" and target in ("run", "idle"):
        if server_gear != want_gear:
            return Request("idle", want_gear)
        return Request(state, want_gear)
    if state in ("idle", "run"):
        return Request(state, want_gear)
    return Request(state, server_gear)


def wants_low_gear(params: VehicleParams, in_low: bool, limit_mps: float, slippery: bool,
                   pitch_rad: float, config: DrivingConfig,
                   low_gear_max_mps: float | None = None) -> bool:
    """Low gear for a low limit, slippery or steep ground (seed 001), with hysteresis.

    A limit of zero is a hold (stop and wait), not a speed regime: it keeps the current choice.
    """
    low_max = (params.gear(params.low_gear).max_speed_mps if low_gear_max_mps is None
               else low_gear_max_mps)   # the node passes it: gear() is a search
    steep = config.steep_pitch_fraction * params.max_pitch_rad
    if slippery:
        return True
    if limit_mps <= 0.0 and abs(pitch_rad) < steep:
        return in_low
    if in_low:
        return (abs(pitch_rad) >= config.steep_exit_ratio * steep
                or limit_mps <= min(config.low_gear_exit_fraction * low_max,
                                    config.low_gear_exit_limit_mps))
    return abs(pitch_rad) >= steep or limit_mps <= min(config.low_gear_enter_fraction * low_max,
                                                       config.low_gear_max_limit_mps)


# --------------------------------------------------------------------------- the node

class DrivingModule:
    """Seed-003 driving module node (see the module docstring)."""

    name = "driving"
    period_s = 0.01
    subscriptions = (Topic.STEERING, Topic.MAX_SPEED, Topic.ADVANCE, Topic.DRIVE_MODE,
                     Topic.SPEED_STATE, Topic.GPS_INS, Topic.IMU, Topic.VEHICLE_STATUS,
                     Topic.WHEEL_SPEED)

    def __init__(self, params: VehicleParams, *, config: DrivingConfig | None = None,
                 friction: float = 0.8, friction_max: float | None = None) -> None:
        if not (math.isfinite(friction) and friction > 0.0):
            raise ValueError(f"friction: must be a positive finite number, got {friction}")
        self.params = params
        self.config = cfg = config or DrivingConfig()
        if not (math.isfinite(cfg.command_silence_s) and cfg.command_silence_s > 0.0):
            raise ValueError("command_silence_s: must be a positive finite number, got "
                             f"{cfg.command_silence_s}")
        if not all(_valid_source(s) for s in cfg.streaming_sources):
            raise ValueError(f"streaming_sources: non-empty names, got {cfg.streaming_sources!r}")
        # assumed at start, then re-estimated from ABS / traction control and the IMU (issue 31;
        # no friction sensor): never above friction_max (default: the friction assumed)
        self.grip = GripEstimator(params, friction, friction_max, cfg.grip)
        self.friction = self.grip.estimate
        self.imu: Imu | None = None
        self.traction = TractionMonitor(cfg.envelope)
        self.limits = SpeedLimits(cfg.max_speed_ttl_s)
        self.authorizations = Authorizations()
        self.mode = DriveMode(state="run", direction="forward")
        self.requested_1pm = 0.0
        self.curvature_1pm = 0.0
        self.gps: GpsIns | None = None
        self.gps_s = -math.inf
        self.odometer_m = 0.0
        self.speed_state: SpeedState | None = None
        self.slippery_s = -math.inf
        self.rejected = ""
        self._sensor_rejection = ""
        self.planned_gear = params.drive_gear
        self._wish: tuple[str, float] | None = None
        self.gear_hints = GearHints(params, gear_speed_fraction=cfg.gear_speed_fraction,
                                    accel_mps2=cfg.accel_mps2)   # seed 001 hints acted on
        self.request: Request | None = None
        self._sent_key: tuple[str | None, str, str] | None = None   # (server state, target,
                                                        # gear) when the request was last sent
        self.next_spss_s = -math.inf
        self.last_now_s: float | None = None
        self.first_s: float | None = None
        self.a_signed_mps2 = 0.0
        self.goal_mps = 0.0
        self._cut: float | None = None   # distance left when the terminal stop was commanded
        self.hard_brake = False          # braking with everything until the vehicle stands
        self.history = OdometerHistory()  # odometer by time: authorizations count from their issue
        # issue 16: motion sensing cross-checked; progress is signed and conservative, so each
        # direction has its own odometer (forward in ``history``, reverse here)
        self.motion = MotionPlausibility(SOURCE, plausibility_config(params))
        self.history_reverse = OdometerHistory()
        self._arrived: list[AdvanceAuthorization] = []   # this period's, applied after the sensors
        self._newest_issue: dict[tuple, float] = {}   # (kind, source[, reverse]) -> newest issued_s
        self._out_of_order: set[tuple] = set()        # keys with a refused message not yet followed
        self._cut_direction = False
        self.gears = GearTable(params)
        self._low_gear_max_mps = params.gear(params.low_gear).max_speed_mps
        self._max_curvature_1pm = params.max_curvature_1pm   # a property: tan() per call
        self._steer_rate_1pmps = cfg.steer_rate_fraction * params.steer_rate_rps / params.wheelbase_m
        self._gear_caps = {g.name: g.max_speed_mps * cfg.gear_speed_fraction if g.direction else 0.0
                           for g in reversed(params.gears)}   # reversed: the first of a name wins
        self._inputs = {Topic.STEERING: self._steering, Topic.MAX_SPEED: self._max_speed,
                        Topic.ADVANCE: self._advance, Topic.DRIVE_MODE: self._drive_mode,
                        Topic.GPS_INS: self._gps, Topic.SPEED_STATE: self._speed_state_input,
                        Topic.VEHICLE_STATUS: self._vehicle_status,
                        Topic.WHEEL_SPEED: self._wheel, Topic.IMU: self._imu}
        # per-period values that only change with their inputs (see step)
        self._ellipses: tuple[Any, ...] = ()       # (friction, shrink, ell, cap_ell, plan_ell)
        self._lateral: tuple[Any, ...] = ()        # (cap_ell, k_req, k_cmd, grade, roll, v_lat)
        self._safe_speeds: dict[tuple[float, ...], float] = {}   # see _safe_speed_mps
        self._safe_plan: Ellipse | None = None                    # ... the ellipse they are for
        self._brakings = BrakingCache()
        # actuator monitoring (issue 16, safety.actuators): stuck road wheels stop the vehicle
        self.steer_monitor = SteeringMonitor(params)
        self.steer_status: VehicleStatus | None = None
        self.yaw_rate_rps: float | None = None
        self.steer_sent_pct: float | None = None
        self.steering_stuck = False     # latched: the vehicle stops and stays stopped
        self.monitor_actuators = cfg.monitor_actuators
        self._inputs[Topic.IMU] = self._imu
        # loss of command traffic (issue 38): a streaming source silent beyond command_silence_s
        self.running_s = 0.0    # this module's running time: steps of at most MAX_CONTROL_STEP_S
                                # (its own stall is the speed server's watchdog's, not silence)
        self.heard_s: dict[str, float] = {}       # streaming source -> running_s last heard
        self.traffic_lost: dict[str, str] = {}    # streaming source -> why it is held at 0
        self.unasked_stops = 0  # stops made on its own since the start (DrivingStatus)
        self.last_unasked_stop = ""   # the newest one's cause (DrivingStatus.last_unasked_stop)
        self.last_unasked_stop_s = -1.0   # ... and when (DrivingStatus.last_unasked_stop_s)
        self._drift_rad = 0.0   # heading lost to sliding in a curve (issue 30, _sliding) ...
        self._drift_m = 0.0     # ... and the distance outside the curve it made
        # interruptions (issue 31, _watch_interruptions): latched until a new authorization
        self.vehicle_status: VehicleStatus | None = None
        self.interrupted = ""   # the latched interruption's cause ("" when none)
        self.hold_state = "paused"   # what the speed server is asked for while latched
        self._vehicle_ok: bool | None = None   # drive-by-wire with computer speed, last seen
        self._speed_stops: tuple[int, float] | None = None   # (unasked_stops, started_s) seen
        self._speed_stop_cause = ""   # a rise or a restart seen since the last step
        self._held_noticed: set[tuple[str, bool]] = set()   # sources told they are held
        self._latched: set[str] = set()   # sources held until their own authorization after
        self._release_s: float | None = None   # ... the vehicle came back (or the stop, when
                                                 # the vehicle never left drive-by-wire)
        self._vehicle_key: tuple[str, bool] | None = None   # (safety mode, computer speed) seen
        self._status_cause = ""   # an interruption seen in this step's statuses
        self.pause_stop = False   # a pause-like interruption's stop under way (_pause_rate)
        self._pause_sent = False  # ... and the SPSS sent last asked for it
        self._pause_cause = ""    # ... its cause, for the hold once it ends

    # ------------------------------------------------------------------ inputs

    def _reject(self, code: str, reason: str, out: list) -> None:
        self.rejected = reason
        out.append((Topic.NOTICE, Notice(kind="rejected", source=SOURCE, code=code, reason=reason)))

    def _sensor(self, reason: str, out: list) -> bool:
        """Accept a sensor message ("" reason) or reject it, noticing each new reason once."""
        if not reason:
            return True
        if reason != self._sensor_rejection:
            self._sensor_rejection = reason
            self._reject("sensor", reason, out)
        return False

    def _receive(self, now_s: float, topic: str, msg: Any, out: list) -> None:
        handler = self._inputs.get(topic)
        if handler is not None:
            handler(now_s, msg, out)

    def _steering(self, now_s: float, msg: Any, out: list) -> None:
        reason = validate_steering(msg, self.params, self._max_curvature_1pm)
        if reason:
            self._reject("steering", reason, out)
        else:
            self.requested_1pm = float(msg.curvature_1pm)

    def _max_speed(self, now_s: float, msg: Any, out: list) -> None:
        reason = validate_max_speed(msg)
        if reason:
            self._reject("max_speed", reason, out)
        elif not self._in_order(("max_speed", msg.source), msg.issued_s, out):
            # out of order: a lower limit still applies (what slows is always obeyed)
            self.limits.restrict(msg.source, float(msg.speed_mps))
        else:
            why = "" if msg.issued_s is None else self.history.dated(msg.issued_s, now_s)
            if why:
                self._reject("max_speed", f"max_speed from {msg.source!r}: {why}", out)
                return
            self._taken(("max_speed", msg.source), msg.issued_s)
            self.limits.update(msg.source, float(msg.speed_mps), now_s)
            self._heard(msg.source)

    def _advance(self, now_s: float, msg: Any, out: list) -> None:
        reason = validate_advance(msg)
        if reason:
            self._reject("advance", reason, out)
        else:
            self._arrived.append(msg)

    def _in_order(self, key: tuple, issued_s: float | None, out: list) -> bool:
        """False for a message older than the last taken from its source (``key``): it was
        reordered on the way (one notice per run of them). An equal stamp is taken (the last
        word wins; anchoring makes a repeat harmless)."""
        if issued_s is None:
            return True
        newest = self._newest_issue.get(key)
        if newest is not None and issued_s < newest:
            if key not in self._out_of_order:
                self._out_of_order.add(key)
                self._reject(key[0], f"{key[0]} from {key[1]!r} issued at t={issued_s:.3f} s is "
                                     f"older than t={newest:.3f} s: reordered", out)
            return False
        return True

    def _taken(self, key: tuple, issued_s: float | None) -> None:
        """Record an accepted message's stamp (a refused one never blocks its source)."""
        if issued_s is not None:
            self._newest_issue[key] = issued_s
            self._out_of_order.discard(key)

    def _apply_advances(self, now_s: float, out: list) -> None:
        """This period's authorizations, each counted from where the vehicle was when it was
        issued; a stale or future-dated one is refused and its source holds at 0 (fail-safe)."""
        for msg in self._arrived:
            key = ("advance", msg.source, msg.reverse)
            if not self._in_order(key, msg.issued_s, out):
                # out of order: a closer end still applies, counted from where the vehicle was
                # when it was issued; where that is unknown the source holds at 0 (fail-safe)
                history = self.history_reverse if msg.reverse else self.history
                progress = self._progress_m(msg.reverse)
                anchored, _ = history.anchor(msg.issued_s, now_s)
                if anchored is None:
                    self.authorizations.restrict(msg.source, msg.reverse, progress)
                else:
                    self.authorizations.restrict(msg.source, msg.reverse,
                                                 anchored + msg.distance_m)
                continue
            odometer0 = self._progress_m(msg.reverse)
            if msg.issued_s is not None:
                history = self.history_reverse if msg.reverse else self.history
                anchored, why = history.anchor(msg.issued_s, now_s)
                if anchored is None:
                    if msg.distance_m > 0.0:   # refusing a zero authorization changes nothing
                        self._reject("advance", f"advance from {msg.source!r}: {why}; holding",
                                     out)
                    self.authorizations.update(msg.source, msg.reverse, 0.0,
                                               self._progress_m(msg.reverse))
                    continue
                odometer0 = anchored
            self._taken(key, msg.issued_s)
            self._heard(msg.source)
            distance_m = float(msg.distance_m)
            if msg.source in self.traffic_lost:
                if distance_m > 0.0:
                    distance_m = 0.0   # lost once: held until it says it knows (it sends 0)
                else:
                    del self.traffic_lost[msg.source]
            if distance_m > 0.0 and (self.interrupted or msg.source in self._latched):
                if self._after_release(msg.issued_s):
                    self._resume(msg.source, out)   # its own authorization after the release
                elif self.pause_stop:
                    # the pause's stop: a closer end applies, a further one never (one that
                    # reaches further is noticed as held; the move server's kept end is not)
                    kept = self.authorizations.by_source.get((msg.source, msg.reverse))
                    if kept is None or odometer0 + distance_m > sum(kept) + END_EPS_M:
                        self._held(msg.source, msg.reverse, out)
                    self.authorizations.restrict(msg.source, msg.reverse, odometer0 + distance_m)
                    continue
                else:
                    distance_m = self._held(msg.source, msg.reverse, out)
            self.authorizations.update(msg.source, msg.reverse, distance_m, odometer0)
        self._arrived.clear()

    def _heard(self, source: str) -> None:
        """A streaming source's message taken: it is alive (``_watch_command_traffic``)."""
        if source in self.config.streaming_sources:
            self.heard_s[source] = self.running_s

    def _watch_command_traffic(self, v: float, out: list) -> None:
        """Loss of command traffic (issue 38; seed 003: authorizations "come in regularly"): a
        streaming source (``streaming_sources``: the move server, every 10 ms) silent for more
        than ``command_silence_s`` of this module's running time while it authorizes motion
        (more than ``min_move_m`` left) or the vehicle moves is lost: it may have been told to
        stop (a STOP waits in a stalled move server's inbox). Its authorizations are held at 0
        (the hard braking of a STOP follows, ``_hard_brake``), the stop is counted in
        ``DrivingStatus.unasked_stops`` and reported; the source stays held until it sends a
        zero authorization (it knows it lost the vehicle), so a source that resumes and carries
        the old command on does not move the vehicle."""
        cfg = self.config
        reverse = self.mode.direction == "reverse"
        for source, heard_s in self.heard_s.items():
            silent_s = self.running_s - heard_s
            if source in self.traffic_lost or silent_s <= cfg.command_silence_s + TIME_EPS_S:
                continue
            left_m = self._source_remaining_m(source, reverse)
            if not (left_m > cfg.min_move_m or v >= cfg.hard_brake_min_mps):
                continue   # nothing at stake: a quiet source that authorizes nothing stops nothing
            for rev in (False, True):
                if (source, rev) in self.authorizations.by_source:
                    self.authorizations.update(source, rev, 0.0, self._progress_m(rev))
            why = (f"no authorization or limit from {source!r} for {silent_s:.2f} s (beyond "
                   f"{cfg.command_silence_s:.2f} s) with {left_m:.2f} m authorized at "
                   f"{v:.2f} m/s: loss of command traffic, stopping; its authorization is held "
                   f"at 0 until it sends 0")
            self.traffic_lost[source] = why
            self.unasked_stops += 1
            self.last_unasked_stop = "command_silence"
            self.last_unasked_stop_s = self.last_now_s or 0.0   # this step's time
            out.append((Topic.NOTICE, Notice(kind="fault", source=SOURCE,
                                             code="command_silence", reason=why)))

    def _interruption_edge(self, status: VehicleStatus) -> None:
        """Each status on its own (a pause and its end read in one step's inbox still latch): the
        vehicle leaving drive-by-wire or computer speed control, or, before it was ever seen in
        drive-by-wire, entering an operator's interruption (a SafeStop pause, an override, an
        e-stop, a door: anything but the XGV's software pause, which only says no client holds
        control yet) is the step's cause, the first one kept."""
        ok = status.safety_mode == "drive-by-wire" and status.computer_speed
        key = (status.safety_mode, status.computer_speed)
        was_ok, self._vehicle_ok = self._vehicle_ok, ok
        last_key, self._vehicle_key = self._vehicle_key, key
        entered = (was_ok is True or (key != last_key and status.safety_mode != "software-pause"))
        if not ok and entered and not self._status_cause:
            self._status_cause = status.safety_mode if status.computer_speed \
                else f"{status.safety_mode}, no computer speed control"

    def _watch_interruptions(self, now_s: float, out: list) -> None:
        """Issue 31 (seed 000's pause, override, e-stop and door; seed 004's "nothing moves until
        a new command"): the vehicle leaving drive-by-wire or computer speed control, or a stop
        the speed server made on its own (a rise of ``SpeedState.unasked_stops``, a restart),
        latches an interruption. Every authorization is held at 0 (a streaming source until it
        sends 0, as after a loss of command traffic) and the speed server is asked for
        ``paused`` (``parked`` once the engine is off), so a client of this module that keeps
        its old authorization, or re-sends it during the interruption, never drives on after
        the release. Each source is released only by its own authorization issued after the
        vehicle came back (``_after_release``)."""
        status = self.vehicle_status
        cause = self._speed_stop_cause or self._status_cause
        self._speed_stop_cause = self._status_cause = ""
        if status is not None:
            if self.interrupted and _engine_off(status, self.params):
                self.hold_state = "parked"
            if self._vehicle_ok and (self._latched or self.interrupted) \
                    and self._release_s is None:
                self._release_s = now_s   # the vehicle is back: what is issued from now counts
            if self._vehicle_ok and self.pause_stop:
                self.end_pause_stop()     # back before it stood: stop now, as without a command
        if not cause:
            return
        held = sorted({source for source, _ in self.authorizations.by_source})
        self._latched.update(held)
        self._release_s = now_s if self._vehicle_ok is not False else None
        pause = _pause_stop_cause(cause)
        self._pause_cause = f"interrupted ({cause})"
        if pause:
            self.pause_stop = True   # held at 0 once it stands (end_pause_stop)
        else:
            self.end_pause_stop()
        self.hold_state = ("parked" if status is not None and _engine_off(status, self.params)
                           else "paused")
        self._held_noticed.clear()
        already = self.interrupted
        self.interrupted = cause
        # an unasked stop for the move server too (DrivingStatus): one that missed the
        # interruption ends its command and streams 0, so its next command drives
        self.unasked_stops += 1
        self.last_unasked_stop = "interrupted"
        self.last_unasked_stop_s = now_s
        if not already:
            how = (f"kept, never extended, while the vehicle stops at its pause rate "
                   f"({self.params.pause_decel_mps2:g} m/s^2, harder only as they need), then "
                   f"held at 0" if pause else "held at 0")
            out.append((Topic.NOTICE, Notice(
                kind="latched", source=SOURCE, code=cause,
                reason=f"interrupted ({cause}): authorizations of {held or 'no source'} {how}, "
                       f"the speed server asked for {self.hold_state}; nothing moves "
                       f"until a new authorization after the vehicle is back")))

    def end_pause_stop(self) -> None:
        """The pause's stop is over (the vehicle stands, is back in drive-by-wire, or another
        cause stopped it): every authorization held at 0 from here (``_hold_every_source``)."""
        self.pause_stop = False
        self._hold_every_source(self._pause_cause)

    def _pause_rate_mps2(self, remaining_m: float, v: float) -> float:
        """The deceleration of a pause's stop (seed 000: a pause "brings the vehicle to a stop
        using a constant (user set) acceleration"): the vehicle's ``pause_decel_mps2``, or
        the least that still stops inside what is left of the authorization (the normal
        path's reaction allowed at speed) when that is harder. The hard braking of
        ``_hard_brake`` takes over where even the ellipse's would not do."""
        cfg = self.config
        rate = self.params.pause_decel_mps2
        if math.isfinite(remaining_m):
            room_m = remaining_m - cfg.stop_margin_m - v * cfg.normal_stop_reaction_s
            rate = max(rate, v * v / (2.0 * room_m)) if room_m > 0.0 else cfg.max_rate_mps2
        return rate

    def _hold_every_source(self, why: str) -> None:
        """Every authorization held at 0; a streaming source until it sends 0 (``traffic_lost``:
        it knows it lost the vehicle), so nothing it streams on moves the vehicle."""
        for source, rev in list(self.authorizations.by_source):
            self.authorizations.update(source, rev, 0.0, self._progress_m(rev))
            if source in self.config.streaming_sources:
                self.traffic_lost[source] = why

    def _after_release(self, issued_s: float | None) -> bool:
        """True for an authorization sent after the interruption ended: issued after the vehicle
        came back (after the stop, when it never left drive-by-wire). An unstamped one never
        is: it cannot show when it was sent, and neither can anything else its source sends (one
        sent during the pause and delayed past the release drove 29.8 m; with its own 0 sent
        before it and delayed as long, 29.65 m). Its source is told to stamp it."""
        release_s = self._release_s
        if release_s is None or not self._vehicle_ok or issued_s is None:
            return False
        return issued_s > release_s

    def _held(self, source: str, reverse: bool, out: list) -> float:
        """An authorization that arrives during an interruption, or one sent before its end:
        held at 0 (noticed once per source), its source latched until it sends anew."""
        self._latched.add(source)
        if (source, reverse) not in self._held_noticed:
            self._held_noticed.add((source, reverse))
            self._reject("advance", f"advance from {source!r} held at 0: interrupted "
                                    f"({self.interrupted}); send it again once the vehicle "
                                    f"is back, stamped with issued_s (an unstamped one "
                                    f"cannot show it was sent after the release)", out)
        return 0.0

    def _resume(self, source: str, out: list) -> None:
        """A source's own authorization after the release: that source is free; the first
        one ends the interruption's latch (the speed server is asked for run again). Other
        latched sources stay held at 0 until they send anew (the most restrictive applies)."""
        self._latched.discard(source)
        self._held_noticed = {k for k in self._held_noticed if k[0] != source}
        if not self.interrupted:
            return
        if self.pause_stop:   # (not reached: a source resumes only once the vehicle is back)
            self.end_pause_stop()
        out.append((Topic.NOTICE, Notice(
            kind="resumed", source=SOURCE, code=self.interrupted,
            reason=f"a new authorization from {source!r} after the interruption "
                   f"({self.interrupted}): driving again")))
        self.interrupted = ""

    def _source_remaining_m(self, source: str, reverse: bool) -> float:
        """What is left of one source's authorization for a direction (0 when it has none)."""
        entry = self.authorizations.by_source.get((source, reverse))
        if entry is None:
            return 0.0
        distance_m, odometer0_m = entry
        return max(0.0, distance_m - (self._progress_m(reverse) - odometer0_m))

    def _drive_mode(self, now_s: float, msg: Any, out: list) -> None:
        reason = validate_drive_mode(msg)
        if reason:
            self._reject("drive_mode", reason, out)
        else:
            self.mode = msg

    def _gps(self, now_s: float, msg: Any, out: list) -> None:
        if self._sensor(validate_gps(msg), out):
            self.gps, self.gps_s = msg, now_s
            self.odometer_m = msg.odometer_m
            self.motion.gps(now_s, msg)

    def _wheel(self, now_s: float, msg: Any, out: list) -> None:
        if isinstance(msg, WheelSpeed) and finite(msg.speed_mps):
            self.motion.wheel(now_s, msg)

    def _imu(self, now_s: float, msg: Any, out: list) -> None:
        """One IMU handler: yaw rate for the steering monitor, acceleration for the motion
        cross-check (review of issue 16: a second ``_imu`` once hid the first)."""
        if not isinstance(msg, Imu):
            return
        if finite(msg.yaw_rate_rps):
            self.yaw_rate_rps = msg.yaw_rate_rps
        if finite(msg.accel_x_mps2, msg.accel_y_mps2):
            self.imu = msg
        if finite(msg.accel_x_mps2):
            self.motion.imu(now_s, msg)

    def _progress_m(self, reverse: bool) -> float:
        """Signed, conservative progress along a direction (issue 16: never path length)."""
        return self.motion.progress_m(-1 if reverse else 1)

    def _speed_state_input(self, now_s: float, msg: Any, out: list) -> None:
        if self._sensor(validate_speed_state(msg), out):
            self.speed_state = msg
            if msg.hint == "slipping":
                self._slip(now_s)
            seen = self._speed_stops
            if seen is None or msg.started_s != seen[1] or msg.unasked_stops > seen[0]:
                # (a report older than the last, delivered late, never lowers the count seen)
                self._speed_stops = (msg.unasked_stops, msg.started_s)
            if seen is not None and msg.started_s != seen[1]:
                self._speed_stop_cause = "speed_restart"
            elif seen is not None and msg.unasked_stops > seen[0]:
                self._speed_stop_cause = f"speed_stop_{msg.estop_code}" if msg.estop_code \
                    else "speed_stop"

    def _vehicle_status(self, now_s: float, msg: Any, out: list) -> None:
        if isinstance(msg, VehicleStatus):
            self.vehicle_status = msg
            self._interruption_edge(msg)
            if finite(msg.steer_pct):
                self.steer_status = msg
            if msg.traction_control is True:
                # a spin or a slide (ABS too, on a vehicle that does not report it apart);
                # ABS reported apart is braking at the limit, not slippery ground (issue 31):
                # it feeds the friction estimate (_learn_grip) and, with traction control (a
                # hard stop in a curve), the slide checks, but wants no low gear
                self._slip(now_s, slippery=slippery_ground(msg))

    def _learn_grip(self, now_s: float, dt_s: float, v_mps: float, pitch_rad: float) -> None:
        """Friction online (issue 31, ``dynamics.grip_estimate``) from a trusted IMU."""
        status, imu = self.vehicle_status, self.imu
        if status is None or imu is None or not self.motion.trusted("imu") or status.shifting:
            return
        self.friction = self.grip.update(
            now_s, dt_s, speed_mps=v_mps, accel_x_mps2=imu.accel_x_mps2,
            accel_y_mps2=imu.accel_y_mps2, pitch_rad=pitch_rad,
            direction=self.gears.direction(status.gear), slipping=tyres_at_limit(status))

    def _slip(self, now_s: float, slippery: bool = True) -> None:
        self.traction.update(now_s, True)
        if slippery:
            self.slippery_s = now_s

    # ------------------------------------------------------------------ step

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        inputs = self._inputs
        dt_s = 0.0 if self.last_now_s is None else max(0.0, now_s - self.last_now_s)
        self.running_s += min(dt_s, MAX_CONTROL_STEP_S)
        if self.first_s is None:
            self.first_s = now_s
        # a sensor sample counts at its own time, not at its arrival: after a stall the queue is
        # read at once, and one reading must not be credited for the whole gap (issue 38)
        times = sample_times(inbox, SENSOR_TOPICS, self.last_now_s, now_s)
        self.last_now_s = now_s
        for (topic, msg), at_s in zip(inbox, times, strict=True):
            handler = inputs.get(topic)
            if handler is not None:
                handler(at_s, msg, out)
        out.extend((Topic.NOTICE, n) for n in self.motion.step(
            now_s, -1 if self.mode.direction == "reverse" else 1))
        if self.gps is not None:
            self.history.record(now_s, self._progress_m(False))
            self.history_reverse.record(now_s, self._progress_m(True))
        self._watch_interruptions(now_s, out)
        if self._arrived:
            self._apply_advances(now_s, out)
        p, cfg = self.params, self.config

        trusted_mps = self.motion.speed_mps   # issue 16: never an untrusted speed
        fresh = (self.gps is not None and now_s - self.gps_s <= cfg.sensor_timeout_s + TIME_EPS_S
                 and trusted_mps is not None)
        if fresh:
            v = abs(trusted_mps)
        else:
            v = abs(self.speed_state.speed_mps) if self.speed_state is not None else 0.0
        reverse = self.mode.direction == "reverse"
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        roll = self.gps.roll_rad if self.gps is not None else 0.0
        grade = -pitch if reverse else pitch
        if fresh and trusted_mps is not None:
            self._learn_grip(now_s, min(dt_s, MAX_CONTROL_STEP_S), trusted_mps, pitch)
        ell, cap_ell, plan_ell = self._period_ellipses(self.traction.shrink(now_s))
        lon_axis, lat_axis = load_axes_mps2(ell, grade, roll)
        g_along = G_MPS2 * math.sin(grade)
        stuck_k = self._monitor_steering(now_s, dt_s, out)

        # longitudinal allocation: the path's curve if it fits, else the curve we are in
        d_req = abs(lateral_demand_mps2(v, self.requested_1pm, roll))
        d_cmd = abs(lateral_demand_mps2(v, self.curvature_1pm, roll))
        demand = max(d_req, d_cmd) if d_req <= lat_axis else d_cmd
        if stuck_k is not None:   # the curve the stuck wheels drive, or the commanded one
            demand = max(demand, abs(lateral_demand_mps2(v, stuck_k, roll)))
        overload = demand > lat_axis
        tyre = tyre_longitudinal_mps2(lon_axis, lat_axis, demand)
        limits = Longitudinal(accel_mps2=tyre - g_along, decel_mps2=tyre + g_along)

        if self.heard_s:
            self._watch_command_traffic(v, out)
        pause_starts = self.pause_stop and not self._pause_sent
        if self.pause_stop and v < cfg.stopped_mps:
            self.end_pause_stop()   # it stands: every authorization held at 0 from here
        source_limit = self.limits.lowest_mps(now_s)
        remaining = self.authorizations.remaining_m(reverse, self._progress_m(reverse))
        self._plan_gear(now_s, v, source_limit, pitch, remaining)
        server = self.speed_state
        driving_gear = server.gear if server is not None and server.state == "run" \
            else self.planned_gear
        gear_cap = self._gear_cap(driving_gear)
        speed_limit = min(source_limit, gear_cap)

        v_lat = self._lateral_limit_mps(cap_ell, grade, roll)
        v_auth = 0.0
        if self._cut_direction != reverse:
            self._cut, self._cut_direction = None, reverse
        if math.isfinite(remaining):
            v_auth = self._authorized_speed(remaining - cfg.stop_margin_m, v, ell, grade, roll,
                                            plan_ell)
        request, prompt = self._client(now_s, v)
        goal = min(v_auth, speed_limit, v_lat) if (request.drive and fresh) else 0.0
        if stuck_k is not None:
            goal = 0.0   # under the lateral limit of the actual curve: braking inside the ellipse
        # the normal path can brake with the whole longitudinal axis once it slows out of a curve
        normal_decel = max(limits.decel_mps2, lon_axis + g_along)
        against_m = self._against_travel_m(v, trusted_mps if fresh else None, reverse)
        if against_m is None:
            urgent = self._hard_brake(remaining, v, v_auth, grade, normal_decel, out)
        else:   # driving the old direction after a change: its authorization binds (stop now)
            urgent = self._hard_brake(against_m, v, 0.0, -grade,
                                      max(limits.accel_mps2, lon_axis - g_along), out)
        if not self.hard_brake and self._sliding(now_s, dt_s, v, reverse):
            urgent = self._grip_lost(now_s, v, demand, lat_axis, out) or urgent
        if self.hard_brake:
            goal = 0.0
        self.goal_mps = goal

        waiting = server is None and now_s < self.first_s + cfg.spss_period_s - TIME_EPS_S
        urgent = urgent or (pause_starts and self.pause_stop)   # the pause's rate at once
        if (now_s + TIME_EPS_S >= self.next_spss_s or urgent or prompt) and not waiting:
            overload_rate = cfg.overload_decel_fraction * lon_axis if overload else None
            spss_limits = limits
            if (self.limits.lapsed(now_s) and not self.hard_brake
                    and min(v_auth, v_lat, gear_cap, self.limits.lowest_live_mps(now_s))
                    >= v - cfg.accel_band_mps):
                # only a lapsed source asks for the stop: a controlled one, not the ellipse's
                spss_limits = Longitudinal(accel_mps2=limits.accel_mps2,
                                           decel_mps2=min(limits.decel_mps2, cfg.lapse_decel_mps2))
            speed_cmd, rate, self.a_signed_mps2 = longitudinal_command(goal, v, spss_limits,
                                                                       overload_rate, cfg)
            if self.hard_brake:
                # the speed server's full-brake request, in a curve too: braking takes
                # precedence and the tyres share what they give (docs/driving-module.md,
                # "Grip lost in a curve")
                rate = self.params.max_brake_decel_mps2
            elif self.pause_stop:
                rate = self._pause_rate_mps2(remaining, v)
                self.a_signed_mps2 = -rate
            self._pause_sent = self.pause_stop
            if not request.drive:
                speed_cmd = 0.0
            out.append((Topic.SET_SPEED, set_speed_message(
                speed_cmd, rate, request.gear, request.state, self.mode.fault, cfg)))
            self.next_spss_s = max(self.next_spss_s + cfg.spss_period_s, now_s)
            if urgent or prompt or self.next_spss_s <= now_s + TIME_EPS_S:   # a period after this
                self.next_spss_s = now_s + cfg.spss_period_s

        # steering: rate- and jerk-limited, inside what the longitudinal command leaves
        lo, hi = curvature_bounds_1pm(ell, v, self.a_signed_mps2 + g_along, grade, roll)
        rate_1pmps = self._steer_rate_1pmps
        if v * v > 0.0:
            rate_1pmps = min(rate_1pmps, cfg.lat_jerk_mps3 / (v * v))
        # a stall is not one long step: the steering rate limit never jumps after one
        k = limit_curvature(self.requested_1pm, self.curvature_1pm, lo, hi, rate_1pmps,
                            min(dt_s, MAX_CONTROL_STEP_S))
        max_k = self._max_curvature_1pm
        self.curvature_1pm = min(max(k, -max_k), max_k)

        self.steer_sent_pct = steer_pct_for(self.curvature_1pm, p)
        out.append((Topic.STEER, SteerCommand(steer_pct=self.steer_sent_pct, source=SOURCE)))
        out.append((Topic.DRIVING_STATUS, DrivingStatus(
            goal_speed_mps=goal, authorized_m=remaining, speed_limit_mps=speed_limit,
            curvature_1pm=self.curvature_1pm, accel_limit_mps2=limits.accel_mps2,
            decel_limit_mps2=limits.decel_mps2, rejected=self.rejected,
            unasked_stops=self.unasked_stops, last_unasked_stop=self.last_unasked_stop,
            last_unasked_stop_s=self.last_unasked_stop_s, started_s=self.first_s if self.first_s is not None else now_s)))
        return out

    # ------------------------------------------------------------------ helpers

    def _monitor_steering(self, now_s: float, dt_s: float, out: list) -> float | None:
        """Issue 16: last period's steering command against the road wheels' reported position
        (``safety.actuators.SteeringMonitor``). Stuck wheels latch a stop (one fault notice);
        returns the curvature the vehicle actually drives while stuck, else None."""
        status = self.steer_status
        if (status is None or self.steer_sent_pct is None or self.gps is None
                or not self.monitor_actuators):
            return None
        armed = status.computer_steering and status.safety_mode == "drive-by-wire"
        finding = self.steer_monitor.update(
            dt_s, armed=armed, command_pct=self.steer_sent_pct, actual_pct=status.steer_pct,
            speed_mps=self.motion.speed_mps or 0.0, yaw_rate_rps=self.yaw_rate_rps)
        if finding is not None and not self.steering_stuck:
            self.steering_stuck = True
            out.append((Topic.NOTICE, Notice(kind="fault", source=SOURCE,
                                             code=str(int(finding.code)), reason=finding.message)))
        return self.steer_monitor.actual_curvature_1pm if self.steering_stuck else None

    def _against_travel_m(self, v: float, signed_mps: float | None, reverse: bool) -> float | None:
        """What is left of the authorization of the way the vehicle drives, when that is against
        the drive mode's direction (issue 31 item 9: a command in the other direction replaced
        the one in force while the vehicle moved); None otherwise. Driving, not rolling: the
        speed server is in run in a gear of the way it moves. The old direction's authorization
        still binds that travel (the move server voids it: 0, a stop now); one no source gave
        is 0."""
        server = self.speed_state
        if (signed_mps is None or v < self.config.hard_brake_min_mps or server is None
                or server.state != "run"):
            return None
        travel_reverse = signed_mps < 0.0
        if travel_reverse == reverse or self.gears.direction(server.gear) != (
                -1 if travel_reverse else 1):
            return None
        left_m = self.authorizations.remaining_m(travel_reverse,
                                                 self._progress_m(travel_reverse))
        return 0.0 if math.isnan(left_m) else left_m

    def _hard_brake(self, remaining_m: float, v: float, v_auth: float, grade_rad: float,
                    normal_decel_mps2: float, out: list) -> bool:
        """Issue 17: when what is left of the authorization is shorter than a stop on the normal
        path (``normal_stop_reaction_s`` at speed, then the ellipse's longitudinal axis, or the
        terminal tail), brake with everything at once, without waiting for the SPSS period,
        until the vehicle stands. Only when the authorization asks to slow at all (``v_auth``
        below the speed): a curve or a shrunk ellipse alone never starts it. True on the
        period it starts (send the SPSS now)."""
        cfg = self.config
        if self.hard_brake:
            if v < cfg.stopped_mps:
                self.hard_brake = False
            return False
        if (not math.isfinite(remaining_m) or v < cfg.hard_brake_min_mps
                or v_auth >= v - cfg.accel_band_mps):
            return False
        decel = max(normal_decel_mps2, cfg.min_rate_mps2)
        normal_m = max(v * cfg.normal_stop_reaction_s + v * v / (2.0 * decel),
                       stop_tail_m(v, grade_rad, cfg.stop_tail_s))
        if remaining_m >= normal_m:
            return False
        self.hard_brake = True
        out.append((Topic.NOTICE, Notice(
            kind="hard_brake", source=SOURCE, code="authorization",
            reason=f"{remaining_m:.2f} m authorized at {v:.2f} m/s, a normal stop needs "
                   f"{normal_m:.2f} m: braking with everything")))
        return True

    def _sliding(self, now_s: float, dt_s: float, v: float, reverse: bool) -> bool:
        """The tyres slide in the curve (issue 30). While traction control reports (within
        ``grip_slip_fresh_s``), the vehicle turns short of the commanded curvature (the IMU's
        yaw rate against ``v k``) by ``grip_min_deficit_mps2`` of lateral acceleration, or the
        deficit integrated since the slide began reaches ``grip_drift_rad`` of heading or
        ``grip_drift_m`` outside the curve (a slow slide: the open-loop curve would run
        displaced for good). Wheel spin alone, on a straight or in a curve still followed, is
        not a slide. The integral restarts after ``grip_drift_reset_s`` without slip."""
        cfg = self.config
        yaw = self.yaw_rate_rps
        k_cmd = self.curvature_1pm
        quiet_s = now_s - self.traction.last_active_s
        if quiet_s > cfg.grip_drift_reset_s:
            self._drift_rad = self._drift_m = 0.0
        if (yaw is None or v < cfg.hard_brake_min_mps or k_cmd == 0.0
                or quiet_s > cfg.grip_slip_fresh_s + TIME_EPS_S):
            return False
        v_signed = -v if reverse else v
        k_actual = -yaw / v_signed            # the IMU's sign: heading rate -v k
        short_1pm = abs(k_cmd) - k_actual * math.copysign(1.0, k_cmd)
        step_s = min(dt_s, MAX_CONTROL_STEP_S)
        self._drift_rad += v * short_1pm * step_s
        self._drift_m += v * self._drift_rad * step_s
        return (v * v * short_1pm >= cfg.grip_min_deficit_mps2 or self._drift_m >= cfg.grip_drift_m
                or self._drift_rad >= cfg.grip_drift_rad)

    def _grip_lost(self, now_s: float, v: float, demand_mps2: float, lat_axis_mps2: float,
                   out: list) -> bool:
        """Issue 30: the tyres slide in the curve (``_sliding``): the ellipse shrank below what
        the curve needs, whatever the module believed of it. Braking takes precedence: a
        full-brake stop at once (the tyres share what they give; the curvature is held,
        neither tightened nor straightened: docs/driving-module.md, "Grip lost in a curve"),
        counted as a stop the module made on its own and latched
        like a loss of command traffic: every authorization is held at 0, a streaming source
        until it sends 0 (the move server discards its command), so nothing moves again
        until the planner sends a new command that fits the smaller ellipse. True when it
        starts (send the SPSS now)."""
        why = (f"grip lost in a curve: traction control active, the vehicle turns short of the "
               f"command; lateral demand {demand_mps2:.2f} m/s^2 (ellipse's lateral axis "
               f"{lat_axis_mps2:.2f} m/s^2) at "
               f"{v:.2f} m/s: braking with everything, curvature held; nothing moves until a "
               f"new command")
        self._hold_every_source(why)
        self.hard_brake = True
        self.unasked_stops += 1
        self.last_unasked_stop = "grip_lost"
        self.last_unasked_stop_s = now_s
        out.append((Topic.NOTICE, Notice(kind="hard_brake", source=SOURCE, code="grip_lost",
                                         reason=why)))
        out.append((Topic.NOTICE, Notice(kind="fault", source=SOURCE, code="grip_lost",
                                         reason=why)))
        return True

    def _period_ellipses(self, shrink: float) -> tuple[Ellipse, Ellipse, Ellipse]:
        """The ellipse, its share for the curve speed cap and the braking plan's share.

        They change only with the friction and the traction-control shrink: kept between periods.
        """
        cached = self._ellipses
        if cached and cached[0] == self.friction and cached[1] == shrink:
            return cached[2], cached[3], cached[4]
        cfg = self.config
        ell = ellipse_for(self.params, self.friction, cfg.envelope, shrink)
        cap_ell = Ellipse(lon_mps2=ell.lon_mps2, lat_mps2=ell.lat_mps2 * cfg.lateral_use_fraction)
        plan_ell = Ellipse(lon_mps2=ell.lon_mps2 * cfg.plan_decel_fraction, lat_mps2=ell.lat_mps2)
        self._ellipses = (self.friction, shrink, ell, cap_ell, plan_ell)
        return ell, cap_ell, plan_ell

    def _lateral_limit_mps(self, cap_ell: Ellipse, grade: float, roll: float) -> float:
        """Curve speed cap: the lower of the requested and the commanded curve's.

        Its inputs rarely change (a straight or a steady curve on constant ground), so the last
        result is kept; ``lateral_speed_limit_mps`` gives the same for +0.0 and -0.0 inputs.
        """
        k_req, k_cmd = self.requested_1pm, self.curvature_1pm
        last = self._lateral
        if (last and last[0] is cap_ell and last[1] == k_req and last[2] == k_cmd
                and last[3] == grade and last[4] == roll):
            return last[5]
        v_lat = lateral_speed_limit_mps(cap_ell, k_req, grade, roll)
        if k_cmd != k_req:
            v_lat = min(v_lat, lateral_speed_limit_mps(cap_ell, k_cmd, grade, roll))
        self._lateral = (cap_ell, k_req, k_cmd, grade, roll, v_lat)
        return v_lat

    def _authorized_speed(self, distance_m: float, v: float, ell: Ellipse, grade: float,
                          roll: float, plan: Ellipse | None = None) -> float:
        """Goal speed for ``distance_m`` left to the stop point (docs: terminal approach).

        ``plan``: the braking plan's ellipse (``ell`` with ``plan_decel_fraction`` of its
        longitudinal axis), when the caller has it.
        """
        cfg = self.config
        if self._cut is not None:
            if distance_m <= self._cut + cfg.min_move_m:
                return 0.0   # stopped at the end: wait for an authorization that reaches further
            self._cut = None
        if plan is None:
            plan = Ellipse(lon_mps2=ell.lon_mps2 * cfg.plan_decel_fraction, lat_mps2=ell.lat_mps2)
        tail = stop_tail_m(v, grade, cfg.stop_tail_s)
        if distance_m <= cfg.min_move_m or (v <= cfg.cut_speed_mps and distance_m <= tail):
            self._cut = distance_m
            return 0.0
        brake = self._safe_speed_mps(plan, distance_m - cfg.creep_zone_m, grade, roll)
        if brake >= cfg.creep_speed_mps:
            return brake   # the creep speed is at most creep_speed_mps: max(brake, creep) = brake
        creep = min(cfg.creep_speed_mps, self._safe_speed_mps(plan, distance_m, grade, roll))
        return max(brake, creep)

    def _safe_speed_mps(self, plan: Ellipse, distance_m: float, grade: float,
                        roll: float) -> float:
        """``max_safe_speed_mps`` in the tighter of the requested and the commanded curve.

        The same curvature (the usual case) is computed once. Standing (waiting in runwait, or
        at a stop), the inputs repeat every period: recent results are kept. A +0.0 and a -0.0
        input give the same result, so keys that compare equal may share it.
        """
        reaction_s = self.config.reaction_s
        k_req, k_cmd = self.requested_1pm, self.curvature_1pm
        if plan is not self._safe_plan:
            self._safe_plan = plan
            self._safe_speeds.clear()
        key = (distance_m, k_req, k_cmd, grade, roll)
        v = self._safe_speeds.get(key)
        if v is not None:
            return v
        v = self._brakings.get(plan, k_req, grade, roll).max_safe_speed_mps(distance_m, reaction_s)
        if k_cmd != k_req:
            v = min(v, self._brakings.get(plan, k_cmd, grade, roll).max_safe_speed_mps(
                distance_m, reaction_s))
        if len(self._safe_speeds) >= 8:
            self._safe_speeds.clear()
        self._safe_speeds[key] = v
        return v

    def _gear_cap(self, gear_name: str) -> float:
        try:
            return self._gear_caps.get(gear_name, 0.0)
        except TypeError:   # unhashable: not a gear name
            return 0.0

    def _plan_gear(self, now_s: float, v: float, source_limit: float, pitch: float,
                   remaining: float) -> None:
        """Choose the gear the client sequences towards (hysteresis in docs/driving-module.md)."""
        p, cfg = self.params, self.config
        slippery = now_s - self.slippery_s < cfg.slippery_hold_s
        server = self.speed_state
        if self.mode.direction == "reverse":
            want = p.reverse_gear
        else:
            if server is not None:
                self.gear_hints.update(server.hint, server.state, server.gear, v,
                                       server.accel_mps2, remaining, source_limit,
                                       math.sin(pitch), self.goal_mps)
            low = wants_low_gear(p, self.planned_gear == p.low_gear, source_limit, slippery,
                                 pitch, cfg, self._low_gear_max_mps) or self.gear_hints.prefer_low
            want = p.low_gear if low else p.drive_gear
        if want == self.planned_gear:
            self._wish = None
            return
        current_dir = self.gears.direction(self.planned_gear)
        if self.gears.direction(want) != current_dir:
            self.planned_gear = want   # a change of direction cannot wait; the client stops first
            self._wish = None
            return
        if self._wish is None or self._wish[0] != want:
            self._wish = (want, now_s)
        if server is None:
            return   # the speed server's state is unknown: no gear change can be judged free
        state = server.state
        stopped = v < cfg.stopped_mps
        terrain = slippery or abs(pitch) >= cfg.steep_pitch_fraction * p.max_pitch_rad
        idle_time = not (remaining > cfg.stop_margin_m)   # no authorization left: waiting anyway
        held = now_s - self._wish[1] >= cfg.gear_dwell_s - TIME_EPS_S
        if state in ("runwait", "shifting"):
            return   # on its way to a gear already; changing now would cost another runwait
        free = state in ("parked", "reset", "starting", "startwait", "paused") or (
            state == "idle" and stopped)
        hinted_now = self.mode.direction != "reverse" and self.gear_hints.now_gear == want
        if free or (held and stopped and (terrain or idle_time)) or hinted_now:
            self.planned_gear = want
            self._wish = None

    def _client(self, now_s: float, v: float) -> tuple[Request, bool]:
        """The current request to the speed server (kept between SPSS sends), and whether it
        is to be sent now, before the next SPSS period (the server's state moved on)."""
        server = self.speed_state
        target = self.mode.state
        if self.interrupted and target in ("run", "idle"):
            target = self.hold_state   # latched: paused (parked once the engine is off)
        stopped = v < self.config.stopped_mps
        if server is None:
            request = Request(target, self.planned_gear, drive=False)
        else:
            request = client_request(target, server.state, server.gear, self.planned_gear,
                                     stopped, self.request)
        # the server reached a new state, or the target or gear changed, and that calls for
        # another request: sent at once, not at the next 100 ms tick (issue 31 item 9: each
        # step of a sequence waited up to a period). Only on such a change: a standstill that
        # flickers in the speed noise never sends more often than every period
        key = (server.state if server is not None else None, target, self.planned_gear)
        prompt = (server is not None and self.request is not None and key != self._sent_key
                  and request != self.request)
        if now_s + TIME_EPS_S >= self.next_spss_s or prompt:
            self.request = request
            self._sent_key = key
        return request, prompt


__all__ = [
    "REQUEST_TOWARD", "Authorizations", "DrivingConfig", "DrivingModule", "Request",
    "SpeedLimits", "client_request", "curvature_bounds_1pm", "limit_curvature",
    "longitudinal_command", "set_speed_message", "steer_pct_for", "validate_advance",
    "validate_drive_mode", "validate_max_speed", "validate_steering", "wants_low_gear",
]
