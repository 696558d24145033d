"""Driving module inputs: validation swept around every limit, limits, authorizations, outputs."""

from __future__ import annotations

import math

import pytest

from overdrive.dynamics.control import MAX_CONTROL_STEP_S
from overdrive.dynamics.ellipse import ellipse_for, max_safe_speed_mps
from overdrive.messages import (
    AdvanceAuthorization,
    DriveMode,
    DrivingStatus,
    MaxSpeed,
    Notice,
    SetSpeed,
    SteerCommand,
    SteeringRequest,
    Topic,
    WheelSpeed,
)
from overdrive.safety.plausibility import PlausibilityFault
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import (
    Authorizations,
    DrivingConfig,
    DrivingModule,
    SpeedLimits,
    curvature_bounds_1pm,
    limit_curvature,
    steer_pct_for,
)
from tests.sensor_messages import gps_ins, imu
from tests.servers.driving_harness import DT_S, IdealLoop, outputs, sensors

PRESET_NAMES = tuple(PRESETS)
BAD_NUMBERS = (math.nan, math.inf, -math.inf)


@pytest.fixture(params=PRESET_NAMES)
def params(request):
    return PRESETS[request.param]


def step(node, t, *msgs, speed=0.0, odometer=0.0, **kw):
    return node.step(t, sensors(node.params, speed_mps=speed, odometer_m=odometer, **kw)
                     + list(msgs))


def status(out) -> DrivingStatus:
    return outputs(out, Topic.DRIVING_STATUS)[-1]


def rejections(out) -> list[Notice]:
    return [n for n in outputs(out, Topic.NOTICE) if n.kind == "rejected"]


# --------------------------------------------------------------------------- validation

def _curvature_cases(params):
    kmax = params.max_curvature_1pm
    above = math.nextafter(kmax, math.inf)
    return [(kmax, True), (-kmax, True), (math.nextafter(kmax, 0.0), True), (0.0, True),
            (above, False), (-above, False), (kmax * 1.5, False), (10.0, False),
            *((x, False) for x in BAD_NUMBERS)]


def test_curvature_swept_around_the_vehicle_limit(params):
    for k, ok in _curvature_cases(params):
        node = DrivingModule(params)
        step(node, 0.0)
        out = step(node, 0.01, (Topic.STEERING, SteeringRequest(curvature_1pm=k)))
        assert (node.requested_1pm == k) is ok, k
        assert bool(rejections(out)) is not ok, k
        if not ok:
            reject = rejections(out)[0]
            assert reject.source == "driving" and reject.code == "steering"
            assert status(out).rejected == reject.reason


@pytest.mark.parametrize("speed", [0.0, 1e-9, 5.0, 70.0, 1e6, -1e-12, -1.0, *BAD_NUMBERS])
def test_max_speed_validation(params, speed):
    node = DrivingModule(params)
    out = step(node, 0.0, (Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=speed)))
    ok = math.isfinite(speed) and speed >= 0.0
    assert bool(rejections(out)) is not ok
    assert ("map" in node.limits.by_source) is ok


@pytest.mark.parametrize("distance", [0.0, 1e-9, 30.0, 1e5, -1e-12, -5.0, *BAD_NUMBERS])
def test_advance_validation(params, distance):
    node = DrivingModule(params)
    out = step(node, 0.0, (Topic.ADVANCE, AdvanceAuthorization(source="lidar",
                                                                 distance_m=distance)))
    ok = math.isfinite(distance) and distance >= 0.0
    assert bool(rejections(out)) is not ok
    assert math.isnan(status(out).authorized_m) is not ok


