"""Red team of the issue-15 judge (``overdrive.observe.judge``): each test failed against the
first version of the judge because of a defect of the judge, not of the stack, and is kept.

- false negatives: unsafe runs the judge passes, or whose amount it understates;
- false positives: runs the judge fails although the vehicle did what was physically possible
  or what the stack documents.

Figures in the docstrings come from an independent checker that integrates the path from the
trace's x/y and fixes every end where the vehicle was when the command was issued.
Synthetic traces use the helpers of ``tests/safety/test_monitor.py``.
"""

from __future__ import annotations

import functools
import itertools
import math
import random
from typing import Any

import pytest

from overdrive.messages import (
    AdvanceAuthorization,
    MaxSpeed,
    MoveCommand,
    SafetyDevices,
    Topic,
    Truth,
)
from overdrive.observe.judge import Monitor, physical_decel_mps2
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers import speed as speed_module
from overdrive.vehicle.plant import Plant, World
from tests.safety.test_monitor import DT, Clock, move, rules

ESCAPE_HYBRID = PRESETS["escape-hybrid"]


def run(vehicle: Any = "escape-hybrid", duration_s: float = 20.0, start: str = "ready",
        world: dict | None = None, events: list[dict] = ()) -> Any:
    data = {"name": "redteam", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "world": world or {}, "events": list(events)}
    return run_scenario(parse_scenario(data), None)


def details(result: Any) -> dict[str, dict]:
    return {d["key"]: d for d in result.summary["violation_details"]}


def travel_after_m(result: Any, t_s: float) -> float:
    """Path length driven after ``t_s``, from the trace's x/y."""
    rows = [r for r in result.trace if float(r["t_s"]) >= t_s - 1e-9]
    return sum(math.hypot(float(b["x_m"]) - float(a["x_m"]), float(b["y_m"]) - float(a["y_m"]))
               for a, b in itertools.pairwise(rows))


def slow_spss_watchdog(monkeypatch: pytest.MonkeyPatch, timeout_s: float) -> None:
    slow = functools.partial(speed_module.SpeedServerConfig, spss_timeout_s=timeout_s)
    monkeypatch.setattr(speed_module, "SpeedServerConfig", slow)


MOVE_80 = {"at_s": 0.5, "move": {"distance_m": 80, "maxspeed_mps": 8, "curvature_1pm": 0}}


# =========================================================================== false negatives

@pytest.mark.parametrize("pause", [SafetyDevices(door_open=True), SafetyDevices(internal_error=True)],
                         ids=["door", "internal-error"])
def test_a_software_pause_is_an_interruption_too(pause: SafetyDevices) -> None:
    """FN, rule 4 (unintended_motion): ``interruption()`` knows SafeStop, the overrides and the
    e-stop but not the door or an internal error, although both pause the vehicle (safety mode
    ``software-pause``) and docs/reliability.md lists "SafeStop pause / door / internal error"
    as judged by unintended_motion. Motion after the door closes goes unjudged."""
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


def test_door_release_does_not_resume_the_stale_move() -> None:
    """FN, rule 4, whole run: MOVE 80 m, door open at 5 s (the vehicle stops, software pause),
    closed at 10 s. The stack resumed the stale MOVE and drove 59.8 m more with no new command
    while the judge exited 0 (independent: 59.78 m after the door closed, allowed 0.10 m). The
    judge now treats the door as an interruption (synthetic test above) and the stack latches
    it (issue 17): nothing moves after the door closes."""
    result = run(duration_s=25, events=[MOVE_80, {"at_s": 5, "door": "open"},
                                        {"at_s": 10, "door": "closed"}])
    assert travel_after_m(result, 10.5) < 0.05
    assert result.summary["violation_details"] == []


def test_a_partial_speed_override_is_an_interruption() -> None:
    """FN, rule 4: ``partial_mode: manual-speed`` hands the pedals to the human (the simulated
    driver brakes); when it returns to ``full`` the stack resumes the stale MOVE (56.6 m in a
    whole run: MOVE 80 m, manual-speed 5-10 s) and the judge says nothing. Like a manual
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


def test_an_advance_from_another_source_does_not_switch_off_the_rollback_rule() -> None:
    """FN, rule 2 (direction): once the planner has spoken, every other source's advance sets
    ``direction = None`` and the direction rule is off until the next planner command, so a
    vehicle rolling back under a forward MOVE is never judged."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(30.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=100.0))
    clock.path([1.0, 2.0, 0.0, -5.0], speed_mps=-0.5)
    found = rules(monitor)
    assert found.get("direction", {}).get("amount") == pytest.approx(7.0)


