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
  most grip used without slip since the last episode (the grip *demonstrated*), nor above
  ``maximum`` (the configured maximum; the owners default it to the friction the stack was
  configured with, so a run that configures nothing only ever tightens and recovers). The
  headroom of 2 keeps the driving module's braking plan (25 % derate x 0.6 of the ellipse: 0.45
  of the estimate) at 0.9 of the grip demonstrated; a curve's cap (0.675 of the estimate) can
  exceed the truth once the estimate passes 1.48 times it: that slide is the measurement
  (grip is only measurable near its limit), caught by the curve's grip-lost stop (issue 30).

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


def grip_used(params: VehicleParams, lon_mps2: float, lat_mps2: float, pitch_rad: float) -> float:
    """Friction the tyre force ``(lon, lat)`` needs on the vehicle file's ellipse (see module)."""
    lat_scale = DRY_MU / max(params.skidpad_lat_g, 1e-6)
    used = math.hypot(lon_mps2 / G_MPS2, lat_mps2 * lat_scale / G_MPS2)
    return used / max(math.cos(pitch_rad), 0.1)


class GripEstimator:
    """The friction the stack plans with (see the module doc)."""

    __slots__ = ("_before", "_count", "_sum", "config", "demonstrated", "episodes", "estimate",
                 "evidence_s", "last_episode_s", "maximum", "params")

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

    def update(self, now_s: float, dt_s: float, *, speed_mps: float, accel_x_mps2: float,
               accel_y_mps2: float, pitch_rad: float, direction: int, slipping: bool) -> float:
        """One period: ``slipping`` is ABS or traction control reported; the IMU's specific
        forces; ``direction`` the travel's sign (+1 forward). Returns the estimate."""
        cfg = self.config
        v_along = direction * speed_mps
        if (direction == 0 or abs(speed_mps) < cfg.min_speed_mps or dt_s <= 0.0
                or not all(map(math.isfinite, (speed_mps, accel_x_mps2, accel_y_mps2, pitch_rad)))):
            self._before = None
            return self.estimate
        sin_grade = direction * math.sin(pitch_rad)
        losses = resistance_mps2(self.params, v_along, sin_grade) - G_MPS2 * sin_grade
        lon = direction * accel_x_mps2 + losses    # tyre force along travel (rolling, drag out)
        used = grip_used(self.params, lon, accel_y_mps2, pitch_rad)
        if slipping:
            if self._before is None:
                self._before, self._sum, self._count = self.estimate, 0.0, 0
                self.episodes += 1
            self._sum += used
            self._count += 1
            self.estimate = max(cfg.floor, min(self._before, self._sum / self._count))
            self.last_episode_s = now_s
            self.evidence_s = 0.0
            self.demonstrated = 0.0
            return self.estimate
        self._before = None
        self.demonstrated = max(self.demonstrated, used)
        if (now_s - self.last_episode_s >= cfg.quiet_s
                and used >= cfg.evidence_fraction * self.estimate
                and self.estimate < self.maximum):
            self.evidence_s += dt_s
            cap = min(self.maximum, cfg.headroom * self.demonstrated)
            self.estimate = max(self.estimate, min(cap, self.estimate + cfg.rise_per_s * dt_s))
        return self.estimate


__all__ = ["GripConfig", "GripEstimator", "grip_used"]
