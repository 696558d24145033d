"""The judge on whole runs: it catches what an independent checker computing the path from the
trace's x/y catches, and its figures match that checker's.

Cases the stack still fails (issues 16 and 17) are kept as strict xfails: each fix must flip
one, and the judge must keep failing the stack until then.
"""

from __future__ import annotations

import functools
import itertools
import math
from pathlib import Path
from typing import Any

import pytest

from overdrive.messages import Topic
from overdrive.run.sim import run_scenario
from overdrive.run.sweep import sweep
from overdrive.scenario.schema import load_scenario, parse_scenario
from overdrive.servers import speed as speed_module
from overdrive.vehicle.sim_node import VehicleSim
from tests.conftest import PRESET_NAMES, reachable_mps
from tests.safety.test_grip_lost_in_curve import NOMINAL_CURVES

ROOT = Path(__file__).resolve().parents[2]
MOVE_30 = {"at_s": 0.5, "move": {"distance_m": 30, "maxspeed_mps": 5, "curvature_1pm": 0}}


def run(vehicle: Any = "escape-hybrid", duration_s: float = 30.0, start: str = "ready",
        world: dict | None = None, events: list[dict] = ()) -> Any:
    data = {"name": "judge", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "world": world or {}, "events": list(events)}
    return run_scenario(parse_scenario(data), None)


def rules_of(result: Any) -> set[str]:
    return {d["rule"] for d in result.summary["violation_details"]}


def independent_overrun_m(trace: list[dict[str, str]], issued_s: float, distance_m: float) -> float:
    """Largest travel past ``distance_m`` from where the vehicle was at ``issued_s``, from x/y only."""
    rows = [r for r in trace if float(r["t_s"]) >= issued_s - 1e-9]
    x0, y0, h0 = float(rows[0]["x_m"]), float(rows[0]["y_m"]), float(rows[0]["heading_rad"])
    return max((float(r["x_m"]) - x0) * math.cos(h0) + (float(r["y_m"]) - y0) * math.sin(h0)
               for r in rows) - distance_m


# --------------------------------------------------------------------------- acceptance

def test_brake_stuck_released_at_cruise_is_an_overrun_named_by_its_largest_value() -> None:
    """No brake left at all (the parking brake failed too, a 6x6 without engine braking): the
    vehicle coasts far past the end."""
    result = run(vehicle="ranger-6x6", duration_s=40, events=[
        {"at_s": 0.1, "actuator": {"park_brake": {"failed": True}}},
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 5.0, "actuator": {"brake": {"stuck": True}}}])
    assert result.exit_code == 1
    [detail] = [d for d in result.summary["violation_details"] if d["rule"] == "authorization"]
    expected = independent_overrun_m(result.trace, 0.5, 60.0)
    assert expected > 20.0
    assert detail["amount"] == pytest.approx(expected, abs=0.02)
    assert f"by {detail['amount']:.3f} m" in next(v for v in result.summary["violations"]
                                                   if "authorization[planner]" in v)


def test_spss_loss_sweep_fails_when_the_speed_servers_timeout_is_raised(tmp_path: Path,
                                                                        monkeypatch) -> None:
    scenario = ROOT / "scenarios" / "sweep-spss-loss.yaml"
    honest = sweep(scenario, 6, 1, tmp_path / "honest")
    assert honest["violations"] == 0
    slow = functools.partial(speed_module.SpeedServerConfig, spss_timeout_s=0.3)
    monkeypatch.setattr(speed_module, "SpeedServerConfig", slow)
    report = sweep(scenario, 6, 1, tmp_path / "slow")       # jobs=1: in this process, patched
    assert report["violations_by_rule"].get("watchdog") == 6, report["violations_by_rule"]


SPSS_DROP = [
    {"at_s": 0.5, "set_speed": {"speed_mps": 5, "accel_mps2": 1, "gear": "drive", "state": "run"}},
    {"at_s": 2.0, "drop": {"channel": "set_speed", "for_s": 2.0}}]


def test_the_watchdog_judges_spss_as_delivered_not_as_issued(monkeypatch) -> None:
    """During a drop the scenario still issues SPSS; only what reached the speed server counts:
    a healthy speed server passes, one whose timeout is 0.6 s fails by how late it was."""
    result = run(duration_s=4, events=SPSS_DROP)
    assert result.exit_code == 0
    estops = [e for e in result.summary["events"] if e["kind"] == "estop"]
    assert estops and 2.0 < estops[0]["t_s"] <= 2.0 + 0.21
    slow = functools.partial(speed_module.SpeedServerConfig, spss_timeout_s=0.6)
    monkeypatch.setattr(speed_module, "SpeedServerConfig", slow)
    late = run(duration_s=4, events=SPSS_DROP)
    [watchdog] = [d for d in late.summary["violation_details"] if d["rule"] == "watchdog"]
    assert late.exit_code == 1 and watchdog["amount"] == pytest.approx(0.4, abs=0.02)


