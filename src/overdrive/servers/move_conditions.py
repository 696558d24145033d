"""Speed reductions of the move server (seed 004 "several factors can cause that speed to be
reduced"): each condition is watched with hysteresis and, while active, caps the speed.

Conditions (``code``):

- ``bumpy``: vertical-acceleration variance from the IMU (exponential window), noise floor of
  the sensor removed; speed x ``bumpy_start / roughness`` (not below ``bumpy_min_factor``).
- ``steep``: GPS/INS pitch beyond ``steep_start_fraction`` of the vehicle's limit; speed
  scaled linearly down to ``steep_min_factor`` at the limit.
- ``sticky``: slip (wheel speed vs GPS speed, the vehicle's traction control, the speed
  server's ``slipping`` hint) or the vehicle not keeping up with the goal speed at high
  throttle (mud); speed x ``sticky_factor`` for ``sticky_hold_s`` after the last sign.
- ``actuator``: an actuator estimate degraded (``adaptive``); the caps themselves come from the
  adaptive scheme (brake: stopping profile and sqrt(effectiveness); steering: turn-in).
- ``estop``: a safety mode other than drive-by-wire, or the speed server's e-stop: speed 0.
- ``slowdown``: the speed server's ``suggest_slowdown`` hint: speed x ``slowdown_factor``.
- ``curve``: the command's curve needs a lower speed than asked (lateral part of the ellipse).
- ``localization``: no GPS/INS for ``gps_timeout_s``: speed 0 (the progress is unknown).
- ``lag`` (issue 31; seed 004 adapts to "software performance and bandwidth"): the move
  server's own inputs (GPS/INS, the speed server's state) arrived late or were lost: the worst
  gap between arrivals over the last ``lag_window_s`` (``InputGaps``, on this server's own step
  times, so its own stall counts too), less ``lag_allowance_s``, is extra blind time ``L``;
  speed x ``lag_reaction_s / (lag_reaction_s + L)``, so the distance driven on stale state
  within the reaction allowance stays what it was budgeted (not below ``lag_min_factor``).

``ConditionMonitor.update`` takes plain values; ``active`` is the current set; ``started``
lists the conditions that became active at the last update (for the notices).
"""

from __future__ import annotations

import math
from collections import deque

import msgspec

from overdrive.dynamics.vehicle_params import VehicleParams


class ConditionConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    bumpy_window_s: float = 1.0       # variance window: a few wheelbases at walking speed
    bumpy_start_mps2: float = 1.0     # RMS vertical accel ~0.1 g: ISO 2631 "uncomfortable"
    bumpy_stop_ratio: float = 0.8     # hysteresis: inactive again below 0.8 x start
    bumpy_min_factor: float = 0.3
    steep_start_fraction: float = 0.5  # same threshold the driving module uses for low gear
    steep_stop_ratio: float = 0.9
    steep_min_factor: float = 0.5
    slip_min_mps: float = 0.5         # wheel vs ground disagreement (speed server's threshold)
    slip_fraction: float = 0.15
    lag_mps: float = 1.5              # goal - speed beyond this ...
    lag_throttle_pct: float = 80.0    # ... at this much throttle ...
    lag_time_s: float = 2.0           # ... for this long: not keeping up (mud)
    sticky_hold_s: float = 3.0
    sticky_factor: float = 0.5
    slowdown_factor: float = 0.8
    slowdown_hold_s: float = 2.0
    gps_timeout_s: float = 0.2        # same as the driving module's sensor timeout
    slip_gps_fresh_s: float = 0.05    # wheel vs ground speed only against fresh GPS/INS (5 samples):
                                      # a stale ground speed during a dropout is not slip
    lag_allowance_s: float = 0.05     # arrival gaps up to this are normal: 5 of the 10 ms state
                                      # periods, one of a 20 Hz stream (the XGV's reports)
    lag_window_s: float = 1.0         # the worst gap is remembered this long
    lag_reaction_s: float = 0.7       # the driving module's latency allowance (same figure)
    lag_min_factor: float = 0.2       # never below this share: a gap beyond gps_timeout_s is a
                                      # localization stop anyway


