"""Review of issue 16 (actuator monitoring, direction hold): the must-fix findings, each pinned."""

from __future__ import annotations

import math

import pytest

from overdrive.messages import GpsIns, SetSpeed, Topic, VehicleStatus, WheelSpeed
from overdrive.safety.actuators import (
    ActuatorFault,
    ActuatorMonitorConfig,
    PedalMonitor,
    SteeringMonitor,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.speed import SpeedServer
from tests.conftest import PRESET_NAMES


def gps(speed_mps: float) -> GpsIns:
    return GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=speed_mps, pitch_rad=0.0,
                  roll_rad=0.0, odometer_m=0.0)


# ------------------------------------------------------------------ item 5: trusted sources

def test_an_untrusted_gps_is_not_a_source_of_the_slow_creep_rule() -> None:
    """A frozen GPS reading 0 (untrusted by the plausibility checks) must not hide a rollback the
    wheels see: the direction hold gets only trusted sources."""
    server = SpeedServer(PRESETS["escape-hybrid"], initial_state="run")
    server.last_now_s = 1.0
    server.gps, server.last_gps_s = gps(0.0), 1.0
    server.wheel_mps, server.last_wheel_s = -0.08, 1.0
    assert sorted(server._source_speeds_mps(1)) == [-0.08, 0.0]
    server.motion.gps_track.trusted = False
    assert server._source_speeds_mps(1) == [-0.08]


# ------------------------------------------------------------------ item 1: stuck under sensor loss

def status(params, throttle_pct: float, brake_pct: float) -> VehicleStatus:
    return VehicleStatus(gear=params.drive_gear, shifting=False, engine="running",
                         engine_rpm=1500.0, start_failed=False, traction_control=False,
                         steer_pct=0.0, throttle_pct=throttle_pct, brake_pct=brake_pct,
                         safety_mode="drive-by-wire")


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_throttle_stuck_open_under_a_sensor_loss_stop_cuts_the_engine(preset: str) -> None:
    """Speed sources silent: the sensor e-stop brakes full; the throttle reported stuck at 40 %
    while commanded 0 must still be found and the engine cut (the stuck checks need only the
    reported positions)."""
    params = PRESETS[preset]
    server = SpeedServer(params, initial_state="run")
    notices = []
    for i in range(150):
        inbox = [(Topic.VEHICLE_STATUS, status(params, 0.0 if i < 100 else 40.0, 100.0))]
        if i < 50:
            inbox.append((Topic.GPS_INS, gps(0.0)))   # then the speed sources fall silent
        out = server.step(i * 0.01, inbox)
        notices += [m for t, m in out if t == Topic.NOTICE]
        if i == 99:
            assert server.sensor_lost and not server.engine_cut
    assert server.sensor_lost and server.pedals.throttle_pct == 0.0
    assert str(int(ActuatorFault.THROTTLE_STUCK_OPEN)) in [n.code for n in notices]
    assert server.engine_cut


# ------------------------------------------------------------------ item 3: near full travel

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


# ------------------------------------------------------------------ item 2: slow vehicle status

def run_with_status_period(preset: str, status_period_s: float, seconds: float = 4.0,
                           throttle_stuck_at_s: float | None = None) -> list:
    """A speed server in run asked for 5 m/s from a standstill on flat ground; healthy lagged
    pedals (the preset's lags) reported every ``status_period_s`` and quantised to 1 %. Returns
    the fault codes raised."""
    params = PRESETS[preset]
    server = SpeedServer(params, initial_state="run")
    throttle = brake = 0.0
    speed = 0.0
    faults = []
    spss = SetSpeed(speed_mps=5.0, accel_mps2=1.0, gear=params.drive_gear, state="run")
    steps_per_status = round(status_period_s / 0.01)
    for i in range(round(seconds / 0.01)):
        t = i * 0.01
        pedals = server.pedals
        if throttle_stuck_at_s is None or t < throttle_stuck_at_s:
            throttle += (pedals.throttle_pct - throttle) * (1 - math.exp(-0.01 / params.throttle_lag_s))
        brake += (pedals.brake_pct - brake) * (1 - math.exp(-0.01 / params.brake_lag_s))
        speed = max(0.0, speed + 0.01 * (0.03 * throttle - 0.09 * brake))   # rough, enough here
        inbox = [(Topic.SET_SPEED, spss), (Topic.GPS_INS, gps(speed)),
                 (Topic.WHEEL_SPEED, WheelSpeed(speed_mps=speed))]
        if i % steps_per_status == 0:
            inbox.append((Topic.VEHICLE_STATUS, status(params, float(round(throttle)),
                                                       float(round(brake)))))
        out = server.step(t, inbox)
        faults += [int(m.code) for tp, m in out if tp == Topic.NOTICE and m.kind == "fault"]
    return faults


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("status_period_s", [0.01, 0.1, 0.12, 0.2])
def test_a_slow_status_is_no_stuck_actuator(preset: str, status_period_s: float) -> None:
    """Review of issue 16: with the status at 10 Hz (or 120-200 ms, a real XGV over JAUS) a
    healthy throttle stepping 0 -> 30 % read the same position for a period and was called stuck
    after 0.10 s. The checks step on each new status only, and hold for 3 status periods."""
    faults = run_with_status_period(preset, status_period_s)
    assert not {int(c) for c in ActuatorFault} & set(faults), faults


@pytest.mark.parametrize("status_period_s", [0.01, 0.1, 0.2])
def test_a_stuck_throttle_is_still_found_with_a_slow_status(status_period_s: float) -> None:
    faults = run_with_status_period("escape-hybrid", status_period_s, throttle_stuck_at_s=0.5)
    assert int(ActuatorFault.THROTTLE_STUCK_CLOSED) in faults or \
        int(ActuatorFault.THROTTLE_STUCK_OPEN) in faults
