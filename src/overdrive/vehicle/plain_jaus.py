"""The "plain JAUS" vehicle profile: what the XGV client reads from a JAUS 3.3 vehicle that has
none of the XGV's own messages (OpenJAUS's ojVehicleSim, issue 19). Pure functions, sans-IO.

A plain JAUS 3.3 vehicle has a Primitive Driver, a Global Pose Sensor and a Velocity State
Sensor, and no Report Vehicle Mode (0xE456), Local Pose, Discrete Devices or Wheels Speed
reports. The client's ``profile="plain"`` takes instead:

- **safety mode** from the Primitive Driver's Report Component Status (primary status) and
  whether the client holds its control (``safety_mode_from_status``);
- **pose** from Report Global Pose, projected on a flat-earth local tangent plane
  (``LocalFrame``): origin at the first valid fix, x axis along that fix's heading, so the run
  starts at (0, 0) heading 0 as every scenario assumes; equirectangular on a sphere of the
  WGS-84 equatorial radius (the simulated XGV's own Global Pose projection, ``vehicle.xgv``):
  ``north = R * dlat``, ``east = R * cos(lat0) * dlon``. Its error grows as the square of the
  distance from the origin (under 1 mm within 1 km on flat ground), far below a GPS's noise;
- **speed** from Report Velocity State (as the XGV profile).

Global Pose fixes are validated before anything uses them (``LocalFrame.project``): a fix
without latitude, longitude or yaw, with a value outside its range or not finite, beyond the
latitudes where the projection holds, or further from the last accepted fix than any JAUS 3.3
speed allows, is refused with a reason and never moves the stack's pose.

Velocity State is the plain vehicle's only speed (it is both the stack's wheel speed and its
GPS speed, and its integral is the odometer the move server stops on), so it is checked
against the Global Pose, an independent sensor (``SpeedCheck``): accepted poses further apart
than the odometer says were driven, beyond the position noise, mean the speed reads low.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Final, Literal

from overdrive.jaus import ComponentStatus, ReportGlobalPose, ReportLocalPose

JausProfile = Literal["xgv", "plain"]
JAUS_PROFILES: Final = ("xgv", "plain")

EARTH_RADIUS_M: Final = 6_378_137.0   # WGS-84 equatorial radius, as vehicle.xgv's projection
MAX_ABS_LATITUDE_DEG: Final = 84.0    # UTM's northern limit: nearer the poles the east scale
                                      # cos(lat) collapses and a flat plane is no longer local
PLAUSIBLE_SPEED_MPS: Final = 65.534   # the largest speed JAUS 3.3 can report (Velocity State
                                      # velocity x, reference §5): no vehicle jumps faster
DEFAULT_POSITION_RMS_M: Final = 1.0   # a fix without its accuracy: ojVehicleSim's reported rms
JUMP_NOISE_SIGMAS: Final = 6.0        # position noise allowed on a jump (as REPORTED_POSE_BOUND_M)
SPEED_CHECK_WINDOW_S: Final = 10.0    # poses compared with the odometer this far back: a speed
                                      # reading half the truth at 2.5 m/s (1.25 m/s short)
                                      # exceeds ojVehicleSim's 8.5 m noise bound within it
SPEED_CHECK_SAMPLE_S: Final = 0.1     # one reference pose per this (100 in the window)
REPORT_SKEW_S: Final = 0.25           # pose and velocity reports out of step by up to the
                                      # odometer's gap (xgv_client.ODOMETER_GAP_S): |v| x this
STATUS_TIMEOUT_S: Final = 1.5         # no component status for this long: unknown (the
                                      # heartbeat timeout; OpenJAUS reports at up to 50 Hz)


class JausSensor(IntEnum):
    """JAUS 3.3 component ids of the sensors a plain vehicle reports from (ojVehicleSim's)."""

    GLOBAL_POSE = 38
    VELOCITY_STATE = 42


def safety_mode_from_status(primary_status: int | None, control: bool) -> str:
    """The contract's safety mode of a plain JAUS vehicle.

    Drive-by-wire only while the client controls a Primitive Driver that reports ready;
    standby (or ready, but controlled by someone else) is a software pause (the stack holds
    its brakes and Resumes), emergency an e-stop pause, shutdown and failure e-stop disable;
    initialize, an unknown code or no status at all: inactive (the stack does not drive).
    """
    if primary_status == ComponentStatus.READY:
        return "drive-by-wire" if control else "software-pause"
    if primary_status == ComponentStatus.STANDBY:
        return "software-pause"
    if primary_status == ComponentStatus.EMERGENCY:
        return "estop-pause"
    if primary_status in (ComponentStatus.SHUTDOWN, ComponentStatus.FAILURE):
        return "estop-disable"
    return "inactive"


def _wrap_rad(angle_rad: float) -> float:
    return math.atan2(math.sin(angle_rad), math.cos(angle_rad))


class SpeedCheck:
    """Velocity State against Global Pose: the straight line between two accepted poses can
    never be longer than the path driven between them (the odometer, integrated |speed|) by
    more than the position noise of the pair (``JUMP_NOISE_SIGMAS`` sqrt 2 rms) and the
    reports' skew. Only a speed reading low is caught (a high one stops the move early)."""

    def __init__(self) -> None:
        self.samples: list[tuple[float, float, float, float]] = []   # t (s), x, y, odometer (m)

    def check(self, now_s: float, x_m: float, y_m: float, odometer_m: float, rms_m: float,
              speed_mps: float) -> str | None:
        """None while plausible, else the reason (the speed reads low)."""
        allowed_m = JUMP_NOISE_SIGMAS * math.sqrt(2.0) * rms_m + abs(speed_mps) * REPORT_SKEW_S
        while self.samples and now_s - self.samples[0][0] > SPEED_CHECK_WINDOW_S:
            self.samples.pop(0)
        for t_s, x0_m, y0_m, odometer0_m in self.samples:
            chord_m = math.hypot(x_m - x0_m, y_m - y0_m)
            driven_m = odometer_m - odometer0_m
            if chord_m - driven_m > allowed_m:
                return (f"Velocity State reads low: the Global Pose moved {chord_m:.1f} m in "
                        f"{now_s - t_s:.1f} s, the speed says {driven_m:.1f} m")
        if not self.samples or now_s - self.samples[-1][0] >= SPEED_CHECK_SAMPLE_S:
            self.samples.append((now_s, x_m, y_m, odometer_m))
        return None


class PoseRefused(ValueError):
    """A Global Pose fix that must not be used; the message says why."""


class LocalFrame:
    """Global Pose fixes as Local Pose in the run's frame (see the module docstring).

    JAUS conventions are kept: local x along the first heading, y to its right, yaw clockwise;
    the client turns that into the stack's frame as it does for an XGV's Local Pose.
    """

    def __init__(self) -> None:
        self.origin: tuple[float, float, float] | None = None   # lat, lon (deg), yaw (rad)
        self.last: tuple[float, float, float] | None = None     # north, east (m), time (s)

    def project(self, fix: ReportGlobalPose, now_s: float) -> ReportLocalPose:
        """The fix in the local frame, or ``PoseRefused`` with the reason."""
        lat, lon, yaw = fix.latitude_deg, fix.longitude_deg, fix.yaw_rad
        if lat is None or lon is None or yaw is None:
            raise PoseRefused("Global Pose without latitude, longitude or yaw")
        if not all(math.isfinite(v) for v in (lat, lon, yaw)):
            raise PoseRefused(f"Global Pose not finite (lat {lat}, lon {lon}, yaw {yaw})")
        if abs(lat) > MAX_ABS_LATITUDE_DEG or abs(lon) > 180.0 or abs(yaw) > math.pi + 1e-9:
            raise PoseRefused(f"Global Pose out of range (lat {lat} deg, lon {lon} deg, "
                              f"yaw {yaw} rad; |lat| <= {MAX_ABS_LATITUDE_DEG})")
        rms = fix.position_rms_m
        rms_m = rms if rms is not None and math.isfinite(rms) and rms > 0.0 \
            else DEFAULT_POSITION_RMS_M
        if self.origin is None:
            self.origin = (lat, lon, yaw)
        lat0, lon0, yaw0 = self.origin
        dlon_deg = (lon - lon0 + 180.0) % 360.0 - 180.0    # across the antimeridian too
        north_m = EARTH_RADIUS_M * math.radians(lat - lat0)
        east_m = EARTH_RADIUS_M * math.cos(math.radians(lat0)) * math.radians(dlon_deg)
        if self.last is not None:
            jump_m = math.hypot(north_m - self.last[0], east_m - self.last[1])
            dt_s = max(now_s - self.last[2], 0.0)
            allowed_m = PLAUSIBLE_SPEED_MPS * dt_s + JUMP_NOISE_SIGMAS * math.sqrt(2.0) * rms_m
            if jump_m > allowed_m:
                raise PoseRefused(f"Global Pose jumped {jump_m:.1f} m in {dt_s:.3f} s "
                                  f"(at most {allowed_m:.1f} m)")
        self.last = (north_m, east_m, now_s)
        cos0, sin0 = math.cos(yaw0), math.sin(yaw0)
        return ReportLocalPose(
            x_m=cos0 * north_m + sin0 * east_m, y_m=-sin0 * north_m + cos0 * east_m,
            z_m=fix.elevation_m, position_rms_m=rms_m, roll_rad=fix.roll_rad,
            pitch_rad=fix.pitch_rad, yaw_rad=_wrap_rad(yaw - yaw0),
            attitude_rms_rad=fix.attitude_rms_rad, timestamp=fix.timestamp)


__all__ = ["JAUS_PROFILES", "JausProfile", "JausSensor", "LocalFrame", "PoseRefused", "SpeedCheck",
           "safety_mode_from_status"]
