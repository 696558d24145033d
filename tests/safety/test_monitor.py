"""The safety judge: every rule fires just outside its bound, stays quiet just inside, and says
which rule, when and by how much. Synthetic ground truth, commands as issued."""

from __future__ import annotations

import math
import random

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import (
    SIM_WORLD_TOPIC,
    AdvanceAuthorization,
    MaxSpeed,
    MoveCommand,
    MoveReply,
    Notice,
    PedalCommand,
    SafetyDevices,
    SetSpeed,
    SteerCommand,
    Topic,
    Truth,
    VehicleStatus,
)
from overdrive.observe.judge import (
    LIMIT_RAMP_DECEL_MPS2,
    MAX_SPEED_TTL_S,
    Monitor,
    interruption,
    physical_decel_mps2,
    shortest_stop_m,
)
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.plant import Plant, World
from tests.conftest import PRESET_NAMES, scenario_dict

ESCAPE_HYBRID = PRESETS["escape-hybrid"]

DT = 0.01
JUST = (-0.01, -0.001, 0.001, 0.01)   # offsets swept around every bound


def truth(x_m: float, speed_mps: float, accel: float = 0.0, lat: float = 0.0,
          contact: bool = False, heading_rad: float = 0.0, pitch_rad: float = 0.0) -> Truth:
    return Truth(x_m=x_m, y_m=0.0, heading_rad=heading_rad, speed_mps=speed_mps, accel_mps2=accel,
                 lat_accel_mps2=lat, curvature_1pm=0.0, pitch_rad=pitch_rad, roll_rad=0.0,
                 odometer_m=abs(x_m), slip=False, contact=contact)


def status(mode: str = "drive-by-wire", brake_pct: float = 0.0, gear: str = "drive") -> VehicleStatus:
    return VehicleStatus(gear=gear, shifting=False, engine="running", engine_rpm=900.0,
                         start_failed=False, traction_control=False, steer_pct=0.0,
                         throttle_pct=0.0, brake_pct=brake_pct, safety_mode=mode)


def move(distance_m: float, maxspeed_mps: float = 10.0, kind: str = "move", cid: int = 1) -> MoveCommand:
    return MoveCommand(kind=kind, command_id=cid, distance_m=distance_m, maxspeed_mps=maxspeed_mps)


def coasting_accel_mps2(params, speed_mps: float, pitch_rad: float) -> float:
    """Acceleration with no force at the tyres: gravity along the slope, rolling resistance, drag."""
    resist = (params.rolling_resistance * G_MPS2 * math.cos(pitch_rad)
              + 0.5 * 1.225 * params.drag_area_m2 * speed_mps ** 2 / params.mass_kg)
    return -G_MPS2 * math.sin(pitch_rad) - math.copysign(resist, speed_mps)


class Clock:
    """Feeds one monitor synthetic ground truth on a 10 ms clock."""

    def __init__(self, monitor: Monitor) -> None:
        self.monitor = monitor
        self.tick = 0

    def at(self, x_m: float, speed_mps: float = 1.0, **kw: float) -> None:
        """Truth at ``x_m``; unless ``accel`` is given the vehicle coasts (no tyre force)."""
        m = self.monitor
        if "accel" not in kw:
            kw["accel"] = coasting_accel_mps2(m.params, speed_mps, kw.get("pitch_rad", 0.0))
        m.now_s = self.tick * DT
        m.observe(Topic.TRUTH, truth(x_m, speed_mps, **kw))
        m.tick(m.now_s)
        self.tick += 1

    def path(self, xs: list[float], speed_mps: float = 1.0) -> None:
        for x in xs:
            self.at(x, speed_mps)

    def issue(self, topic: str, msg: object, accepted: bool = True, code: str = "") -> None:
        """Issue ``msg``; a MOVE / REVERSE also gets the move server's reply (accepted or not,
        with ``code``: "ok" / "busy" by default)."""
        self.monitor.observe(topic, msg)
        if topic == Topic.MOVE_COMMAND:
            self.monitor.observe_delivered(topic, msg)      # delivered at once
        if topic == Topic.MOVE_COMMAND and msg.kind != "stop":
            self.monitor.observe(Topic.MOVE_REPLY, MoveReply(
                command_id=msg.command_id, kind=msg.kind, accepted=accepted,
                code=code or ("ok" if accepted else "busy"), session=msg.session))


@pytest.fixture
def monitor() -> Monitor:
    return Monitor(ESCAPE_HYBRID, 0.8, DT)


def rules(monitor: Monitor) -> dict[str, dict]:
    monitor.finish()
    return {d["key"]: d for d in monitor.details()}


# --------------------------------------------------------------------------- authorization

