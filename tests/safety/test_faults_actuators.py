"""Issue 16, actuator monitoring, on whole runs: stuck steering, stuck throttle, failed or weak
brakes, on both presets, swept over fault times, speeds, grades, curvatures and effectiveness.

Judged from the summary (ground-truth violations) and its events, never from the stack's view
of itself. Healthy vehicles (hills, descents, curves, ice) must raise no actuator fault.
"""

from __future__ import annotations

import functools
from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.safety import actuators
from overdrive.safety.actuators import ActuatorFault, ActuatorMonitorConfig
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES

pytestmark = pytest.mark.variants

ACTUATOR_CODES = {str(int(code)) for code in ActuatorFault}


def run(vehicle: str = "escape-hybrid", duration_s: float = 30.0, world: dict | None = None,
        events: list[dict] = ()) -> Any:
    data = {"name": "actuators", "vehicle": vehicle, "start": "ready", "duration_s": duration_s,
            "world": world or {}, "events": list(events)}
    return run_scenario(parse_scenario(data), None)


def move(distance_m: float, speed_mps: float, curvature_1pm: float = 0.0, at_s: float = 0.5) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                   "curvature_1pm": curvature_1pm}}


def faults(result: Any, *codes: ActuatorFault) -> list[dict]:
    wanted = {str(int(c)) for c in codes} if codes else ACTUATOR_CODES
    return [e for e in result.summary["events"] if e["kind"] == "fault" and e.get("code") in wanted]


def rules(result: Any) -> set[str]:
    return {d["rule"] for d in result.summary["violation_details"]}


def final_speed(result: Any) -> float:
    return abs(float(result.trace[-1]["speed_mps"]))


# --------------------------------------------------------------------------- stuck throttle

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_percent", [0.0, 15.0])
@pytest.mark.parametrize("stuck_s", [0.6, 1.0, 1.5, 2.0, 2.5, 3.0])
def test_throttle_stuck_while_accelerating_never_overruns(preset: str, grade_percent: float,
                                                          stuck_s: float) -> None:
    """Issue 16 case 5: 19 of 28 such runs overran by 0.10-0.54 m before."""
    result = run(vehicle=preset, duration_s=20, world={"grade_percent": grade_percent}, events=[
        move(15, 3), {"at_s": stuck_s, "actuator": {"throttle": {"stuck": True}}}])
    assert result.summary["violations"] == []
    if faults(result):   # stuck where the loop wanted it changed: cut and stopped for good
        assert result.trace[-1]["engine"] == "off"
        assert final_speed(result) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("stuck_s", [0.5, 2.0, 4.0, 5.0, 6.0, 8.0])
def test_throttle_stuck_during_a_60_m_move_is_cut(preset: str, stuck_s: float) -> None:
    result = run(vehicle=preset, duration_s=40, events=[
        move(60, 8), {"at_s": stuck_s, "actuator": {"throttle": {"stuck": True}}}])
    assert result.summary["violations"] == []
    found = faults(result, ActuatorFault.THROTTLE_STUCK_OPEN, ActuatorFault.THROTTLE_STUCK_CLOSED)
    assert len(found) == 1, "one fault per onset"
    assert any(e["kind"] == "estop" and e.get("source") == "speed" for e in result.summary["events"])
    assert result.trace[-1]["engine"] == "off"
    assert final_speed(result) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_percent", [-6.0, 6.0])
def test_throttle_stuck_at_cruise_on_a_grade(preset: str, grade_percent: float) -> None:
    result = run(vehicle=preset, duration_s=40, world={"grade_percent": grade_percent}, events=[
        move(60, 8), {"at_s": 6.0, "actuator": {"throttle": {"stuck": True}}}])
    assert result.summary["violations"] == []
    assert final_speed(result) < 0.05


# --------------------------------------------------------------------------- brakes

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("stuck_s", [3.0, 5.0, 8.0])
def test_brake_stuck_released_ends_in_an_estop_with_the_engine_cut(preset: str,
                                                                   stuck_s: float) -> None:
    """No service brake: the e-stop, the fault, the takeover request and the engine cut (once
    stopped: engine braking keeps it running while moving) are required; the secondary brakes
    (tests/safety/test_secondary_braking.py) stop it, any overrun is judged by the audit."""
    result = run(vehicle=preset, duration_s=40, events=[
        move(60, 8), {"at_s": stuck_s, "actuator": {"brake": {"stuck": True}}}])
    assert len(faults(result, ActuatorFault.BRAKE_NOT_APPLYING)) == 1
    assert any(e["kind"] == "estop" and e.get("source") == "speed" for e in result.summary["events"])
    assert any(e["kind"] == "takeover" for e in result.summary["events"])
    assert result.trace[-1]["engine"] == "off"
    assert final_speed(result) < 0.05
    assert rules(result) <= {"authorization"}, result.summary["violations"]


