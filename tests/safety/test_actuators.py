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


# --------------------------------------------------------------------------- each limit swept: brake, probe, steering

ESCAPE = PRESETS["escape-hybrid"]


def pedals(m: PedalMonitor, seconds: float, dt: float = DT, **inputs: object) -> list:
    """Steps ``m`` with one set of inputs for ``seconds`` (periods of DT, each ``dt`` since the
    last status); the codes it reports."""
    kw: dict = dict(armed=True, throttle_cmd_pct=0.0, brake_cmd_pct=0.0, throttle_pct=0.0,
                    brake_pct=0.0, direction=1, speed_mps=0.0, accel_x_mps2=0.0, pitch_rad=0.0,
                    slipping=False)
    kw.update(inputs)
    return [f.code for _ in range(round(seconds / DT)) for f in m.update(dt, **kw)]


@pytest.mark.parametrize(("command", "actual", "stuck"), [
    # below brake_strict_below_pct (10 %): the strict pedal gap (5 %)
    (9.9, 4.85, True), (9.9, 4.9, False), (9.9, 4.95, False),
    # from 10 %: short only below half the command ...
    (CFG.brake_strict_below_pct, 4.95, True), (CFG.brake_strict_below_pct, 5.0, False),
    (30.0, 14.9, True), (30.0, 15.0, False), (30.0, 15.1, False),
    # ... and below brake_short_pct (20 %): a partly applied brake is the response check's
    (60.0, 19.9, True), (60.0, 20.0, False), (60.0, 20.1, False),
    (100.0, 19.9, True), (100.0, 20.0, False)])
def test_brake_not_applying_only_when_clearly_short_of_the_command(command: float, actual: float,
                                                                   stuck: bool) -> None:
    found = pedals(PedalMonitor(ESCAPE), 0.5, brake_cmd_pct=command, brake_pct=actual)
    assert found == ([ActuatorFault.BRAKE_NOT_APPLYING] if stuck else [])


@pytest.mark.parametrize(("period_s", "hold_s"), [(0.05, CFG.hold_s), (0.1, CFG.hold_s), (0.2, 0.6)])
def test_a_slow_status_needs_hold_periods_of_still_positions(period_s: float, hold_s: float) -> None:
    """hold_s = max(hold_s, hold_periods x the status period): never less than 0.3 s."""
    m = PedalMonitor(ESCAPE)
    m.set_status_period(period_s)
    stuck_open = dict(throttle_cmd_pct=0.0, throttle_pct=40.0)
    assert pedals(m, DT, **stuck_open) == []                     # anchors
    assert pedals(m, hold_s - DT, **stuck_open) == []
    assert pedals(m, DT, **stuck_open) == [ActuatorFault.THROTTLE_STUCK_OPEN]


def imu_for_ratio(v: float, brake_pct: float, ratio: float) -> float:
    """The IMU's specific force (forward, level) of a brake giving ``ratio`` of the preset's."""
    p = ESCAPE
    losses = p.rolling_resistance * G_MPS2 + 0.5 * 1.225 * p.drag_area_m2 * v * v / p.mass_kg
    return -(ratio * brake_pct * 0.01 * p.max_brake_decel_mps2 + losses)


FAILING = dict(brake_cmd_pct=40.0, brake_pct=40.0, speed_mps=5.0,
               accel_x_mps2=imu_for_ratio(5.0, 40.0, 0.1))


def test_a_repeated_status_is_not_an_actuator_standing_still() -> None:
    """dt 0 (no new status): nothing counts, neither the stuck checks nor the brake response."""
    m = PedalMonitor(ESCAPE)
    stuck_open = dict(throttle_cmd_pct=0.0, throttle_pct=40.0)
    assert pedals(m, 1.0, dt=0.0, **stuck_open) == []
    assert pedals(m, DT, **stuck_open) == []                     # the first new status anchors
    assert pedals(m, CFG.hold_s - DT, **stuck_open) == []
    assert pedals(m, DT, **stuck_open) == [ActuatorFault.THROTTLE_STUCK_OPEN]
    m = PedalMonitor(ESCAPE)
    assert pedals(m, 1.0, dt=0.0, **FAILING) == []
    assert not m.cut and not m.response.verified
    assert pedals(m, 1.0, **FAILING) == [ActuatorFault.BRAKE_WEAK, ActuatorFault.BRAKE_FAILED]


@pytest.mark.parametrize(("ratio", "codes", "cut"), [
    (CFG.weak_ratio + 0.02, [], False),
    (CFG.weak_ratio - 0.02, [ActuatorFault.BRAKE_WEAK], False),           # a notice: no cut
    (CFG.failed_ratio + 0.01, [ActuatorFault.BRAKE_WEAK], False),
    (CFG.failed_ratio - 0.01, [ActuatorFault.BRAKE_WEAK, ActuatorFault.BRAKE_FAILED], True)])
def test_pedal_monitor_weak_brake_is_a_notice_a_failed_one_cuts(ratio: float, codes: list,
                                                                cut: bool) -> None:
    m = PedalMonitor(ESCAPE)
    found = pedals(m, 3.0, brake_cmd_pct=40.0, brake_pct=40.0, speed_mps=5.0,
                   accel_x_mps2=imu_for_ratio(5.0, 40.0, ratio))
    assert found == codes and m.cut is cut


