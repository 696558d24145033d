"""Issue 30, whole runs: GPS/INS poses that step or drift, speeds that drift or scale.

Judged from ground truth (the judge's violations, the trace's true x/y/speed) and the events,
both presets. A step is injected only once the obstacle has left the radar's cone (checked on
the true pose at the step): the remembered obstacle alone stands between the vehicle and it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.run.sweep import sample_run
from overdrive.safety.plausibility import PlausibilityFault
from overdrive.scenario.schema import load_scenario, parse_scenario, read_scenario_data
from overdrive.scenario.vehicles import PRESETS
from tests.conftest import PRESET_NAMES

pytestmark = pytest.mark.variants

OBSTACLE = (40.0, 0.6)     # inside both presets' width, leaves the 12-deg cone ~5.7 m before
JUDGE_SPEED_TOLERANCE_MPS = 0.3   # observe.judge: the speed rule's tolerance


def run(vehicle: str | dict, events: list[dict], world: dict | None = None,
        duration_s: float = 40.0, seed: int = 7) -> Any:
    data = {"name": "sensor-errors", "vehicle": vehicle, "start": "ready",
            "duration_s": duration_s, "seed": seed, "world": world or {}, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def move(distance_m: float, speed_mps: float, at_s: float = 0.5) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                   "curvature_1pm": 0.0}}


def error(at_s: float, **body: Any) -> dict:
    return {"at_s": at_s, "sensor_error": body}


def codes(result: Any, code: PlausibilityFault) -> list[dict]:
    return [e for e in result.summary["events"]
            if e["kind"] == "fault" and e.get("code") == str(int(code))]


def row_at(result: Any, t_s: float) -> dict:
    return min(result.trace, key=lambda r: abs(float(r["t_s"]) - t_s))


def outside_cone(preset: str, row: dict) -> bool:
    """The obstacle is outside the radar's cone from the true pose ``row``."""
    p = PRESETS[preset]
    h = float(row["heading_rad"])
    front = p.length_m - p.rear_overhang_m
    bx = float(row["x_m"]) + front * math.cos(h)
    by = float(row["y_m"]) + front * math.sin(h)
    dx, dy = OBSTACLE[0] - bx, OBSTACLE[1] - by
    along, left = dx * math.cos(h) + dy * math.sin(h), -dx * math.sin(h) + dy * math.cos(h)
    return along > 0.0 and abs(math.atan2(left, along)) > p.radar_half_angle_rad


def step_time_s(preset: str) -> float:
    """A time at which the obstacle has just left the cone (healthy run, same seed)."""
    healthy = run(preset, [move(80.0, 2.0)], {"obstacles": [{"x_m": OBSTACLE[0],
                                                               "y_m": OBSTACLE[1]}]})
    for row in healthy.trace:
        if outside_cone(preset, row):
            return round(float(row["t_s"]) + 0.3, 2)
    raise AssertionError("the obstacle never left the cone")


_STEP_TIMES: dict[str, float] = {}


def left_cone_s(preset: str) -> float:
    if preset not in _STEP_TIMES:
        _STEP_TIMES[preset] = step_time_s(preset)
    return _STEP_TIMES[preset]


def assert_stopped_short(preset: str, result: Any) -> None:
    assert result.summary["violations"] == [], result.summary["violations"]
    assert any(e["kind"] == "estop" and e["source"] == "move" for e in result.summary["events"])
    assert float(result.trace[-1]["x_m"]) < OBSTACLE[0] - PRESETS[preset].length_m


# --------------------------------------------------------------------------- pose steps

@pytest.mark.variants   # `make test`: one case in four and the edges; `make test-variants`: all
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("step_m", "direction_rad"), [
    pytest.param(0.3, -math.pi / 2, marks=pytest.mark.variant_edge),
    pytest.param(0.8, -math.pi / 2, marks=pytest.mark.variant_edge),   # the issue's case
    (0.8, math.pi / 2), (1.5, math.pi), (3.0, 0.0), (3.0, -math.pi / 2),
    (5.0, -3 * math.pi / 4), pytest.param(5.0, math.pi / 4, marks=pytest.mark.variant_edge)])
