"""Scenario files: schema, validation and loading.

The schema is a set of frozen msgspec Structs, so a file is type-checked, range-checked and
checked for unknown keys in one pass. Every number carries bounds, which also rejects NaN and
infinities. Errors become ``ScenarioError`` with the file, the field path and the reason.
The full reference is docs/scenarios.md.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec

from overdrive.dynamics.vehicle_params import VehicleParams, VehicleSpecError, vehicle_to_data
from overdrive.scenario.safe_yaml import (
    MAX_DEPTH,
    MAX_JSON_BYTES,
    MAX_NODES,
    InputError,
    load_json,
    load_yaml,
    one_line,
    read_text,
)
from overdrive.scenario.vehicles import VehicleFileError, names_a_file, vehicle_from_spec

# Bounds: generous physical limits, chosen to catch typos and unit mistakes, not to restrict use.
Time = Annotated[float, msgspec.Meta(ge=0.0, le=86_400.0)]          # within a day
Duration = Annotated[float, msgspec.Meta(gt=0.0, le=86_400.0)]
Distance = Annotated[float, msgspec.Meta(ge=0.0, le=100_000.0)]     # 100 km per command
Coordinate = Annotated[float, msgspec.Meta(ge=-100_000.0, le=100_000.0)]
Speed = Annotated[float, msgspec.Meta(ge=0.0, le=70.0)]              # above any road vehicle here
Accel = Annotated[float, msgspec.Meta(gt=0.0, le=20.0)]              # 2 g
Curvature = Annotated[float, msgspec.Meta(ge=-10.0, le=10.0)]        # 0.1 m radius: beyond any car
Percent = Annotated[float, msgspec.Meta(ge=0.0, le=100.0)]
SignedPercent = Annotated[float, msgspec.Meta(ge=-100.0, le=100.0)]
Grade = Annotated[float, msgspec.Meta(ge=-100.0, le=100.0)]          # 45 degrees
Friction = Annotated[float, msgspec.Meta(gt=0.0, le=1.5)]            # racing slicks reach ~1.5
Fraction = Annotated[float, msgspec.Meta(ge=0.0, le=1.0)]
Scale = Annotated[float, msgspec.Meta(ge=0.0, le=2.0)]
Name = Annotated[str, msgspec.Meta(min_length=1, max_length=64)]


class Spec(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    pass


class GradeSegment(Spec, frozen=True):
    from_m: Coordinate
    grade_percent: Grade


class Obstacle(Spec, frozen=True):
    x_m: Coordinate
    y_m: Coordinate


class WorldSpec(Spec, frozen=True):
    grade_percent: Grade | list[GradeSegment] = 0.0
    friction: Friction = 0.8
    obstacles: list[Obstacle] = []
    roughness_mps2: Annotated[float, msgspec.Meta(ge=0.0, le=20.0)] = 0.0


class MoveSpec(Spec, frozen=True):
    distance_m: Distance
    maxspeed_mps: Speed
    curvature_1pm: Curvature = 0.0


class Empty(Spec, frozen=True):
    pass


RESERVED_SOURCE = "move"
"""The move server's own source name: its authorizations and limits are the stack's output (the
safety judge tells them apart by that name), so a scenario's other sources may not use it."""


class AdvanceSpec(Spec, frozen=True):
    source: Name
    distance_m: Distance
    reverse: bool = False


class MaxSpeedSpec(Spec, frozen=True):
    source: Name
    speed_mps: Speed


class SetSpeedSpec(Spec, frozen=True):
    speed_mps: Speed
    accel_mps2: Accel
    gear: Name
    state: Name
    fault: Annotated[int, msgspec.Meta(ge=0, le=65535)] = 0


class SteerSpec(Spec, frozen=True):
    curvature_1pm: Curvature


class ActuatorsSpec(Spec, frozen=True):
    throttle_pct: Percent = 0.0
    brake_pct: Percent = 0.0
    steer_pct: SignedPercent = 0.0


