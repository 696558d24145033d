"""Tyre-road friction re-estimated online from what the vehicle reports (seed 004, issue 31).

Seed 004: the move server adapts "to actuator performance, vehicle dynamics, terrain, software
performance and bandwidth". Terrain's first figure is the grip. Grip is only measurable near its
limit: while ABS or traction control acts, the tyres give all they have, so the specific force
the IMU reads then (less rolling resistance and drag, which are not tyre force) *is* the grip.
Below the limit a sample only says "at least this much". Hence the rule:

- **Tightening, at once**: during an ABS or traction-control episode the estimate is the mean
  of the episode's grip samples (from its first period on), never above the estimate before the
  episode. ``mu = sqrt((f_x / g)^2 + (f_y * DRY_MU / (g * skidpad_lat_g))^2) / cos(pitch)``: the
  vehicle file's friction ellipse (longitudinal ``mu g``, lateral ``skidpad_lat_g g mu / DRY_MU``)
  solved for the ``mu`` at which the force measured lies on it. A 2WD wheel spin uses only the
  driven share of the weight: its sample reads low, the safe side.
- **Loosening, slowly, with evidence**: ``quiet_s`` after the last episode, each second in
  which the tyres work at ``evidence_fraction`` or more of the estimate (braking, accelerating,
  turning) without slipping raises it by ``rise_per_s``, never above ``headroom`` times the
  most grip used without slip since ``quiet_s`` after the last episode (the grip
  *demonstrated*: forces low-passed over ``filter_s``, so one noisy IMU sample is no evidence),
  nor above ``maximum`` (the configured maximum; the owners default it to the friction the stack
  was configured with, so a run that configures nothing only ever tightens and recovers). The
  headroom of 2 keeps the driving module's braking plan (25 % derate x 0.6 of the ellipse: 0.45
  of the estimate) at 0.9 of the grip demonstrated; a curve's cap (0.675 of the estimate) can
  exceed the truth once the estimate passes 1.48 times it: that slide is the measurement
  (grip is only measurable near its limit), caught by the curve's grip-lost stop (issue 30).
- **A measurement is a ceiling**: after an ABS episode or a slide the estimate loosens no higher
  than the grip it measured until grip above it is used without slip (new evidence); else a curve
  at its cap would slide again every few seconds on unchanged ground. A wheel spin (tyre force
  forward) sets none: in 2WD it loads only the driven wheels and reads low.
- **IMU bias**: the IMU's forward force and the trusted speed's derivative plus gravity along the
  pitch, low-passed alike, are compared; a difference averaging more than ``crosscheck_mps2``
  over ``bias_s`` is the IMU's bias and is taken out of every sample.

Never from the simulator's truth: only ``VehicleStatus`` (its ABS and traction-control flags),
the IMU and the trusted speed. Pure, time passed in. Docs: docs/driving-module.md,
"Friction, online".
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.speed_control import resistance_mps2
from overdrive.dynamics.vehicle_params import DRY_MU, G_MPS2, VehicleParams


class GripConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """The estimator's rule; each default says where its number comes from."""

    floor: float = 0.05             # never below: the lowest friction a scenario may set is > 0,
                                    # ice is ~0.05-0.1 (a lower sample is IMU noise at rest)
    rise_per_s: float = 0.05        # loosening per second of evidence: 0.25 -> 0.8 in 11 s of
                                    # tyres at work (stated in docs/driving-module.md)
    quiet_s: float = 2.0            # no episode for this long before loosening starts (the
                                    # traction monitor's hold is 5 s; ABS cycles at ~10 Hz)
    evidence_fraction: float = 0.3  # tyres at work: grip used >= this share of the estimate
    headroom: float = 2.0           # never above this x the grip demonstrated (see module doc)
    min_speed_mps: float = 0.3      # below: the last instants of a stop, a start from rest
    filter_s: float = 0.3           # time constant of the low-pass on the IMU's forces and the
                                    # trusted speed's derivative: the grip demonstrated is a force
                                    # sustained for ~this long, not one noisy sample (sigma 1
                                    # m/s^2 at 100 Hz -> 0.13 m/s^2 filtered)
    crosscheck_mps2: float = 1.0    # the IMU's forward force and the trusted speed's derivative
                                    # (plus gravity), both low-passed alike, differ by more on
                                    # average over ``bias_s``: the IMU is biased, the difference
                                    # is taken out (the plausibility checks let 3 m/s^2 through)
    bias_s: float = 0.5             # averaging time of that difference: a bias is constant, the
                                    # GPS speed's derivative noise (~0.3 m/s^2) averages out


def grip_used(params: VehicleParams, lon_mps2: float, lat_mps2: float, pitch_rad: float) -> float:
    """Friction the tyre force ``(lon, lat)`` needs on the vehicle file's ellipse (see module)."""
    lat_scale = DRY_MU / max(params.skidpad_lat_g, 1e-6)
    used = math.hypot(lon_mps2 / G_MPS2, lat_mps2 * lat_scale / G_MPS2)
    return used / max(math.cos(pitch_rad), 0.1)