@pytest.mark.parametrize("mass_kg", [1.0e308, 1.0e30, float("inf")])
def test_non_finite_runs_never_exit_0(tmp_path: Path, mass_kg: float) -> None:
    """A run whose physics goes non-finite is a violation (exit 1) unless its file is refused
    first (exit 2); summary.json stays strict JSON either way."""
    from overdrive.scenario.schema import ScenarioError

    data = {"name": "nan", "vehicle": {"preset": "escape-hybrid", "mass_kg": mass_kg},
            "start": "ready", "duration_s": 3, "events": [
                {"at_s": 0.5, "move": {"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0}}]}
    try:
        scenario = parse_scenario(data)
    except ScenarioError:
        return                                   # exit 2: the plausible-range check refused it
    result = run_scenario(scenario, tmp_path / "run", plot=False)
    assert result.exit_code == 1 and "finite" in rules_of(result)


def test_a_run_whose_truth_goes_non_finite_is_judged_and_written_as_strict_json(tmp_path: Path,
                                                                               monkeypatch) -> None:
    """The plant made to produce NaN (a defect the judge must catch, whatever the input checks)."""
    import json

    from overdrive.vehicle import plant as plant_module

    step = plant_module.Plant.step

    def broken(self, *args, **kwargs):
        step(self, *args, **kwargs)
        if self.x_m > 1.0:
            self.x_m = math.nan

    monkeypatch.setattr(plant_module.Plant, "step", broken)
    result = run(duration_s=6, events=[MOVE_30])
    assert result.exit_code == 1 and "finite" in rules_of(result)
    out = run_scenario(parse_scenario({"name": "nan", "start": "ready", "duration_s": 6,
                                       "events": [MOVE_30]}), tmp_path / "run", plot=False)
    text = (out.out_dir / "summary.json").read_text()

    def refuse(name: str) -> None:
        raise ValueError(f"bare {name} in summary.json")

    json.loads(text, parse_constant=refuse)


def test_freeze_repeats_the_last_real_reading_from_its_first_use() -> None:
    """Issue 15: ``fault: freeze`` published nothing unless an earlier sensor fault had run."""
    data = {"name": "freeze", "start": "ready", "duration_s": 3, "events": [
        {"at_s": 0.5, "move": {"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0}},
        {"at_s": 1.5, "sensor": {"name": "gps", "fault": "freeze", "for_s": 1.0}}]}
    seen: list[tuple[float, Any]] = []

    class Tap:
        now_s = 0.0

        def set_time(self, now_s: float) -> None:
            self.now_s = now_s

        def observe(self, topic: str, msg: Any) -> None:
            if topic == Topic.GPS_INS:
                seen.append((self.now_s, msg))

    run_scenario(parse_scenario(data), None, observers=[Tap()])
    frozen = [m for t, m in seen if 1.5 < t < 2.5 - 1e-9]
    assert len(frozen) == 99, "a reading every period during the freeze"
    assert len({(m.x_m, m.odometer_m) for m in frozen}) == 1, "the same reading repeated"
    before = [m for t, m in seen if t <= 1.5 + 1e-9][-1]
    assert frozen[0] == before


def test_vehicle_sim_keeps_the_last_readings_without_any_fault() -> None:
    from overdrive.scenario.vehicles import PRESETS
    from overdrive.vehicle.plant import World

    sim = VehicleSim(PRESETS["escape-hybrid"], World(), 1, ready=True)
    sim.step(0.0, [])
    assert Topic.GPS_INS in sim.last_readings and Topic.WHEEL_SPEED in sim.last_readings


SHIPPED = sorted(p.name for p in (ROOT / "scenarios").glob("*.yaml")
                 if not p.name.startswith(("xgv-", "sweep-")) and p.name not in NOMINAL_CURVES)
"""xgv runs need sockets (tests/xgv); sweeps are run by tests/test_sweep.py; the nominal curves
(the demo among them) by tests/safety/test_grip_lost_in_curve.py, which asserts exit 0 (no
violation) on the same run: one run of each shipped scenario."""


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenarios_are_judged(name: str) -> None:
    """Every shipped scenario passes the judge: no violation, its expectations met (exit 0)."""
    result = run_scenario(load_scenario(ROOT / "scenarios" / name), None, keep_trace=False,
                          plot=False, record_mcap=False)
    assert result.summary["violations"] == []
    assert result.exit_code == 0


# -------------------------------------------------------------- the judge's misses and false alarms
# Each case failed against the judge's first version because of a defect of the judge, not of
# the stack: an unsafe run it passed (or whose amount it understated), or a run it failed although
# the vehicle did what was physically possible or documented. Figures from an independent checker
# integrating the path from the trace's x/y, every end fixed where the vehicle was when issued.

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


def test_door_release_does_not_resume_the_stale_move() -> None:
    """Was missed, rule 4, whole run: MOVE 80 m, door open at 5 s (the vehicle stops, software
    pause), closed at 10 s. The stack resumed the stale MOVE and drove 59.8 m more with no new
    command while the judge exited 0 (independent: 59.78 m after the door closed, allowed 0.10 m).
    The judge now treats the door as an interruption (synthetic test above) and the stack latches it
    (issue 17): nothing moves after the door closes."""
    result = run(duration_s=25, events=[MOVE_80, {"at_s": 5, "door": "open"},
                                        {"at_s": 10, "door": "closed"}])
    assert travel_after_m(result, 10.5) < 0.05
    assert result.summary["violation_details"] == []


@pytest.fixture
def without_direction_hold(monkeypatch) -> None:
    """The stack as it was before issue 16's direction hold (the speed server's hold never
    acts), so the judge still has the known hill-start rollback to judge."""
    from overdrive.servers.direction_hold import FREE

    monkeypatch.setattr(speed_module.DirectionHold, "step", lambda self, *a, **k: FREE)


@pytest.mark.usefixtures("without_direction_hold")
def test_hill_start_rollback_with_another_source_advancing_is_judged() -> None:
    """Was missed, rule 2, whole run: the known hill-start rollback (15 % grade, throttle at 20 %),
    MOVE 15 m at 8 m/s, plus one advance of 100 m from ``lidar`` 0.1 s later. The vehicle rolls back
    16.96 m under the forward MOVE (independent, from x/y); the judge exits 0. Without the advance
    it reports ``direction`` 16.957 m. (The stack without issue 16's direction hold.)"""
    result = run(duration_s=20, world={"grade_percent": 15}, events=[
        {"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
        {"at_s": 0.5, "move": {"distance_m": 15, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 0.6, "advance": {"source": "lidar", "distance_m": 100}}])
    assert float(result.trace[-1]["x_m"]) < -10.0      # the known rollback (issue 16)
    assert details(result).get("direction", {}).get("amount", 0.0) > 10.0


@pytest.mark.usefixtures("without_direction_hold")
def test_set_speed_runs_judge_rollback_against_the_gear() -> None:
    """Was missed, rule 2 (and 3): in a ``set_speed`` run every SPSS is a command with no direction
    (``_new_command(None)``), so the direction rule never applies although each SPSS names its gear.
    Here (15 % grade, throttle at 20 %, SPSS 3 m/s in ``drive``) the vehicle rolls backwards 135 m,
    reaching 13.7 m/s backwards in drive, in 20 s; the judge exits 0."""
    result = run(duration_s=12, world={"grade_percent": 15}, events=[
        {"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
        {"at_s": 0.5, "set_speed": {"speed_mps": 3, "accel_mps2": 1, "gear": "drive",
                                    "state": "run"}}])
    assert float(result.trace[-1]["x_m"]) < -10.0
    assert "direction" in details(result)


def test_a_brake_hold_is_not_the_watchdogs_emergency_stop(monkeypatch: pytest.MonkeyPatch) -> None:
    """Was missed, rule 5 (watchdog): any speed-server pedal command with brake >= 99 % after the
    last delivered SPSS counts as the emergency stop, and nothing checks that it lasts. The speed
    server sends 100 % brake in every brakes-locked state (starting, paused, runwait, idle,
    shifting), so an SPSS stream lost there satisfies the judge. With the speed server's timeout
    raised to 30 s (its watchdog effectively gone): start parked, SPSS 5 m/s from 0.5 s, set_speed
    dropped from 1.0 s: the speed server goes on to run at 7.7 s and drives at 5 m/s with no SPSS
    for 11 s (48.6 m in 20 s, no e-stop, no fault); the judge exits 0. With the healthy 0.2 s
    timeout the same run e-stops at 1.1 s."""
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


def test_ranger_braking_at_the_tyre_limit_on_a_slippery_road_is_inside_the_ellipse() -> None:
    """Was a false alarm, rule 9 (acceleration_ellipse): the judge scales the preset's braking decel
    by friction / 0.9, but the ranger-6x6 is brake-limited on dry ground (6.5 m/s^2 < 0.9 g): at
    friction 0.3 its tyres still give 0.3 g = 2.94 m/s^2, the judge allows 6.5 * 0.3 / 0.9 = 2.17
    m/s^2 (+15 %), and it also counts rolling resistance (0.29 m/s^2) as tyre force. A SafeStop
    pause at 5 m/s (the vehicle's own pause braking, ABS at the tyre limit) is reported as "uses 150
    % of the ellipse"."""
    result = run(vehicle="ranger-6x6", duration_s=12, world={"friction": 0.3}, events=[
        {"at_s": 0.5, "move": {"distance_m": 80, "maxspeed_mps": 6, "curvature_1pm": 0}},
        {"at_s": 8, "safestop": "pause"}])
    assert "acceleration_ellipse" not in details(result)


def test_a_stop_at_cruise_stops_within_the_shortest_physical_stop() -> None:
    """Decided: issue 15 defines STOP as "stop now", judged against the shortest physical stop;
    the stack meets it through issue 17's hard-braking path. Found, rule 1:
    docs/move-server.md then defined STOP as a controlled stop on the ellipse's deceleration,
    and every STOP at speed failed: MOVE 100 m at 8 m/s, replaced at 6.0 s, STOP at 6.05 s at
    7.96 m/s: the stack stopped in 8.15 m (~4 m/s^2) where 4.83 m was possible."""
    result = run(duration_s=20, events=[
        {"at_s": 0.5, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.0, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.05, "stop": {}}])
    assert "authorization[planner]" not in details(result)


REFUSED = [
    pytest.param({"at_s": 4, "move": {"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0.5}},
                 "infeasible", id="infeasible-curvature"),
]


@pytest.mark.parametrize(("refused", "reason"), REFUSED)
def test_a_refused_command_is_not_held_against_the_vehicle(refused: dict, reason: str) -> None:
    """Was a false alarm, rules 1-3: the judge ignores *invalid* commands ("the move server must
    reject it") but holds the vehicle to commands the move server refuses by design (``infeasible``,
    ``busy``, ``not_ready``; docs/move-server.md), whose planner is told to re-plan or to STOP first
    while the current command stays in force. MOVE 60 m at 8 m/s, then

    - at 4 s a MOVE 10 m at 3 m/s with curvature 0.5 (tighter than the turning circle,
      |k| <= 0.179, a static limit the judge knows): rejected ``infeasible``; the vehicle
      completes the accepted MOVE 0.18 m short of its end; the judge reports a 41.26 m overrun
      of the refused MOVE and 4.98 m/s of speeding;
    - (until issue 31 item 9) at 8 s (7.94 m/s, at 37.69 m) a REVERSE 10 m at 2 m/s: rejected
      ``busy``; the vehicle completed the accepted MOVE (stopped at 59.82 m); the judge reported
      "moved forward 22.128 m under a REVERSE". Such a REVERSE now replaces the MOVE
      (``test_a_reverse_at_cruise_replaces_the_move_stopping_within_the_shortest_stop``)."""
    result = run(duration_s=20, events=[
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8, "curvature_1pm": 0}}, refused])
    assert any(e["kind"] == "rejected" and e["reason"] == reason
               for e in result.summary["events"])
    assert result.summary["violation_details"] == []


def test_a_reverse_clearance_from_another_source_is_not_a_reverse_command() -> None:
    """Was a false alarm, rule 2 (direction): with no planner, every advance sets the judged
    direction, so a ``reverse: true`` advance (a rear source granting reverse clearance) turns the
    judge to "reverse" although the driving module applies reverse authorizations only while the
    drive mode is reverse (docs/driving-module.md; without a DriveMode it drives forward). Lidar
    advance 30 m at 0.5 s, rear reverse advance 5 m at 1 s: the vehicle drives 29.79 m forward
    inside the lidar's authorization; the judge reports "moved forward 29.743 m under a REVERSE"."""
    result = run(duration_s=20, events=[
        {"at_s": 0.5, "advance": {"source": "lidar", "distance_m": 30}},
        {"at_s": 1.0, "advance": {"source": "rear", "distance_m": 5, "reverse": True}}])
    assert 25.0 < float(result.trace[-1]["x_m"]) < 30.0
    assert result.summary["violation_details"] == []


# --------------------------------------------------------------------------- known defects

def no_violation(result: Any, *rules: str) -> None:
    """No violation at all; or, with ``rules``, none of those (an xfail names what it waits for,
    so an unrelated false positive cannot keep it failing)."""
    if rules:
        assert not set(rules) & rules_of(result), result.summary["violations"]
    else:
        assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_frozen_gps_at_standstill_does_not_run_away(preset: str) -> None:
    no_violation(run(vehicle=preset, events=[
        {"at_s": 0.2, "sensor": {"name": "gps", "fault": "freeze", "for_s": 30}}, MOVE_30]), "authorization")


def test_hill_start_does_not_roll_back() -> None:
    no_violation(run(duration_s=20, world={"grade_percent": 15}, events=[
        {"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
        {"at_s": 0.5, "move": {"distance_m": 15, "maxspeed_mps": 3, "curvature_1pm": 0}}]), "direction")


def test_offset_obstacle_is_not_hit() -> None:
    no_violation(run(world={"obstacles": [{"x_m": 40, "y_m": 0.6}]}, events=[
        {"at_s": 0.5, "move": {"distance_m": 80, "maxspeed_mps": 2, "curvature_1pm": 0}}]), "contact")


def test_stuck_steering_is_noticed() -> None:
    no_violation(run(duration_s=20, events=[
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 12, "curvature_1pm": 0.1}},
        {"at_s": 3.0, "actuator": {"steering": {"stuck": True}}},
        {"at_s": 3.5, "move": {"distance_m": 60, "maxspeed_mps": 12, "curvature_1pm": 0}}]), "acceleration_ellipse")


def test_throttle_stuck_while_accelerating_does_not_overrun() -> None:
    no_violation(run(duration_s=20, world={"grade_percent": 15}, events=[
        {"at_s": 0.5, "move": {"distance_m": 15, "maxspeed_mps": 3, "curvature_1pm": 0}},
        {"at_s": 1.5, "actuator": {"throttle": {"stuck": True}}}]), "authorization")


INTERRUPTIONS = {
    "pause": ({"safestop": "pause"}, {"safestop": "run"}),
    "override": ({"manual_override": True}, {"manual_override": False}),
    "emergency-override": ({"emergency_manual_override": True}, {"emergency_manual_override": False}),
    "estop": ({"safestop": "stop"}, {"safestop": "run"}),
    "estop-button": ({"estop_button": True}, {"estop_button": False}),
}


@pytest.mark.variants   # `make test`: one case in four; `make test-variants`: all
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", sorted(INTERRUPTIONS))
@pytest.mark.parametrize(("at_s", "speed_mps"), [(2.0, 4.0), (6.0, 8.0)])
def test_no_motion_after_an_interruption_until_a_new_move(preset: str, kind: str, at_s: float,
                                                          speed_mps: float) -> None:
    """Issue 17: the interrupted MOVE is discarded; a MOVE issued later goes through runwait."""
    begin, end = INTERRUPTIONS[kind]
    new_move_s = at_s + 8.0
    result = run(vehicle=preset, duration_s=new_move_s + 25.0, events=[
        {"at_s": 0.5, "move": {"distance_m": 200, "maxspeed_mps": speed_mps, "curvature_1pm": 0}},
        {"at_s": at_s, **begin}, {"at_s": at_s + 4.0, **end},
        {"at_s": new_move_s, "move": {"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0}}])
    no_violation(result)
    events = result.summary["events"]
    assert [e for e in events if e["kind"] == "interrupted" and at_s <= e["t_s"] <= at_s + 0.1]
    rows = result.trace
    still = [abs(float(r["speed_mps"])) for r in rows
             if at_s + 4.0 + 1.0 <= float(r["t_s"]) <= new_move_s + 5.0]
    assert max(still) < 0.05, "standing from the interruption's end until runwait is over"
    runwait = [e for e in events if e["kind"] == "speed_state" and e["to"] == "runwait"
               and e["t_s"] >= new_move_s]
    assert runwait, "the new MOVE starts through the 5 s runwait"
    moved = float(rows[-1]["odometer_m"]) - next(float(r["odometer_m"]) for r in rows
                                                 if float(r["t_s"]) >= new_move_s)
    assert 9.0 < moved <= 10.0, "and then the new MOVE is driven"


def test_a_pause_goes_through_paused() -> None:
    result = run(events=[
        {"at_s": 0.5, "move": {"distance_m": 200, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 5, "safestop": "pause"}, {"at_s": 10, "safestop": "run"}])
    no_violation(result)
    states = [e["to"] for e in result.summary["events"] if e["kind"] == "speed_state"]
    assert "paused" in states and result.summary["final"]["speed_state"] == "paused"


def test_reordered_stop_is_not_overtaken() -> None:
    no_violation(run(events=[
        {"at_s": 0.5, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 5.9, "reorder": {"channel": "move", "for_s": 0.2}},
        {"at_s": 6.0, "move": {"distance_m": 100, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.05, "stop": {}}]), "authorization")


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("speed_mps", "cut_m"), [(12.0, 12.0), (9.0, 8.0), (6.0, 3.0), (3.0, 1.0)])
def test_authorization_cut_is_not_overrun(preset: str, speed_mps: float, cut_m: float) -> None:
    """Issue 17: a cut shorter than the normal stop is met by hard braking, without waiting
    for the SPSS period; a cut no vehicle could meet is judged from the shortest stop."""
    speed_mps = reachable_mps(preset, speed_mps)
    result = run(vehicle=preset, events=[
        {"at_s": 0.5, "move": {"distance_m": 300, "maxspeed_mps": speed_mps, "curvature_1pm": 0}},
        {"at_s": 12, "advance": {"source": "lidar", "distance_m": cut_m}}])
    no_violation(result)
    if preset == "escape-hybrid" and speed_mps >= 9.0:   # (the ranger's top speed is lower)
        assert any(e["kind"] == "hard_brake" for e in result.summary["events"])


STOPS_AT_SPEED = [pytest.param(v, g, marks=pytest.mark.variant_edge) if (v, g) == (11.0, -8.0)
                  else (v, g) for g in (-8.0, 0.0, 8.0) for v in (2.0, 5.0, 8.0, 11.0)]
"""(speed, grade): the fastest stop downhill is the edge `make test` always runs."""


@pytest.mark.variants   # `make test`: one case in four and the edge; `make test-variants`: all
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("speed_mps", "grade_percent"), STOPS_AT_SPEED)
def test_a_stop_at_speed_stops_within_the_shortest_physical_stop(preset: str, speed_mps: float,
                                                                 grade_percent: float) -> None:
    speed_mps = reachable_mps(preset, speed_mps)
    result = run(vehicle=preset, world={"grade_percent": grade_percent}, events=[
        {"at_s": 0.5, "move": {"distance_m": 300, "maxspeed_mps": speed_mps, "curvature_1pm": 0}},
        {"at_s": 12, "stop": {}}])
    no_violation(result)
    assert abs(float(result.trace[-1]["speed_mps"])) < 0.05


@pytest.mark.variants   # `make test`: one case in four and the longest delay
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("channel", ["advance", "move"])
@pytest.mark.parametrize("delay_s", [0.1, 0.3, pytest.param(0.5, marks=pytest.mark.variant_edge)])
def test_delayed_authorizations_are_not_overrun(preset: str, channel: str, delay_s: float) -> None:
    """Issue 17: distances count from where the vehicle was when they were issued, so latency on
    the advance or move channel never becomes distance."""
    result = run(vehicle=preset, events=[
        {"at_s": 0.2, "delay": {"channel": channel, "for_s": 30, "delay_s": delay_s}},
        {"at_s": 0.5, "move": {"distance_m": 40, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 6.0, "move": {"distance_m": 20, "maxspeed_mps": 6, "curvature_1pm": 0}}])
    no_violation(result)
    assert float(result.trace[-1]["odometer_m"]) > 15.0, "and the drive happened"


def test_brake_stuck_released_ends_in_an_emergency_stop_with_the_engine_cut() -> None:
    result = run(duration_s=40, events=[
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 5.0, "actuator": {"brake": {"stuck": True}}}])
    assert any(e["kind"] == "estop" for e in result.summary["events"])
    assert result.trace[-1]["engine"] == "off"


# --------------------------------------------------------------------------- one fault at a time

MOVE_60 = {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8, "curvature_1pm": 0}}
OBSTACLE_45 = {"obstacles": [{"x_m": 45, "y_m": 0}]}


def sensor(name: str, fault: str, at_s: float = 4.0, for_s: float = 3.0, **kw: float) -> dict:
    return {"at_s": at_s, "sensor": {"name": name, "fault": fault, "for_s": for_s, **kw}}


def actuator(at_s: float = 0.1, **faults: dict) -> dict:
    return {"at_s": at_s, "actuator": faults}


def issue(n: int, why: str) -> pytest.MarkDecorator:
    return pytest.mark.xfail(strict=True, reason=f"issue {n}: {why}")


FAULTS = [
    pytest.param([sensor("gps", "dropout", for_s=2.0)], {}, id="gps-lost"),
    pytest.param([sensor("gps", "noise", sigma=5.0)], {}, id="gps-jumping"),
    pytest.param([sensor("gps", "freeze", for_s=30.0)], {}, id="gps-frozen-at-cruise"),
    pytest.param([sensor("wheel_speed", "dropout")], {}, id="wheel-speed-lost"),
    pytest.param([sensor("wheel_speed", "freeze", at_s=0.2, for_s=30.0)], {}, id="wheel-speed-frozen"),
    pytest.param([actuator(brake={"effectiveness": 0.5})], {}, id="brake-weak-50"),
    pytest.param([actuator(throttle={"effectiveness": 0.3})], {}, id="throttle-weak-30"),
    pytest.param([actuator(steering={"rate_scale": 0.2})], {}, id="steering-slow"),
    pytest.param([{"at_s": 0.4, "duplicate": {"channel": "move", "for_s": 10}},
                  {"at_s": 5, "move": {"distance_m": 30, "maxspeed_mps": 6, "curvature_1pm": 0}}],
                 {}, id="move-duplicated"),
    pytest.param([{"at_s": 5, "drop": {"channel": "set_speed", "for_s": 1}}], {}, id="spss-lost-1s"),
    pytest.param([{"at_s": 5, "drop": {"channel": "pedals", "for_s": 1}}], {}, id="pedals-lost-1s"),
    pytest.param([sensor("radar", "dropout", at_s=0.2, for_s=40.0)], OBSTACLE_45, id="radar-lost"),
    pytest.param([sensor("radar", "freeze", at_s=0.2, for_s=40.0)], OBSTACLE_45, id="radar-frozen"),
    pytest.param([actuator(brake={"effectiveness": 0.2})], {}, id="brake-weak-20",
                 ),
    pytest.param([actuator(at_s=5.0, throttle={"stuck": True})], {}, id="throttle-stuck-at-cruise"),
]


@pytest.mark.parametrize(("faults", "world"), FAULTS)
def test_one_fault_during_a_60_m_move(faults: list[dict], world: dict) -> None:
    no_violation(run(duration_s=40, world=world, events=[MOVE_60, *faults]))


def test_reversing_towards_an_unreported_obstacle_does_not_hit_it() -> None:
    no_violation(run(duration_s=20, world={"obstacles": [{"x_m": -8, "y_m": 0}]}, events=[
        {"at_s": 0.5, "reverse": {"distance_m": 12, "maxspeed_mps": 2, "curvature_1pm": 0}}]), "contact")


def test_hill_start_rollback_does_not_hit_the_car_behind() -> None:
    no_violation(run(duration_s=20, world={"grade_percent": 15, "obstacles": [{"x_m": -6, "y_m": 0}]},
                     events=[{"at_s": 0.1, "actuator": {"throttle": {"effectiveness": 0.2}}},
                             {"at_s": 0.5, "move": {"distance_m": 15, "maxspeed_mps": 3,
                                                    "curvature_1pm": 0}}]), "contact")



@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_short_replacing_move_is_braked_hard_and_announced(preset: str) -> None:
    """Issue 17: a MOVE of 2 m accepted at ~10 m/s used to travel 11 m with a plain reply."""
    result = run(vehicle=preset, events=[
        {"at_s": 0.5, "move": {"distance_m": 300, "maxspeed_mps": 10, "curvature_1pm": 0}},
        {"at_s": 14, "move": {"distance_m": 2, "maxspeed_mps": 10, "curvature_1pm": 0}}])
    no_violation(result)
    kinds = {e["kind"] for e in result.summary["events"] if e["t_s"] >= 14}
    assert {"short_command", "hard_brake"} <= kinds


# -------------------------------------------------------- lapsed sources, the engine, parking, JAUS

def test_a_lapsed_limit_source_stops_the_vehicle_gently() -> None:
    """A limit source that goes quiet counts as 0 (fail-safe), but nothing else needs braking:
    a controlled stop, not the ellipse's deceleration (was 5.3 m/s^2)."""
    result = run(duration_s=20, events=[
        {"at_s": 0.5, "move": {"distance_m": 200, "maxspeed_mps": 8, "curvature_1pm": 0}},
        {"at_s": 1.0, "max_speed": {"source": "map", "speed_mps": 20}},
        {"at_s": 8.0, "drop": {"channel": "max_speed", "for_s": 12}}])
    no_violation(result)
    decels = [-float(r["accel_mps2"]) for r in result.trace if float(r["t_s"]) > 8.0]
    assert max(decels) < 2.5 * 1.15 and abs(float(result.trace[-1]["speed_mps"])) < 0.05


def test_the_computer_cannot_switch_the_engine_under_manual_override() -> None:
    from overdrive.messages import PowertrainCommand, SafetyDevices
    from overdrive.scenario.vehicles import PRESETS
    from overdrive.vehicle.plant import World

    sim = VehicleSim(PRESETS["escape-hybrid"], World(), 1, ready=True)
    sim.step(0.0, [(Topic.SAFETY, SafetyDevices(manual_override=True))])
    off = PowertrainCommand(gear="drive", engine_on=False, source="speed")
    for i in range(1, 100):
        sim.step(i * 0.01, [(Topic.POWERTRAIN, off)])
    assert sim.plant.engine == "running", "the human holds the engine under manual override"
    sim.step(1.0, [(Topic.SAFETY, SafetyDevices()), (Topic.POWERTRAIN, off)])
    for i in range(101, 150):
        sim.step(i * 0.01, [(Topic.POWERTRAIN, off)])
    assert sim.plant.engine == "off", "in drive-by-wire the computer's command stands"


def test_the_fuel_saver_parks_a_vehicle_left_paused_for_ten_minutes() -> None:
    """Seed 001's paused -> parked after 10 minutes, reachable in the full stack now that an
    interruption leaves the speed server paused."""
    result = run(duration_s=625, events=[
        {"at_s": 0.5, "move": {"distance_m": 20, "maxspeed_mps": 5, "curvature_1pm": 0}},
        {"at_s": 3.0, "safestop": "pause"}, {"at_s": 6.0, "safestop": "run"}])
    no_violation(result)
    to = [(e["t_s"], e["to"]) for e in result.summary["events"] if e["kind"] == "speed_state"]
    paused_at = next(t for t, state in to if state == "paused")
    assert ("parked" in [s for _, s in to]) and result.summary["final"]["speed_state"] == "parked"
    parked_at = next(t for t, state in to if state == "parked")
    assert parked_at - paused_at == pytest.approx(600.0, abs=1.0)


@pytest.mark.parametrize("kind", ["pause", "override", "estop"])
def test_no_motion_after_an_interruption_over_jaus(kind: str) -> None:
    """Issue 17 acceptance, over JAUS/UDP (the simulated XGV on loopback): the XGV reports the
    safety mode, the stack discards the MOVE, and only the new MOVE moves the vehicle."""
    begin, end = INTERRUPTIONS[kind]
    data = {"name": "jaus-interruption", "interface": "jaus", "start": "ready", "duration_s": 32,
            "events": [
                {"at_s": 0.5, "move": {"distance_m": 200, "maxspeed_mps": 6, "curvature_1pm": 0}},
                {"at_s": 4.0, **begin}, {"at_s": 8.0, **end},
                {"at_s": 12.0, "move": {"distance_m": 8, "maxspeed_mps": 3, "curvature_1pm": 0}}]}
    result = run_scenario(parse_scenario(data), None)
    no_violation(result)
    rows = result.trace
    still = [abs(float(r["speed_mps"])) for r in rows if 9.0 <= float(r["t_s"]) <= 12.0]
    assert max(still) < 0.05
    moved = float(rows[-1]["odometer_m"]) - next(float(r["odometer_m"]) for r in rows
                                                 if float(r["t_s"]) >= 12.0)
    assert 7.0 < moved <= 8.0



@pytest.mark.parametrize("friction", [0.3, 0.5])
@pytest.mark.parametrize("curvature", [0.02, 0.03])
def test_no_hard_brake_in_a_long_curve_on_a_slippery_road(friction: float, curvature: float) -> None:
    """Found (issue 17): a curve that uses up the ellipse made the "normal stop" look endless
    and latched a full brake with 250 m authorized."""
    result = run(world={"friction": friction}, events=[
        {"at_s": 0.5, "move": {"distance_m": 300, "maxspeed_mps": 10, "curvature_1pm": curvature}}])
    assert not [e for e in result.summary["events"] if e["kind"] == "hard_brake"]
    no_violation(result, "authorization", "direction")
