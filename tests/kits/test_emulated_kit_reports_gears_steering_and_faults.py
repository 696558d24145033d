"""What the emulated PACMod 3 kit reports and does with the vehicle: every report at 30 Hz,
BETWEEN_GEARS while a shift lasts, a left steering-wheel angle turns the vehicle left by the
road-wheel angle the vehicle's variable ratio gives, a stuck actuator is a latched fault that
disables its system until the actuator works and clear_faults is sent, and report silence stops
every report for its window. Judged from the vehicle's ground truth."""

from __future__ import annotations

import itertools
import math

import pytest

from overdrive.dynamics.steering_ratio import road_wheel_rad
from overdrive.kits.pacmod3 import (
    AccelRpt,
    BrakeRpt,
    Gear,
    GlobalRpt,
    ShiftRpt,
    SteeringRpt,
    VehicleSpeedRpt,
    WheelSpeedRpt,
    YawRateRpt,
)
from overdrive.messages import SafetyDevices
from overdrive.vehicle.pacmod3_kit import REPORT_PERIOD_S, KitFault, accel_effort, brake_effort
from overdrive.vehicle.plant import ActuatorFaults
from tests.kits.kit_driver import KitDriver, command, drive_stream, lexus_kit

REPORTS = (GlobalRpt, AccelRpt, BrakeRpt, SteeringRpt, ShiftRpt, VehicleSpeedRpt, WheelSpeedRpt,
           YawRateRpt)


def test_every_report_comes_at_30_hz() -> None:
    d = KitDriver(lexus_kit())
    d.advance(3.0)
    for cls in REPORTS:
        times = [t for t, r in d.reports if isinstance(r, cls)]
        gaps = [b - a for a, b in itertools.pairwise(times)]
        assert len(times) == pytest.approx(3.0 / REPORT_PERIOD_S, abs=1.5)
        assert max(gaps) <= REPORT_PERIOD_S + 0.01 + 1e-9   # within one 10 ms step


def test_report_silence_stops_every_report_for_its_window_only() -> None:
    d = KitDriver(lexus_kit(faults=(KitFault(kind="silence", start_s=1.0, end_s=2.0),)))
    d.advance(3.0)
    times = [t for t, _ in d.reports]
    assert not [t for t in times if 1.0 <= t < 2.0 - 1e-9]
    assert [t for t in times if t < 1.0] and [t for t in times if t > 2.0]


def test_a_shift_reports_between_gears_while_it_lasts_then_the_gear() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.2, drive_stream(brake=0.5))
    shift_at = d.now_s
    d.advance(1.5, drive_stream(brake=0.5, gear=Gear.FORWARD))
    seen = [(t, r.output_value) for t, r in d.reports if isinstance(r, ShiftRpt) and t > shift_at]
    between = [t for t, g in seen if g == Gear.BETWEEN_GEARS]
    assert between and max(between) - min(between) == pytest.approx(
        d.kit.params.shift_time_s, abs=2 * REPORT_PERIOD_S)
    assert seen[-1][1] == Gear.FORWARD and d.kit.plant.gear == "drive"
    assert all(g == Gear.PARK for t, g in seen if t < min(between))


@pytest.mark.parametrize("wheel_rad", [-6.0, -2.0, -0.5, 0.5, 2.0, 6.0])
def test_the_steering_wheel_angle_turns_the_road_wheels_through_the_variable_ratio(
        wheel_rad: float) -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.2, drive_stream(brake=0.5, gear=Gear.FORWARD))
    d.advance(3.0, drive_stream(brake=0.5, steer_rad=wheel_rad, gear=Gear.FORWARD))
    truth = d.kit.truth(d.now_s)
    expected_left = road_wheel_rad(d.kit.params.steering_ratio, wheel_rad)
    assert -truth.road_wheel_rad == pytest.approx(expected_left, abs=1e-3)
    assert d.last_report(SteeringRpt).output_value == pytest.approx(wheel_rad, abs=2e-3)
    # and the vehicle turns that way: heading rises (left) for a positive wheel angle
    d.advance(8.0, drive_stream(accel=0.35, steer_rad=wheel_rad, gear=Gear.FORWARD))
    truth = d.kit.truth(d.now_s)
    assert truth.odometer_m > 2.0
    assert math.copysign(1.0, truth.heading_rad) == math.copysign(1.0, wheel_rad)
    assert math.copysign(1.0, d.last_report(YawRateRpt).yaw_rate_radps) == math.copysign(
        1.0, wheel_rad)


def test_a_steering_wheel_angle_past_full_lock_is_refused_not_clamped() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    past = d.kit.max_wheel_rad + 0.01
    d.advance(1.0, drive_stream(brake=0.5, steer_rad=past))
    assert d.kit.bad_frames.get("out_of_range", 0) >= 25
    assert d.kit.truth(d.now_s).road_wheel_rad == 0.0


def test_the_steering_rate_limit_is_the_commanded_one() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.2, drive_stream(brake=0.5))
    d.advance(0.7, lambda t: [command("brake", True, 0.5),
                              command("steering", True, 4.0, rate=1.0)])
    assert d.kit.wheel_target_rad == pytest.approx(0.5, abs=0.02)   # 0.5 s at 1 rad/s


@pytest.mark.parametrize("system, plant_fault", [("accel", "throttle_stuck"),
                                                 ("brake", "brake_stuck"),
                                                 ("steering", "steering_stuck")])
def test_a_stuck_actuator_is_a_latched_fault_until_it_works_and_faults_are_cleared(
        system: str, plant_fault: str) -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5))
    d.kit.apply_actuator_faults(ActuatorFaults(**{plant_fault: True}))
    d.advance(1.0, drive_stream(brake=0.5))
    rpt = {"accel": AccelRpt, "brake": BrakeRpt, "steering": SteeringRpt}[system]
    assert d.last_report(rpt).output_reported_fault and not d.kit.systems[system].enabled
    assert d.last_report(GlobalRpt).fault_active
    d.kit.apply_actuator_faults(ActuatorFaults())          # works again: still latched
    d.advance(1.3, drive_stream(brake=0.5, enable=False))
    d.advance(1.5, drive_stream(brake=0.5))
    assert not d.kit.systems[system].enabled
    d.advance(1.7, drive_stream(brake=0.5, enable=False, clear_faults=True))
    d.advance(2.0, drive_stream(brake=0.5))
    assert d.kit.systems[system].enabled and not d.last_report(GlobalRpt).fault_active


def test_the_pedal_maps_are_the_kits_own_nonlinear_curves() -> None:
    assert accel_effort(0.05) == 0.0 and brake_effort(0.03) == 0.0        # dead bands
    for f in (accel_effort, brake_effort):
        mid = f(0.5)
        assert 0.0 < mid < 0.5 - 0.05                                     # not linear
        assert f(1.0) == 1.0 and all(f(a / 20) <= f((a + 1) / 20) for a in range(20))


def test_a_scenario_override_released_can_be_cleared_and_re_engaged() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5))
    d.kit.set_devices(SafetyDevices(manual_override=True))
    d.advance(1.0, drive_stream(brake=0.5))
    d.kit.set_devices(SafetyDevices())
    d.advance(1.2, drive_stream(brake=0.5, enable=False))
    d.advance(1.5, drive_stream(brake=0.5, clear_override=True))
    assert d.kit.truth(d.now_s).enabled == ("accel", "brake", "steering", "shift")