@pytest.fixture
def without_direction_hold(monkeypatch) -> None:
    """The stack as it was before issue 16's direction hold (the speed server's hold never
    acts), so the judge still has the known hill-start rollback to judge."""
    from overdrive.servers.direction_hold import FREE

    monkeypatch.setattr(speed_module.DirectionHold, "step", lambda self, *a, **k: FREE)


@pytest.mark.usefixtures("without_direction_hold")
def test_hill_start_rollback_with_another_source_advancing_is_judged() -> None:
    """FN, rule 2, whole run: the known hill-start rollback (15 % grade, throttle at 20 %),
    MOVE 15 m at 8 m/s, plus one advance of 100 m from ``lidar`` 0.1 s later. The vehicle rolls
    back 16.96 m under the forward MOVE (independent, from x/y); the judge exits 0. Without the
    advance it reports ``direction`` 16.957 m. (The stack without issue 16's direction hold.)"""
    result = run(world={"grade_percent": 15}, events=[
        {"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
        {"at_s": 0.5, "move": {"distance_m": 15, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 0.6, "advance": {"source": "lidar", "distance_m": 100}}])
    assert float(result.trace[-1]["x_m"]) < -10.0      # the known rollback (issue 16)
    assert details(result).get("direction", {}).get("amount", 0.0) > 10.0


@pytest.mark.usefixtures("without_direction_hold")
def test_set_speed_runs_judge_rollback_against_the_gear() -> None:
    """FN, rule 2 (and 3): in a ``set_speed`` run every SPSS is a command with no direction
    (``_new_command(None)``), so the direction rule never applies although each SPSS names its
    gear. Here (15 % grade, throttle at 20 %, SPSS 3 m/s in ``drive``) the vehicle rolls
    backwards 135 m, reaching 13.7 m/s backwards in drive, in 20 s; the judge exits 0."""
    result = run(duration_s=12, world={"grade_percent": 15}, events=[
        {"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
        {"at_s": 0.5, "set_speed": {"speed_mps": 3, "accel_mps2": 1, "gear": "drive",
                                    "state": "run"}}])
    assert float(result.trace[-1]["x_m"]) < -10.0
    assert "direction" in details(result)


def test_a_reverse_advance_does_not_erase_the_same_sources_forward_end() -> None:
    """FN, rule 1: the driving module keeps authorizations per (source, direction)
    (docs/driving-module.md) but the judge keys ends by source only, so a ``reverse: true``
    advance replaces the same source's forward end. Whole-run form: MOVE 200 m at 12 m/s,
    lidar advance 12 m at 9 s (the known authorization-cut overrun: 3.17 m past the lidar's end,
    independent), lidar reverse advance 5 m at 9.01 s: the judge exits 0."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=10.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=5.0, reverse=True))
    clock.path([5.0, 10.0, 15.0], speed_mps=0.5)
    assert rules(monitor).get("authorization[advance lidar]", {}).get("amount") == pytest.approx(5.0)


def test_an_advance_named_planner_does_not_erase_the_moves_end() -> None:
    """FN, rule 1: ends are keyed by source name and the planner's key is the string
    ``"planner"``, so an advance from a source called ``planner`` replaces the MOVE's end.
    Whole-run form: MOVE 60 m at 8 m/s, ``advance: {source: planner, distance_m: 1000}`` at 1 s,
    brake stuck released at 5 s: the vehicle ends 168.5 m past the MOVE's end (independent) and
    the judge exits 0; without the advance it reports the overrun."""
    monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
    clock = Clock(monitor)
    clock.at(0.0, 0.0)
    clock.issue(Topic.MOVE_COMMAND, move(10.0))
    clock.issue(Topic.ADVANCE, AdvanceAuthorization(source="planner", distance_m=1000.0))
    clock.path([5.0, 10.0, 20.0], speed_mps=0.5)
    overruns = [d["amount"] for d in rules(monitor).values() if d["rule"] == "authorization"]
    assert overruns and max(overruns) == pytest.approx(10.0)


def test_a_brake_hold_is_not_the_watchdogs_emergency_stop(monkeypatch: pytest.MonkeyPatch) -> None:
    """FN, rule 5 (watchdog): any speed-server pedal command with brake >= 99 % after the last
    delivered SPSS counts as the emergency stop, and nothing checks that it lasts. The speed
    server sends 100 % brake in every brakes-locked state (starting, paused, runwait, idle,
    shifting), so an SPSS stream lost there satisfies the judge. With the speed server's
    timeout raised to 30 s (its watchdog effectively gone): start parked, SPSS 5 m/s from
    0.5 s, set_speed dropped from 1.0 s: the speed server goes on to run at 7.7 s and drives at
    5 m/s with no SPSS for 11 s (48.6 m in 20 s, no e-stop, no fault); the judge exits 0. With
    the healthy 0.2 s timeout the same run e-stops at 1.1 s."""
    slow_spss_watchdog(monkeypatch, 30.0)
    result = run(duration_s=12, start="parked", events=[
        {"at_s": 0.5, "set_speed": {"speed_mps": 5, "accel_mps2": 1, "gear": "drive",
                                    "state": "run"}},
        {"at_s": 1.0, "drop": {"channel": "set_speed", "for_s": 11.0}}])
    assert result.summary["odometer_m"] > 5.0             # it drove without a command stream
    assert "watchdog" in details(result)


def test_the_watchdogs_amount_is_how_late_the_emergency_stop_came(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Understated amount, rule 5: the violation is recorded once, at the first tick past the
    deadline, so its amount is always ~0.02 s: with the speed server's timeout at 0.3 s or at
    5 s (e-stop 5.0 s after the last SPSS, 4.8 s late, the vehicle cruising at 8 m/s meanwhile)
    the judge reports the same "0.02 s". Here the timeout is 3 s: the e-stop comes ~2.8 s late."""
    slow_spss_watchdog(monkeypatch, 3.0)
    result = run(duration_s=10, events=[
        {"at_s": 0.5, "set_speed": {"speed_mps": 8, "accel_mps2": 2, "gear": "drive",
                                    "state": "run"}},
        {"at_s": 6.0, "drop": {"channel": "set_speed", "for_s": 4.0}}])
    estops = [e["t_s"] for e in result.summary["events"] if e["kind"] == "estop"]
    assert estops and estops[0] > 8.5
    assert details(result)["watchdog"]["amount"] > 2.5


# =========================================================================== false positives

def test_ranger_braking_at_the_tyre_limit_on_a_slippery_road_is_inside_the_ellipse() -> None:
    """FP, rule 9 (acceleration_ellipse): the judge scales the preset's braking decel by
    friction / 0.9, but the ranger-6x6 is brake-limited on dry ground (6.5 m/s^2 < 0.9 g): at
    friction 0.3 its tyres still give 0.3 g = 2.94 m/s^2, the judge allows 6.5 * 0.3 / 0.9 =
    2.17 m/s^2 (+15 %), and it also counts rolling resistance (0.29 m/s^2) as tyre force. A
    SafeStop pause at 5 m/s (the vehicle's own pause braking, ABS at the tyre limit) is
    reported as "uses 150 % of the ellipse"."""
    result = run(vehicle="ranger-6x6", duration_s=12, world={"friction": 0.3}, events=[
        {"at_s": 0.5, "move": {"distance_m": 80, "maxspeed_mps": 6, "curvature_1pm": 0}},
        {"at_s": 8, "safestop": "pause"}])
    assert "acceleration_ellipse" not in details(result)


def test_a_lowered_limit_is_not_demanded_faster_than_the_road_allows() -> None:
    """FP, rule 3 (speed): a lowered limit had to be met along a 2.0 m/s^2 ramp whatever the
    road. On ice (friction 0.15) the judge's own ``physical_decel_mps2`` is 1.47 m/s^2: a
    vehicle braking that hard from 6 m/s to a new 2 m/s limit is still reported as speeding
    (1.06 m/s over the ramp)."""
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


def test_a_stop_at_cruise_stops_within_the_shortest_physical_stop() -> None:
    """Decided: issue 15 defines STOP as "stop now", judged against the shortest physical stop;
    the stack meets it through issue 17's hard-braking path. The red team's finding, rule 1:
    docs/move-server.md then defined STOP as a controlled stop on the ellipse's deceleration,
    and every STOP at speed failed: MOVE 100 m at 8 m/s, replaced at 6.0 s, STOP at 6.05 s at
    7.96 m/s: the stack stopped in 8.15 m (~4 m/s^2) where 4.83 m was possible."""
    result = run(events=[
        {"at_s": 0.5, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.0, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.05, "stop": {}}])
    assert "authorization[planner]" not in details(result)


REFUSED = [
    pytest.param({"at_s": 4, "move": {"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0.5}},
                 "infeasible", id="infeasible-curvature"),
    pytest.param({"at_s": 8, "reverse": {"distance_m": 10, "maxspeed_mps": 2, "curvature_1pm": 0}},
                 "busy", id="busy-reverse-while-moving"),
]


@pytest.mark.parametrize(("refused", "reason"), REFUSED)
def test_a_refused_command_is_not_held_against_the_vehicle(refused: dict, reason: str) -> None:
    """FP, rules 1-3: the judge ignores *invalid* commands ("the move server must reject it")
    but holds the vehicle to commands the move server refuses by design (``infeasible``,
    ``busy``, ``not_ready``; docs/move-server.md), whose planner is told to re-plan or to STOP
    first while the current command stays in force. MOVE 60 m at 8 m/s, then

    - at 4 s a MOVE 10 m at 3 m/s with curvature 0.5 (tighter than the turning circle,
      |k| <= 0.179, a static limit the judge knows): rejected ``infeasible``; the vehicle
      completes the accepted MOVE 0.18 m short of its end; the judge reports a 41.26 m overrun
      of the refused MOVE and 4.98 m/s of speeding;
    - at 8 s (7.94 m/s, at 37.69 m) a REVERSE 10 m at 2 m/s: rejected ``busy``; the vehicle
      completes the accepted MOVE (stops at 59.82 m); the judge reports "moved forward 22.128 m
      under a REVERSE" and 2.16 m/s of speeding (same with ranger-6x6 still finishing a hilly
      MOVE: "moved forward 1.845 m under a REVERSE")."""
    result = run(events=[
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8, "curvature_1pm": 0}}, refused])
    assert any(e["kind"] == "rejected" and e["reason"] == reason
               for e in result.summary["events"])
    assert result.summary["violation_details"] == []


@pytest.mark.parametrize("kind", ["advance", "max_speed"])
def test_a_scenario_source_may_not_be_named_move(kind: str) -> None:
    """FP (and FN), rules 1-2: the judge tells the move server's re-publications from other
    sources by the name ``move``, which a scenario source could use: an advance of 20 m from
    ``move`` drove the vehicle 19.8 m and the judge reported "moved 19.801 m with no command",
    and an overrun of it would not have been judged. Decided: ``move`` is a reserved source
    name; such a scenario is refused (exit 2) naming the field."""
    from overdrive.scenario.schema import ScenarioError

    body = {"source": "move", "distance_m": 20} if kind == "advance" else \
        {"source": "move", "speed_mps": 2}
    with pytest.raises(ScenarioError, match=rf"events\[0\]\.{kind}\.source: 'move' is reserved"):
        run(duration_s=15, events=[{"at_s": 0.5, kind: body}])


def test_the_shortest_stop_includes_the_throttle_actuators_lag() -> None:
    """FP, rule 1: "the shortest physical stop ... no vehicle can beat" counts one period and
    the brake's lag but not the throttle's: at full throttle the drive force decays with the
    throttle lag (0.15 s) while the brake builds up. The plant itself, at 12 m/s on a -15 %
    grade with full throttle, commanded throttle 0 / brake 100 % one period after a STOP,
    stops 0.38 m beyond the judge's shortest stop (0.25 m on the flat): an ideal response is
    reported as an overrun."""
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


def test_a_reverse_clearance_from_another_source_is_not_a_reverse_command() -> None:
    """FP, rule 2 (direction): with no planner, every advance sets the judged direction, so a
    ``reverse: true`` advance (a rear source granting reverse clearance) turns the judge to
    "reverse" although the driving module applies reverse authorizations only while the drive
    mode is reverse (docs/driving-module.md; without a DriveMode it drives forward). Lidar
    advance 30 m at 0.5 s, rear reverse advance 5 m at 1 s: the vehicle drives 29.79 m forward
    inside the lidar's authorization; the judge reports "moved forward 29.743 m under a
    REVERSE"."""
    result = run(events=[
        {"at_s": 0.5, "advance": {"source": "lidar", "distance_m": 30}},
        {"at_s": 1.0, "advance": {"source": "rear", "distance_m": 5, "reverse": True}}])
    assert 25.0 < float(result.trace[-1]["x_m"]) < 30.0
    assert result.summary["violation_details"] == []