LAG_EPS_S = 1e-6
"""A gap must exceed the allowance by this (float sums of 10 ms steps are not exact)."""


class InputGaps:
    """Worst gap between arrivals of each watched topic over a window, on the owner's step
    times (time passed in; issue 31)."""

    def __init__(self, topics: tuple[str, ...], window_s: float) -> None:
        self.topics = topics
        self.window_s = window_s
        self.last_s: dict[str, float] = {}
        self.closed: deque[tuple[float, float, str]] = deque()   # (closed at, gap, topic)

    def arrived(self, now_s: float, topics: set[str]) -> None:
        for topic in self.topics:
            if topic in topics:
                last = self.last_s.get(topic)
                if last is not None and now_s > last:
                    self.closed.append((now_s, now_s - last, topic))
                self.last_s[topic] = now_s
        while self.closed and now_s - self.closed[0][0] > self.window_s:
            self.closed.popleft()

    def worst(self, now_s: float) -> tuple[float, str]:
        """(gap, topic): the largest closed in the window, or the one still open."""
        gap, topic = 0.0, ""
        for _, g, t in self.closed:
            if g > gap:
                gap, topic = g, t
        for t, last in self.last_s.items():
            if now_s - last > gap:
                gap, topic = now_s - last, t
        return gap, topic


class Reduction(msgspec.Struct, frozen=True):
    code: str
    cap_mps: float
    reason: str