Channel = Literal["set_speed", "steering", "pedals", "radar", "gps", "imu", "wheel_speed",
                  "speed_state", "move", "advance", "max_speed", "jaus"]
LinkDirection = Literal["both", "to_vehicle", "from_vehicle"]
"""Which way a fault on channel ``jaus`` acts: ``to_vehicle`` the stack's datagrams to the XGV
only, ``from_vehicle`` the XGV's to the stack only (a link cut one way: the XGV hears nothing
while the stack still hears it, or the reverse). Only channel ``jaus`` has directions."""


class DropSpec(Spec, frozen=True):
    """Also the body of ``duplicate`` and ``reorder``: the fault holds for ``for_s``."""

    channel: Channel
    for_s: Duration
    direction: LinkDirection | None = None   # channel jaus only; None: both ways


class DelaySpec(Spec, frozen=True):
    channel: Channel
    for_s: Duration
    delay_s: Annotated[float, msgspec.Meta(gt=0.0, le=60.0)]
    direction: LinkDirection | None = None


class LossSpec(Spec, frozen=True):
    """Each message on the channel lost independently with probability ``fraction`` for
    ``for_s`` (drawn from the scenario's seed: a run repeats exactly)."""

    channel: Channel
    for_s: Duration
    fraction: Annotated[float, msgspec.Meta(gt=0.0, le=1.0)]
    direction: LinkDirection | None = None


class SensorFaultSpec(Spec, frozen=True):
    name: Literal["gps", "imu", "wheel_speed", "radar"]
    fault: Literal["freeze", "noise", "dropout"]
    for_s: Duration
    sigma: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)] = 1.0   # noise, in the sensor's units


SensorQuantity = Literal["gps_position", "gps_heading", "gps_speed", "wheel_speed", "imu_accel",
                         "imu_yaw_rate"]
"""What a ``sensor_error`` corrupts; its bias is in that quantity's unit (m, rad, m/s, m/s,
m/s^2, rad/s)."""


class SensorErrorSpec(Spec, frozen=True):
    """A sensor reads wrong from this event on (issue 30): ``reading = scale x true + bias +
    drift_per_s x (t - at_s)``. A ``bias`` alone is a step; ``drift_per_s`` a slow drift. For
    ``gps_position`` bias and drift are a distance along ``direction_rad`` (counter-clockwise
    from the vehicle's heading at the event: pi/2 is a step to the left) and ``scale`` must be
    1. A GPS/INS speed error also runs the receiver's odometer (it integrates its velocity). A
    later ``sensor_error`` on the same quantity replaces it (bias 0: healthy again)."""

    quantity: SensorQuantity
    bias: Annotated[float, msgspec.Meta(ge=-100.0, le=100.0)] = 0.0
    drift_per_s: Annotated[float, msgspec.Meta(ge=-10.0, le=10.0)] = 0.0
    scale: Annotated[float, msgspec.Meta(ge=0.5, le=2.0)] = 1.0
    direction_rad: Annotated[float, msgspec.Meta(ge=-7.0, le=7.0)] = 0.0
    for_s: Duration | None = None


class GpsStatusSpec(Spec, frozen=True):
    """The receiver's solution status changes (an RTK fix dropping to float): it reports
    ``solution`` and ``position_sigma_m``, and its position noise becomes that sigma."""

    solution: Literal["rtk_fixed", "rtk_float", "dgps", "single", "dead_reckoning", "none"]
    position_sigma_m: Annotated[float, msgspec.Meta(ge=0.0, le=100.0)]


LagScale = Annotated[float, msgspec.Meta(ge=0.1, le=50.0)]


class PedalFaultSpec(Spec, frozen=True):
    effectiveness: Scale = 1.0        # weak: force per unit of effort
    lag_scale: LagScale = 1.0         # slow: actuator time constant multiplied
    stuck: bool = False               # stuck: the actuator holds its position


class SteeringFaultSpec(Spec, frozen=True):
    rate_scale: Scale = 1.0           # slow / weak: steering rate multiplied
    stuck: bool = False


