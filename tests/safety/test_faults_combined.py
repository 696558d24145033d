"""Whole runs: two or three faults at once, at times the single-fault sweeps do not try (a bad
radar with a frozen GPS/INS before an obstacle, every motion sensor frozen at cruise, a frozen
GPS/INS then a stuck throttle).

Judged only by the independent judge (``summary["violations"]``) and by ground truth (the
trace's x/y and speed), never by the stack's view of itself. A known defect is a strict xfail
naming what happens, with figures.
"""

from __future__ import annotations

import pytest

from tests.conftest import PRESET_NAMES
from tests.safety.fault_runs import (
    actuator,
    estops,
    final_x_m,
    move,
    peak_speed_mps,
    rules_of,
    run,
    sensor,
)


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


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("at_s", [0.2, 3.0])
def test_radar_dropout_and_gps_freeze_together_before_an_obstacle(preset: str, at_s: float) -> None:
    """Radar silent and GPS/INS frozen at once, an obstacle ahead: no contact and no
    authorization violation (the cap shrinks with the wheels' progress)."""
    from tests.safety import test_faults_radar as radar_sweep
    result = radar_sweep.run(preset, [radar_sweep.move(150.0, 9.0),
                                      {"at_s": at_s, "sensor": {"name": "radar",
                                                                "fault": "dropout", "for_s": 100}},
                                      {"at_s": at_s, "sensor": {"name": "gps", "fault": "freeze",
                                                                "for_s": 100}}],
                             {"obstacles": [{"x_m": 60, "y_m": 0.0}]}, duration_s=40)
    assert result.summary["violations"] == []


@pytest.mark.xfail(strict=True, reason=(
    "known defect (issue 16): GPS/INS, wheel speed and IMU all frozen at 4 s during a 60 m MOVE at 8 m/s: "
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
def test_frozen_gps_then_stuck_throttle_at_cruise_stops_inside_the_authorization(preset: str) -> None:
    """Two faults at once: the speed loop already runs on the wheel speed when the throttle sticks."""
    result = run(preset, duration_s=14.0, events=[
        move(0.5, 60, 8), sensor(4.0, "gps", "freeze"), actuator(6.0, throttle={"stuck": True})])
    assert result.summary["violations"] == []
    assert estops(result)
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert final_x_m(result) < 30.0