@pytest.mark.parametrize("msg, ok", [
    (DriveMode(state="run"), True),
    (DriveMode(state="paused", direction="reverse", fault=3), True),
    (DriveMode(state="runwait"), False),          # seed 001: not requestable
    (DriveMode(state="run", direction="sideways"), False),
    (DriveMode(state="run", fault=-1), False),
    (SteeringRequest(curvature_1pm=0.0), False),  # wrong type on the topic
])
def test_drive_mode_validation(params, msg, ok):
    node = DrivingModule(params)
    out = step(node, 0.0, (Topic.DRIVE_MODE, msg))
    assert bool(rejections(out)) is not ok
    assert (node.mode is msg) is ok


def test_empty_source_rejected(params):
    node = DrivingModule(params)
    out = step(node, 0.0, (Topic.ADVANCE, AdvanceAuthorization(source="", distance_m=5.0)),
               (Topic.MAX_SPEED, MaxSpeed(source="", speed_mps=5.0)))
    assert len(rejections(out)) == 2


def test_bad_sensor_sample_is_ignored_and_noticed_once(params):
    node = DrivingModule(params)
    step(node, 0.0, odometer=5.0)
    bad = sensors(params, odometer_m=math.nan)
    out1 = node.step(0.01, bad)
    out2 = node.step(0.02, bad)
    assert node.odometer_m == 5.0
    assert len(rejections(out1)) == 1 and not rejections(out2)


# --------------------------------------------------------------------------- speed limits

def test_lowest_limit_applies_and_a_lapsed_source_holds_at_zero():
    limits = SpeedLimits(ttl_s=0.5)
    assert limits.lowest_mps(0.0) == math.inf   # no source ever heard: no limit
    limits.update("map", 8.0, 0.0)
    limits.update("terrain", 5.0, 0.0)
    limits.update("planner", 6.0, 0.3)
    assert limits.lowest_mps(0.5) == 5.0
    assert limits.lowest_mps(0.51) == 0.0       # map and terrain went quiet: hold
    limits.update("terrain", 9.0, 0.6)          # a source replaces its own limit
    limits.update("map", 7.0, 0.6)
    assert limits.lowest_mps(0.6) == 6.0
    assert limits.lowest_mps(0.8) == 6.0
    assert limits.lowest_mps(0.81) == 0.0       # planner went quiet
    limits.update("planner", 9.5, 1.0)
    assert limits.lowest_mps(1.0) == 7.0


def test_goal_capped_by_lowest_limit_and_held_when_a_source_goes_quiet(params):
    node = DrivingModule(params)
    t = 0.0
    out = step(node, t, (Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=1e5)),
               (Topic.MAX_SPEED, MaxSpeed(source="a", speed_mps=6.0)),
               (Topic.MAX_SPEED, MaxSpeed(source="b", speed_mps=3.0)))
    assert status(out).speed_limit_mps == 3.0
    out = step(node, 0.4, (Topic.MAX_SPEED, MaxSpeed(source="a", speed_mps=6.0)))
    assert status(out).speed_limit_mps == 3.0
    out = step(node, 0.6, (Topic.MAX_SPEED, MaxSpeed(source="a", speed_mps=6.0)))
    assert status(out).speed_limit_mps == 0.0     # b went quiet
    assert status(out).goal_speed_mps == 0.0
    out = step(node, 0.7, (Topic.MAX_SPEED, MaxSpeed(source="b", speed_mps=4.0)))
    assert status(out).speed_limit_mps == 4.0


# --------------------------------------------------------------------------- authorizations

def test_authorization_used_up_and_most_restrictive_applies():
    auth = Authorizations()
    assert math.isnan(auth.remaining_m(False, 0.0))
    auth.update("lidar", False, 30.0, 10.0)
    auth.update("radar", False, 22.0, 12.0)
    assert auth.remaining_m(False, 12.0) == pytest.approx(22.0)
    assert auth.remaining_m(False, 20.0) == pytest.approx(14.0)
    auth.update("radar", False, 50.0, 20.0)    # radar replaces its own; lidar now the shortest
    assert auth.remaining_m(False, 20.0) == pytest.approx(20.0)
    assert auth.remaining_m(False, 45.0) == 0.0   # used up, never negative
    assert math.isnan(auth.remaining_m(True, 45.0))   # nothing authorizes reverse


