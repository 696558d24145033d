"""The motion-sensing plausibility checker (``safety.plausibility``) at a standstill: a static
hold repeating the same GPS/INS reading and a wheel speed of 0 is a zero-velocity update, so an
IMU bias is no fault and the vehicle starts; both speeds repeating 0 while the IMU shows a real
acceleration are still frozen."""

from __future__ import annotations

import pytest

from overdrive.messages import WheelSpeed
from overdrive.safety.plausibility import MotionPlausibility, PlausibilityFault
from tests.sensor_messages import gps_ins as gps
from tests.sensor_messages import imu

DT_S = 0.01


def stand_then_drive(bias_mps2: float, stand_s: float = 10.0, drive_s: float = 5.0,
                     accel_mps2: float = 1.0):
    """Feed one checker: a standstill with exact repeats (static hold, wheel speed 0.0) and an
    IMU with ``bias_mps2`` plus varying noise, then a start at ``accel_mps2``."""
    m = MotionPlausibility("test")
    notices, speeds = [], []
    v = odo = 0.0
    n_stand = round(stand_s / DT_S)
    for i in range(n_stand + round(drive_s / DT_S)):
        t = i * DT_S
        a = 0.0 if i < n_stand else accel_mps2
        noise = 1e-3 * ((i * 7) % 11 - 5)
        if i < n_stand:
            m.gps(t, gps(x_m=5.0, odometer_m=5.0))         # static hold: one exact reading
            m.wheel(t, WheelSpeed(speed_mps=0.0))
        else:
            v += a * DT_S
            odo += v * DT_S
            m.gps(t, gps(x_m=5.0 + odo, speed_mps=v + noise, odometer_m=5.0 + odo))
            m.wheel(t, WheelSpeed(speed_mps=v - noise))
        m.imu(t, imu(a + bias_mps2 + noise))
        notices += m.step(t, 1)
        speeds.append(m.speed_mps)
    return notices, speeds


@pytest.mark.parametrize("bias_mps2", [0.05, 0.09, 0.15, -0.09, -0.15])
def test_a_standstill_with_exact_repeats_and_an_imu_bias_is_no_fault(bias_mps2: float) -> None:
    notices, speeds = stand_then_drive(bias_mps2)
    assert notices == []
    assert speeds[-1] is not None and speeds[-1] > 4.0   # it started and drives


@pytest.mark.parametrize("accel_mps2", [0.5, 1.0, -0.5])
def test_both_speeds_frozen_at_zero_while_the_imu_accelerates_is_still_a_fault(
        accel_mps2: float) -> None:
    """GPS/INS and wheel speed repeat 0 while the IMU shows a real acceleration: frozen."""
    m = MotionPlausibility("test")
    codes = set()
    for i in range(300):
        t = i * DT_S
        m.gps(t, gps(x_m=5.0, odometer_m=5.0))
        m.wheel(t, WheelSpeed(speed_mps=0.0))
        m.imu(t, imu(accel_mps2 + 1e-3 * (i % 7)))
        codes |= {int(n.code) for n in m.step(t, 1)}
    assert int(PlausibilityFault.NO_TRUSTED_SPEED) in codes