class ParkBrakeFaultSpec(Spec, frozen=True):
    failed: bool = False              # failed: the parking brake gives nothing, moving or at rest


class ActuatorFaultSpec(Spec, frozen=True):
    throttle: PedalFaultSpec | None = None
    brake: PedalFaultSpec | None = None
    steering: SteeringFaultSpec | None = None
    park_brake: ParkBrakeFaultSpec | None = None


class WorldChangeSpec(Spec, frozen=True):
    friction: Friction | None = None
    obstacles: list[Obstacle] | None = None


class PlannerRestartSpec(Spec, frozen=True):
    """The planner restarts: its command ids start again at 1. ``new_session``: it says so with
    a new session (false: a planner that sends no session, as before sessions existed)."""

    new_session: bool = True


class PlannerClockSpec(Spec, frozen=True):
    """The planner's clock from this event on (it runs on another machine): ``offset_s`` ahead
    of the stack's (negative: behind), drifting ``drift_ppm`` parts per million (+100: it gains
    0.1 ms a second). ``echo``: its commands echo the newest MoveStatus it received, so the move
    server measures the offset (false: a planner that does not)."""

    offset_s: Annotated[float, msgspec.Meta(ge=-10.0, le=10.0)] = 0.0
    drift_ppm: Annotated[float, msgspec.Meta(ge=-10_000.0, le=10_000.0)] = 0.0
    echo: bool = True


StallNode = Literal["move", "driving", "speed"]
"""The stack's nodes a ``stall`` event may freeze (the vehicle's physics never stalls)."""


class StallSpec(Spec, frozen=True):
    """The node is not stepped for ``for_s`` and its inbox accumulates, as a process stopped
    (SIGSTOP) then resumed (SIGCONT): on resume it steps once with everything queued."""

    node: StallNode
    for_s: Annotated[float, msgspec.Meta(gt=0.0, le=60.0)]


class EventSpec(Spec, frozen=True):
    """One timed event: ``at_s`` plus exactly one kind."""

    at_s: Time
    move: MoveSpec | None = None
    reverse: MoveSpec | None = None
    stop: Empty | None = None
    advance: AdvanceSpec | None = None
    max_speed: MaxSpeedSpec | None = None
    set_speed: SetSpeedSpec | None = None
    steer: SteerSpec | None = None
    actuators: ActuatorsSpec | None = None
    gear: Name | None = None
    engine: Literal["on", "off"] | None = None
    safestop: Literal["run", "pause", "stop"] | None = None
    manual_override: bool | None = None
    emergency_manual_override: bool | None = None
    estop_button: bool | None = None
    internal_error: bool | None = None
    door: Literal["open", "closed"] | None = None
    partial_mode: Literal["full", "manual-steering", "manual-speed"] | None = None
    drop: DropSpec | None = None
    loss: LossSpec | None = None
    delay: DelaySpec | None = None
    duplicate: DropSpec | None = None
    reorder: DropSpec | None = None
    sensor: SensorFaultSpec | None = None
    sensor_error: SensorErrorSpec | None = None
    gps_status: GpsStatusSpec | None = None
    actuator: ActuatorFaultSpec | None = None
    engine_stall: Empty | None = None
    world: WorldChangeSpec | None = None
    planner_restart: PlannerRestartSpec | None = None
    planner_clock: PlannerClockSpec | None = None
    stall: StallSpec | None = None

    @property
    def kind(self) -> str:
        return next(f for f in self.__struct_fields__[1:] if getattr(self, f) is not None)

    @property
    def body(self) -> Any:
        return getattr(self, self.kind)


EVENT_KINDS = EventSpec.__struct_fields__[1:]
OPEN_LOOP_KINDS = frozenset({"actuators", "gear", "engine"})
SPEED_KINDS = frozenset({"set_speed"})
DRIVING_KINDS = frozenset({"advance", "max_speed", "steer"})
MOVE_KINDS = frozenset({"move", "reverse", "stop", "planner_restart", "planner_clock"})


