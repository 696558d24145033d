"""The pedal and steering monitors (``safety.actuators``) near full travel: every e-stop commands
100 % brake and a real brake settles a little short, so a brake or throttle near full travel, or
steering near full lock, follows; only one clearly short is stuck. Small commands keep the
strict gap. Each threshold just inside and just outside."""

from __future__ import annotations

import pytest

from overdrive.safety.actuators import (
    ActuatorFault,
    ActuatorMonitorConfig,
    PedalMonitor,
    SteeringMonitor,
)
from overdrive.scenario.vehicles import PRESETS

CFG = ActuatorMonitorConfig()


def brake_found(command_pct: float, actual_pct: float, steps: int = 100) -> list:
    m = PedalMonitor(PRESETS["escape-hybrid"])
    found = []
    for _ in range(steps):
        found += m.update(0.01, armed=True, throttle_cmd_pct=0.0, throttle_pct=0.0,
                          brake_cmd_pct=command_pct, brake_pct=actual_pct, direction=1,
                          speed_mps=0.0, accel_x_mps2=None, pitch_rad=0.0, slipping=False)
    return [f.code for f in found]


@pytest.mark.parametrize(("command_pct", "actual_pct", "stuck"), [
    (100.0, 97.0, False), (100.0, 90.0, False), (100.0, 50.0, False),
    (100.0, CFG.brake_short_pct + 0.1, False), (100.0, CFG.brake_short_pct - 0.1, True),
    (100.0, 0.0, True), (30.0, 15.1, False), (30.0, 14.9, True),
    (8.0, 8.0 - CFG.pedal_gap_pct + 0.1, False), (8.0, 8.0 - CFG.pedal_gap_pct - 0.1, True),
    (9.9, 9.9 - CFG.pedal_gap_pct - 0.1, True)])
def test_brake_not_applying_only_when_clearly_short(command_pct: float, actual_pct: float,
                                                     stuck: bool) -> None:
    """Every e-stop commands 100 %: a brake settling at 97 % follows; a stuck-released one sits
    near 0. Small commands keep the strict gap."""
    assert (brake_found(command_pct, actual_pct) == [ActuatorFault.BRAKE_NOT_APPLYING]) is stuck


@pytest.mark.parametrize(("command_pct", "actual_pct", "stuck"), [
    (100.0, 97.0, False), (100.0, CFG.full_travel_pct + 0.1, False),
    (100.0, CFG.full_travel_pct - 0.1, True), (50.0, 50.0 - CFG.pedal_gap_pct - 0.1, True),
    (50.0, 50.0 - CFG.pedal_gap_pct + 0.1, False)])
def test_throttle_near_full_travel_follows(command_pct: float, actual_pct: float,
                                          stuck: bool) -> None:
    m = PedalMonitor(PRESETS["escape-hybrid"])
    found = []
    for _ in range(100):
        found += m.update(0.01, armed=True, throttle_cmd_pct=command_pct, throttle_pct=actual_pct,
                          brake_cmd_pct=0.0, brake_pct=0.0, direction=1, speed_mps=5.0,
                          accel_x_mps2=None, pitch_rad=0.0, slipping=False)
    assert ([f.code for f in found] == [ActuatorFault.THROTTLE_STUCK_CLOSED]) is stuck


@pytest.mark.parametrize(("command_pct", "actual_pct", "stuck"), [
    (-100.0, -96.0, False), (100.0, 93.0, False), (100.0, 80.0, True), (-40.0, -30.0, True)])
def test_steering_near_full_lock_follows(command_pct: float, actual_pct: float,
                                        stuck: bool) -> None:
    m = SteeringMonitor(PRESETS["escape-hybrid"])
    found = [m.update(0.01, armed=True, command_pct=command_pct, actual_pct=actual_pct,
                      speed_mps=5.0, yaw_rate_rps=0.0) for _ in range(100)]
    assert any(f is not None for f in found) is stuck
