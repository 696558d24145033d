"""Adaptive actuator estimates and speed-reduction conditions, against the plant model."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.servers.adaptive import ActuatorModel, AdaptiveConfig, RatioEstimator
from overdrive.servers.move_conditions import ConditionMonitor
from overdrive.vehicle.plant import ActuatorFaults, Plant, World

DT = 0.01


# ----------------------------------------------------------------------------- estimator

def test_ratio_estimator_believes_a_drop_fast_and_a_recovery_slowly() -> None:
    est = RatioEstimator(AdaptiveConfig())
    for _ in range(100):                      # 1 s of excited time at 0.6
        est.update(0.6, DT)
    assert est.value == pytest.approx(0.6, abs=0.02)
    for _ in range(100):                      # 1 s back at nominal
        est.update(1.0, DT)
    assert est.fast > 0.95
    assert est.value < 0.92 and est.value < est.fast - 0.05   # the slow average holds on


@given(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), max_size=200))
def test_ratio_estimator_stays_within_bounds(samples: list[float]) -> None:
    cfg = AdaptiveConfig()
    est = RatioEstimator(cfg)
    for r in samples:
        est.update(r, DT)
    lo, hi = cfg.estimate_bounds
    assert lo <= est.value <= hi
    assert cfg.sample_bounds[0] <= est.fast <= cfg.sample_bounds[1]


def test_outlier_samples_are_clamped() -> None:
    est = RatioEstimator(AdaptiveConfig())
    est.update(1000.0, DT)
    assert est.fast <= 1.5 and est.value == 1.0


# ----------------------------------------------------------------------------- against the plant

def drive(preset, faults: ActuatorFaults, throttle: float, brake: float, seconds: float,
          model: ActuatorModel, plant: Plant | None = None, steer_pct=None) -> Plant:
    plant = plant or Plant(preset, World(), random.Random(1), engine_running=True,
                           gear=preset.drive_gear)
    plant.faults = faults
    rng = random.Random(2)
    cmd = 0.0
    for i in range(round(seconds / DT)):
        if steer_pct is not None:
            cmd = steer_pct(i * DT)
        plant.step(DT, throttle, brake, cmd, plant.gear, True)
        accel_x = plant.accel_mps2 + G_MPS2 * math.sin(plant.pitch_rad) + rng.gauss(0.0, 0.05)
        model.update_pedals(DT, preset.gear(plant.gear).direction, plant.gear,
                            plant.speed_mps + rng.gauss(0.0, 0.02), accel_x, plant.pitch_rad,
                            100.0 * plant.throttle, 100.0 * plant.brake, plant.slip)
        model.update_steering(DT, cmd, 100.0 * plant.road_wheel_rad / preset.max_steer_rad)
    return plant


@pytest.mark.parametrize("effectiveness", [1.0, 0.8, 0.6, 0.4])
def test_brake_estimate_converges(preset, effectiveness: float) -> None:
    model = ActuatorModel(preset)
    plant = drive(preset, ActuatorFaults(), 40.0, 0.0, 8.0, model)
    assert plant.speed_mps > 5.0
    drive(preset, ActuatorFaults(brake_effectiveness=effectiveness), 0.0, 25.0, 2.5, model,
          plant)
    assert model.brake.fast == pytest.approx(effectiveness, abs=0.05)
    assert model.brake.value <= 1.0
    assert model.brake_decel_mps2 == pytest.approx(
        min(effectiveness, 1.0) * preset.max_brake_decel_mps2, rel=0.08)


@pytest.mark.parametrize("effectiveness", [1.0, 0.7])
def test_throttle_estimate_converges(preset, effectiveness: float) -> None:
    model = ActuatorModel(preset)
    drive(preset, ActuatorFaults(throttle_effectiveness=effectiveness), 30.0, 0.0, 5.0, model)
    assert model.throttle.fast == pytest.approx(effectiveness, abs=0.05)
    assert ("throttle" in model.degraded()) is (effectiveness < 0.8)


@pytest.mark.parametrize("scale", [1.0, 0.5, 0.3])
def test_steering_rate_estimate(preset, scale: float) -> None:
    model = ActuatorModel(preset)
    nominal = 100.0 * preset.steer_rate_rps / preset.max_steer_rad   # % of lock per s
    # the driving module ramps at 0.8 of the nominal rate: a healthy actuator never saturates
    ramp = lambda t: max(-80.0, min(80.0, 80.0 - 0.8 * nominal * abs(t % 4.0 - 2.0) * 1.0))  # noqa: E731
    drive(preset, ActuatorFaults(steering_rate_scale=scale), 10.0, 0.0, 8.0, model,
          steer_pct=ramp)
    assert model.steering.value == pytest.approx(min(scale, 1.0), abs=0.03)
    assert ("steering" in model.degraded()) is (scale < 0.85)


def test_no_brake_learning_without_signal(preset) -> None:
    model = ActuatorModel(preset)
    # standing with the brake on tells nothing about deceleration
    model.update_pedals(DT, 1, preset.drive_gear, 0.0, 0.0, 0.0, 0.0, 100.0, False)
    # ABS / traction control: the tyres limit, not the brake
    model.update_pedals(DT, 1, preset.drive_gear, 10.0, -2.0, 0.0, 0.0, 100.0, True)
    assert model.brake.samples == 0 and model.brake.value == 1.0


# ----------------------------------------------------------------------------- conditions

def monitor_update(mon: ConditionMonitor, now: float, **kw) -> None:
    base = dict(maxspeed_mps=8.0, pitch_rad=0.0, speed_mps=5.0, wheel_speed_mps=5.0,
                traction_control=False, hint="none", goal_speed_mps=5.0, throttle_pct=20.0,
                safety_mode="drive-by-wire", speed_server_estop=False, gps_age_s=0.0,
                lateral_cap_mps=math.inf, degraded=[], actuator_cap_mps=math.inf,
                actuator_reason="")
    base.update(kw)
    mon.update(now, **base)


def test_quiet_conditions_reduce_nothing(preset) -> None:
    mon = ConditionMonitor(preset)
    rng = random.Random(3)
    for i in range(300):
        mon.update_imu(DT, G_MPS2 + rng.gauss(0.0, preset.accel_noise_mps2))
        monitor_update(mon, i * DT)
    assert mon.active == {} and mon.cap_mps() == math.inf


@pytest.mark.parametrize("rough", [0.5, 1.5, 3.0, 6.0])
def test_bumpy(preset, rough: float) -> None:
    mon = ConditionMonitor(preset)
    rng = random.Random(4)
    started = []
    for i in range(400):
        mon.update_imu(DT, G_MPS2 + rng.gauss(0.0, rough))
        monitor_update(mon, i * DT)
        started += [r.code for r in mon.started]
    bumpy = rough > mon.config.bumpy_start_mps2 * 1.2
    assert ("bumpy" in mon.active) is bumpy
    assert started == (["bumpy"] if bumpy else [])
    if bumpy:
        assert mon.active["bumpy"].cap_mps < 8.0


def test_steep_sticky_estop_localization(preset) -> None:
    mon = ConditionMonitor(preset)
    monitor_update(mon, 0.0, pitch_rad=0.4 * preset.max_pitch_rad)
    assert "steep" not in mon.active
    monitor_update(mon, 0.01, pitch_rad=-0.9 * preset.max_pitch_rad)
    assert mon.active["steep"].cap_mps == pytest.approx(8.0 * 0.6)
    monitor_update(mon, 0.02, wheel_speed_mps=7.0)
    assert "sticky" in mon.active and mon.active["sticky"].cap_mps == 4.0
    monitor_update(mon, 2.0)
    assert "sticky" in mon.active                      # held
    monitor_update(mon, 3.1)
    assert "sticky" not in mon.active
    monitor_update(mon, 3.2, safety_mode="estop-pause")
    assert mon.active["estop"].cap_mps == 0.0 and mon.cap_mps() == 0.0
    monitor_update(mon, 3.3, gps_age_s=0.5)
    assert mon.active["localization"].cap_mps == 0.0


@pytest.mark.parametrize("explained", [False, True])
def test_not_keeping_up_is_sticky_unless_the_throttle_estimate_explains_it(
        preset, explained: bool) -> None:
    """A lag the throttle estimate explains (a weak throttle, capped as an actuator) is not
    sticky ground; one it does not (mud) is."""
    mon = ConditionMonitor(preset)
    for i in range(250):
        monitor_update(mon, i * DT, goal_speed_mps=6.0, speed_mps=3.0, wheel_speed_mps=3.0,
                       throttle_pct=95.0, lag_explained=explained)
    assert ("sticky" in mon.active) is not explained
    if not explained:
        assert "not keeping up" in mon.active["sticky"].reason


@pytest.mark.parametrize(("gps_age_s", "sticky"), [(0.0, True), (0.05, True), (0.06, False),
                                                    (0.15, False)])
def test_wheel_vs_ground_slip_only_against_fresh_gps(preset, gps_age_s: float, sticky: bool) -> None:
    """A stale GPS/INS speed during a dropout is not evidence of slip (no spurious reduction)."""
    mon = ConditionMonitor(preset)
    monitor_update(mon, 0.0, speed_mps=7.9, wheel_speed_mps=6.7, gps_age_s=gps_age_s)
    assert ("sticky" in mon.active) == sticky