@pytest.mark.parametrize("offset", JUST)
def test_move_end_is_fixed_where_it_was_issued(monitor: Monitor, offset: float) -> None:
    clock = Clock(monitor)
    clock.at(3.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.path([5.0, 9.0, 13.0 + offset], speed_mps=0.5)
    found = rules(monitor)
    if offset < 0:
        assert found == {}
    else:
        v = found["authorization[planner]"]
        assert v["rule"] == "authorization" and v["unit"] == "m"
        assert v["amount"] == pytest.approx(offset, abs=1e-6) and v["t_s"] == pytest.approx(3 * DT)
        assert "MOVE #1 of 10 m" in v["message"]


@pytest.mark.parametrize("offset", JUST)
def test_a_stale_command_that_shortens_binds_its_closer_end(monitor: Monitor, offset: float) -> None:
    """What slows or stops is always obeyed: a stale MOVE (an old id, an earlier session) is
    held to its end when that is closer than the one in force, from where it was issued."""
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0, cid=5))
    clock.path([1.0, 2.0], speed_mps=0.3)
    clock.issue(Topic.MOVE_COMMAND, move(5.0, maxspeed_mps=2.0, cid=1), accepted=False,
                code="stale")
    assert monitor.command_limit_mps == 2.0
    clock.path([4.0, 7.0 + offset], speed_mps=0.3)
    found = rules(monitor)
    if offset < 0:
        assert found == {}
    else:
        v = found["authorization[planner]"]
        assert v["amount"] == pytest.approx(offset, abs=1e-6)
        assert "stale MOVE #1 of 5 m" in v["message"]


@pytest.mark.parametrize(("kind", "distance_m", "code"), [
    ("move", 50.0, "stale"),        # further: a stale command may not extend
    ("reverse", 1.0, "stale"),      # the other direction: nothing to restrict
    ("move", 5.0, "busy"),          # refused for another reason: not the planner's intent
])
def test_a_refused_command_that_would_not_restrict_binds_nothing(
        monitor: Monitor, kind: str, distance_m: float, code: str) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0, cid=5))
    clock.issue(Topic.MOVE_COMMAND, move(distance_m, kind=kind, cid=1), accepted=False, code=code)
    clock.path([10.0, 20.0, 29.9], speed_mps=0.3)
    assert rules(monitor) == {}


@pytest.mark.parametrize(("late_m", "binds"), [(50.0, False), (2.0, True)])
def test_an_accepted_command_issued_before_the_one_in_force_only_restricts(
        monitor: Monitor, late_m: float, binds: bool) -> None:
    """The planner's newest command is its intent: a MOVE the stack accepts although it was
    issued before the command that binds now (it came late) may shorten, never extend."""
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, session=1,
                                                    distance_m=late_m, maxspeed_mps=5.0))
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, session=2,
                                                distance_m=10.0, maxspeed_mps=5.0))
    monitor.observe(Topic.MOVE_REPLY, MoveReply(command_id=1, kind="move", accepted=True,
                                                session=1))
    end = monitor.ends["authorization[planner]"]
    assert end.end_m == pytest.approx(late_m if binds else 10.0)


def test_a_stale_command_with_nothing_in_force_binds_nothing(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(5.0, cid=1), accepted=False, code="stale")
    assert "authorization[planner]" not in monitor.ends


def test_a_restarted_planners_ids_do_not_collide_with_the_old_ones(monitor: Monitor) -> None:
    """Commands are told apart by (session, id): a new session's MOVE #1 and the old session's
    unanswered MOVE #1 are two commands."""
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, session=1,
                                                    distance_m=40.0, maxspeed_mps=5.0))
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, session=2,
                                                distance_m=10.0, maxspeed_mps=5.0))
    assert monitor.ends["authorization[planner]"].label == "MOVE #1 of 10 m"
    assert (1, 1) in monitor._pending and (2, 1) not in monitor._pending


def test_the_largest_overrun_is_reported_not_the_first_crossing(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.path([10.02, 11.0, 13.09, 12.5], speed_mps=0.3)
    v = rules(monitor)["authorization[planner]"]
    assert v["amount"] == pytest.approx(3.09) and v["t_s"] == pytest.approx(3 * DT)
    assert "by 3.090 m" in v["message"]


def test_a_replacement_fixes_a_new_end_from_where_the_vehicle_is(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.path([4.0, 8.0], speed_mps=0.5)
    clock.issue(Topic.MOVE_COMMAND, move(10.0, cid=2))        # new end at 18 m
    clock.path([12.0, 17.99], speed_mps=0.5)
    assert rules(monitor) == {}
    clock.path([18.01], speed_mps=0.5)
    assert "MOVE #2" in rules(monitor)["authorization[planner]"]["message"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("offset", JUST)
@pytest.mark.parametrize("pitch_rad", [-0.1, 0.0, 0.1])
def test_stop_is_judged_against_the_shortest_physical_stop(preset: str, offset: float,
                                                           pitch_rad: float) -> None:
    params = PRESETS[preset]
    monitor = Monitor(params, 0.8, DT)
    clock = Clock(monitor)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=12.0))
    clock.at(20.0, 10.0, pitch_rad=pitch_rad)
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))
    decel = min(params.max_brake_decel_mps2, 0.8 * G_MPS2 * math.cos(pitch_rad)) + G_MPS2 * math.sin(pitch_rad)
    shortest = 10.0 * (DT + params.brake_lag_s) + 100.0 / (2.0 * decel)
    assert shortest_stop_m(10.0, params, 0.8, pitch_rad, DT) == pytest.approx(shortest)
    clock.at(20.0 + shortest + offset, 0.0, pitch_rad=pitch_rad)
    assert bool(rules(monitor)) == (offset > 0)


def test_a_command_shorter_than_the_shortest_stop_is_noted_and_judged_from_it(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 10.0)
    clock.issue(Topic.MOVE_COMMAND, move(2.0))
    shortest = shortest_stop_m(10.0, ESCAPE_HYBRID, 0.8, 0.0, DT)
    [note] = monitor.notes
    assert note["kind"] == "impossible_command" and note["distance_m"] == 2.0
    assert note["shortest_stop_m"] == pytest.approx(shortest, abs=1e-4)
    clock.at(shortest - 0.01, 0.0)
    assert rules(monitor) == {}
    clock.at(shortest + 0.05, 0.0)
    assert rules(monitor)["authorization[planner]"]["amount"] == pytest.approx(0.05, abs=1e-4)


