"""Review of issue 16 (actuator monitoring, direction hold): the must-fix findings, each pinned."""

from __future__ import annotations

from overdrive.messages import GpsIns
from overdrive.servers.speed import SpeedServer
from overdrive.vehicle.presets import PRESETS


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