def test_a_gps_position_step_after_the_obstacle_left_the_cone_never_reaches_it(
        preset: str, step_m: float, direction_rad: float) -> None:
    """Steps of 0.3-5 m in all directions (towards the obstacle's side, away, along): the
    memory is dead-reckoned, so the vehicle stops short; a step beyond the bound is fault
    1105 at the step."""
    at_s = left_cone_s(preset)
    result = run(preset, [move(80.0, 2.0), error(at_s, quantity="gps_position", bias=step_m,
                                                 direction_rad=direction_rad)],
                 {"obstacles": [{"x_m": OBSTACLE[0], "y_m": OBSTACLE[1]}]})
    assert outside_cone(preset, row_at(result, at_s)), "the step comes after the cone lost it"
    assert_stopped_short(preset, result)
    faults = codes(result, PlausibilityFault.GPS_POSITION_STEP)
    # the bound at 2 m/s: position_step_m + 2 m/s x 20 ms of time-stamp slack; within 0.1 m of
    # it the position noise decides (0.3 m is there)
    bound_m = PRESETS[preset].position_step_m + 2.0 * 0.02
    if step_m > bound_m + 0.1:
        assert faults and all(abs(f["t_s"] - at_s) <= 0.02 for f in faults), faults
    elif step_m < bound_m - 0.1:
        assert faults == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("step_rad", [-0.3, -0.06, 0.06, 0.3])
def test_a_gps_heading_step_never_turns_the_remembered_obstacle(preset: str,
                                                                step_rad: float) -> None:
    at_s = left_cone_s(preset)
    result = run(preset, [move(80.0, 2.0), error(at_s, quantity="gps_heading", bias=step_rad)],
                 {"obstacles": [{"x_m": OBSTACLE[0], "y_m": OBSTACLE[1]}]})
    assert_stopped_short(preset, result)
    assert codes(result, PlausibilityFault.GPS_HEADING_STEP), "a step beyond 0.05 rad is a fault"


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("drift_mps", [-0.5, -0.1, 0.1, 0.5])
def test_a_slow_lateral_gps_drift_never_moves_the_remembered_obstacle(preset: str,
                                                                     drift_mps: float) -> None:
    """Drifting sideways from before the obstacle is seen until the stop (too slow to be a
    step: no fault required), either side."""
    result = run(preset, [move(80.0, 2.0), error(5.0, quantity="gps_position",
                                                 drift_per_s=drift_mps,
                                                 direction_rad=math.pi / 2)],
                 {"obstacles": [{"x_m": OBSTACLE[0], "y_m": OBSTACLE[1]}]})
    assert_stopped_short(preset, result)


# --------------------------------------------------------------------------- speed drift

LIMIT_MPS = 8.0


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("rate_mps2", [pytest.param(-0.5, marks=pytest.mark.variant_edge), -0.1,
                                       -0.03, 0.03, 0.1,
                                       pytest.param(0.5, marks=pytest.mark.variant_edge)])
def test_a_drifting_gps_speed_is_outvoted_and_a_fault_past_the_bound(preset: str,
                                                                      rate_mps2: float) -> None:
    """GPS/INS speed bias growing at ``rate_mps2`` (both signs), the wheels healthy: true speed
    never above the limit by more than the judge allows; once the bias passes the vehicle
    file's bound (plus the confirmation time) fault 1107 has been raised."""
    p = PRESETS[preset]
    at_s = 6.0
    result = run(preset, [move(1000.0, LIMIT_MPS),
                          error(at_s, quantity="gps_speed", drift_per_s=rate_mps2)],
                 duration_s=40.0)
    assert result.summary["violations"] == [], result.summary["violations"]
    peak = max(float(r["speed_mps"]) for r in result.trace)
    assert peak <= LIMIT_MPS + JUDGE_SPEED_TOLERANCE_MPS
    bound_mps = p.speed_disagree_fault_mps + p.speed_disagree_fault_frac * (LIMIT_MPS + 1.0)
    due_s = at_s + bound_mps / abs(rate_mps2) + p.speed_disagree_confirm_s + 0.2
    faults = codes(result, PlausibilityFault.SPEED_DISAGREE)
    if due_s < 40.0:
        assert faults and min(f["t_s"] for f in faults) <= due_s, (due_s, faults)
    early = at_s + (p.speed_disagree_fault_mps) / abs(rate_mps2)
    assert all(f["t_s"] >= early for f in faults), "no fault before the bias reaches the bound"


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("quantity", "body"), [
    ("gps_speed", {"bias": -1.0}), ("gps_speed", {"scale": 0.85}),
    ("wheel_speed", {"scale": 0.85}), ("wheel_speed", {"bias": -1.0}),
    ("imu_accel", {"bias": 0.3})])