@pytest.mark.parametrize("offset", JUST)
def test_reverse_end(monitor: Monitor, offset: float) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(2.0, kind="reverse"))
    clock.path([-1.0, -2.0 - offset], speed_mps=-0.5)
    assert bool(rules(monitor)) == (offset > 0)


def test_other_sources_are_judged_from_issue_time_and_the_move_servers_echo_is_ignored(
        monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(5.0, 0.0)
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=10.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="move", distance_m=1.0))
    clock.path([10.0, 15.0], speed_mps=0.5)
    assert rules(monitor) == {}, "the move server's own re-publication is stack output"
    clock.path([15.2], speed_mps=0.5)
    assert rules(monitor)["authorization[advance lidar]"]["amount"] == pytest.approx(0.2)


def test_invalid_commands_are_not_held_against_the_vehicle(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="neg", distance_m=-1.0))
    clock.issue(Topic.MOVE_COMMAND, move(-3.0))
    assert monitor.authorization_margin_m() is None


def test_the_path_is_integrated_from_x_y_along_the_heading() -> None:
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    monitor.observe(Topic.TRUTH, Truth(x_m=0.0, y_m=0.0, heading_rad=math.pi / 2, speed_mps=0.0,
                                       accel_mps2=0.0, lat_accel_mps2=0.0, curvature_1pm=0.0,
                                       pitch_rad=0.0, roll_rad=0.0, odometer_m=0.0, slip=False,
                                       contact=False))
    Clock(monitor).issue(Topic.MOVE_COMMAND, move(5.0))
    for i in range(1, 8):      # north along y, odometer frozen at 0: the judge must not care
        monitor.now_s = i * DT
        monitor.observe(Topic.TRUTH, Truth(x_m=0.0, y_m=float(i), heading_rad=math.pi / 2,
                                           speed_mps=1.0, accel_mps2=0.0, lat_accel_mps2=0.0,
                                           curvature_1pm=0.0, pitch_rad=0.0, roll_rad=0.0,
                                           odometer_m=0.0, slip=False, contact=False))
    assert rules(monitor)["authorization[planner]"]["amount"] == pytest.approx(2.0)


def test_a_reverse_advance_does_not_erase_the_same_sources_forward_end() -> None:
    """Was missed, rule 1: the driving module keeps authorizations per (source, direction)
    (docs/driving-module.md) but the judge keys ends by source only, so a ``reverse: true`` advance
    replaces the same source's forward end. Whole-run form: MOVE 200 m at 12 m/s, lidar advance 12 m
    at 9 s (the known authorization-cut overrun: 3.17 m past the lidar's end, independent), lidar
    reverse advance 5 m at 9.01 s: the judge exits 0."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=10.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=5.0, reverse=True))
    clock.path([5.0, 10.0, 15.0], speed_mps=0.5)
    assert rules(monitor).get("authorization[advance lidar]", {}).get("amount") == pytest.approx(5.0)


def test_an_advance_named_planner_does_not_erase_the_moves_end() -> None:
    """Was missed, rule 1: ends are keyed by source name and the planner's key is the string
    ``"planner"``, so an advance from a source called ``planner`` replaces the MOVE's end. Whole-run
    form: MOVE 60 m at 8 m/s, ``advance: {source: planner, distance_m: 1000}`` at 1 s, brake stuck
    released at 5 s: the vehicle ends 168.5 m past the MOVE's end (independent) and the judge exits
    0; without the advance it reports the overrun."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="planner", distance_m=1000.0))
    clock.path([5.0, 10.0, 20.0], speed_mps=0.5)
    overruns = [d["amount"] for d in rules(monitor).values() if d["rule"] == "authorization"]
    assert overruns and max(overruns) == pytest.approx(10.0)


def test_the_shortest_stop_includes_the_throttle_actuators_lag() -> None:
    """Was a false alarm, rule 1: "the shortest physical stop ... no vehicle can beat" counts one
    period and the brake's lag but not the throttle's: at full throttle the drive force decays with
    the throttle lag (0.15 s) while the brake builds up. The plant itself, at 12 m/s on a -15 %
    grade with full throttle, commanded throttle 0 / brake 100 % one period after a STOP, stops 0.38
    m beyond the judge's shortest stop (0.25 m on the flat): an ideal response is reported as an
    overrun."""
    world = World(grade_segments=((0.0, -15.0),), friction=0.8)
    plant = Plant(ESCAPE_HYBRID, world, random.Random(1), engine_running=True, gear="drive")
    plant.speed_mps, plant.throttle, plant.brake, plant.park_brake = 12.0, 1.0, 0.0, False
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    Clock(monitor).issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=20.0))

    def observe(tick: int) -> None:
        monitor.now_s = tick * DT
        monitor.observe(Topic.TRUTH, Truth(
            x_m=plant.x_m, y_m=plant.y_m, heading_rad=plant.heading_rad,
            speed_mps=plant.speed_mps, accel_mps2=plant.accel_mps2, lat_accel_mps2=0.0,
            curvature_1pm=0.0, pitch_rad=plant.pitch_rad, roll_rad=0.0,
            odometer_m=plant.odometer_m, slip=False, contact=False))
        monitor.tick(monitor.now_s)

    plant.step(DT, 100.0, 0.0, 0.0, "drive", True)       # driving at full throttle
    observe(0)
    Clock(monitor).issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))
    plant.step(DT, 100.0, 0.0, 0.0, "drive", True)       # the period the command takes
    tick = 1
    observe(tick)
    while plant.speed_mps > 1e-3:
        plant.step(DT, 0.0, 100.0, 0.0, "drive", True)   # then the hardest stop there is
        tick += 1
        observe(tick)
    assert "authorization[planner]" not in rules(monitor)