@pytest.fixture
def no_brake_probe(monkeypatch: pytest.MonkeyPatch) -> None:
    """The speed server's launch brake probe switched off (on by default: ActuatorMonitorConfig)."""
    monkeypatch.setattr(actuators, "ActuatorMonitorConfig",
                        functools.partial(ActuatorMonitorConfig, probe_enabled=False))


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("effectiveness", [0.1, 0.15, 0.2, 0.3, 0.45, 0.6])
@pytest.mark.parametrize("distance_m", [40, 60])
def test_weak_brakes_from_the_start_do_not_overrun(preset: str, effectiveness: float,
                                                   distance_m: float) -> None:
    """Issue 16 case 6: brakes at 20 % overran a 40 m MOVE by 6.25 m (learned only once braking
    hard). The launch probe (on by default) finds them; the weaker ones are a fault."""
    result = run(vehicle=preset, duration_s=50, events=[
        {"at_s": 0.1, "actuator": {"brake": {"effectiveness": effectiveness}}},
        move(distance_m, 8)])
    assert result.summary["violations"] == []
    assert final_speed(result) < 0.05
    if effectiveness <= 0.45:
        assert faults(result, ActuatorFault.BRAKE_WEAK)
    failed = faults(result, ActuatorFault.BRAKE_FAILED)
    if effectiveness < ActuatorMonitorConfig().failed_ratio:   # cannot hold a 15 % grade: stop
        assert len(failed) == 1 and result.trace[-1]["engine"] == "off"
    else:                                   # weak but drivable: it keeps driving to the end
        assert not failed
        assert float(result.trace[-1]["odometer_m"]) > distance_m - 1.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_percent", [-6.0, -3.0, 0.0])
def test_weak_brakes_on_a_grade_do_not_overrun(preset: str, grade_percent: float) -> None:
    result = run(vehicle=preset, duration_s=50, world={"grade_percent": grade_percent}, events=[
        {"at_s": 0.1, "actuator": {"brake": {"effectiveness": 0.25}}}, move(50, 8)])
    assert result.summary["violations"] == []


@pytest.mark.usefixtures("no_brake_probe")
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("effectiveness", "weak"), [(0.5, True), (0.7, False)])
def test_weak_brakes_without_the_probe_are_noticed_at_the_first_stop(preset: str,
                                                                     effectiveness: float,
                                                                     weak: bool) -> None:
    """Without the probe, the loop's own braking measures the brake; below 60 % of the
    preset's deceleration it is a notice (weak_ratio), above it only the estimate follows."""
    result = run(vehicle=preset, duration_s=40, events=[
        {"at_s": 0.1, "actuator": {"brake": {"effectiveness": effectiveness}}}, move(60, 8)])
    assert result.summary["violations"] == []
    assert bool(faults(result, ActuatorFault.BRAKE_WEAK)) is weak
    assert not faults(result, ActuatorFault.BRAKE_FAILED)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("case", ["flat", "climb-8-fast", "curves"])
def test_a_healthy_launch_is_probed_once(preset: str, case: str) -> None:
    """Healthy runs: one light brake probe at launch (no more: it costs ~1.5 s), no fault, no
    violation; no brake before the loop asks for one otherwise."""
    world, events = HEALTHY[case]
    result = run(vehicle=preset, duration_s=12, world=world, events=events[:1])
    probing = [float(r["t_s"]) for r in result.trace
               if float(r["brake_cmd_pct"]) > 0.0 and float(r["speed_mps"]) > 1.0
               and float(r["goal_speed_mps"]) >= float(r["speed_mps"]) + 0.5]
    spans = [t for i, t in enumerate(probing) if i == 0 or t - probing[i - 1] > 0.05]
    assert len(spans) <= 1, spans
    assert probing == [] or probing[-1] - probing[0] <= 2.5, "one short probe"
    assert result.summary["violations"] == []
    assert not [e for e in result.summary["events"] if e["kind"] == "fault"]


@pytest.mark.xfail(strict=True, reason="issue 16: uphill the launch window (1.5 m/s plus 2 s of "
                   "the grade's deceleration, below 20 % of the target) never opens: a weak brake "
                   "is learned at the first stop")
