"""The speed server's hints to its client (seed 001): slipping, slowdown, downshift, upshift.

Seed 001: "suggest_upshift: Current speed and RPM high enough for upshift to HIGH",
"suggest_downshift: Current speed and RPM low enough for downshift to LOW", "suggest_slowdown:
RPM too high for vehicle speed", "slipping: Odometer and radar indicate slipping". The client
"should gracefully take corrective action" (the driving module, ``servers.gear_hints``).

Decisions (docs/speed-server.md, "Hints"):

- **Downshift = lugging.** In a forward gear that pulls less than the preset's low gear, at
  (nearly) full throttle, at least ``lug_gap_mps`` (or half the target, if less) below the
  target the gear allows and gaining
  less than ``lug_accel_mps2``, slow enough for the low gear (ground speed below its cap, so the
  rpm after the shift stays in range), for ``lug_time_s``. Judged against the *target*, not the
  controller's speed reference: the reference never leads the measured speed by more than
  0.3 m/s (no wind-up), so a gap to the reference can never show lugging. Standing still at
  full throttle on a grade the gear cannot hold counts (a stall), and so does a hill start the
  direction hold keeps on the brakes because the gear cannot beat the grade
  (``servers.direction_hold``, ``cannot_climb``): its throttle is closed, yet it is the same
  stall, found before the throttle is tried. The hint comes ``lug_time_s`` into the hold, well
  before the hold's fault (``hold_timeout_s``, 3 s), so the client can stop, shift and restart.
- **Upshift.** In a forward gear below the drive gear, when the engine speed *and* the ground
  speed are both at least ``upshift_rpm_fraction`` of the gear's range (the rpm alone is not
  enough: spinning wheels rev the engine at a standstill), the client asks for about that much,
  and the drive gear could still accelerate by ``upshift_accel_mps2`` at this speed on this
  grade (the preset's powertrain model), for ``upshift_time_s``. The last clause keeps an
  upshift from leading straight into a downshift on a hill.
- "LOW" is the preset's ``low_gear`` (ranger-6x6: ``low6wd``, the seed's gear "on slippery or
  tilted surfaces"; escape-hybrid: ``low``); "HIGH" is its ``drive_gear``.
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.dynamics.vehicle_params import Gear, VehicleParams

HINTS = ("none", "suggest_upshift", "suggest_downshift", "suggest_slowdown", "slipping")


class HintConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Thresholds of the hints; every number says where it comes from."""

    hold_s: float = 1.0                  # a hint stays at least this long (no chatter)
    slip_min_mps: float = 0.5            # wheel vs ground speed disagreement that is slipping ...
    slip_fraction: float = 0.15          # ... or this share of the ground speed, if larger
    slip_time_s: float = 0.2             # ... for at least this long
    slowdown_rpm_fraction: float = 0.97  # rpm share of idle..redline that suggests slowing down
    lug_throttle_pct: float = 80.0       # "full" throttle: above what the speed loop needs to
                                         # accelerate at the comfort 1.5 m/s^2 on the flat (~75 %)
    lug_gap_mps: float = 0.5             # behind the target by this much (25 sigma of the
                                         # GPS/INS speed noise): not just easing into it ...
    lug_gap_fraction: float = 0.5        # ... or by half a slower target (a creep to the end of
                                         # a move: 0.3 m/s, stalled 0.15 m/s behind)
    lug_accel_mps2: float = 0.3          # ... and gaining less than this (a fifth of the driving
                                         # module's comfort 1.5 m/s^2; 6x the IMU noise)
    lug_time_s: float = 1.0              # ... for this long (throttle lag 0.15 s + the 0.2 s
                                         # throttle filter, several times over)
    upshift_rpm_fraction: float = 0.85   # rpm and ground speed share of the gear's range; the
                                         # speed server caps at 0.9 of the top speed
    upshift_accel_mps2: float = 0.6      # the drive gear must gain this at this speed and grade:
                                         # twice the lugging threshold (hysteresis)
    upshift_time_s: float = 1.0          # as lug_time_s


class HintInputs(msgspec.Struct, frozen=True):
    """The vehicle as the speed server sees it in run. Speeds and accelerations signed along
    the heading; ``target_mps``: the speed asked for, capped by the gear (0 unless asked to
    run); ``sin_pitch`` + uphill along the heading."""

    gear: Gear
    speed_mps: float
    wheel_mps: float | None
    accel_mps2: float
    target_mps: float
    sin_pitch: float
    engine_rpm: float
    throttle_pct: float
    traction_control: bool
    abs_active: bool = False          # ABS acts (issue 31): the wheels read slow while braking
                                      # at the limit, which is not slippery ground
    held_cannot_climb: bool = False   # the direction hold keeps a start on the brakes: this
                                      # gear cannot beat the grade (direction_hold.cannot_climb)