class GripEstimator:
    """The friction the stack plans with (see the module doc)."""

    __slots__ = ("_before", "_count", "_fx", "_fy", "_prev_mps", "_sum", "_vdot", "bias_mps2", "config",
                 "demonstrated", "episodes", "estimate", "evidence_s", "last_episode_s",
                 "maximum", "measured", "params")

    def __init__(self, params: VehicleParams, initial: float, maximum: float | None = None,
                 config: GripConfig | None = None) -> None:
        top = initial if maximum is None else maximum
        if not (math.isfinite(initial) and initial > 0.0 and math.isfinite(top) and top > 0.0):
            raise ValueError(f"friction: positive finite numbers, got {initial}, {maximum}")
        self.params = params
        self.config = config or GripConfig()
        self.maximum = top
        self.estimate = min(initial, top)
        self.last_episode_s = -math.inf
        self.evidence_s = 0.0      # evidence time since the last episode
        self.demonstrated = 0.0    # most grip used without slip since the last episode
        self.episodes = 0
        self._before: float | None = None   # the estimate when the episode began (None: none)
        self._sum = 0.0
        self._count = 0
        self.measured = math.inf   # the grip the last episode measured: no loosening above it
                                   # without new evidence (grip demonstrated above it)
        self._prev_mps: float | None = None   # the trusted speed last period (None: restart)
        self._fx = self._fy = self._vdot = 0.0   # low-passed IMU forces, speed derivative
        self.bias_mps2 = 0.0       # the IMU's forward force less the speed's, averaged

    def update(self, now_s: float, dt_s: float, *, speed_mps: float, accel_x_mps2: float,
               accel_y_mps2: float, pitch_rad: float, direction: int, slipping: bool) -> float:
        """One period: ``slipping`` is ABS or traction control reported; the IMU's specific
        forces; ``direction`` the travel's sign (+1 forward). Returns the estimate."""
        cfg = self.config
        v_along = direction * speed_mps
        if (direction == 0 or abs(speed_mps) < cfg.min_speed_mps or dt_s <= 0.0
                or not all(map(math.isfinite, (speed_mps, accel_x_mps2, accel_y_mps2, pitch_rad)))):
            self._before = None
            self._prev_mps = None
            return self.estimate
        self._filter(speed_mps, dt_s, accel_x_mps2, accel_y_mps2, pitch_rad)
        sin_grade = direction * math.sin(pitch_rad)
        losses = resistance_mps2(self.params, v_along, sin_grade) - G_MPS2 * sin_grade
        # the IMU's forward force, less its bias when the trusted speed shows one
        bias = self.bias_mps2 if abs(self.bias_mps2) > cfg.crosscheck_mps2 else 0.0
        raw_x = accel_x_mps2 - bias
        steady_x = self._fx - bias
        if slipping:
            lon = direction * raw_x + losses
            used = grip_used(self.params, lon, accel_y_mps2, pitch_rad)
            # a wheel spin (the tyre force forward, mostly along): in 2WD only the driven
            # share of the weight, so a low reading, no ceiling; ABS or a slide measure the grip
            spin = lon > 0.0 and lon >= grip_used(self.params, 0.0, accel_y_mps2, 0.0) * G_MPS2
            if self._before is None:
                self._before, self._sum, self._count = self.estimate, 0.0, 0
                self.episodes += 1
            self._sum += used
            self._count += 1
            mean = max(cfg.floor, self._sum / self._count)
            self.estimate = min(self._before, mean)
            if not spin:
                self.measured = mean
            self.last_episode_s = now_s
            self.evidence_s = 0.0
            self.demonstrated = 0.0
            return self.estimate
        self._before = None
        # evidence is a force sustained over ``filter_s``, never one (noisy) sample
        used = grip_used(self.params, direction * steady_x + losses, self._fy, pitch_rad)
        if now_s - self.last_episode_s < cfg.quiet_s:
            return self.estimate          # an episode's tail (at the limit) is no evidence
        self.demonstrated = max(self.demonstrated, used)
        if self.demonstrated > self.measured:
            self.measured = math.inf      # new evidence of more grip than the last measurement
        if (used >= cfg.evidence_fraction * self.estimate
                and self.estimate < self.maximum):
            self.evidence_s += dt_s
            cap = min(self.maximum, cfg.headroom * self.demonstrated, self.measured)
            self.estimate = max(self.estimate, min(cap, self.estimate + cfg.rise_per_s * dt_s))
        return self.estimate

    def _filter(self, speed_mps: float, dt_s: float, accel_x_mps2: float, accel_y_mps2: float,
                pitch_rad: float) -> None:
        """Low-pass the IMU's forces and the trusted speed's derivative alike (same lag), and
        average their forward difference (the IMU's bias; the speed's derivative plus gravity
        along the pitch is the forward specific force a healthy IMU reads). The bias estimate
        survives restarts (a bias is the sensor's, not the drive's)."""
        prev = self._prev_mps
        self._prev_mps = speed_mps
        if prev is None:        # a restart: the filters start from this sample
            self._fx, self._fy = accel_x_mps2, accel_y_mps2
            self._vdot = accel_x_mps2 - G_MPS2 * math.sin(pitch_rad)
        else:
            k = min(1.0, dt_s / self.config.filter_s)
            self._fx += k * (accel_x_mps2 - self._fx)
            self._fy += k * (accel_y_mps2 - self._fy)
            self._vdot += k * ((speed_mps - prev) / dt_s - self._vdot)
            fx_speed = self._vdot + G_MPS2 * math.sin(pitch_rad)
            self.bias_mps2 += min(1.0, dt_s / self.config.bias_s) * (
                self._fx - fx_speed - self.bias_mps2)


__all__ = ["GripConfig", "GripEstimator", "grip_used"]
