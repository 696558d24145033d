"""Must-fix items of the review of issue 16: each with the test that failed before its fix."""

from __future__ import annotations

import math

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import GpsIns, Imu, Topic, WheelSpeed
from overdrive.safety.plausibility import PlausibilityFault
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingModule
from overdrive.servers.move import MoveServer
from overdrive.servers.speed import SpeedServer
from tests.conftest import PRESET_NAMES

DT_S = 0.01
BAD_NUMBERS = (math.nan, math.inf, -math.inf)
GPS_FIELDS = ("x_m", "y_m", "heading_rad", "speed_mps", "pitch_rad", "roll_rad", "odometer_m")


def gps(**kw) -> GpsIns:
    fields = dict(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=0.0, pitch_rad=0.0, roll_rad=0.0,
                  odometer_m=0.0)
    fields.update(kw)
    return GpsIns(**fields)


def imu(accel_x_mps2: float, yaw_rate_rps: float = 0.0) -> Imu:
    return Imu(accel_x_mps2=accel_x_mps2, accel_y_mps2=0.0, accel_z_mps2=G_MPS2,
               yaw_rate_rps=yaw_rate_rps)


def fault_codes(out) -> set[int]:
    return {int(n.code) for t, n in out if t == Topic.NOTICE and n.kind == "fault"}


# ------------------------------------------------------------------ 1: one IMU handler

@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_driving_module_checker_sees_the_imu(preset: str) -> None:
    """GPS/INS and wheel speed frozen at 3 m/s while the IMU shows 1 m/s^2 of braking: the
    driving module's own checker must call them frozen (it saw no IMU when ``_imu`` was
    defined twice)."""
    node = DrivingModule(PRESETS[preset])
    frozen_gps = gps(speed_mps=3.0, odometer_m=10.0)
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


# ------------------------------------------------------------------ 2: finite checks

