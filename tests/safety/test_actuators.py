"""Unit tests of ``overdrive.safety.actuators``: each threshold just inside and just outside."""

from __future__ import annotations

import math

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.safety.actuators import (
    ActuatorFault,
    ActuatorMonitorConfig,
    BrakeProbe,
    BrakeResponse,
    FollowCheck,
    PedalMonitor,
    SteeringMonitor,
    brake_ratio,
)
from overdrive.scenario.vehicles import PRESETS
from tests.conftest import PRESET_NAMES

CFG = ActuatorMonitorConfig(probe_enabled=True)
DT = 0.01


def hold(check: FollowCheck, command: float, actual: float, seconds: float,
         armed: bool = True) -> bool:
    stuck = False
    for _ in range(round(seconds / DT)):
        stuck = check.update(DT, command, actual, armed)
    return stuck


def check(sense: int = +1) -> FollowCheck:
    return FollowCheck(sense, CFG.pedal_gap_pct, CFG.still_pct, CFG.hold_s)


@pytest.mark.parametrize(("gap_pct", "stuck"), [(CFG.pedal_gap_pct - 0.05, False),
                                                (CFG.pedal_gap_pct + 0.05, True)])
def test_follow_check_gap_threshold(gap_pct: float, stuck: bool) -> None:
    assert hold(check(), 50.0 + gap_pct, 50.0, 0.5) is stuck


@pytest.mark.parametrize(("seconds", "stuck"), [(CFG.hold_s - 0.02, False), (CFG.hold_s + 0.02, True)])
def test_follow_check_hold_time(seconds: float, stuck: bool) -> None:
    c = check()
    c.update(DT, 60.0, 50.0, True)   # anchors
    assert hold(c, 60.0, 50.0, seconds) is stuck


@pytest.mark.parametrize(("rate_pct_per_s", "stuck"), [(0.2, True), (4.0, False)])
def test_follow_check_a_moving_actuator_is_not_stuck(rate_pct_per_s: float, stuck: bool) -> None:
    """Still means less than still_pct in hold_s (0.67 %/s here): 0.2 %/s is stuck, 4 %/s moves."""
    c = check()
    actual = 10.0
    result = False
    for _ in range(100):
        actual += rate_pct_per_s * DT
        result = c.update(DT, 50.0, actual, True)
    assert result is stuck


@pytest.mark.parametrize("lag_scale", [1.0, 5.0])
def test_follow_check_healthy_and_slow_first_order_lags_never_trip(lag_scale: float) -> None:
    for params_name in PRESET_NAMES:
        p = PRESETS[params_name]
        for lag in (p.throttle_lag_s, p.brake_lag_s):
            c, actual = check(), 0.0
            for command in [100.0] * 200 + [0.0] * 200 + [30.0] * 200:
                actual += (command - actual) * (1.0 - math.exp(-DT / (lag * lag_scale)))
                assert not c.update(DT, command, actual, True)


def test_follow_check_senses_and_disarming() -> None:
    up, down = check(+1), check(-1)
    assert not hold(down, 60.0, 50.0, 0.5), "below the command: only the +1 sense"
    assert hold(up, 60.0, 50.0, 0.5)
    assert hold(up, 60.0, 50.0, 0.5, armed=False), "disarmed: a stuck actuator stays stuck"
    assert not up.update(DT, 50.0, 50.0, True), "reaching the command clears it"
    assert not hold(check(), 60.0, 50.0, 0.5, armed=False)


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("grade", [-0.15, 0.0, 0.15])
@pytest.mark.parametrize("effectiveness", [0.2, 1.0])
def test_brake_ratio_is_grade_compensated(name: str, grade: float, effectiveness: float) -> None:
    p = PRESETS[name]
    v, brake_pct = 6.0, 40.0
    pitch = math.atan(grade)
    decel = (brake_pct / 100 * p.max_brake_decel_mps2 * effectiveness
             + p.rolling_resistance * G_MPS2 * math.cos(pitch)
             + 0.5 * 1.225 * p.drag_area_m2 * v * v / p.mass_kg)
    accel = -decel - G_MPS2 * math.sin(pitch)
    imu = accel + G_MPS2 * math.sin(pitch)    # the IMU's specific force
    assert brake_ratio(p, 1, v, imu, pitch, brake_pct) == pytest.approx(effectiveness, abs=1e-9)
    assert brake_ratio(p, 0, v, imu, pitch, brake_pct) is None


@pytest.mark.parametrize(("ratio", "weak"), [(CFG.weak_ratio - 0.02, True), (CFG.weak_ratio + 0.02, False)])
def test_brake_response_weak_threshold_after_verification(ratio: float, weak: bool) -> None:
    r = BrakeResponse(CFG)
    onsets = [c for _ in range(round(2.0 / DT)) for c in r.update(DT, ratio)]
    assert r.verified and r.weak is weak
    assert onsets == ([ActuatorFault.BRAKE_WEAK] if weak else [])


@pytest.mark.parametrize(("ratio", "failed"), [(CFG.failed_ratio - 0.01, True), (CFG.failed_ratio + 0.01, False)])
def test_brake_response_failed_threshold(ratio: float, failed: bool) -> None:
    r = BrakeResponse(CFG)
    onsets = [c for _ in range(round(3.0 / DT)) for c in r.update(DT, ratio)]
    assert (ActuatorFault.BRAKE_FAILED in onsets) is failed and r.failed is failed
    assert onsets.count(ActuatorFault.BRAKE_FAILED) <= 1