class ConditionMonitor:
    """Watches the speed-reducing conditions; see the module docstring."""

    def __init__(self, params: VehicleParams, config: ConditionConfig | None = None) -> None:
        self.params = params
        self.config = config or ConditionConfig()
        self.z_mean: float | None = None
        self.z_var = 0.0
        self.roughness_mps2 = 0.0
        self.bumpy = False
        self.steep = False
        self.sticky_until_s = -math.inf
        self.sticky_reason = ""
        self.lag_since_s: float | None = None
        self.slowdown_until_s = -math.inf
        self.active: dict[str, Reduction] = {}
        self.started: list[Reduction] = []

    def update_imu(self, dt_s: float, accel_z_mps2: float) -> None:
        """Exponentially weighted mean and variance of the vertical specific force."""
        if not math.isfinite(accel_z_mps2):
            return
        if self.z_mean is None:
            self.z_mean = accel_z_mps2
            return
        if dt_s <= 0.0:
            return
        alpha = 1.0 - math.exp(-dt_s / self.config.bumpy_window_s)
        d = accel_z_mps2 - self.z_mean
        self.z_mean += alpha * d
        self.z_var = (1.0 - alpha) * (self.z_var + alpha * d * d)
        floor = self.params.accel_noise_mps2
        self.roughness_mps2 = math.sqrt(max(self.z_var - floor * floor, 0.0))

    def update(self, now_s: float, *, maxspeed_mps: float, pitch_rad: float, speed_mps: float,
               wheel_speed_mps: float | None, traction_control: bool, hint: str,
               goal_speed_mps: float, throttle_pct: float, safety_mode: str,
               speed_server_estop: bool, gps_age_s: float, lateral_cap_mps: float,
               degraded: list[str], actuator_cap_mps: float, actuator_reason: str,
               abs_active: bool = False, input_gap_s: float = 0.0,
               input_gap_topic: str = "", lag_explained: bool = False) -> None:
        """One period. ``lag_explained``: the vehicle accelerates as the throttle estimate says
        it can (a weak throttle, already capped as an actuator), so falling short of the goal
        at full throttle is not sticky ground."""
        cfg, p = self.config, self.params
        found: dict[str, Reduction] = {}
        v = abs(speed_mps)

        start = cfg.bumpy_start_mps2
        rough = self.roughness_mps2
        self.bumpy = rough > start or (self.bumpy and rough > cfg.bumpy_stop_ratio * start)
        if self.bumpy:
            factor = max(cfg.bumpy_min_factor, min(1.0, start / max(rough, 1e-9)))
            found["bumpy"] = Reduction("bumpy", maxspeed_mps * factor,
                                       f"too bumpy: vertical acceleration {rough:.2f} m/s^2 RMS")

        steep_start = cfg.steep_start_fraction * p.max_pitch_rad
        pitch = abs(pitch_rad)
        self.steep = pitch > steep_start or (self.steep and pitch > cfg.steep_stop_ratio * steep_start)
        if self.steep:
            span = max(p.max_pitch_rad - steep_start, 1e-9)
            over = min(max(pitch - steep_start, 0.0) / span, 1.0)
            factor = 1.0 - (1.0 - cfg.steep_min_factor) * over
            found["steep"] = Reduction("steep", maxspeed_mps * factor,
                                       f"too steep: pitch {math.degrees(pitch):.1f} deg")

        reason = ""
        # ABS (issue 31) reads the wheels slow while braking at the limit: not slippery ground
        if (wheel_speed_mps is not None and v > cfg.slip_min_mps and not abs_active
                and gps_age_s <= cfg.slip_gps_fresh_s):
            diff = abs(wheel_speed_mps - speed_mps)
            if diff > max(cfg.slip_min_mps, cfg.slip_fraction * v):
                reason = f"wheel speed {wheel_speed_mps:.2f} vs ground {speed_mps:.2f} m/s"
        if traction_control:
            reason = reason or "traction control active"
        if hint == "slipping":
            reason = reason or "speed server reports slipping"
        lagging = (goal_speed_mps - v > cfg.lag_mps and throttle_pct >= cfg.lag_throttle_pct
                   and not lag_explained)
        if lagging:
            if self.lag_since_s is None:
                self.lag_since_s = now_s
            if now_s - self.lag_since_s >= cfg.lag_time_s:
                reason = reason or (f"not keeping up: {v:.2f} m/s of {goal_speed_mps:.2f} m/s "
                                    f"at {throttle_pct:.0f} % throttle")
        else:
            self.lag_since_s = None
        if reason:
            self.sticky_until_s = now_s + cfg.sticky_hold_s
            self.sticky_reason = reason
        if now_s < self.sticky_until_s:
            found["sticky"] = Reduction("sticky", maxspeed_mps * cfg.sticky_factor,
                                        f"too sticky: {self.sticky_reason}")

        if degraded or actuator_cap_mps < maxspeed_mps:
            found["actuator"] = Reduction(
                "actuator", min(actuator_cap_mps, maxspeed_mps),
                actuator_reason or f"actuator response degraded: {', '.join(degraded)}")

        if safety_mode != "drive-by-wire" or speed_server_estop:
            why = (f"safety mode {safety_mode}" if safety_mode != "drive-by-wire"
                   else "speed server e-stop")
            found["estop"] = Reduction("estop", 0.0, f"e-stop: {why}")

        if hint == "suggest_slowdown":
            self.slowdown_until_s = now_s + cfg.slowdown_hold_s
        if now_s < self.slowdown_until_s:
            found["slowdown"] = Reduction("slowdown", maxspeed_mps * cfg.slowdown_factor,
                                          "speed server suggests slowing down (rpm)")

        if lateral_cap_mps < maxspeed_mps:
            found["curve"] = Reduction("curve", lateral_cap_mps,
                                       f"curve: lateral acceleration limits the speed to "
                                       f"{lateral_cap_mps:.2f} m/s")

        if gps_age_s > cfg.gps_timeout_s:
            found["localization"] = Reduction("localization", 0.0,
                                              f"no GPS/INS for {gps_age_s:.2f} s")

        extra_s = input_gap_s - cfg.lag_allowance_s
        if extra_s > LAG_EPS_S:
            factor = max(cfg.lag_min_factor, cfg.lag_reaction_s / (cfg.lag_reaction_s + extra_s))
            found["lag"] = Reduction("lag", maxspeed_mps * factor,
                                     f"inputs late or lost: {input_gap_topic} {input_gap_s:.2f} s "
                                     f"apart (allowance {cfg.lag_allowance_s:.2f} s): speed x "
                                     f"{factor:.2f}")

        self.started = [r for code, r in found.items() if code not in self.active] if found else []
        self.active = found

    def cap_mps(self) -> float:
        if not self.active:
            return math.inf
        return min([r.cap_mps for r in self.active.values()])


__all__ = ["ConditionConfig", "ConditionMonitor", "InputGaps", "Reduction"]