@pytest.mark.parametrize(("change", "sampled"), [
    ({}, True),
    ({"armed": False}, False),
    ({"sample_response": False}, False),       # speed / IMU lost
    ({"accel_x_mps2": None}, False),
    ({"slipping": True}, False),
    ({"brake_cmd_pct": CFG.min_brake_pct, "brake_pct": CFG.min_brake_pct,
      "accel_x_mps2": imu_for_ratio(5.0, CFG.min_brake_pct, 0.1)}, True),
    ({"brake_cmd_pct": CFG.min_brake_pct - 0.01, "brake_pct": CFG.min_brake_pct - 0.01,
      "accel_x_mps2": imu_for_ratio(5.0, CFG.min_brake_pct - 0.01, 0.1)}, False),
    ({"throttle_pct": CFG.pedal_off_pct}, True),
    ({"throttle_pct": CFG.pedal_off_pct + 0.01}, False),
    ({"speed_mps": CFG.min_speed_mps, "accel_x_mps2": imu_for_ratio(CFG.min_speed_mps, 40.0, 0.1)},
     True),
    ({"speed_mps": CFG.min_speed_mps - 0.01,
      "accel_x_mps2": imu_for_ratio(CFG.min_speed_mps - 0.01, 40.0, 0.1)}, False),
    ({"direction": -1}, False),                # moving against the direction: no brake sample
    ({"direction": -1, "speed_mps": -5.0, "accel_x_mps2": -FAILING["accel_x_mps2"]}, True),
])
def test_brake_response_is_sampled_only_when_it_carries_signal(change: dict, sampled: bool) -> None:
    """A brake giving 10 % of its deceleration: BRAKE_FAILED only from usable samples."""
    m = PedalMonitor(ESCAPE)
    found = pedals(m, 1.0, **{**FAILING, **change})
    assert (ActuatorFault.BRAKE_FAILED in found) is sampled


@pytest.mark.parametrize(("predicted_mps2", "sampled"), [(0.29, False), (0.31, True)])
def test_brake_response_needs_min_predicted_deceleration(predicted_mps2: float,
                                                         sampled: bool) -> None:
    m = PedalMonitor(ESCAPE, ActuatorMonitorConfig(min_brake_pct=0.0))
    brake = 100.0 * predicted_mps2 / ESCAPE.max_brake_decel_mps2
    found = pedals(m, 1.0, **{**FAILING, "brake_cmd_pct": brake, "brake_pct": brake,
                              "accel_x_mps2": imu_for_ratio(5.0, brake, 0.1)})
    assert (ActuatorFault.BRAKE_FAILED in found) is sampled


@pytest.mark.parametrize(("throttle_pct", "phase"), [(CFG.pedal_off_pct - 0.01, "braking"),
                                                     (CFG.pedal_off_pct, "braking"),
                                                     (CFG.pedal_off_pct + 0.01, "closing")])
def test_brake_probe_brakes_once_the_throttle_reports_closed(throttle_pct: float,
                                                             phase: str) -> None:
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    assert probe.step(DT, True, True, response, 20.0) == 0.0
    assert probe.step(DT, True, True, response, throttle_pct) == 0.0
    assert probe.phase == phase
    expected = CFG.probe_brake_pct if phase == "braking" else 0.0
    assert probe.step(DT, True, True, response, throttle_pct) == expected


def test_brake_probe_gives_up_on_a_throttle_that_does_not_close() -> None:
    """The throttle check reports the stuck pedal; the probe hands back and retries later."""
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    out = [probe.step(DT, True, True, response, 20.0)   # the starting period counts
           for _ in range(round(CFG.probe_close_max_s / DT) - 1)]
    assert out == [0.0] * len(out) and probe.phase == "closing"
    assert probe.step(DT, True, True, response, 20.0) is None and probe.phase == "idle"
    out = [probe.step(DT, True, True, response, 0.0)
           for _ in range(round(CFG.probe_retry_s / DT) - 1)]
    assert out == [None] * len(out)


def test_brake_probe_not_needed_once_the_brake_is_known() -> None:
    probe, response = BrakeProbe(CFG), BrakeResponse(CFG)
    while not response.verified:
        response.update(DT, 1.0)
    assert probe.step(DT, True, True, response, 0.0) is None and probe.phase == "done"
    assert probe.step(DT, True, True, response, 0.0) is None


def probe_once(m: PedalMonitor, **inputs: object) -> float | None:
    kw: dict = dict(loop_braking=False, keep_ok=True, direction=1, speed_mps=5.0, pitch_rad=0.0,
                    throttle_pct=20.0, throttle_cmd_pct=20.0)
    kw.update(inputs)
    return m.probe_brake_pct(DT, **kw)


