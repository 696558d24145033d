"""Whole runs: noisy but healthy sensors must not stop the vehicle (no e-stop, no engine cut, no
rejected MOVE): GPS/INS noise while driving and at a standstill, IMU noise at a hill start.

Judged only by the independent judge (``summary["violations"]``) and by ground truth (the
trace's x/y and speed), never by the stack's view of itself. A known defect is a strict xfail
naming what happens, with figures.
"""

from __future__ import annotations

import pytest

from tests.conftest import PRESET_NAMES
from tests.safety.fault_runs import (
    estops,
    final_x_m,
    move,
    run,
    sensor,
)


@pytest.mark.parametrize(("preset", "speed_mps", "sigma_m", "distance_m"), [
    *[(preset, 8.0, 1.5, 60.0) for preset in PRESET_NAMES], ("escape-hybrid", 2.0, 0.5, 30.0)])
def test_noisy_gps_does_not_stop_a_healthy_vehicle(preset: str, speed_mps: float, sigma_m: float,
                                                   distance_m: float) -> None:
    result = run(preset, duration_s=22.0, events=[
        move(0.5, distance_m, speed_mps), sensor(3.0, "gps", "noise", for_s=8.0, sigma=sigma_m)])
    assert result.summary["violations"] == []
    assert estops(result) == []
    assert final_x_m(result) > distance_m - 2.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_noisy_gps_at_standstill_does_not_cut_the_engine_of_a_healthy_vehicle(preset: str) -> None:
    """GPS/INS noise of 1 m / 1 m/s (1 sigma) for 5 s on a healthy vehicle at standstill: the
    speed server read the noisy speed as a brake that does not hold (1134 at 1.32 s, 1136 at
    1.53 s), cut the engine and e-stopped. The brake's response is not judged while the parking
    brake holds the vehicle (issue 30 item 4), so no false alarm."""
    result = run(preset, duration_s=8.0, events=[
        sensor(0.3, "gps", "noise", for_s=5.0, sigma=1.0), move(0.5, 30, 5)])
    assert estops(result) == []
    assert result.trace[-1]["engine"] == "running"


def test_slight_gps_noise_at_standstill_does_not_reject_a_move() -> None:
    """GPS/INS noise of 0.1 m / 0.1 m/s (the sweep's smallest) at standstill, seed 1: the move
    server once took the noisy GPS speed over the wheel speed (0) and rejected the MOVE ('vehicle
    still moving reverse at 0.12 m/s: MOVE needs a standstill first'; 3 of seeds 1-8). A command
    in the other direction now replaces the one in force (it stops first, issue 31 item 9), so
    the healthy stopped vehicle drives its 30 m."""
    result = run("escape-hybrid", duration_s=12.0, seed=1, events=[
        sensor(0.3, "gps", "noise", for_s=1.0, sigma=0.1), move(0.5, 30, 5)])
    assert not [e for e in result.summary["events"] if e["kind"] == "rejected"]
    assert final_x_m(result) > 29.0


def test_imu_noise_at_a_hill_start_is_no_false_alarm() -> None:
    """IMU noise of 2 m/s^2 (the sweep's top) while starting up 15 %: the MOVE completes."""
    result = run("ranger-6x6", duration_s=25.0, world={"grade_percent": 15}, events=[
        sensor(0.3, "imu", "noise", for_s=5.0, sigma=2.0), move(0.5, 30, 5)])
    assert result.summary["violations"] == []
    assert estops(result) == []
    assert final_x_m(result) > 29.0