def test_no_authorization_means_goal_zero(params):
    node = DrivingModule(params)
    out = step(node, 0.0, (Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=8.0)))
    assert status(out).goal_speed_mps == 0.0
    assert math.isnan(status(out).authorized_m)
    out = step(node, 0.1)
    assert outputs(out, Topic.SET_SPEED)[0].speed_mps == 0.0


def test_authorization_is_measured_from_where_the_vehicle_is(params):
    node = DrivingModule(params)
    step(node, 0.0, odometer=100.0)
    out = step(node, 0.01, (Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=30.0)),
               odometer=100.0)
    assert status(out).authorized_m == pytest.approx(30.0)
    out = step(node, 0.02, odometer=110.5)
    assert status(out).authorized_m == pytest.approx(19.5)


def test_goal_is_the_max_safe_speed_for_the_remaining_distance(params):
    cfg = DrivingConfig()
    node = DrivingModule(params, config=cfg)
    out = step(node, 0.0, (Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=12.0)))
    e = ellipse_for(params, 0.8)
    plan = type(e)(lon_mps2=e.lon_mps2 * cfg.plan_decel_fraction, lat_mps2=e.lat_mps2)
    expected = max_safe_speed_mps(plan, 12.0 - cfg.stop_margin_m - cfg.creep_zone_m,
                                  reaction_s=cfg.reaction_s)
    assert status(out).goal_speed_mps == pytest.approx(expected)
    # a second, shorter source wins
    out = step(node, 0.01, (Topic.ADVANCE, AdvanceAuthorization(source="r", distance_m=6.0)))
    assert status(out).goal_speed_mps < expected
    assert status(out).authorized_m == 6.0


def test_reverse_authorizations_apply_to_reverse_only(params):
    node = DrivingModule(params)
    fwd = AdvanceAuthorization(source="l", distance_m=20.0)
    rev = AdvanceAuthorization(source="l", distance_m=4.0, reverse=True)
    out = step(node, 0.0, (Topic.ADVANCE, fwd), (Topic.ADVANCE, rev))
    assert status(out).authorized_m == 20.0
    out = step(node, 0.01, (Topic.DRIVE_MODE, DriveMode(state="run", direction="reverse")))
    assert status(out).authorized_m == 4.0


def test_goal_zero_without_fresh_pose(params):
    node = DrivingModule(params)
    step(node, 0.0, (Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=50.0)))
    assert node.goal_mps > 0.0
    out = node.step(0.3, [])          # GPS/INS silent for 0.3 s > sensor_timeout_s
    assert status(out).goal_speed_mps == 0.0


# --------------------------------------------------------------------------- outputs

def test_spss_every_100ms_with_drive_mode_fault_forwarded(params):
    node = DrivingModule(params)
    times = []
    for i in range(100):
        msgs = [(Topic.DRIVE_MODE, DriveMode(state="run", fault=7))] if i == 50 else []
        out = step(node, i * 0.01, *msgs)
        assert len(outputs(out, Topic.STEER)) == 1
        assert len(outputs(out, Topic.DRIVING_STATUS)) == 1
        for spss in outputs(out, Topic.SET_SPEED):
            times.append((round(i * 0.01, 2), spss))
    assert [t for t, _ in times] == [round(0.1 * i, 2) for i in range(10)]
    assert all(isinstance(s, SetSpeed) and s.accel_mps2 > 0 for _, s in times)
    assert [s.fault for _, s in times] == [0] * 5 + [7] * 5


def test_steer_pct_is_road_wheel_angle_share_of_full_lock(params):
    kmax = params.max_curvature_1pm
    assert steer_pct_for(kmax, params) == pytest.approx(100.0)
    assert steer_pct_for(-kmax, params) == pytest.approx(-100.0)
    assert steer_pct_for(0.0, params) == 0.0
    k = 0.5 * kmax
    assert steer_pct_for(k, params) == pytest.approx(
        math.degrees(math.atan(k * params.wheelbase_m)) / math.degrees(params.max_steer_rad) * 100)


