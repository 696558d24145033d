"""Typed, immutable bus messages and the topics they travel on.

Every message is a frozen ``msgspec.Struct``: cheap to build (~0.1 us), hashable, and it
emits a JSON Schema (used for MCAP logs and the message reference). Quantities carry their
unit in the field name. Sign conventions, fixed for the whole stack:

- curvature ``_1pm`` and steering ``steer_pct``: positive turns right, negative left
  (seed 004's MOVE convention);
- heading ``_rad``: counter-clockwise from the x axis, so a left turn increases it;
- speed ``speed_mps``: signed along the vehicle's heading, negative when reversing,
  unless a field says otherwise.

Topics are plain strings; the Zenoh bus prefixes them with ``overdrive/<vehicle>/``.
"""

from __future__ import annotations

from typing import Literal

import msgspec

SCHEMA_VERSION = 3   # 2: issue 16 (Radar.bearing_rad and seq, SpeedState.direction_hold);
                     # 3: issue 30 (GpsIns.solution and position_sigma_m)
"""Bumped on any incompatible change to a message below; carried by serialized bus frames."""


class Message(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """Base of all bus messages."""


# --------------------------------------------------------------------------- topics

SIM_WORLD_TOPIC = "sim/world"
"""Scenario -> simulator: a new ``World`` (obstacles moved, friction changed). Not a stack topic:
only a simulated vehicle (and the judge, which knows the world) listens."""
SIM_FAULTS_TOPIC = "sim/faults"
"""Scenario -> simulator: ``ActuatorFaults``, ``SensorFault``, ``EngineStall``."""


class Topic:
    """Topic names. One publisher per topic unless noted."""

    MOVE_COMMAND = "move/command"            # planner -> move server (MoveCommand)
    MOVE_REPLY = "move/reply"                # move server -> planner (MoveReply)
    MOVE_STATUS = "move/status"              # move server -> anyone (MoveStatus)
    PLANNER_CLOCK = "move/planner_clock"     # move server -> recorder (ClockEstimate)
    STEERING = "driving/steering"            # path controller / move server -> driving (SteeringRequest)
    MAX_SPEED = "driving/max_speed"          # many sources -> driving (MaxSpeed)
    ADVANCE = "driving/advance"              # many sources -> driving (AdvanceAuthorization)
    DRIVE_MODE = "driving/mode"              # move server -> driving (DriveMode)
    DRIVING_STATUS = "driving/status"        # driving -> anyone (DrivingStatus)
    SET_SPEED = "speed/set_speed"            # driving (or scenario) -> speed server (SetSpeed, "SPSS")
    SPEED_STATE = "speed/state"              # speed server -> client (SpeedState)
    PEDALS = "vehicle/pedals"                # speed server -> vehicle (PedalCommand)
    STEER = "vehicle/steer"                  # driving -> vehicle (SteerCommand)
    POWERTRAIN = "vehicle/powertrain"        # speed server -> vehicle (PowertrainCommand)
    SAFETY = "vehicle/safety"                # scenario/world -> vehicle (SafetyDevices)
    VEHICLE_STATUS = "vehicle/status"        # vehicle -> stack (VehicleStatus)
    WHEEL_SPEED = "sensors/wheel_speed"      # vehicle -> stack (WheelSpeed)
    GPS_INS = "sensors/gps_ins"              # vehicle -> stack (GpsIns)
    IMU = "sensors/imu"                      # vehicle -> stack (Imu)
    RADAR = "sensors/radar"                  # vehicle -> stack (Radar)
    TRUTH = "sim/truth"                      # simulator ground truth, never read by the stack
    NOTICE = "events"                        # any node -> recorder (Notice)
    DISPLAY = "display"                      # speed server -> LED sign, runners' console (Display)
    TICK = "process/tick"                    # every process of a launch -> launcher (NodeTick)
    CAN_FRAMES = "can/frames"                # CAN edge -> recorder (CanTraffic: raw frames)


# --------------------------------------------------------------------------- move server (seed 004)

MoveKind = Literal["move", "reverse", "stop"]
SpeedStateName = Literal[
    "parked", "reset", "starting", "startwait", "paused", "runwait", "idle", "shifting", "run"
]
RequestableState = Literal["parked", "paused", "idle", "run"]
Hint = Literal["none", "suggest_upshift", "suggest_downshift", "suggest_slowdown", "slipping"]
DirectionHoldState = Literal["free", "holding", "caught", "failed"]



class MoveCommand(Message, frozen=True):
    """MOVE / REVERSE / STOP from the planner (seed 004 ``MsgMOVE``/``MsgREVERSE``/``MsgSTOP``).

    ``session`` identifies one run of the planner: a planner picks a new one when it starts (a
    random 63-bit number), so a restarted planner is recognised and its ids may start again.
    ``command_id`` increases with every command one session issues. A STOP is always obeyed. A
    MOVE or REVERSE from the current session whose id is not newer than one already seen, or
    from an earlier session, is ``stale``: it only restricts the command in force (its end,
    if closer; its max speed, if lower) and never starts, extends or turns motion.
    """

    kind: MoveKind
    command_id: int = 0
    session: int = 0                 # the planner's run (0: a planner that does not say)
    distance_m: float = 0.0
    maxspeed_mps: float = 0.0
    curvature_1pm: float = 0.0
    issued_s: float | None = None    # when the planner sent it (its clock): the distance
                                     # counts from where the vehicle was then; None: on arrival
    status_sent_s: float | None = None      # echo of the newest MoveStatus received: its
    status_received_s: float | None = None  # sent_s, and when it arrived (the planner's clock);
                                            # with issued_s, the clock offset (move_clock)


class MoveReply(Message, frozen=True):
    """Every MoveCommand gets one reply: accepted, or rejected with a reason code."""

    command_id: int
    kind: MoveKind
    accepted: bool
    code: Literal["ok", "infeasible", "busy", "not_ready", "invalid", "stale", "clock"] = "ok"
    restricted: bool = False         # a stale command's restriction was applied (see MoveCommand)
    session: int = 0                 # the command's session, echoed
    message: str = ""


class ClockEstimate(Message, frozen=True):
    """Bounds on a peer's clock offset (this clock minus the peer's), NTP-style
    (``servers.clock_offset``): published when they move, reported in ``summary.json``."""

    peer: str
    offset_s: float | None = None      # midpoint of [lo_s, hi_s]; None: not known (yet)
    lo_s: float | None = None
    hi_s: float | None = None
    uncertainty_s: float | None = None  # hi_s - lo_s: the best round trip plus drift allowance
    worst_uncertainty_s: float = 0.0
    refusals: int = 0            # commands refused for time reasons so far
    resets: int = 0              # times the bounds crossed (a clock stepped)


class MoveStatus(Message, frozen=True):
    """Progress of the command being executed."""

    command_id: int
    phase: str                     # idle, starting, shifting, moving, stopping, estopped
    remaining_m: float
    latched_estop: bool = False
    reason: str = ""
    sent_s: float | None = None    # the move server's clock when sent: planners echo it


# --------------------------------------------------------------------------- driving module (seed 003)

class SteeringRequest(Message, frozen=True):
    """Desired path curvature from the (single) path controller."""

    curvature_1pm: float


class MaxSpeed(Message, frozen=True):
    """A speed limit from one source; the lowest live limit applies.

    ``issued_s`` (the run's clock) orders one source's messages: one not newer than the last
    taken from that source (reordered or repeated on the way) is refused.
    """

    source: str
    speed_mps: float
    issued_s: float | None = None


class AdvanceAuthorization(Message, frozen=True):
    """Source ``source`` considers it safe to advance ``distance_m`` from where the vehicle was
    at ``issued_s`` (the run's clock; None: from wherever it is when this arrives).

    Each source's authorization replaces that source's previous one and is used up as the
    vehicle moves; the most restrictive source applies. The travel since ``issued_s`` is
    subtracted on arrival; a stale or future-dated one is refused (``servers.anchoring``), and so
    is one not newer than the last taken from that source for that direction (reordered or
    repeated on the way).
    """

    source: str
    distance_m: float
    reverse: bool = False
    issued_s: float | None = None


class DriveMode(Message, frozen=True):
    """What the driving module should make the speed server do (from the move server).

    The driving module is the speed server's only client: it sequences the speed server
    (parked -> paused -> idle -> run, gear changes through idle) towards ``state`` in
    ``direction``. A nonzero ``fault`` is forwarded in the SPSS: the seed-001 way to force an
    emergency stop.
    """

    state: RequestableState
    direction: Literal["forward", "reverse"] = "forward"
    fault: int = 0
    reason: str = ""


class DrivingStatus(Message, frozen=True):
    goal_speed_mps: float
    authorized_m: float            # NaN when there is no authorization
    speed_limit_mps: float
    curvature_1pm: float
    accel_limit_mps2: float        # longitudinal acceleration still available in the ellipse
    decel_limit_mps2: float
    rejected: str = ""             # reason of the last rejected input, "" if none
    unasked_stops: int = 0         # stops the module made on its own since it started (loss of
                                   # command traffic: a streaming source silent beyond its
                                   # bound; grip lost in a curve; an interruption it latched);
                                   # never reset: the move server latches on any increase, so
                                   # a lost DrivingStatus cannot hide one
    started_s: float = 0.0         # this module's first step: a change is a restart (its count
                                   # starts again from 0)
    last_unasked_stop: str = ""    # the newest unasked stop's cause: "command_silence",
                                   # "grip_lost" (a curve that no longer fits the ellipse) or
                                   # "interrupted" (the vehicle left drive-by-wire, the speed
                                   # server stopped on its own)
    last_unasked_stop_s: float = -1.0   # when the newest one was made (this module's clock; -1:
                                        # none): the move server ignores an "interrupted" it saw
                                        # end itself (a late report must not end a new MOVE)


# --------------------------------------------------------------------------- speed server (seed 001)



class SetSpeed(Message, frozen=True):
    """SPSS: sent to the speed server every 100 ms; 200 ms without one is an emergency stop.

    ``accel_mps2`` is always positive: the rate at which to reach ``speed_mps`` (up or down).
    ``speed_mps`` is a magnitude; direction comes from the gear. ``fault`` nonzero forces a stop.
    """

    speed_mps: float
    accel_mps2: float
    gear: str
    state: str
    fault: int = 0


class SpeedState(Message, frozen=True):
    """Reply to every SPSS, and the speed server's periodic status."""

    speed_mps: float
    accel_mps2: float
    gear: str
    state: SpeedStateName
    fault: int = 0
    fault_message: str = ""
    hint: Hint = "none"
    estop: bool = False
    direction_hold: DirectionHoldState = "free"   # hill start / rollback hold; failed: held after a fault
    estop_code: int = 0            # the fault that latched the e-stop: 1..999 a client's (asked
                                   # for), 1001+ the server's own (watchdog, timeouts, actuators)
    unasked_stops: int = 0         # stops the server made on its own since it started (e-stops
                                   # 1001+, engine stalls); never reset: a client latches on any
                                   # increase, so a lost SpeedState cannot hide one
    started_s: float = 0.0         # this server's first step: a change is a restart (no latch
                                   # survives it), which clients treat as an unasked stop
    takeover: bool = False         # the safety driver must take over (the service brake lost:
                                   # issue 30 item 4); latched for the server's life


class Display(Message, frozen=True):
    """The fault display (seed 001: "Sending a nonzero fault code will result in a message
    being displayed in the LED sign"): the speed server's current fault, "" when none.

    Published on every change and re-sent every ``DISPLAY_REFRESH_S`` (a sign or viewer that
    joins late, or a lost message, is right within that time); ``code`` 0 with ``text`` "" is
    a blank sign.
    """

    text: str
    code: int = 0                  # the fault code shown (1..999 a client's, 1001+ the server's)
    also_in_force: tuple[int, ...] = ()   # the other faults in force, newest first (text ends
                                          # with them: "(also 1101, 1102)")


DISPLAY_REFRESH_S = 1.0
"""A repeated ``Display`` is re-sent this often: a human reads the sign, so a second is soon
enough for a late joiner, and 1 message/s instead of the 100/s of a per-period output."""

DISPLAY_CHANGE_MIN_S = 0.1
"""A changed ``Display`` is sent at most once per this interval (the newest text then): seed
001's SPSS period (10 Hz), the rate a client can change its fault by design; a client changing
its fault every 10 ms period gets 10 messages a second, not 100."""

DISPLAY_TEXT_MAX_CHARS = 120
"""Longest sign text: an LED sign shows tens of characters, and the longest fault template is
80 (``speed_table.FAULT_MESSAGES``, 2026-11-26); a longer text is cut and ends in an ellipsis
(the full text stays in the fault's ``Notice``)."""


def sign_text(text: str, max_chars: int = DISPLAY_TEXT_MAX_CHARS) -> str:
    """``text`` as a sign shows it: every character that is not printable (control
    characters, lone surrogates, line breaks) replaced by "?" so it always encodes as UTF-8
    and prints on one line, then cut to ``max_chars`` (at least 1) with an ellipsis."""
    if len(text) > max_chars:
        text = text[:max(max_chars, 1) - 1] + "\u2026"
    return "".join(c if c.isprintable() else "?" for c in text)


# --------------------------------------------------------------------------- actuators

class PedalCommand(Message, frozen=True):
    """Throttle and brake efforts, 0..100 %. Never both nonzero (the command gate enforces it)."""

    throttle_pct: float
    brake_pct: float
    source: str = ""


class SteerCommand(Message, frozen=True):
    """Steering effort, -100..100 % of full lock; positive steers right."""

    steer_pct: float
    source: str = ""


class PowertrainCommand(Message, frozen=True):
    """Gear, engine and horn requests."""

    gear: str
    engine_on: bool
    horn: bool = False
    park_brake: bool = False
    source: str = ""


class SafetyDevices(Message, frozen=True):
    """Physical safety devices (seed 000): SafeStop, manual overrides, door, e-stop, errors."""

    safestop: Literal["run", "pause", "stop"] = "run"
    safestop_link: Literal["none", "bypass", "good"] = "good"
    manual_override: bool = False
    emergency_manual_override: bool = False
    door_open: bool = False
    estop_button: bool = False
    internal_error: bool = False
    steering_needs_init: bool = False
    steering_awaiting_user: bool = False
    partial_mode: Literal["full", "manual-steering", "manual-speed"] = "full"


# --------------------------------------------------------------------------- vehicle -> stack

EngineState = Literal["off", "cranking", "running"]


ENGINE_CUT_MODES = frozenset({"estop-disable", "inactive"})
"""``VehicleStatus.safety_mode`` values in which the vehicle may kill its engine (seed 000; in
e-stop disable as its ``estop_engine_cut`` says)."""

PAUSE_STOP_MODES = frozenset({"software-pause", "estop-pause", "manual-override",
                              "emergency-manual-override"})
"""``VehicleStatus.safety_mode`` values whose stop is a pause's, at the vehicle's
``pause_decel_mps2`` (seed 000: a pause "brings the vehicle to a stop using a constant (user
set) acceleration"; the door's software pause; an override, where the human brakes): not
e-stop disable's full brake."""


class VehicleStatus(Message, frozen=True):
    gear: str
    shifting: bool
    engine: EngineState
    engine_rpm: float
    start_failed: bool             # last crank attempt failed
    traction_control: bool         # tyre slip detected by the vehicle's traction control
                                   # (wheel spin or a slide; ABS too when abs_active is None)
    steer_pct: float               # actual steering position, % of full lock
    throttle_pct: float            # actual (lagged) actuator positions
    brake_pct: float
    safety_mode: str
    computer_speed: bool = True    # partial mode: computer controls throttle/brake
    computer_steering: bool = True
    command_timeout: bool = False  # the vehicle's own pedal-command timeout brake is holding
                                   # (released only by the stack's restart: a runwait)
    abs_active: bool | None = None  # the brakes' ABS acts (issue 31): braking at the grip
                                   # limit, not slippery ground. None: the vehicle does not report
                                   # it apart; its traction_control is then taken as slip


def tyres_at_limit(status: VehicleStatus) -> bool:
    """ABS or traction control acts: the tyres, not the actuators, set the acceleration."""
    return status.traction_control or status.abs_active is True


def braking_at_limit(status: VehicleStatus) -> bool:
    """ABS acts while the brake outweighs the throttle: the slip is the brakes' own (a hard stop,
    even in a curve where the vehicle reports its traction control with it), not slippery ground
    (issue 31). The stack never commands both pedals; they overlap only while the lagged throttle
    closes after a stop is commanded (measured 2026-11-26: 20 % -> 5 % in ~0.3 s). An unreadable
    pedal position (NaN) compares false: slip, the safe side."""
    return status.abs_active is True and status.brake_pct > status.throttle_pct


def slippery_ground(status: VehicleStatus) -> bool:
    """Traction control reports a spin or a slide that braking at the limit does not explain."""
    return status.traction_control and not braking_at_limit(status)


class WheelSpeed(Message, frozen=True):
    speed_mps: float               # signed by gear direction; differs from ground speed when slipping


GpsSolution = Literal["rtk_fixed", "rtk_float", "dgps", "single", "dead_reckoning", "none",
                      "unknown"]
"""The receiver's own solution status (NMEA GGA quality 4/5/2/1/6/0; "unknown": not reported)."""

GPS_SOLUTIONS: tuple[str, ...] = GpsSolution.__args__   # type: ignore[attr-defined]


class GpsIns(Message, frozen=True):
    """GPS/INS pose and motion; ``solution`` and ``position_sigma_m`` are the receiver's own
    status and horizontal covariance (1 sigma), checked by ``safety.plausibility`` (issue 30)."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float               # signed ground speed along the heading
    pitch_rad: float               # nose up positive
    roll_rad: float                # right side down positive
    odometer_m: float              # path length from the integrated pose, forward and reverse
    solution: GpsSolution = "unknown"
    position_sigma_m: float | None = None   # horizontal position 1 sigma; None: not reported


class Imu(Message, frozen=True):
    accel_x_mps2: float            # specific force, forward (includes gravity along the pitch)
    accel_y_mps2: float            # specific force, left
    accel_z_mps2: float            # specific force, up (about +9.81 at rest on flat ground)
    yaw_rate_rps: float            # counter-clockwise positive


class Radar(Message, frozen=True):
    """Forward collision radar (seed 004's VORAD): nearest target in the cone ahead."""

    target: bool
    range_m: float                 # from the front bumper; max range when no target
    closing_speed_mps: float = 0.0
    bearing_rad: float | None = None  # of the target, counter-clockwise (left) from the heading;
                                      # None: not reported (a VORAD EVT-300 reports azimuth)
    seq: int | None = None         # alive counter, +1 per reading (None: the sensor has none)


class Truth(Message, frozen=True):
    """Simulator ground truth for traces and invariant checks; the stack never reads it."""

    x_m: float
    y_m: float
    heading_rad: float
    speed_mps: float
    accel_mps2: float
    lat_accel_mps2: float
    curvature_1pm: float
    pitch_rad: float
    roll_rad: float
    odometer_m: float
    slip: bool
    contact: bool                  # the vehicle's footprint touches an obstacle


# --------------------------------------------------------------------------- events

class Notice(Message, frozen=True):
    """A discrete happening for the run's event list (fault, estop, rejection, hint, ...)."""

    kind: str
    source: str
    code: str = ""
    reason: str = ""


# --------------------------------------------------------------------------- CAN logs

class CanFrameRecord(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """One raw CAN frame as it crossed the stack's CAN edge (for ``run.mcap`` and candump/ASC)."""

    time_s: float                  # when the edge sent or received it (the run's clock)
    arbitration_id: int
    data: bytes
    direction: Literal["rx", "tx"]
    is_extended: bool = False


class CanTraffic(Message, frozen=True):
    """The raw frames one CAN edge sent and received since its last ``CanTraffic``."""

    channel: str                   # the python-can channel, as resolved ("can0", "vcan0", ...)
    frames: tuple[CanFrameRecord, ...]


# --------------------------------------------------------------------------- supervision

NODE_TICK_PERIOD_S = 0.1
"""Every process of a multi-process run publishes a ``NodeTick`` this often (docs/multiprocess.md,
"Supervision"): ten a second, so a hang bound of half a second is five ticks."""


class NodeTick(Message, frozen=True):
    """A process's liveness tick, sent from its stepping loop every ``NODE_TICK_PERIOD_S``: a
    process whose ticks stop is hung (or its link is); ``seq`` tells the two apart afterwards."""

    process: str                   # the sender's bus name (vehicle, speed, driving, move, gate)
    seq: int                       # ticks this process has sent before this one (0 after a restart)


ALL_MESSAGES: tuple[type[Message], ...] = (
    MoveCommand, MoveReply, MoveStatus, ClockEstimate, SteeringRequest, MaxSpeed, AdvanceAuthorization,
    DriveMode, DrivingStatus, SetSpeed, SpeedState, PedalCommand, SteerCommand, PowertrainCommand,
    SafetyDevices, VehicleStatus, WheelSpeed, GpsIns, Imu, Radar, Truth, Notice, NodeTick,
    Display, CanTraffic,
)