class Window(Spec, frozen=True):
    kind: Name
    within_s: tuple[Time, Time] | None = None
    match: dict[str, str | float | int | bool] = {}


class PositionSpec(Spec, frozen=True):
    x_m: Coordinate
    y_m: Coordinate
    tolerance_m: Annotated[float, msgspec.Meta(gt=0.0, le=1000.0)]


Bound = Annotated[float, msgspec.Meta(ge=-1e6, le=1e6)]


class ExpectSpec(Spec, frozen=True):
    """One expectation; exactly one field set. See docs/scenarios.md."""

    final_speed_below_mps: Bound | None = None
    odometer_between_m: tuple[Bound, Bound] | None = None
    final_position: PositionSpec | None = None
    peak_speed_below_mps: Bound | None = None
    peak_accel_below_mps2: Bound | None = None
    peak_decel_below_mps2: Bound | None = None
    peak_lat_accel_below_mps2: Bound | None = None
    event: Window | None = None
    no_event: Window | None = None
    speed_state_reached: Name | None = None
    safety_mode_reached: Name | None = None
    final_speed_state: Name | None = None
    final_safety_mode: Name | None = None
    no_contact: bool | None = None

    @property
    def kind(self) -> str:
        return next(f for f in self.__struct_fields__ if getattr(self, f) is not None)


FrictionRange = tuple[Friction, Friction]
GradeRange = tuple[Grade, Grade]


SweptFault = Literal[
    "sensor_freeze", "sensor_dropout", "sensor_noise", "throttle_stuck", "throttle_weak",
    "brake_weak", "brake_slow", "brake_stuck", "steering_stuck", "steering_slow", "delay_move",
    "delay_advance", "reorder_move",
]
SWEPT_FAULTS: tuple[str, ...] = SweptFault.__args__   # type: ignore[attr-defined]


class FaultSweepSpec(Spec, frozen=True):
    """Faults a sweep draws: with ``probability`` one fault of ``kinds``, at a time in ``at_s``."""

    probability: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 1.0
    kinds: Annotated[tuple[SweptFault, ...], msgspec.Meta(min_length=1)] = SWEPT_FAULTS
    at_s: tuple[Time, Time] = (1.0, 10.0)


class SweepSpec(Spec, frozen=True):
    """Sampling ranges for ``overdrive sweep`` (uniform); ``null`` keeps the file's value."""

    friction: FrictionRange | None = (0.5, 1.0)
    grade_percent: GradeRange | None = (-5.0, 5.0)
    obstacle_jitter_m: Annotated[float, msgspec.Meta(ge=0.0, le=1000.0)] = 3.0
    event_jitter_s: Annotated[float, msgspec.Meta(ge=0.0, le=3600.0)] = 0.5
    drop_expectations: bool = False
    faults: FaultSweepSpec | None = None


class ScenarioFile(Spec, frozen=True):
    name: Name
    description: str = ""
    vehicle: str | dict[str, Any] = "escape-hybrid"
    interface: Literal["embedded", "jaus"] = "embedded"
    control: Literal["wrench", "motion-profile"] = "wrench"
    start: Literal["parked", "ready"] = "parked"
    planner_machine: Literal["same", "separate"] = "same"   # the planner's clock (move_clock)
    friction_max: Friction | None = None   # the stack's friction estimate never loosens above
                                           # this (issue 31); None: world.friction at start
    seed: Annotated[int, msgspec.Meta(ge=0, le=2**63 - 1)] = 1
    duration_s: Duration = 60.0
    world: WorldSpec = WorldSpec()
    events: list[EventSpec] = []
    expect: list[ExpectSpec] = []
    sweep: SweepSpec = SweepSpec()


class Scenario(msgspec.Struct, frozen=True):
    """A validated scenario: the file's content plus resolved vehicle parameters."""

    spec: ScenarioFile
    vehicle: VehicleParams
    source: str
    events: tuple[EventSpec, ...]     # sorted by time, stable for equal times

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def event_kinds(self) -> frozenset[str]:
        return frozenset(e.kind for e in self.events)