def test_steering_is_rate_limited_at_a_standstill(params):
    node = DrivingModule(params)
    kmax = params.max_curvature_1pm
    step(node, 0.0, (Topic.STEERING, SteeringRequest(curvature_1pm=kmax)))
    rate = 0.8 * params.steer_rate_rps / params.wheelbase_m
    for i in range(1, 6):
        out = step(node, i * 0.01)
        assert status(out).curvature_1pm == pytest.approx(min(kmax, rate * i * 0.01))
    steer = outputs(out, Topic.STEER)[0]
    assert isinstance(steer, SteerCommand) and steer.source == "driving"
    assert steer.steer_pct == pytest.approx(steer_pct_for(node.curvature_1pm, params))


def test_after_a_stall_the_steering_moves_no_more_than_two_periods_worth(params):
    """The module is not stepped for 0.3 s after a full-lock request at a standstill: on
    resume its steering moves by the rate over MAX_CONTROL_STEP_S (two periods), not over the
    whole gap (which would be one jump of 30 periods' worth)."""
    node = DrivingModule(params)
    kmax = params.max_curvature_1pm
    step(node, 0.0, (Topic.STEERING, SteeringRequest(curvature_1pm=kmax)))
    before = node.curvature_1pm
    out = step(node, 0.31)
    rate = 0.8 * params.steer_rate_rps / params.wheelbase_m
    assert status(out).curvature_1pm - before == pytest.approx(
        min(kmax - before, rate * MAX_CONTROL_STEP_S))


def test_curvature_limiter_holds_outside_never_steers_back():
    # inside: clamped to the bound, then rate limited
    assert limit_curvature(0.2, 0.0, -0.1, 0.1, 100.0, 0.01) == 0.1
    assert limit_curvature(0.2, 0.0, -0.1, 0.1, 1.0, 0.01) == pytest.approx(0.01)
    # the ellipse shrank below the current curvature: hold it, do not steer out of the path
    assert limit_curvature(0.2, 0.15, -0.1, 0.1, 100.0, 0.01) == 0.15
    # ... but follow the path when it needs less
    assert limit_curvature(0.12, 0.15, -0.1, 0.1, 100.0, 0.01) == 0.12
    # the other side keeps its own bound
    assert limit_curvature(-0.3, 0.15, -0.1, 0.1, 100.0, 0.01) == -0.1
    assert limit_curvature(-0.12, -0.15, -0.1, 0.1, 100.0, 0.01) == -0.12


def test_curvature_bounds_leave_room_for_the_longitudinal_command(params):
    e = ellipse_for(params, 0.8)
    lo, hi = curvature_bounds_1pm(e, 10.0, 0.0)
    assert hi == pytest.approx(e.lat_mps2 / 100.0) and lo == pytest.approx(-hi)
    _, hi2 = curvature_bounds_1pm(e, 10.0, 0.6 * e.lon_mps2)
    assert hi2 == pytest.approx(0.8 * e.lat_mps2 / 100.0)
    assert curvature_bounds_1pm(e, 0.0, 0.0) == (-math.inf, math.inf)