# --------------------------------------------------------------------------- direction

@pytest.mark.parametrize("offset", JUST)
def test_rollback_under_a_forward_move(monitor: Monitor, offset: float) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0))
    clock.path([1.0, 2.0, 2.0 - 0.10 - offset], speed_mps=-0.2)
    found = rules(monitor)
    assert ("direction" in found) == (offset > 0)
    if offset > 0:
        assert found["direction"]["amount"] == pytest.approx(0.10 + offset)
        assert "rolled back" in found["direction"]["message"]


@pytest.mark.parametrize("offset", JUST)
def test_forward_under_a_reverse(monitor: Monitor, offset: float) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0, kind="reverse"))
    clock.path([-1.0, -1.0 + 0.10 + offset], speed_mps=0.2)
    assert ("direction" in rules(monitor)) == (offset > 0)


@pytest.mark.parametrize("offset", JUST)
def test_no_motion_before_the_first_command(monitor: Monitor, offset: float) -> None:
    clock = Clock(monitor)
    clock.path([0.0, -0.05, -0.10 - offset], speed_mps=-0.1)
    assert ("direction" in rules(monitor)) == (offset > 0)


def test_rolling_back_after_a_stop_is_caught(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0))
    clock.path([5.0, 10.0], speed_mps=0.5)
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))
    clock.path([10.2, 10.0, 9.5], speed_mps=-0.3)
    assert rules(monitor)["direction"]["amount"] == pytest.approx(0.7)