class ScenarioError(ValueError):
    """An invalid scenario: ``str()`` is ``"<source>: <field>: <reason>"``."""

    def __init__(self, source: str, field: str, reason: str) -> None:
        self.source, self.field, self.reason = source, field, reason
        message = f"{source}: {field}: {reason}" if field else f"{source}: {reason}"
        super().__init__(one_line(message))


_AT = re.compile(r"^(?P<msg>.*?)(?: - at `\$(?P<path>[^`]*)`)?$", re.S)
_UNKNOWN = re.compile(r"Object contains unknown field `(?P<field>[^`]+)`")
_MISSING = re.compile(r"Object missing required field `(?P<field>[^`]+)`")


def _split_validation_error(exc: msgspec.ValidationError) -> tuple[str, str]:
    m = _AT.match(str(exc))
    assert m is not None
    msg, path = m.group("msg"), (m.group("path") or "").lstrip(".")
    for pattern, reason in ((_UNKNOWN, "unknown field"), (_MISSING, "required field missing")):
        found = pattern.match(msg)
        if found:
            field = found.group("field")
            return (f"{path}.{field}" if path else field), reason
    return path or "(top level)", msg[0].lower() + msg[1:] if msg else "invalid"


def _check_tree(data: Any, source: str) -> None:
    """Reject NaN/inf anywhere in raw data (bounds catch most, this catches the rest), nesting
    deeper than ``MAX_DEPTH`` and more than ``MAX_NODES`` values.

    A loop over an explicit stack, counting what it visits: data built in Python may share
    sub-lists (what an alias bomb loads to), which a plain recursive walk visits exponentially
    often and deep data overflows it. Nulls are not counted: the launcher's JSON copy of a
    scenario spells out every absent optional field as null (~25 per event).
    """
    pending: list[tuple[Any, str, int]] = [(data, "", 0)]
    visited = 0
    while pending:
        value, path, depth = pending.pop()
        visited += value is not None
        if visited > MAX_NODES:
            raise ScenarioError(source, "", f"more than {MAX_NODES} values")
        where = path or "(top level)"
        if isinstance(value, float) and not math.isfinite(value):
            raise ScenarioError(source, where, f"must be a finite number, got {value}")
        if isinstance(value, (dict, list)) and depth >= MAX_DEPTH:
            raise ScenarioError(source, where, f"nested deeper than {MAX_DEPTH} levels")
        if isinstance(value, dict):
            pending.extend((v, f"{path}.{k}" if path else str(k), depth + 1)
                           for k, v in reversed(value.items()))
        elif isinstance(value, list):
            pending.extend((v, f"{path}[{i}]", depth + 1)
                           for i, v in reversed(list(enumerate(value))))