def test_weak_brakes_uphill_are_not_probed() -> None:
    result = run(duration_s=50, world={"grade_percent": 6}, events=[
        {"at_s": 0.1, "actuator": {"brake": {"effectiveness": 0.25}}}, move(50, 8)])
    assert result.summary["violations"] == []


# --------------------------------------------------------------------------- steering

FAST = {"escape-hybrid": 12.0, "ranger-6x6": 8.0}
"""A MOVE each preset accepts (the ranger's top speed is lower)."""

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("curvature_1pm", [-0.1, 0.03, 0.06, 0.1])
@pytest.mark.parametrize("stuck_s", [3.0, 6.0])
def test_stuck_steering_stops_inside_the_ellipse(preset: str, curvature_1pm: float,
                                                 stuck_s: float) -> None:
    """Issue 16 case 4: stuck in a curve, then a straight MOVE at 12 m/s: the vehicle reached
    8.7 m/s on a 10 m circle before."""
    speed = FAST[preset]
    result = run(vehicle=preset, duration_s=25, events=[
        move(200, speed, curvature_1pm),
        {"at_s": stuck_s, "actuator": {"steering": {"stuck": True}}},
        move(200, speed, 0.0, at_s=stuck_s + 0.5)])
    assert result.summary["violations"] == []
    assert len(faults(result, ActuatorFault.STEERING_STUCK)) == 1
    assert final_speed(result) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_steering_stuck_straight_then_a_curve_is_asked(preset: str) -> None:
    result = run(vehicle=preset, duration_s=30, events=[
        move(200, 8), {"at_s": 4.0, "actuator": {"steering": {"stuck": True}}},
        move(200, 8, 0.08, at_s=6.0)])
    assert result.summary["violations"] == []
    assert faults(result, ActuatorFault.STEERING_STUCK)
    assert final_speed(result) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("rate_scale", [0.2, 0.4])
def test_slow_steering_is_not_stuck(preset: str, rate_scale: float) -> None:
    result = run(vehicle=preset, duration_s=30, events=[
        {"at_s": 0.1, "actuator": {"steering": {"rate_scale": rate_scale}}},
        move(40, 6, 0.08), move(40, 6, -0.08, at_s=8.0), move(20, 6, 0.0, at_s=14.0)])
    assert not faults(result, ActuatorFault.STEERING_STUCK)


# --------------------------------------------------------------------------- no false alarms

HEALTHY = {
    "flat": ({}, [move(60, 8)]),
    "climb-15": ({"grade_percent": 15}, [move(40, 5)]),
    "descent-15": ({"grade_percent": -15}, [move(40, 5)]),
    "climb-8-fast": ({"grade_percent": 8}, [move(80, 10)]),
    "descent-8-fast": ({"grade_percent": -8}, [move(80, 10)]),
    "curves": ({}, [move(30, 6, 0.08), move(30, 6, -0.08, at_s=6.0), move(30, 6, 0.0, at_s=11.0)]),
    "ice": ({"friction": 0.2}, [move(40, 6)]),
    "ice-curve": ({"friction": 0.3}, [move(40, 5, 0.05)]),
    "stop-and-go": ({}, [move(10, 3), move(10, 5, at_s=8.0), move(10, 3, at_s=16.0)]),
    "reverse": ({}, [{"at_s": 0.5, "reverse": {"distance_m": 8, "maxspeed_mps": 2,
                                               "curvature_1pm": 0}}]),
}


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("case", sorted(HEALTHY))
def test_healthy_vehicles_raise_no_actuator_fault(preset: str, case: str) -> None:
    world, events = HEALTHY[case]
    result = run(vehicle=preset, duration_s=35, world=world, events=events)
    assert faults(result) == []
    assert not [e for e in result.summary["events"]
                if e["kind"] == "estop" and e.get("source") == "speed"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", ["pause", "override", "pedals-lost"])
def test_interruptions_are_not_actuator_faults(preset: str, kind: str) -> None:
    """The vehicle, not the actuator, overrides the pedals or the wheel: no fault."""
    begin, end = {
        "pause": ({"safestop": "pause"}, {"safestop": "run"}),
        "override": ({"manual_override": True}, {"manual_override": False}),
        "pedals-lost": ({"drop": {"channel": "pedals", "for_s": 1}}, None),
    }[kind]
    events = [move(200, 8, 0.02), {"at_s": 5.0, **begin}]
    if end is not None:
        events.append({"at_s": 8.0, **end})
    result = run(vehicle=preset, duration_s=15, events=events)
    assert faults(result) == []
