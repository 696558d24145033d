"""Issue 16 red team: the merged stack attacked from outside, with faults combined and at times the
parts' own tests did not try, and with noisy but healthy sensors that must not stop the vehicle.

Judged only by the independent judge (``summary["violations"]``) and by ground truth (the
trace's x/y and speed), never by the stack's view of itself. Attacks that found a defect are
strict xfails naming what happens, with figures; a few attacks that found nothing are kept as
guards.
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES


def run(vehicle: str, events: list[dict], world: dict | None = None, duration_s: float = 30.0,
        start: str = "ready", seed: int = 7) -> Any:
    data = {"name": "redteam-16", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "seed": seed, "world": world or {}, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def move(at_s: float, distance_m: float, speed_mps: float, curvature_1pm: float = 0.0) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                   "curvature_1pm": curvature_1pm}}


def sensor(at_s: float, name: str, fault: str, for_s: float = 60.0, sigma: float = 1.0) -> dict:
    return {"at_s": at_s, "sensor": {"name": name, "fault": fault, "for_s": for_s, "sigma": sigma}}


def actuator(at_s: float, **body: Any) -> dict:
    return {"at_s": at_s, "actuator": body}


def rules_of(result: Any) -> set[str]:
    return {d["rule"] for d in result.summary["violation_details"]}


def peak_speed_mps(result: Any) -> float:
    return max(float(r["speed_mps"]) for r in result.trace)


def final_x_m(result: Any) -> float:
    return float(result.trace[-1]["x_m"])


def estops(result: Any) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == "estop"]


# --------------------------------------------------------------------------- defects found

@pytest.mark.parametrize(("preset", "radar_fault", "speed_mps", "obstacle"), [
    *[(preset, "dropout", 8.0, {"x_m": 60, "y_m": 0.4}) for preset in PRESET_NAMES],
    ("escape-hybrid", "freeze", 8.0, {"x_m": 60, "y_m": 0.4}),
    ("escape-hybrid", "dropout", 3.0, {"x_m": 30, "y_m": 0.0})])
def test_bad_radar_and_frozen_gps_together_still_stop_before_a_seen_obstacle(
        preset: str, radar_fault: str, speed_mps: float, obstacle: dict) -> None:
    result = run(preset, duration_s=14.0, world={"obstacles": [obstacle]}, events=[
        move(0.5, 100, speed_mps), sensor(3.0, "radar", radar_fault), sensor(3.5, "gps", "freeze")])
    assert "contact" not in rules_of(result), result.summary["violations"]
    assert final_x_m(result) < obstacle["x_m"] - 1.0


@pytest.mark.xfail(strict=True, reason=(
    "issue 16 red team: GPS/INS, wheel speed and IMU all frozen at 4 s during a 60 m MOVE at 8 m/s: "
    "no trusted speed is left, yet nothing is raised for 5 s; the vehicle speeds up to 12.82 m/s "
    "(escape-hybrid; 8.70 m/s ranger-6x6) against the 8 m/s limit before faults 1134/1136 e-stop it "
    "at 9.3 s (7.3 s); the issue asks for an emergency stop as soon as no speed is trusted"))
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_all_motion_sensors_frozen_at_cruise_stop_without_overspeed(preset: str) -> None:
    result = run(preset, duration_s=12.0, events=[
        move(0.5, 60, 8), sensor(4.0, "gps", "freeze"), sensor(4.0, "wheel_speed", "freeze"),
        sensor(4.0, "imu", "freeze")])
    assert result.summary["violations"] == []
    assert peak_speed_mps(result) < 8.3


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_weak_brake_on_a_downhill_stays_inside_the_authorization(preset: str) -> None:
    result = run(preset, duration_s=14.0, world={"grade_percent": -10}, events=[
        actuator(0.2, brake={"effectiveness": 0.3}), move(0.5, 40, 8)])
    assert result.summary["violations"] == []


@pytest.mark.parametrize(("preset", "speed_mps", "sigma_m", "distance_m"), [
    *[(preset, 8.0, 1.5, 60.0) for preset in PRESET_NAMES], ("escape-hybrid", 2.0, 0.5, 30.0)])
def test_noisy_gps_does_not_stop_a_healthy_vehicle(preset: str, speed_mps: float, sigma_m: float,
                                                   distance_m: float) -> None:
    result = run(preset, duration_s=22.0, events=[
        move(0.5, distance_m, speed_mps), sensor(3.0, "gps", "noise", for_s=8.0, sigma=sigma_m)])
    assert result.summary["violations"] == []
    assert estops(result) == []
    assert final_x_m(result) > distance_m - 2.0


@pytest.mark.xfail(strict=True, reason=(
    "issue 16 red team, false alarm: GPS/INS noise of 1 m / 1 m/s (1 sigma; 0.5 m does it too, at "
    "2.8 s) for 5 s on a healthy vehicle at standstill: the speed server reads the noisy GPS speed "
    "as a brake that does not hold (fault 1134 at 1.32 s, 1136 at 1.53 s), cuts the engine and "
    "e-stops, both presets; the vehicle never moves (0.00 m of a 30 m MOVE) and stays stopped after "
    "the noise ends"))
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_noisy_gps_at_standstill_does_not_cut_the_engine_of_a_healthy_vehicle(preset: str) -> None:
    result = run(preset, duration_s=8.0, events=[
        sensor(0.3, "gps", "noise", for_s=5.0, sigma=1.0), move(0.5, 30, 5)])
    assert estops(result) == []
    assert result.trace[-1]["engine"] == "running"


@pytest.mark.xfail(strict=True, reason=(
    "issue 16 red team, false alarm: GPS/INS noise of 0.1 m / 0.1 m/s (the sweep's smallest) at "
    "standstill (seed 1; 3 of seeds 1-8 are rejected): the move server takes the noisy GPS speed over the wheel speed (0) and rejects the "
    "MOVE ('vehicle still moving reverse at 0.12 m/s: MOVE needs a standstill first') and the "
    "driving module raises 'hard_brake' notices for 0.15-0.26 m/s of GPS speed noise; the healthy "
    "stopped vehicle does not drive the MOVE (0.00 m of 30 m; the scenario sends it once)"))
def test_slight_gps_noise_at_standstill_does_not_reject_a_move() -> None:
    result = run("escape-hybrid", duration_s=12.0, seed=1, events=[
        sensor(0.3, "gps", "noise", for_s=1.0, sigma=0.1), move(0.5, 30, 5)])
    assert not [e for e in result.summary["events"] if e["kind"] == "rejected"]
    assert final_x_m(result) > 29.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_brakes_at_20_percent_from_the_start_as_shipped_stay_inside_a_40_m_move(preset: str) -> None:
    result = run(preset, duration_s=14.0, events=[
        actuator(0.2, brake={"effectiveness": 0.2}), move(0.5, 40, 8)])
    assert result.summary["violations"] == []


# --------------------------------------------------------------------------- attacks that held

@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_frozen_gps_then_stuck_throttle_at_cruise_stops_inside_the_authorization(preset: str) -> None:
    """Two faults at once: the speed loop already runs on the wheel speed when the throttle sticks."""
    result = run(preset, duration_s=14.0, events=[
        move(0.5, 60, 8), sensor(4.0, "gps", "freeze"), actuator(6.0, throttle={"stuck": True})])
    assert result.summary["violations"] == []
    assert estops(result)
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert final_x_m(result) < 30.0


@pytest.mark.parametrize("at_s", [0.55, 0.9])
def test_throttle_stuck_at_launch_downhill_barely_moves(at_s: float) -> None:
    result = run("escape-hybrid", duration_s=6.0, world={"grade_percent": -15}, events=[
        move(0.5, 15, 3), actuator(at_s, throttle={"stuck": True})])
    assert result.summary["violations"] == []
    assert estops(result)
    assert final_x_m(result) < 1.0   # the stuck check needs 0.3 s (three status periods at most)


def test_imu_noise_at_a_hill_start_is_no_false_alarm() -> None:
    """IMU noise of 2 m/s^2 (the sweep's top) while starting up 15 %: the MOVE completes."""
    result = run("ranger-6x6", duration_s=25.0, world={"grade_percent": 15}, events=[
        sensor(0.3, "imu", "noise", for_s=5.0, sigma=2.0), move(0.5, 30, 5)])
    assert result.summary["violations"] == []
    assert estops(result) == []
    assert final_x_m(result) > 29.0
