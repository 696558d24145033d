"""The "plain JAUS" vehicle profile: what the XGV client reads from a JAUS 3.3 vehicle that has
none of the XGV's own messages (OpenJAUS's ojVehicleSim, issue 19). Pure functions, sans-IO.

A plain JAUS 3.3 vehicle has a Primitive Driver, a Global Pose Sensor and a Velocity State
Sensor, and no Report Vehicle Mode (0xE456), Local Pose, Discrete Devices or Wheels Speed
reports. The client's ``profile="plain"`` takes instead:

- **safety mode** from the Primitive Driver's Report Component Status (primary status) and
  whether the client holds its control (``safety_mode_from_status``);
- **pose** from Report Global Pose, projected on a local plane (``LocalFrame``): origin at
  the first valid fix, x axis along that fix's heading, so the run starts at (0, 0) heading 0
  as every scenario assumes; equirectangular with the WGS-84 radii of curvature at the
  origin's latitude (``local_radii_m``; the simulated XGV's Global Pose is its exact inverse):
  ``north = M(lat0) * dlat``, ``east = N(lat0) * cos(lat0) * dlon``. Against the exact
  east-north-up frame (ECEF -> ENU) its error grows as the square of the distance ``d`` from
  the origin and with the latitude, at most ``0.6 * d**2 * tan|lat0| / N``: 0.7 mm at 100 m
  and 67 mm at 1 km at 37 deg, 0.15 m at 1 km at 60 deg, 0.5 m at 80 deg, nil at the equator
  (measured against ECEF -> ENU in tests/xgv/test_xgv_plain_profile.py): below a GPS's noise
  over the few hundred metres of a run, not over kilometres at high latitudes;
- **speed** from Report Velocity State (as the XGV profile).

Global Pose fixes are validated before anything uses them (``LocalFrame.project``): a fix
without latitude, longitude or yaw, with a value outside its range or not finite, beyond the
latitudes where the projection holds, or claiming an accuracy too poor to drive on
(``MAX_POSITION_RMS_M``), or further from the last accepted fix than any JAUS 3.3 speed and
that accuracy allow, is refused with a reason and never moves the stack's pose.

Velocity State is the plain vehicle's only speed (it is both the stack's wheel speed and its
GPS speed, and its integral is the odometer the move server stops on), so it is checked
against the Global Pose, an independent sensor (``SpeedCheck``): accepted poses further apart
than the odometer says were driven, beyond the position noise, mean the speed reads low. The
poses are averaged over half-second blocks, which shrinks independent noise by sqrt(n).
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Final, Literal

from overdrive.jaus import ComponentStatus, ReportGlobalPose, ReportLocalPose

JausProfile = Literal["xgv", "plain"]
JAUS_PROFILES: Final = ("xgv", "plain")

WGS84_A_M: Final = 6_378_137.0        # WGS-84 semi-major axis (equatorial radius), NIMA TR8350.2
WGS84_E2: Final = 6.694_379_990_14e-3 # WGS-84 first eccentricity squared, NIMA TR8350.2
MAX_ABS_LATITUDE_DEG: Final = 84.0    # UTM's northern limit (its southern is 80 S; polar
                                      # regions use UPS): nearer the poles the east scale
                                      # cos(lat) collapses, and the projection's error
                                      # (tan lat) with it
MAX_POSITION_RMS_M: Final = 3.0       # fixes claiming worse are refused: a lane is 3-3.7 m
                                      # wide, and the jump and speed checks' bounds grow with
                                      # the rms (3x ojVehicleSim's claimed 1 m, 150x the
                                      # simulated XGV's 0.02 m)
PLAUSIBLE_SPEED_MPS: Final = 65.534   # the largest speed JAUS 3.3 can report (Velocity State
                                      # velocity x, reference §5): no vehicle jumps faster
DEFAULT_POSITION_RMS_M: Final = 1.0   # a fix without its accuracy: ojVehicleSim's reported rms
JUMP_NOISE_SIGMAS: Final = 6.0        # position noise allowed on a jump (as REPORTED_POSE_BOUND_M)
SPEED_CHECK_WINDOW_S: Final = 10.0    # blocks compared with the odometer this far back
SPEED_CHECK_BLOCK_S: Final = 0.5      # poses averaged per block: at 100 Hz, 50 fixes, noise of
                                      # a block pair 1/5 of a single pair's (1.3 m bound at
                                      # 1 m rms); a longer block delays the check
SPEED_CHECK_SIGMAS: Final = 6.5       # the bound in standard deviations of the blocks' means:
                                      # healthy runs with 1 m noise peaked at 5.2 (150 runs,
                                      # both presets, straight and curved); thousands of
                                      # comparisons a second need a tail of e^-21 (Rayleigh);
                                      # 7 lets a half speed at 0.02 m rms reach 2.9 m/s
REPORT_SKEW_S: Final = 0.25           # pose and velocity reports out of step by up to the
                                      # odometer's gap (xgv_client.ODOMETER_GAP_S): |v| x this
STATUS_TIMEOUT_S: Final = 0.5         # no component status for this long: unknown (25 of
                                      # OpenJAUS's 50 Hz reports lost; was the 1.5 s heartbeat
                                      # timeout: a stale READY drove on for 1.5 s)


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


def local_radii_m(lat_deg: float) -> tuple[float, float]:
    """WGS-84 meridian (north) and prime-vertical (east) radii of curvature at ``lat_deg``."""
    w2 = 1.0 - WGS84_E2 * math.sin(math.radians(lat_deg)) ** 2
    return WGS84_A_M * (1.0 - WGS84_E2) / w2 ** 1.5, WGS84_A_M / math.sqrt(w2)


class _Block:
    """Sums of the poses of one averaging block (``SpeedCheck``)."""

    __slots__ = ("n", "odometer_m", "rms2_m2", "speed_mps", "t0_s", "x_m", "y_m")

    def __init__(self, t0_s: float) -> None:
        self.t0_s = t0_s
        self.n = 0
        self.x_m = self.y_m = self.odometer_m = self.rms2_m2 = self.speed_mps = 0.0

    def add(self, x_m: float, y_m: float, odometer_m: float, rms_m: float,
            speed_mps: float) -> None:
        self.n += 1
        self.x_m += x_m
        self.y_m += y_m
        self.odometer_m += odometer_m
        self.rms2_m2 += rms_m * rms_m
        self.speed_mps = max(self.speed_mps, abs(speed_mps))

    def mean(self) -> tuple[float, float, float, float]:
        """Mean x, y, odometer, and the variance of the mean position per axis."""
        n = self.n
        return self.x_m / n, self.y_m / n, self.odometer_m / n, self.rms2_m2 / (n * n)


class SpeedCheck:
    """Velocity State against Global Pose: the straight line between two accepted poses can
    never be longer than the path driven between them (the odometer, integrated |speed|).

    Poses are averaged over blocks of ``SPEED_CHECK_BLOCK_S``; with every fix, the fix itself
    (quick when the rms is small) and the block it joins (its mean so far: tight when it is
    large) are compared with each completed block in ``SPEED_CHECK_WINDOW_S``. The chord between two
    blocks' mean positions is at most the difference of their mean odometers on any path
    (triangle inequality over every pair of their poses, all of the later block's after the
    earlier's), so the bound is the noise of the two means, ``SPEED_CHECK_SIGMAS`` times
    sqrt(sum rms^2 / n^2 of each), plus the reports' skew at the later one's speed (the
    odometer integrates velocity reports as they come, so it lags the pose, as before). The
    averaging assumes the fixes' errors independent (a simulator's, or white noise); a GPS
    whose error wanders over seconds is averaged less than the bound assumes. Only a speed
    reading low is caught (a high one stops the move early)."""

    def __init__(self) -> None:
        self.blocks: list[tuple[float, float, float, float, float, float]] = []
        # (end time (s), mean x, mean y, mean odometer (m), variance of the mean (m^2), top |v|)
        self.current: _Block | None = None

    def check(self, now_s: float, x_m: float, y_m: float, odometer_m: float, rms_m: float,
              speed_mps: float) -> str | None:
        """Take one new fix; None while plausible, else the reason (the speed reads low)."""
        block = self.current
        if block is not None and now_s - block.t0_s >= SPEED_CHECK_BLOCK_S:
            self.blocks.append((now_s, *block.mean(), block.speed_mps))
            block = None
        while self.blocks and now_s - self.blocks[0][0] > SPEED_CHECK_WINDOW_S:
            self.blocks.pop(0)
        if block is None:
            block = self.current = _Block(now_s)
        block.add(x_m, y_m, odometer_m, rms_m, speed_mps)
        latest = (x_m, y_m, odometer_m, rms_m * rms_m, abs(speed_mps), 1)
        for x_m, y_m, odometer_m, var_m2, speed1_mps, n in (
                latest, (*block.mean(), block.speed_mps, block.n)):
            for t_s, x0_m, y0_m, odometer0_m, var0_m2, _ in self.blocks:
                chord_m = math.hypot(x_m - x0_m, y_m - y0_m)
                driven_m = odometer_m - odometer0_m
                allowed_m = (SPEED_CHECK_SIGMAS * math.sqrt(var_m2 + var0_m2)
                             + speed1_mps * REPORT_SKEW_S)
                if chord_m - driven_m > allowed_m:
                    return (f"Velocity State reads low: the Global Pose (mean of {n} fixes) "
                            f"moved {chord_m:.1f} m in {now_s - t_s:.1f} s, the speed says "
                            f"{driven_m:.1f} m (noise and skew allow {allowed_m:.1f} m)")
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
        self.radii_m = (WGS84_A_M, WGS84_A_M)   # meridian, prime vertical at the origin

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
        if rms is not None and math.isfinite(rms) and rms > MAX_POSITION_RMS_M:
            raise PoseRefused(f"Global Pose claims {rms:.2f} m rms, more than "
                              f"{MAX_POSITION_RMS_M} m: too inaccurate to drive on")
        rms_m = rms if rms is not None and math.isfinite(rms) and rms > 0.0 \
            else DEFAULT_POSITION_RMS_M
        if self.origin is None:
            self.origin = (lat, lon, yaw)
            self.radii_m = local_radii_m(lat)
        lat0, lon0, yaw0 = self.origin
        meridian_m, prime_vertical_m = self.radii_m
        dlon_deg = (lon - lon0 + 180.0) % 360.0 - 180.0    # across the antimeridian too
        north_m = meridian_m * math.radians(lat - lat0)
        east_m = prime_vertical_m * math.cos(math.radians(lat0)) * math.radians(dlon_deg)
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
           "local_radii_m", "safety_mode_from_status"]
