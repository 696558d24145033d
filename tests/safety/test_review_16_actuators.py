"""Review of issue 16 (actuator monitoring, direction hold): the must-fix findings, each pinned."""

from __future__ import annotations

import pytest

from overdrive.messages import GpsIns, Topic, VehicleStatus
from overdrive.safety.actuators import ActuatorFault
from overdrive.servers.speed import SpeedServer
from overdrive.vehicle.presets import PRESETS
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