def test_brake_response_not_weak_before_verified() -> None:
    r = BrakeResponse(CFG)
    for _ in range(round(CFG.verify_s / DT) - 2):
        assert not r.update(DT, 0.0)
    assert not r.verified


def test_brake_probe_can_be_switched_off() -> None:
    probe, response = BrakeProbe(ActuatorMonitorConfig(probe_enabled=False)), BrakeResponse(CFG)
    assert probe.step(DT, True, True, response, 0.0) is None and probe.phase == "idle"
    assert ActuatorMonitorConfig().probe_enabled, "on by default (issue 16 case 6)"


def test_brake_probe_phases() -> None:
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    assert probe.step(DT, False, True, response, 0.0) is None and probe.phase == "idle"
    assert probe.step(DT, True, True, response, 20.0) == 0.0 and probe.phase == "closing"
    assert probe.step(DT, True, True, response, 0.1) == 0.0 and probe.phase == "braking"
    assert probe.step(DT, True, True, response, 0.0) == CFG.probe_brake_pct
    while not response.verified:
        response.update(DT, 1.0)
    assert probe.step(DT, True, True, response, 0.0) is None and probe.phase == "done"


def test_brake_probe_abort_waits_before_retrying() -> None:
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    probe.step(DT, True, True, response, 20.0)
    assert probe.step(DT, True, False, response, 20.0) is None and probe.phase == "idle"
    for _ in range(round(CFG.probe_retry_s / DT) - 5):
        assert probe.step(DT, True, True, response, 20.0) is None
    for _ in range(10):
        probe.step(DT, True, True, response, 20.0)
    assert probe.phase == "closing"


def test_brake_probe_weak_brake_is_probed_to_the_limit() -> None:
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    probe.step(DT, True, True, response, 0.0)
    braked = 0.0
    while probe.step(DT, True, True, response, 0.0) is not None:
        response.update(DT, 0.2)
        braked += DT
    assert braked == pytest.approx(CFG.probe_max_s, abs=0.03) and response.weak


@pytest.mark.parametrize(("v", "sin_pitch", "ok"), [
    (CFG.probe_min_speed_mps - 0.05, 0.0, False), (CFG.probe_min_speed_mps + 0.05, 0.0, True),
    (3.0, 0.15, False), (CFG.probe_min_speed_mps + G_MPS2 * 0.05 * CFG.probe_margin_s + 0.05, 0.05, True),
    (2.0, -0.15, True)])
def test_brake_probe_speed_for_the_grade(v: float, sin_pitch: float, ok: bool) -> None:
    assert BrakeProbe(CFG).suitable(v, sin_pitch) is ok


def test_pedal_monitor_reports_each_cut_once_and_latches() -> None:
    m = PedalMonitor(PRESETS["escape-hybrid"])
    kw = dict(armed=True, brake_cmd_pct=0.0, brake_pct=0.0, direction=1, speed_mps=5.0,
              accel_x_mps2=0.0, pitch_rad=0.0, slipping=False)
    found = []
    for _ in range(50):
        found += m.update(DT, throttle_cmd_pct=0.0, throttle_pct=40.0, **kw)
    assert [f.code for f in found] == [ActuatorFault.THROTTLE_STUCK_OPEN] and m.cut
    for _ in range(20):
        found += m.update(DT, throttle_cmd_pct=0.0, throttle_pct=40.0, **{**kw, "armed": False})
    for _ in range(50):
        found += m.update(DT, throttle_cmd_pct=0.0, throttle_pct=40.0, **kw)
    assert len(found) == 1


def test_pedal_monitor_a_braking_vehicle_is_no_stuck_closed_throttle() -> None:
    """The vehicle's command watchdog shuts the throttle and brakes: not a throttle fault."""
    m = PedalMonitor(PRESETS["escape-hybrid"])
    found = []
    for _ in range(50):
        found += m.update(DT, armed=True, throttle_cmd_pct=30.0, brake_cmd_pct=0.0,
                          throttle_pct=0.0, brake_pct=100.0, direction=1, speed_mps=5.0,
                          accel_x_mps2=-8.0, pitch_rad=0.0, slipping=False)
    assert found == [] and not m.cut


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_steering_monitor_curvature_from_yaw_and_wheels(name: str) -> None:
    p = PRESETS[name]
    m = SteeringMonitor(p)
    m.update(DT, armed=True, command_pct=10.0, actual_pct=10.0, speed_mps=5.0, yaw_rate_rps=-0.5)
    assert m.actual_curvature_1pm == pytest.approx(0.1)
    m.update(DT, armed=True, command_pct=10.0, actual_pct=10.0, speed_mps=0.2, yaw_rate_rps=0.0)
    assert m.actual_curvature_1pm == pytest.approx(math.tan(0.1 * p.max_steer_rad) / p.wheelbase_m)


def test_steering_monitor_one_onset() -> None:
    m = SteeringMonitor(PRESETS["escape-hybrid"])
    findings = [m.update(DT, armed=True, command_pct=0.0, actual_pct=50.0, speed_mps=5.0,
                         yaw_rate_rps=-0.5) for _ in range(50)]
    assert [f.code for f in findings if f is not None] == [ActuatorFault.STEERING_STUCK]
    assert m.stuck