def test_steering_waits_for_the_speed_to_fit_the_curve(params):
    """A curve too tight for the current speed: slow down first, then steer in."""
    loop = IdealLoop(params)
    big = [(Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=1e4)),
           (Topic.MAX_SPEED, MaxSpeed(source="m", speed_mps=10.0))]
    limit = [(Topic.MAX_SPEED, MaxSpeed(source="m", speed_mps=10.0))]   # refreshed, as sources do
    loop.run(0.2, {0: big})
    for _ in range(6000):
        if loop.speed_mps >= 9.9:
            break
        loop.step(limit)
    assert loop.speed_mps >= 9.9, "reaches the limit within 60 s"
    e = ellipse_for(params, 0.8)
    k = 0.9 * params.max_curvature_1pm
    assert 10.0**2 * k > e.lat_mps2
    loop.step([(Topic.STEERING, SteeringRequest(curvature_1pm=k)), *limit])
    for _ in range(1000):
        out = loop.step(limit)
        st = status(out)
        lat = loop.speed_mps**2 * st.curvature_1pm
        assert lat <= e.lat_mps2 * (1 + 1e-9)
    assert loop.speed_mps**2 * k <= e.lat_mps2 * (1 + 1e-9)
    assert status(out).curvature_1pm == pytest.approx(k)


# --------------------------------------------------------------------------- motion sensing

GPS_FIELDS = ("x_m", "y_m", "heading_rad", "speed_mps", "pitch_rad", "roll_rad", "odometer_m")


def fault_codes(out) -> set[int]:
    return {int(n.code) for t, n in out if t == Topic.NOTICE and n.kind == "fault"}


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_driving_module_checker_sees_the_imu(preset: str) -> None:
    """GPS/INS and wheel speed frozen at 3 m/s while the IMU shows 1 m/s^2 of braking: the
    driving module's own checker must call them frozen (it saw no IMU when ``_imu`` was
    defined twice)."""
    node = DrivingModule(PRESETS[preset])
    frozen_gps = gps_ins(speed_mps=3.0, odometer_m=10.0)
    frozen_wheel = WheelSpeed(speed_mps=3.0)
    codes: set[int] = set()
    for i in range(200):
        t = i * DT_S
        # noisy IMU: every reading differs (a live, varying sensor)
        out = node.step(t, [(Topic.GPS_INS, frozen_gps), (Topic.WHEEL_SPEED, frozen_wheel),
                            (Topic.IMU, imu(-1.0 + 1e-4 * (i % 7), yaw_rate_rps=0.01 * (i % 3)))])
        codes |= fault_codes(out)
    assert int(PlausibilityFault.NO_TRUSTED_SPEED) in codes
    assert node.yaw_rate_rps == pytest.approx(0.01 * (199 % 3))   # yaw rate kept too


@pytest.mark.parametrize("field", GPS_FIELDS)
def test_driving_module_refuses_a_gps_ins_with_any_non_finite_field(field: str) -> None:
    node = DrivingModule(PRESETS["escape-hybrid"])
    good = gps_ins(odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(DT_S, [(Topic.GPS_INS, gps_ins(**{"odometer_m": 1.0, field: math.nan}))])
    assert any(t == Topic.NOTICE and n.kind == "rejected" for t, n in out)
    assert node.gps == good


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_steering_monitor_gets_the_trusted_speed_not_a_frozen_gps(preset: str) -> None:
    """GPS/INS frozen at 5 m/s while the wheels read ~2 m/s: the steering monitor (which turns
    the yaw rate into the curvature actually driven) must get the trusted 2 m/s."""
    params = PRESETS[preset]
    node = DrivingModule(params)
    seen: list[float] = []
    real_update = node.steer_monitor.update

    def spy(dt_s, **kw):
        seen.append(kw["speed_mps"])
        return real_update(dt_s, **kw)

    node.steer_monitor.update = spy
    frozen_gps = gps_ins(speed_mps=5.0, odometer_m=10.0)
    for i in range(100):
        inbox = [(t, m) for t, m in sensors(params, speed_mps=2.0) if t != Topic.GPS_INS]
        inbox += [(Topic.GPS_INS, frozen_gps),
                  (Topic.WHEEL_SPEED, WheelSpeed(speed_mps=2.0 + 1e-3 * (i % 5)))]
        node.step(i * DT_S, inbox)
    assert not node.motion.trusted("gps_ins")
    assert seen and all(abs(v - 2.0) < 0.01 for v in seen[-10:])