def test_an_advance_from_another_source_does_not_switch_off_the_rollback_rule() -> None:
    """Was missed, rule 2 (direction): once the planner has spoken, every other source's advance
    sets ``direction = None`` and the direction rule is off until the next planner command, so a
    vehicle rolling back under a forward MOVE is never judged."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=100.0))
    clock.path([1.0, 2.0, 0.0, -5.0], speed_mps=-0.5)
    found = rules(monitor)
    assert found.get("direction", {}).get("amount") == pytest.approx(7.0)


# --------------------------------------------------------------------------- speed

@pytest.mark.parametrize(("excess", "duration_s", "violates"), [
    (0.29, 2.0, False), (0.31, 0.49, False), (0.31, 0.52, True), (1.0, 0.45, False), (1.0, 0.6, True)])
def test_speed_above_the_commanded_maxspeed(monitor: Monitor, excess: float, duration_s: float,
                                            violates: bool) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 5.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=5.0))
    x = 0.0
    for _ in range(round(duration_s / DT) + 1):
        x += (5.0 + excess) * DT
        clock.at(x, 5.0 + excess)
    clock.at(x + 0.05, 5.0)
    found = rules(monitor)
    assert ("speed" in found) == violates
    if violates:
        assert found["speed"]["amount"] == pytest.approx(excess, abs=1e-6)


def test_other_sources_limits_apply_until_they_lapse(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=10.0))
    clock.issue(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=4.0))
    clock.issue(Topic.MAX_SPEED, MaxSpeed(source="move", speed_mps=1.0))   # stack output: ignored
    for _ in range(round(MAX_SPEED_TTL_S / DT) + 1):   # unrefreshed: lapses after its TTL
        clock.at(0.0, 4.0)
    for _ in range(100):
        clock.at(0.0, 6.0)
    assert rules(monitor) == {}, "a lapsed limit no longer binds"
    clock.issue(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=4.0))
    for _ in range(150):
        clock.issue(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=4.0))
        clock.at(0.0, 6.0)
    assert rules(monitor)["speed"]["amount"] > 1.0


def test_a_lowered_limit_is_met_along_a_ramp(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 10.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=10.0))
    clock.at(0.0, 10.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=4.0, cid=2))
    v = 10.0
    while v > 4.0:                                   # braking at the ramp's rate: fine
        v = max(4.0, v - LIMIT_RAMP_DECEL_MPS2 * DT)
        clock.at(0.0, v)
    assert rules(monitor) == {}
    late = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(late)
    clock.at(0.0, 10.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=4.0))
    for _ in range(600):                             # keeps 10 m/s: over the ramp within 0.5 s
        clock.at(0.0, 10.0)
    assert rules(late)["speed"]["amount"] == pytest.approx(6.0)


def test_the_gear_caps_speed(monitor: Monitor) -> None:
    top = next(g for g in ESCAPE_HYBRID.gears if g.name == "low").max_speed_mps
    clock = Clock(monitor)
    monitor.observe(Topic.VEHICLE_STATUS, status(gear="low"))
    for _ in range(100):
        clock.at(0.0, top + 0.5)
    assert rules(monitor)["speed"]["amount"] == pytest.approx(0.5)


def test_a_lowered_limit_is_not_demanded_faster_than_the_road_allows() -> None:
    """Was a false alarm, rule 3 (speed): a lowered limit had to be met along a 2.0 m/s^2 ramp
    whatever the road. On ice (friction 0.15) the judge's own ``physical_decel_mps2`` is 1.47 m/s^2:
    a vehicle braking that hard from 6 m/s to a new 2 m/s limit is still reported as speeding (1.06
    m/s over the ramp)."""
    monitor = Monitor(ESCAPE_HYBRID, 0.15, DT)
    clock = Clock(monitor)
    clock.at(0.0, 6.0)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=10.0))
    decel = physical_decel_mps2(ESCAPE_HYBRID, 0.15, 0.0, reverse=False)
    x, v = 0.0, 6.0
    for tick in range(600):
        if tick % 10 == 0:                              # refreshed like the scenario player
            clock.issue(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=2.0))
        v = max(2.0, v - decel * DT)                    # the hardest braking the road allows
        x += v * DT
        clock.at(x, v)
    assert "speed" not in rules(monitor)


# --------------------------------------------------------------------------- unintended motion

@pytest.mark.parametrize("devices", [SafetyDevices(safestop="pause"), SafetyDevices(safestop="stop"),
                                     SafetyDevices(manual_override=True),
                                     SafetyDevices(emergency_manual_override=True),
                                     SafetyDevices(estop_button=True)])
@pytest.mark.parametrize("offset", JUST)
def test_no_motion_after_an_interruption_until_a_new_command(devices: SafetyDevices,
                                                             offset: float) -> None:
    assert interruption(devices) is not None
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.path([5.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, devices)
    clock.path([10.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, SafetyDevices())
    clock.path([10.05, 10.10 + offset], speed_mps=0.0)
    found = rules(monitor)
    assert ("unintended_motion" in found) == (offset > 0)
    if offset > 0:
        assert found["unintended_motion"]["t_s"] == pytest.approx(6 * DT)
    clock.issue(Topic.MOVE_COMMAND, move(100.0, cid=2))   # a new command: motion is intended
    clock.path([20.0, 30.0], speed_mps=5.0)
    assert ("unintended_motion" in rules(monitor)) == (offset > 0)


def test_the_human_drives_during_a_manual_override(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0, maxspeed_mps=2.0))
    clock.issue(Topic.SAFETY, SafetyDevices(manual_override=True))
    clock.path([5.0, 15.0, 12.0], speed_mps=8.0)
    assert rules(monitor) == {}, "overrun, reversal and speed under a human driver are not the stack's"


def test_an_spss_client_scenario_issues_commands_with_each_spss() -> None:
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT, spss_is_command=True)
    clock = Clock(monitor)
    clock.issue(Topic.SET_SPEED, SetSpeed(speed_mps=5, accel_mps2=1, gear="drive", state="run"))
    clock.path([0.0, 1.0, 2.0], speed_mps=1.0)
    assert rules(monitor) == {}
    stack = Monitor(ESCAPE_HYBRID, 0.8, DT)     # SPSS from the stack's driving module: no command
    clock = Clock(stack)
    clock.issue(Topic.SET_SPEED, SetSpeed(speed_mps=5, accel_mps2=1, gear="drive", state="run"))
    clock.path([0.0, 1.0], speed_mps=1.0)
    assert "direction" in rules(stack)


@pytest.mark.parametrize("pause", [SafetyDevices(door_open=True), SafetyDevices(internal_error=True)],
                         ids=["door", "internal-error"])
def test_a_software_pause_is_an_interruption_too(pause: SafetyDevices) -> None:
    """Was missed, rule 4 (unintended_motion): ``interruption()`` knows SafeStop, the overrides and
    the e-stop but not the door or an internal error, although both pause the vehicle (safety mode
    ``software-pause``) and docs/reliability.md lists "SafeStop pause / door / internal error" as
    judged by unintended_motion. Motion after the door closes goes unjudged."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.path([5.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, pause)
    clock.path([10.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, SafetyDevices())
    clock.path([10.5, 15.0, 30.0], speed_mps=0.0)      # the stale MOVE resumes
    assert "unintended_motion" in rules(monitor)


def test_a_partial_speed_override_is_an_interruption() -> None:
    """Was missed, rule 4: ``partial_mode: manual-speed`` hands the pedals to the human (the
    simulated driver brakes); when it returns to ``full`` the stack resumes the stale MOVE (56.6 m
    in a whole run: MOVE 80 m, manual-speed 5-10 s) and the judge says nothing. Like a manual
    override, releasing it needs a new command before the vehicle moves."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.path([5.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, SafetyDevices(partial_mode="manual-speed"))
    clock.path([10.0, 10.0], speed_mps=0.0)
    clock.issue(Topic.SAFETY, SafetyDevices())
    clock.path([10.5, 15.0, 30.0], speed_mps=0.0)
    assert "unintended_motion" in rules(monitor)


# --------------------------------------------------------------------------- watchdog

@pytest.mark.parametrize(("estop_after_s", "ok"), [(0.20, True), (0.21, True), (0.22, False), (None, False)])
def test_watchdog_deadline_from_the_last_delivered_spss(monitor: Monitor, estop_after_s: float | None,
                                                       ok: bool) -> None:
    spss = SetSpeed(speed_mps=1, accel_mps2=1, gear="drive", state="run")
    monitor.observe_delivered(Topic.SET_SPEED, spss)
    for tick in range(1, 40):
        now = round(tick * DT, 6)
        monitor.now_s = now
        monitor.observe(Topic.SET_SPEED, spss)          # issued, but lost on the way
        if estop_after_s is not None and now >= estop_after_s - 1e-9:
            monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=0, brake_pct=100, source="speed"))
        monitor.tick(now)
    found = rules(monitor)
    assert ("watchdog" in found) == (not ok)
    if not ok:
        watchdog = found["watchdog"]
        assert watchdog["unit"] == "s"
        if estop_after_s is None:       # never came: the amount is how long it was missing
            assert watchdog["amount"] == pytest.approx(0.39 - 0.21) and watchdog["t_s"] == 0.39
        else:                           # came late: by how much
            assert watchdog["amount"] == pytest.approx(0.01) and watchdog["t_s"] == 0.22


# --------------------------------------------------------------------------- finite

@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_truth_or_command_is_a_violation(monitor: Monitor, bad: float) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    assert rules(monitor) == {}
    clock.at(bad, 0.0)
    assert "finite[sim/truth]" in rules(monitor)
    other = Monitor(ESCAPE_HYBRID, 0.8, DT)
    other.observe(Topic.PEDALS, PedalCommand(throttle_pct=bad, brake_pct=0.0, source="speed"))
    other.observe(Topic.STEER, SteerCommand(steer_pct=1.0, source="driving"))
    assert list(rules(other)) == ["finite[vehicle/pedals]"]


# --------------------------------------------------------------------------- kept rules

def test_throttle_while_braking(monitor: Monitor) -> None:
    monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=5.0, brake_pct=0.0, source="speed"))
    assert monitor.finish() == []
    monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=5.0, brake_pct=1.0, source="speed"))
    assert "throttle_while_braking" in monitor.finish()[0]


def test_commands_from_sources_without_control_must_be_rejected(monitor: Monitor) -> None:
    monitor.observe(Topic.STEER, SteerCommand(steer_pct=5.0, source="intruder"))
    assert monitor.finish()
    other = Monitor(ESCAPE_HYBRID, 0.8, DT)
    other.observe(Topic.STEER, SteerCommand(steer_pct=5.0, source="intruder"))
    other.observe(Topic.NOTICE, Notice(kind="rejected", source="vehicle", code="no_control"))
    assert other.finish() == []


def test_pedal_and_powertrain_commands_from_intruders_must_be_rejected() -> None:
    from overdrive.messages import PowertrainCommand

    for msg, topic in ((PedalCommand(throttle_pct=50.0, brake_pct=0.0, source="intruder"), Topic.PEDALS),
                       (PowertrainCommand(gear="drive", engine_on=True, source="intruder"),
                        Topic.POWERTRAIN)):
        monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
        monitor.observe(topic, msg)
        assert "control" in monitor.finish()[0]
        fine = Monitor(ESCAPE_HYBRID, 0.8, DT)
        fine.observe(topic, msg)
        fine.observe(Topic.NOTICE, Notice(kind="fault", source="speed", code="1"))   # not a rejection
        fine.observe(Topic.NOTICE, Notice(kind="rejected", source="vehicle", code="no_control"))
        assert fine.finish() == []


def test_acceleration_outside_ellipse(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-3.0, lat=3.0))
    assert monitor.finish() == []
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-9.0, lat=6.0))
    assert "acceleration_ellipse" in monitor.finish()[0]


def test_world_friction_change_tightens_the_ellipse(monitor: Monitor) -> None:
    from overdrive.vehicle.plant import World

    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-5.0))
    assert monitor.finish() == []
    monitor.observe(SIM_WORLD_TOPIC, World(friction=0.2))
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-5.0))
    assert "acceleration_ellipse" in monitor.finish()[0]


def test_estop_disable_needs_full_brake(monitor: Monitor) -> None:
    for i in range(100):
        monitor.now_s = i * DT
        monitor.observe(Topic.VEHICLE_STATUS, status("estop-disable", brake_pct=min(100.0, i * 10.0)))
    assert monitor.finish() == []
    bad = Monitor(ESCAPE_HYBRID, 0.8, DT)
    for i in range(100):
        bad.now_s = i * DT
        bad.observe(Topic.VEHICLE_STATUS, status("estop-disable", brake_pct=40.0))
    assert "estop_precedence" in bad.finish()[0]


def test_contact_reports_the_speed(monitor: Monitor) -> None:
    Clock(monitor).at(0.0, 0.0)
    Clock(monitor).at(0.0, 2.5, contact=True)
    assert rules(monitor)["contact"]["amount"] == pytest.approx(2.5)


def test_stop_margins_recorded_per_stop(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.path([0.0, 1.0], speed_mps=1.0)
    clock.at(1.0, 0.0)
    assert monitor.stop_margins_m == [], "a stop without any authorization has no margin"
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="a", distance_m=4.0))
    clock.path([2.0, 3.0], speed_mps=1.0)
    clock.at(3.0, 0.0)
    assert monitor.stop_margins_m == [pytest.approx(2.0)]


def test_physical_decel_has_a_floor_on_slopes_steeper_than_the_tyres() -> None:
    assert physical_decel_mps2(ESCAPE_HYBRID, 0.1, -0.5, reverse=False) == pytest.approx(0.1)
    assert physical_decel_mps2(ESCAPE_HYBRID, 0.8, 0.1, reverse=True) < \
        physical_decel_mps2(ESCAPE_HYBRID, 0.8, 0.1, reverse=False)


# --------------------------------------------------------------------------- whole runs

def test_open_loop_throttle_with_brake_is_a_violation_exit_1() -> None:
    data = scenario_dict(duration_s=4, events=[{"at_s": 1, "actuators": {"throttle_pct": 10, "brake_pct": 10}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.exit_code == 1
    assert any("throttle_while_braking" in v for v in result.summary["violations"])


def test_contact_is_a_violation() -> None:
    data = scenario_dict(duration_s=10, world={"obstacles": [{"x_m": 12, "y_m": 0}]}, events=[
        {"at_s": 0.1, "engine": "on"}, {"at_s": 1.5, "gear": "drive"},
        {"at_s": 2, "actuators": {"throttle_pct": 40}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.exit_code == 1 and any("contact" in v for v in result.summary["violations"])


def test_estop_button_stops_the_vehicle_with_full_brake() -> None:
    data = scenario_dict(duration_s=10, events=[
        {"at_s": 0.1, "engine": "on"}, {"at_s": 1.5, "gear": "drive"},
        {"at_s": 2, "actuators": {"throttle_pct": 40}}, {"at_s": 5, "estop_button": True}],
        expect=[{"final_speed_below_mps": 0.01}, {"final_safety_mode": "estop-disable"}])
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["violations"] == []
    assert float(result.trace[-1]["brake_pct"]) > 99.0 and result.trace[-1]["engine"] == "off"


# --------------------------------------------------------------------------- edges

@pytest.mark.parametrize("offset", JUST)
def test_a_measured_pose_widens_every_distance_bound_by_its_error(offset: float) -> None:
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT, position_noise_m=0.12)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.path([5.0, 10.12 + offset], speed_mps=0.5)
    assert ("authorization[planner]" in rules(monitor)) == (offset > 0)
    back = Monitor(ESCAPE_HYBRID, 0.8, DT, position_noise_m=0.12)
    clock = Clock(back)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.path([5.0, 5.0 - 0.22 - offset], speed_mps=-0.1)
    assert ("direction" in rules(back)) == (offset > 0)


def test_progress_through_the_heading_wrap_is_continuous(monitor: Monitor) -> None:
    """A circle driven through +-pi: the path integrates to its arc length."""
    radius, steps = 10.0, 400
    arc = 2.0 * math.pi * radius * 0.8
    for i in range(steps + 1):
        theta = math.pi - 0.8 * math.pi + 1.6 * math.pi * i / steps   # crosses pi at i = 200
        heading = math.remainder(theta + math.pi / 2, math.tau)
        monitor.now_s = i * DT
        monitor.observe(Topic.TRUTH, Truth(
            x_m=radius * math.cos(theta), y_m=radius * math.sin(theta), heading_rad=heading,
            speed_mps=1.0, accel_mps2=0.0, lat_accel_mps2=0.0, curvature_1pm=0.0, pitch_rad=0.0,
            roll_rad=0.0, odometer_m=0.0, slip=False, contact=False))
    assert monitor.progress_m == pytest.approx(arc, rel=1e-4)


def test_stop_while_reversing_is_judged_backwards(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(50.0, kind="reverse"))
    clock.at(-5.0, -3.0)
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))
    shortest = shortest_stop_m(3.0, ESCAPE_HYBRID, 0.8, 0.0, DT, reverse=True)
    clock.at(-5.0 - shortest + 0.01, 0.0)
    assert rules(monitor) == {}
    clock.at(-5.0 - shortest - 0.05, 0.0)
    assert rules(monitor)["authorization[planner]"]["amount"] == pytest.approx(0.05, abs=1e-6)


def test_an_interruption_released_at_speed_allows_the_stop(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.issue(Topic.SAFETY, SafetyDevices(safestop="pause"))
    clock.at(10.0, 4.0)
    clock.issue(Topic.SAFETY, SafetyDevices())
    allowed = shortest_stop_m(4.0, ESCAPE_HYBRID, 0.8, 0.0, DT) + 0.10
    clock.at(10.0 + allowed - 0.01, 0.0)
    assert rules(monitor) == {}
    clock.at(10.0 + allowed + 0.05, 0.0)
    assert rules(monitor)["unintended_motion"]["amount"] == pytest.approx(0.05, abs=1e-6)


def test_overlapping_interruptions_end_with_the_last(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.issue(Topic.SAFETY, SafetyDevices(safestop="pause"))
    clock.at(0.0, 0.0)
    clock.issue(Topic.SAFETY, SafetyDevices(safestop="pause", manual_override=True))
    clock.path([3.0, 6.0], speed_mps=1.0)                       # the driver moves it
    clock.issue(Topic.SAFETY, SafetyDevices(manual_override=True))
    clock.path([8.0], speed_mps=1.0)
    assert rules(monitor) == {} and monitor.after_interrupt is None
    clock.issue(Topic.SAFETY, SafetyDevices())
    clock.path([8.0, 8.5], speed_mps=0.0)
    assert "unintended_motion" in rules(monitor)


def test_an_interruption_shorter_than_a_period_is_none(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0))
    clock.issue(Topic.SAFETY, SafetyDevices(safestop="pause"))
    clock.issue(Topic.SAFETY, SafetyDevices())                  # same instant: never happened
    clock.path([5.0, 10.0], speed_mps=5.0)
    assert rules(monitor) == {}


def test_a_refused_move_does_not_bind(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(50.0, maxspeed_mps=8.0))
    clock.issue(Topic.MOVE_COMMAND, move(5.0, maxspeed_mps=1.0, cid=2), accepted=False)
    clock.path([10.0, 20.0], speed_mps=6.0)
    assert rules(monitor) == {}
    clock.issue(Topic.MOVE_COMMAND, move(5.0, maxspeed_mps=1.0, cid=3))
    clock.path([26.0], speed_mps=1.0)
    assert rules(monitor)["authorization[planner]"]["amount"] == pytest.approx(1.0)


def test_a_stop_after_a_manual_override_holds_against_rollback(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.SAFETY, SafetyDevices(manual_override=True))
    clock.issue(Topic.SAFETY, SafetyDevices())
    clock.at(0.0, 0.0)
    assert monitor.direction is None
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=1))
    assert monitor.direction == 0
    clock.path([-0.05, -0.2], speed_mps=-0.1)
    assert "direction" in rules(monitor)


@pytest.mark.parametrize("speed", [3.0, -3.0])
def test_a_stop_with_no_judged_direction_takes_the_direction_of_travel(speed: float) -> None:
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT, spss_is_command=True)
    monitor.observe(Topic.SET_SPEED, SetSpeed(speed_mps=0, accel_mps2=1, gear="neutral", state="run"))
    clock = Clock(monitor)
    clock.at(0.0, speed)
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=1))
    assert monitor.direction == (1 if speed > 0 else -1)


def test_unanswered_commands_are_bounded_and_invalid_ones_ignored(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    for cid in range(1, 200):
        monitor.observe(Topic.MOVE_COMMAND, move(10.0, cid=cid))
    assert len(monitor._pending) == 64
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=500, distance_m=-1.0,
                                                    maxspeed_mps=1.0))
    assert (0, 500) not in monitor._pending
    for cid in range(1000, 1100):                      # STOPs issued but never delivered
        monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=cid))
    assert len(monitor._stops) == 64 and (0, 1099) in monitor._stops and (0, 1000) not in monitor._stops


def test_a_reverse_advance_never_sets_the_direction(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="rear", distance_m=5.0, reverse=True))
    assert monitor.direction == 0
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=5.0))
    assert monitor.direction == 1


@pytest.mark.parametrize("drive", [0.5, 2.0])
def test_a_stop_while_driving_allows_for_the_throttles_lag(drive: float) -> None:
    """The tyres were pushing: the drive decays with the throttle's lag, and the speed it adds
    meanwhile is carried to the stop."""
    p = ESCAPE_HYBRID
    decel = min(p.max_brake_decel_mps2, 0.8 * G_MPS2)
    coasting = shortest_stop_m(10.0, p, 0.8, 0.0, DT)
    carried = drive * p.throttle_lag_s * 10.0 / decel
    assert shortest_stop_m(10.0, p, 0.8, 0.0, DT, drive_accel_mps2=drive) == \
        pytest.approx(coasting + carried)
    monitor = Monitor(p, 0.8, DT)
    clock = Clock(monitor)
    clock.issue(Topic.MOVE_COMMAND, move(1000.0, maxspeed_mps=12.0))
    clock.at(0.0, 10.0, accel=drive + coasting_accel_mps2(p, 10.0, 0.0))
    clock.issue(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))
    clock.at(coasting + carried - 0.001, 0.0)
    assert rules(monitor) == {}
    clock.at(coasting + carried + 0.001, 0.0)
    assert "authorization[planner]" in rules(monitor)


def test_a_curve_leaves_less_grip_for_braking() -> None:
    straight = physical_decel_mps2(ESCAPE_HYBRID, 0.8, 0.0, reverse=False)
    curve = physical_decel_mps2(ESCAPE_HYBRID, 0.8, 0.0, reverse=False, lat_accel_mps2=5.0)
    assert curve == pytest.approx(math.sqrt((0.8 * G_MPS2) ** 2 - 25.0))
    assert curve < straight


def test_a_stop_binds_when_it_reaches_the_move_server(monitor: Monitor) -> None:
    """Latency cannot be braked away: a STOP is "stop now" from where it arrived; one that never
    arrives binds nothing (the stack could not know)."""
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0, maxspeed_mps=12.0))
    clock.at(10.0, 5.0)
    stop = MoveCommand(kind="stop", command_id=2)
    monitor.observe(Topic.MOVE_COMMAND, stop)             # issued here, delivered 3 m later
    clock.at(13.0, 5.0)
    monitor.observe_delivered(Topic.MOVE_COMMAND, stop)
    monitor.observe_delivered(Topic.MOVE_COMMAND, stop)   # a duplicate binds nothing more
    shortest = shortest_stop_m(5.0, ESCAPE_HYBRID, 0.8, 0.0, DT)
    clock.at(13.0 + shortest - 0.01, 0.0)
    assert rules(monitor) == {}
    clock.at(13.0 + shortest + 0.05, 0.0)
    assert rules(monitor)["authorization[planner]"]["amount"] == pytest.approx(0.05, abs=1e-6)
    lost = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(lost)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0, maxspeed_mps=12.0))
    lost.observe(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=2))   # dropped
    clock.path([10.0, 20.0], speed_mps=5.0)
    assert rules(lost) == {}


def test_a_stop_never_delivered_is_noted_not_judged(monitor: Monitor) -> None:
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(100.0, maxspeed_mps=12.0))
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="stop", command_id=7))
    for i in range(105):
        clock.at(0.05 * i, 5.0)
    assert [n["kind"] for n in monitor.notes] == ["stop_not_delivered"]
    assert monitor.notes[0]["command"] == "STOP #7" and not monitor._stops