class HintMonitor:
    """The current hint, updated once per period from the speed server's view of the vehicle."""

    def __init__(self, params: VehicleParams, config: HintConfig, gear_cap_fraction: float) -> None:
        self.params = params
        self.config = config
        self.gear_cap_fraction = gear_cap_fraction
        self._low = _gear_or_none(params, params.low_gear)
        self._drive = _gear_or_none(params, params.drive_gear)
        self.hint = "none"
        self.since_s = -math.inf
        self.slip_since_s: float | None = None
        self.lug_since_s: float | None = None
        self.up_since_s: float | None = None

    def reset(self) -> None:
        """Outside run: no condition is timed."""
        self.slip_since_s = self.lug_since_s = self.up_since_s = None

    def update(self, now_s: float, view: HintInputs | None) -> str:
        """The hint to publish; ``view`` is None outside run (nothing is timed there)."""
        cfg = self.config
        hint = "none"
        if view is None:
            self.reset()
        else:
            hint = self._condition(now_s, view)
        if hint != self.hint and (hint != "none" or now_s - self.since_s >= cfg.hold_s):
            self.hint, self.since_s = hint, now_s
        return self.hint

    def _condition(self, now_s: float, view: HintInputs) -> str:
        cfg = self.config
        p = self.params
        ground = view.speed_mps
        wheel = view.wheel_mps if view.wheel_mps is not None else ground
        disagree = (not view.abs_active
                    and abs(wheel - ground) > max(cfg.slip_min_mps, cfg.slip_fraction * abs(ground)))
        self.slip_since_s = _timed(view.traction_control or disagree, self.slip_since_s, now_s)
        rpm_frac = (view.engine_rpm - p.idle_rpm) / max(p.redline_rpm - p.idle_rpm, 1.0)
        gear = view.gear
        self.lug_since_s = _timed(
            self.lugging(gear, ground, view.accel_mps2, view.target_mps, view.throttle_pct,
                         held_cannot_climb=view.held_cannot_climb),
            self.lug_since_s, now_s)
        self.up_since_s = _timed(
            self.upshift_ready(gear, ground, view.target_mps, view.sin_pitch, rpm_frac),
            self.up_since_s, now_s)
        if _held(self.slip_since_s, now_s, cfg.slip_time_s):
            return "slipping"
        if rpm_frac >= cfg.slowdown_rpm_fraction:
            return "suggest_slowdown"
        if _held(self.lug_since_s, now_s, cfg.lug_time_s):
            return "suggest_downshift"
        if _held(self.up_since_s, now_s, cfg.upshift_time_s):
            return "suggest_upshift"
        return "none"

    def lugging(self, gear: Gear, speed_mps: float, accel_mps2: float, target_mps: float,
                throttle_pct: float, *, held_cannot_climb: bool = False) -> bool:
        """Full throttle, behind the target and not gaining, slow enough for the low gear; or
        asked to move but held on the brakes because this gear cannot beat the grade (the
        throttle is closed there, so only the hold knows)."""
        cfg = self.config
        low = self._low
        if (low is None or gear.direction <= 0 or low.direction <= 0
                or low.max_force_n <= gear.max_force_n):
            return False
        v = gear.direction * speed_mps
        gap = min(cfg.lug_gap_mps, cfg.lug_gap_fraction * target_mps)
        if held_cannot_climb and target_mps > 0.0 and target_mps - v >= gap:
            return True
        return (throttle_pct >= cfg.lug_throttle_pct
                and target_mps - v >= gap
                and gear.direction * accel_mps2 < cfg.lug_accel_mps2
                and abs(speed_mps) < low.max_speed_mps * self.gear_cap_fraction)

    def upshift_ready(self, gear: Gear, speed_mps: float, target_mps: float, sin_pitch: float,
                      rpm_frac: float) -> bool:
        """Rpm and ground speed high in this gear, asked for about as much, and the drive gear
        able to gain ``upshift_accel_mps2`` here (``sin_pitch`` + uphill along the heading)."""
        cfg = self.config
        drive = self._drive
        if (drive is None or gear.direction <= 0 or gear.name == drive.name
                or drive.max_speed_mps <= gear.max_speed_mps):
            return False
        high_enough = cfg.upshift_rpm_fraction * gear.max_speed_mps
        if not (rpm_frac >= cfg.upshift_rpm_fraction and speed_mps >= high_enough
                and target_mps >= high_enough):
            return False
        gain = (drive_authority_mps2(self.params, drive, speed_mps)
                - resistance_mps2(self.params, speed_mps, sin_pitch))
        return gain >= cfg.upshift_accel_mps2


def _gear_or_none(params: VehicleParams, name: str) -> Gear | None:
    try:
        return params.gear(name)
    except KeyError:
        return None


def _timed(condition: bool, since_s: float | None, now_s: float) -> float | None:
    if not condition:
        return None
    return now_s if since_s is None else since_s


def _held(since_s: float | None, now_s: float, hold_s: float) -> bool:
    return since_s is not None and now_s - since_s >= hold_s - 1e-9


__all__ = ["HINTS", "HintConfig", "HintInputs", "HintMonitor"]