@pytest.mark.parametrize("field", GPS_FIELDS)
@pytest.mark.parametrize("bad", BAD_NUMBERS)
def test_move_server_refuses_a_gps_ins_with_any_non_finite_field(field: str, bad: float) -> None:
    node = MoveServer(PRESETS["escape-hybrid"])
    good = gps(x_m=1.0, odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(DT_S, [(Topic.GPS_INS, gps(**{"x_m": 1.0, "odometer_m": 1.0, field: bad}))])
    rejected = [n for t, n in out if t == Topic.NOTICE and n.kind == "rejected"]
    assert rejected and rejected[0].code == "sensor"
    assert node.gps == good


@pytest.mark.parametrize("field", ("speed_mps", "pitch_rad", "odometer_m"))
@pytest.mark.parametrize("bad", BAD_NUMBERS)
def test_speed_server_refuses_a_gps_ins_with_a_non_finite_field_it_uses(field: str,
                                                                         bad: float) -> None:
    node = SpeedServer(PRESETS["ranger-6x6"])
    good = gps(odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(DT_S, [(Topic.GPS_INS, gps(**{"odometer_m": 1.0, field: bad}))])
    rejected = [n for t, n in out if t == Topic.NOTICE and n.kind == "rejected"]
    assert rejected and rejected[0].reason.startswith("gps_ins")
    assert node.gps == good


@pytest.mark.parametrize("field", GPS_FIELDS)
def test_driving_module_refuses_a_gps_ins_with_any_non_finite_field(field: str) -> None:
    node = DrivingModule(PRESETS["escape-hybrid"])
    good = gps(odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(DT_S, [(Topic.GPS_INS, gps(**{"odometer_m": 1.0, field: math.nan}))])
    assert any(t == Topic.NOTICE and n.kind == "rejected" for t, n in out)
    assert node.gps == good


# ------------------------------------------------------------------ 6: steering monitor speed

@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_steering_monitor_gets_the_trusted_speed_not_a_frozen_gps(preset: str) -> None:
    """GPS/INS frozen at 5 m/s while the wheels read ~2 m/s: the steering monitor (which turns
    the yaw rate into the curvature actually driven) must get the trusted 2 m/s."""
    from tests.servers.driving_harness import sensors
    params = PRESETS[preset]
    node = DrivingModule(params)
    seen: list[float] = []
    real_update = node.steer_monitor.update

    def spy(dt_s, **kw):
        seen.append(kw["speed_mps"])
        return real_update(dt_s, **kw)

    node.steer_monitor.update = spy
    frozen_gps = gps(speed_mps=5.0, odometer_m=10.0)
    for i in range(100):
        inbox = [(t, m) for t, m in sensors(params, speed_mps=2.0) if t != Topic.GPS_INS]
        inbox += [(Topic.GPS_INS, frozen_gps),
                  (Topic.WHEEL_SPEED, WheelSpeed(speed_mps=2.0 + 1e-3 * (i % 5)))]
        node.step(i * DT_S, inbox)
    assert not node.motion.trusted("gps_ins")
    assert seen and all(abs(v - 2.0) < 0.01 for v in seen[-10:])


# ------------------------------------------------------------------ 3: radar cap on progress

def move_inbox(params, *, speed: float, odo: float, wheel_mps: float | None, radar: bool,
               i: int) -> list:
    from overdrive.messages import Radar, SpeedState, VehicleStatus
    gear = params.drive_gear
    inbox = [
        (Topic.VEHICLE_STATUS, VehicleStatus(
            gear=gear, shifting=False, engine="running", engine_rpm=1000.0, start_failed=False,
            traction_control=False, steer_pct=0.0, throttle_pct=0.0, brake_pct=0.0,
            safety_mode="drive-by-wire")),
        (Topic.GPS_INS, gps(x_m=odo, speed_mps=speed, odometer_m=odo)),
        (Topic.IMU, imu(1e-4 * (i % 7))),
        (Topic.SPEED_STATE, SpeedState(speed_mps=speed, accel_mps2=0.0, gear=gear, state="run")),
    ]
    if wheel_mps is not None:
        inbox.append((Topic.WHEEL_SPEED, WheelSpeed(speed_mps=wheel_mps + 1e-4 * (i % 5))))
    if radar:
        inbox.append((Topic.RADAR, Radar(target=False, range_m=params.radar_range_m)))
    return inbox


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_untrusted_radar_cap_shrinks_with_progress_when_the_gps_freezes(preset: str) -> None:
    """Radar silent and GPS/INS frozen together while the wheels say 2 m/s: the forward
    authorization cap must shrink with the wheels' travel (it stood still on the raw odometer)."""
    from overdrive.messages import AdvanceAuthorization, MoveCommand
    params = PRESETS[preset]
    node = MoveServer(params)
    speed = 2.0
    odo = 0.0
    for i in range(50):                    # healthy: radar clear, GPS and wheels agree
        inbox = move_inbox(params, speed=speed, odo=odo, wheel_mps=speed, radar=True, i=i)
        if i == 0:
            inbox.append((Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1,
                                                          distance_m=150.0, maxspeed_mps=3.0)))
        node.step(i * DT_S, inbox)
        odo += speed * DT_S
    caps = []
    for i in range(50, 350):               # radar silent, GPS frozen, the wheels go on
        out = node.step(i * DT_S, move_inbox(params, speed=speed, odo=odo, wheel_mps=speed,
                                             radar=False, i=i))
        adv = [m for t, m in out if t == Topic.ADVANCE and isinstance(m, AdvanceAuthorization)]
        caps.append(adv[-1].distance_m)
    travelled_m = speed * 300 * DT_S       # 6 m by the wheels
    assert caps[-1] <= caps[30] - (travelled_m - 0.6 - 1.0)


# ------------------------------------------------------------------ 4: memory vs one outlier

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("outlier_m", [3.0, 20.0, 60.0, -60.0])
def test_a_remembered_target_survives_one_outlier_pose(preset: str, outlier_m: float) -> None:
    from overdrive.messages import Radar
    from overdrive.servers.move_radar import RadarCorridor
    params = PRESETS[preset]
    c = RadarCorridor(params)
    front = params.length_m - params.rear_overhang_m
    target_x = 30.0
    x = 0.0
    for i in range(10):                    # the target dead ahead, seen
        c.receive(i * DT_S, Radar(target=True, range_m=target_x - x - front, bearing_rad=0.0))
        c.update(i * DT_S, gps(x_m=x, speed_mps=1.0, odometer_m=x), (0.0,), True)
        x += 0.01
    seen = c.nearest_m
    # one period without a radar reading and a pose `outlier_m` off (odometer consistent)
    c.update(0.10, gps(x_m=x + outlier_m, speed_mps=1.0, odometer_m=x), (0.0,), True)
    assert c.nearest_m == pytest.approx(seen, abs=0.05)
    x += 0.01
    c.update(0.11, gps(x_m=x, speed_mps=1.0, odometer_m=x), (0.0,), True)
    assert c.nearest_m == pytest.approx(seen - 0.01, abs=0.05)


# ------------------------------------------------------------------ 5: zero-velocity update

def stand_then_drive(bias_mps2: float, stand_s: float = 10.0, drive_s: float = 5.0,
                     accel_mps2: float = 1.0):
    """Feed one checker: a standstill with exact repeats (static hold, wheel speed 0.0) and an
    IMU with ``bias_mps2`` plus varying noise, then a start at ``accel_mps2``."""
    from overdrive.safety.plausibility import MotionPlausibility
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
    from overdrive.safety.plausibility import MotionPlausibility
    m = MotionPlausibility("test")
    codes = set()
    for i in range(300):
        t = i * DT_S
        m.gps(t, gps(x_m=5.0, odometer_m=5.0))
        m.wheel(t, WheelSpeed(speed_mps=0.0))
        m.imu(t, imu(accel_mps2 + 1e-3 * (i % 7)))
        codes |= {int(n.code) for n in m.step(t, 1)}
    assert int(PlausibilityFault.NO_TRUSTED_SPEED) in codes


# ------------------------------------------------------------------ 3: whole run

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("at_s", [0.2, 3.0])
def test_radar_dropout_and_gps_freeze_together_before_an_obstacle(preset: str, at_s: float) -> None:
    """Radar silent and GPS/INS frozen at once, an obstacle ahead: no contact and no
    authorization violation (the cap shrinks with the wheels' progress)."""
    from tests.safety.test_faults_radar import move, run
    result = run(preset, [move(150.0, 9.0),
                          {"at_s": at_s, "sensor": {"name": "radar", "fault": "dropout",
                                                    "for_s": 100}},
                          {"at_s": at_s, "sensor": {"name": "gps", "fault": "freeze",
                                                    "for_s": 100}}],
                 {"obstacles": [{"x_m": 60, "y_m": 0.0}]}, duration_s=40)
    assert result.summary["violations"] == []
