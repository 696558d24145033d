"""Sensor messages for unit tests: every field zero unless given (a vehicle at rest, level)."""

from __future__ import annotations

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import GpsIns, Imu


def gps_ins(**kw: float) -> GpsIns:
    fields = dict(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=0.0, pitch_rad=0.0, roll_rad=0.0,
                  odometer_m=0.0)
    fields.update(kw)
    return GpsIns(**fields)


def imu(accel_x_mps2: float, yaw_rate_rps: float = 0.0) -> Imu:
    return Imu(accel_x_mps2=accel_x_mps2, accel_y_mps2=0.0, accel_z_mps2=G_MPS2,
               yaw_rate_rps=yaw_rate_rps)