def test_a_speed_sensor_that_steps_or_scales_low_never_lets_the_vehicle_speed(
        preset: str, quantity: str, body: dict) -> None:
    result = run(preset, [move(1000.0, LIMIT_MPS), error(6.0, quantity=quantity, **body)],
                 duration_s=25.0)
    assert result.summary["violations"] == [], result.summary["violations"]
    peak = max(float(r["speed_mps"]) for r in result.trace)
    assert peak <= LIMIT_MPS + JUDGE_SPEED_TOLERANCE_MPS


# --------------------------------------------------------------------------- no false alarms

ISSUE_30_FAULTS = {str(int(c)) for c in (PlausibilityFault.GPS_POSITION_STEP,
                                         PlausibilityFault.GPS_HEADING_STEP,
                                         PlausibilityFault.SPEED_DISAGREE,
                                         PlausibilityFault.GPS_NO_SOLUTION)}


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("gps_noise_m", "speed_noise_mps"), [(0.02, 0.02), (0.3, 0.05)])
@pytest.mark.parametrize(("drive", "friction"), [("obstacle", 0.8), ("obstacle", 0.3),
                                                 ("curve", 0.8), ("curve", 0.3)])
def test_nominal_drives_raise_no_sensor_fault(preset: str, gps_noise_m: float,
                                              speed_noise_mps: float, drive: str,
                                              friction: float) -> None:
    """Accelerating to 8 m/s and braking hard for an obstacle (ABS on low friction: the wheels
    read 15 % under the ground), or a curve, with RTK and float-grade position noise (the
    receiver reports its sigma): no issue-30 fault."""
    vehicle = {"preset": preset, "gps_noise_m": gps_noise_m, "speed_noise_mps": speed_noise_mps}
    if drive == "obstacle":
        events, world = [move(200.0, 8.0)], {"friction": friction,
                                             "obstacles": [{"x_m": 80.0, "y_m": 0.0}]}
    else:
        events = [{"at_s": 0.5, "move": {"distance_m": 80.0, "maxspeed_mps": 6.0,
                                         "curvature_1pm": 0.03}}]
        world = {"friction": friction}
    result = run(vehicle, events, world, duration_s=30.0)
    assert result.summary["violations"] == []
    found = [e for e in result.summary["events"] if e.get("code") in ISSUE_30_FAULTS]
    assert found == []
    if drive == "obstacle":
        assert max(float(r["speed_mps"]) for r in result.trace) > 5.0
        assert any(e["kind"] == "estop" for e in result.summary["events"])


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_receiver_without_a_solution_is_untrusted_and_a_change_is_reported(preset: str) -> None:
    result = run(preset, [move(40.0, 4.0),
                          {"at_s": 5.0, "gps_status": {"solution": "rtk_float",
                                                       "position_sigma_m": 0.3}},
                          {"at_s": 7.0, "gps_status": {"solution": "none",
                                                       "position_sigma_m": 10.0}}],
                 duration_s=25.0)
    assert result.summary["violations"] == []
    changes = [e for e in result.summary["events"] if e.get("code") == "gps_solution"]
    assert {round(e["t_s"]) for e in changes} == {5, 7}
    assert codes(result, PlausibilityFault.GPS_NO_SOLUTION)
    assert codes(result, PlausibilityFault.GPS_POSITION_STEP) == [], \
        "float-grade noise under its reported sigma is no step"


SWEEP = Path(__file__).resolve().parents[2] / "scenarios" / "sweep-move.yaml"


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("run_index", [0, 1, 2, 3, 4, 5])
def test_sampled_runs_of_the_move_sweep_raise_no_sensor_fault(preset: str, run_index: int) -> None:
    """The Monte Carlo sweep's runs (friction, grade, obstacle and event times sampled; a GPS
    dropout, a brake fade, a SafeStop pause, a radar e-stop): no issue-30 fault."""
    data = read_scenario_data(SWEEP)
    spec = load_scenario(SWEEP).spec
    # the file's expectations are the escape's (the slower ranger may not finish in 45 s, on
    # main too): the judge's invariants and the faults are what count here
    data = {k: v for k, v in data.items() if k != "expect"}
    sampled, _ = sample_run(dict(data, vehicle=preset), run_index, spec.seed, spec.sweep)
    result = run_scenario(parse_scenario(sampled), None, plot=False, record_mcap=False)
    assert result.summary["violations"] == []
    assert [e for e in result.summary["events"] if e.get("code") in ISSUE_30_FAULTS] == []