def parse_scenario(data: Any, source: str = "<scenario>",
                   base_dir: str | Path | None = None) -> Scenario:
    """Validate raw data (as loaded from YAML) into a Scenario, or raise ScenarioError.

    A vehicle file the scenario names is read from ``base_dir`` (the scenario file's folder;
    default the working directory) and its parameters replace the name in ``spec.vehicle``
    (a whole vehicle inline), so a copy of the spec needs neither the file nor the folder.
    """
    if not isinstance(data, dict):
        raise ScenarioError(source, "", "a scenario must be a mapping of keys to values")
    _check_tree(data, source)
    try:
        spec = msgspec.convert(data, ScenarioFile, strict=True)
    except msgspec.ValidationError as exc:
        field, reason = _split_validation_error(exc)
        raise ScenarioError(source, field, reason) from None
    for i, event in enumerate(spec.events):
        present = [f for f in EVENT_KINDS if getattr(event, f) is not None]
        if len(present) != 1:
            what = "no event kind" if not present else f"several event kinds ({', '.join(present)})"
            raise ScenarioError(source, f"events[{i}]",
                                f"{what}; each event needs at_s and exactly one of: "
                                + ", ".join(EVENT_KINDS))
        other = event.advance or event.max_speed
        if other is not None and other.source == RESERVED_SOURCE:
            raise ScenarioError(source, f"events[{i}].{event.kind}.source",
                                f"{RESERVED_SOURCE!r} is reserved for the move server's own "
                                "authorizations and limits; name the source otherwise")
        if (isinstance(event.body, DropSpec | DelaySpec | LossSpec)
                and event.body.direction is not None and event.body.channel != "jaus"):
            raise ScenarioError(source, f"events[{i}].{event.kind}.direction",
                                f"only channel jaus has directions (a bus channel "
                                f"{event.body.channel!r} carries one way already)")
        if (event.sensor_error is not None and event.sensor_error.quantity == "gps_position"
                and event.sensor_error.scale != 1.0):
            raise ScenarioError(source, f"events[{i}].sensor_error.scale",
                                "a position has no scale factor (use bias, drift_per_s and "
                                "direction_rad)")
        if event.at_s > spec.duration_s:
            raise ScenarioError(source, f"events[{i}].at_s",
                                f"{event.at_s} s is after the end of the run (duration_s {spec.duration_s})")
    for i, exp in enumerate(spec.expect):
        present = [f for f in ExpectSpec.__struct_fields__ if getattr(exp, f) is not None]
        if len(present) != 1:
            raise ScenarioError(source, f"expect[{i}]", "each expectation needs exactly one kind")
    try:
        vehicle = vehicle_from_spec(spec.vehicle, "." if base_dir is None else base_dir)
    except VehicleSpecError as exc:
        field = f"vehicle.{exc.field}" if isinstance(spec.vehicle, dict) and exc.field else "vehicle"
        raise ScenarioError(source, field, exc.reason) from None
    except VehicleFileError as exc:
        raise ScenarioError(f"{source}: vehicle file {exc.path}", exc.field, exc.reason) from None
    if names_a_file(spec.vehicle):
        spec = msgspec.structs.replace(spec, vehicle=vehicle_to_data(vehicle))
    for i, event in enumerate(spec.events):
        if event.set_speed is not None and event.set_speed.gear not in vehicle.gear_names:
            raise ScenarioError(source, f"events[{i}].set_speed.gear",
                                f"{vehicle.preset} has no gear {event.set_speed.gear!r} "
                                f"(gears: {', '.join(vehicle.gear_names)})")
        if event.gear is not None and event.gear not in vehicle.gear_names:
            raise ScenarioError(source, f"events[{i}].gear",
                                f"{vehicle.preset} has no gear {event.gear!r} "
                                f"(gears: {', '.join(vehicle.gear_names)})")
    events = tuple(sorted(spec.events, key=lambda e: e.at_s))
    return Scenario(spec=spec, vehicle=vehicle, source=source, events=events)


def read_scenario_data(path: str | Path) -> Any:
    """A scenario file's raw data: YAML, or JSON when it ends in ``.json`` (what the launcher
    hands its nodes). Every failure is a ``ScenarioError``; the limits are in ``safe_yaml``."""
    path = Path(path)
    try:
        if path.suffix == ".json":
            return load_json(read_text(path, MAX_JSON_BYTES))
        return load_yaml(read_text(path))
    except InputError as exc:
        raise ScenarioError(str(path), exc.field, exc.reason) from None


def load_scenario(path: str | Path) -> Scenario:
    """Read and validate a scenario file (a vehicle file it names: from the file's folder)."""
    return parse_scenario(read_scenario_data(path), str(path), Path(path).parent)


def load_scenario_text(text: str, source: str) -> Scenario:
    """Validate scenario YAML held in memory (e.g. the copy inside a run.mcap)."""
    try:
        data = load_yaml(text)
    except InputError as exc:
        raise ScenarioError(source, exc.field, exc.reason) from None
    return parse_scenario(data, source)