@pytest.mark.parametrize(("inputs", "starts"), [
    ({}, True),
    ({"loop_braking": True}, False),
    ({"keep_ok": False}, False),
    ({"direction": -1, "speed_mps": -5.0}, True),
    ({"direction": -1}, False),                       # moving against the gear
    ({"speed_mps": CFG.probe_min_speed_mps}, True),
    ({"speed_mps": CFG.probe_min_speed_mps - 0.01}, False),
])
def test_pedal_monitor_starts_the_probe_at_cruise_only(inputs: dict, starts: bool) -> None:
    m = PedalMonitor(ESCAPE)
    assert probe_once(m, **inputs) == (0.0 if starts else None)


@pytest.mark.parametrize(("direction", "starts"), [(1, False), (-1, True)])
def test_pedal_monitor_probe_speed_counts_the_grade_along_the_travel(direction: int,
                                                                     starts: bool) -> None:
    """Nose up 10 %: forward climbs (needs 1.5 + 9.81 x 0.1 x 2 m/s), reverse descends."""
    pitch = math.asin(0.1)
    v = CFG.probe_min_speed_mps + 0.05
    m = PedalMonitor(ESCAPE)
    assert probe_once(m, direction=direction, speed_mps=direction * v, pitch_rad=pitch) == \
        (0.0 if starts else None)


@pytest.mark.parametrize(("throttle_cmd_pct", "starts"), [(49.9, True), (50.0, True), (50.1, False)])
def test_pedal_monitor_probe_waits_for_the_loop_throttle(throttle_cmd_pct: float,
                                                         starts: bool) -> None:
    m = PedalMonitor(ESCAPE, ActuatorMonitorConfig(probe_start_throttle_pct=50.0))
    assert probe_once(m, throttle_cmd_pct=throttle_cmd_pct) == (0.0 if starts else None)


@pytest.mark.parametrize(("speed_mps", "keeps"), [(CFG.min_speed_mps - 0.01, False),
                                                  (CFG.min_speed_mps, True)])
def test_pedal_monitor_probe_aborts_when_too_slow(speed_mps: float, keeps: bool) -> None:
    m = PedalMonitor(ESCAPE)
    assert probe_once(m) == 0.0
    assert probe_once(m, throttle_pct=0.0) == 0.0                      # closed: braking next
    assert probe_once(m, throttle_pct=0.0, speed_mps=speed_mps) == \
        (CFG.probe_brake_pct if keeps else None)


def test_pedal_monitor_no_probe_after_a_cut() -> None:
    m = PedalMonitor(ESCAPE)
    assert probe_once(m) == 0.0
    assert pedals(m, 0.5, throttle_cmd_pct=0.0, throttle_pct=40.0) == \
        [ActuatorFault.THROTTLE_STUCK_OPEN]
    assert probe_once(m) is None and probe_once(m, throttle_pct=0.0) is None


@pytest.mark.parametrize(("offset", "stuck"), [(CFG.steer_gap_pct - 0.05, False),
                                               (CFG.steer_gap_pct + 0.05, True)])
@pytest.mark.parametrize("sense", [+1, -1])
def test_steering_stuck_beyond_the_steer_gap_either_way(offset: float, stuck: bool,
                                                        sense: int) -> None:
    m = SteeringMonitor(ESCAPE)
    findings = [m.update(DT, armed=True, command_pct=20.0 + sense * offset, actual_pct=20.0,
                         speed_mps=5.0, yaw_rate_rps=0.0) for _ in range(50)]
    assert [f.code for f in findings if f is not None] == \
        ([ActuatorFault.STEERING_STUCK] if stuck else [])


@pytest.mark.parametrize(("speed_mps", "yaw_rate_rps", "from_yaw"), [
    (CFG.min_curvature_speed_mps, -0.2, True), (-CFG.min_curvature_speed_mps, 0.2, True),
    (CFG.min_curvature_speed_mps - 0.01, -0.2, False), (5.0, None, False)])
def test_steering_curvature_from_yaw_only_when_fast_enough(speed_mps: float,
                                                           yaw_rate_rps: float | None,
                                                           from_yaw: bool) -> None:
    m = SteeringMonitor(ESCAPE)
    m.update(DT, armed=True, command_pct=10.0, actual_pct=10.0, speed_mps=speed_mps,
             yaw_rate_rps=yaw_rate_rps)
    wheels = math.tan(0.1 * ESCAPE.max_steer_rad) / ESCAPE.wheelbase_m
    expected = -yaw_rate_rps / speed_mps if from_yaw else wheels
    assert m.actual_curvature_1pm == pytest.approx(expected)


def test_steering_a_repeated_status_reports_nothing_but_the_curvature() -> None:
    m = SteeringMonitor(ESCAPE)
    kw = dict(armed=True, command_pct=0.0, actual_pct=50.0, speed_mps=5.0, yaw_rate_rps=-0.5)
    assert [m.update(0.0, **kw) for _ in range(100)] == [None] * 100 and not m.stuck
    assert m.actual_curvature_1pm == pytest.approx(0.1)
    # the first new status anchors; stuck hold_s later
    findings = [m.update(DT, **kw) for _ in range(round(CFG.hold_s / DT) + 1)]
    assert findings[:-1] == [None] * (len(findings) - 1)
    assert findings[-1] is not None and findings[-1].code == ActuatorFault.STEERING_STUCK
