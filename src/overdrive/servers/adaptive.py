"""Adaptive self-tuning of the move server (seed 004): predicted vs measured actuator response.

For each actuator the model predicts a response from the preset, the response is measured
from the vehicle's own reports, and the ratio measured / predicted (the actuator's
*effectiveness*) is tracked online:

- **brake**: deceleration per brake %. Predicted ``brake_pct/100 * max_brake_decel``;
  measured from the IMU's specific force along the direction of travel (gravity is not in it)
  minus rolling resistance, drag and the gear's engine braking (issue 30 item 4), while
  braking without throttle, moving, and without
  traction-control / ABS activity (then the tyres, not the brake, limit the deceleration).
- **throttle**: acceleration per throttle %. Predicted ``throttle_pct/100 * drive authority``
  of the engaged gear at the current speed; measured the same way while driving without brake.
- **steering**: road-wheel rate. The actual position (``VehicleStatus.steer_pct``) is the
  output of a first-order lag behind a rate limiter; inverting the lag exactly recovers the
  rate-limited signal, whose rate, while it is saturated (far from the command), is the
  actuator's rate. Predicted: the preset's ``steer_rate_rps``. Time to reach a target is
  ``|target - actual| / rate + 3 lag``.

Each ratio sample is clamped to ``sample_bounds`` (one bad sample moves nothing far), then fed
to two exponential averages over *excited* time (time during which the actuator was in use): a
fast one (``fast_tau_s``) and a slow one (``slow_tau_s``). The value used for limits is
``min(fast, slow, 1)`` clamped to ``estimate_bounds``: a degradation is believed quickly, a
recovery slowly, and the estimate never claims more than nominal (adaptation only tightens
limits). ``uncertain`` is set while the two averages disagree by more than ``agree_tol`` or
fewer than ``min_excited_s`` seconds of data exist since the last disagreement.
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.secondary_braking import engine_brake_mps2
from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.dynamics.vehicle_params import G_MPS2, GearTable, VehicleParams
from overdrive.messages import Message

ESTIMATES_TOPIC = "move/estimates"
"""Topic of ``ActuatorEstimates`` (published by the move server at ``estimates_period_s``)."""


class AdaptiveConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Bounds and time constants of the estimators; each default says where it comes from."""

    fast_tau_s: float = 0.3          # ~4 brake lags: follows a step within ~1 s of braking
    slow_tau_s: float = 2.0          # smooths noise; governs how slowly a recovery is believed
    sample_bounds: tuple[float, float] = (0.05, 1.5)   # per-sample ratio clamp (outliers)
    estimate_bounds: tuple[float, float] = (0.05, 1.0)  # used value: never above nominal; the
                                     # floor below the weakest brake swept (0.1, issue 16): a
                                     # floor above the truth would loosen the envelope
    agree_tol: float = 0.05          # fast and slow within 5 %: the estimate is settled
    min_excited_s: float = 0.5       # ... for at least this much excited time
    min_brake_pct: float = 10.0      # brake samples only above this (below: too little signal)
    min_throttle_pct: float = 10.0
    pedal_off_pct: float = 0.5       # the other pedal counts as released below this
    min_speed_mps: float = 0.5       # below: the last instants of a stop are not braking data
    min_predicted_mps2: float = 0.3  # predicted response below this carries too little signal
    steer_gap_pct: float = 2.0       # command this far from the rate-limited signal: saturated
    degraded_brake: float = 0.9      # below these the actuator counts as degraded (notice)
    degraded_throttle: float = 0.8
    degraded_steering: float = 0.85


class RatioEstimator:
    """Fast and slow exponential averages of a clamped ratio, weighted by excited time."""

    __slots__ = ("_value", "config", "excited_s", "fast", "samples", "settled_s", "slow")

    def __init__(self, config: AdaptiveConfig) -> None:
        self.config = config
        self.fast = 1.0
        self.slow = 1.0
        self.excited_s = 0.0     # total time with samples
        self.settled_s = 0.0     # excited time since fast and slow last disagreed
        self.samples = 0
        self._value = self._conservative()

    def update(self, ratio: float, dt_s: float) -> None:
        if not math.isfinite(ratio) or dt_s <= 0.0:
            return
        cfg = self.config
        lo, hi = cfg.sample_bounds
        r = min(max(ratio, lo), hi)
        self.fast += (r - self.fast) * (1.0 - math.exp(-dt_s / cfg.fast_tau_s))
        self.slow += (r - self.slow) * (1.0 - math.exp(-dt_s / cfg.slow_tau_s))
        self.excited_s += dt_s
        self.samples += 1
        if abs(self.fast - self.slow) > cfg.agree_tol:
            self.settled_s = 0.0
        else:
            self.settled_s += dt_s
        self._value = self._conservative()

    def _conservative(self) -> float:
        lo, hi = self.config.estimate_bounds
        return min(max(min(self.fast, self.slow), lo), hi)

    @property
    def value(self) -> float:
        """The conservative estimate used for limits: ``min(fast, slow)`` within the bounds
        (read several times a period: kept from the last ``update``)."""
        return self._value

    @property
    def uncertain(self) -> bool:
        return self.samples > 0 and self.settled_s < self.config.min_excited_s


class ActuatorEstimates(Message, frozen=True):
    """The move server's actuator estimates (topic ``move/estimates``); 1.0 is nominal.

    ``*_effectiveness`` are the values used for limits (``min(fast, slow)``, never above 1);
    ``*_raw`` the fast averages (may exceed 1). ``brake_decel_mps2`` is the deceleration full
    brake is now expected to give; ``steer_time_s`` the predicted time to reach the current
    steering target.
    """

    brake_effectiveness: float
    throttle_effectiveness: float
    steering_rate_scale: float
    brake_raw: float
    throttle_raw: float
    steering_raw: float
    brake_decel_mps2: float
    steer_time_s: float
    uncertain: bool
    degraded: str = ""               # comma-separated degraded actuators, "" when all healthy


class ActuatorModel:
    """Measures brake, throttle and steering response against the preset; see the module doc."""

    def __init__(self, params: VehicleParams, config: AdaptiveConfig | None = None) -> None:
        self.params = params
        self.gears = GearTable(params)
        self.config = cfg = config or AdaptiveConfig()
        self.brake = RatioEstimator(cfg)
        self.throttle = RatioEstimator(cfg)
        self.steering = RatioEstimator(cfg)
        self._last_steer_pct: float | None = None
        self._limited_pct: float | None = None
        self._steer_cmd_pct: float | None = None
        self.steer_target_pct = 0.0
        self.steer_actual_pct = 0.0

    # ------------------------------------------------------------------ longitudinal

    def update_pedals(self, dt_s: float, gear_direction: int, gear_name: str, speed_mps: float,
                      accel_x_mps2: float, pitch_rad: float, throttle_pct: float,
                      brake_pct: float, slipping: bool, engine_running: bool = True) -> None:
        """One sample from actual pedal positions, ground speed and the IMU's forward force.

        ``accel_x_mps2`` is the IMU's specific force (gravity along the pitch is in the plant's
        acceleration but not in the specific force, so the grade needs no model here).
        """
        cfg, p = self.config, self.params
        if dt_s <= 0.0 or gear_direction == 0 or slipping:
            return
        v_along = gear_direction * speed_mps
        if v_along < cfg.min_speed_mps:
            return
        a_along = gear_direction * accel_x_mps2
        sin_pitch = gear_direction * math.sin(pitch_rad)
        losses = resistance_mps2(p, v_along, sin_pitch) - G_MPS2 * sin_pitch   # rolling + drag
        if brake_pct >= cfg.min_brake_pct and throttle_pct <= cfg.pedal_off_pct:
            # the gear's engine braking at closed throttle is no brake (issue 30 item 4)
            gear = self.gears.get(gear_name)
            if gear is not None:
                losses += engine_brake_mps2(gear, throttle_pct * 0.01, v_along, engine_running)
            predicted = brake_pct * 0.01 * p.max_brake_decel_mps2
            if predicted >= cfg.min_predicted_mps2:
                self.brake.update((-a_along - losses) / predicted, dt_s)
        elif throttle_pct >= cfg.min_throttle_pct and brake_pct <= cfg.pedal_off_pct:
            gear = p.gear(gear_name)
            predicted = throttle_pct * 0.01 * drive_authority_mps2(p, gear, v_along)
            if predicted >= cfg.min_predicted_mps2:
                self.throttle.update((a_along + losses) / predicted, dt_s)

    # ------------------------------------------------------------------ steering

    def update_steering(self, dt_s: float, command_pct: float | None, actual_pct: float) -> None:
        """One sample of the steering actuator: last command sent and position now."""
        p, cfg = self.params, self.config
        self.steer_actual_pct = actual_pct
        if command_pct is not None:
            self.steer_target_pct = command_pct
        last = self._last_steer_pct
        self._last_steer_pct = actual_pct
        if last is None or dt_s <= 0.0:
            self._limited_pct = actual_pct
            self._steer_cmd_pct = command_pct
            return
        # invert the first-order lag: u = y_prev + (y - y_prev) / (1 - exp(-dt / tau))
        gain = 1.0 - math.exp(-dt_s / p.steer_lag_s) if p.steer_lag_s > 0.0 else 1.0
        limited = last + (actual_pct - last) / gain
        prev_limited = self._limited_pct if self._limited_pct is not None else limited
        # the vehicle integrated this period under the latest command it had received
        cmd = command_pct if command_pct is not None else self._steer_cmd_pct
        self._limited_pct = limited
        self._steer_cmd_pct = cmd
        if cmd is None:
            return
        nominal_pct_per_s = 100.0 * p.steer_rate_rps / p.max_steer_rad
        step = limited - prev_limited
        gap = cmd - prev_limited
        # saturated: the command stayed further away than one nominal step, and we moved toward it
        if abs(gap) > max(cfg.steer_gap_pct, nominal_pct_per_s * dt_s) and step * gap > 0.0:
            rate = abs(step) / dt_s
            if rate < abs(gap) / dt_s:    # did not simply reach the command this period
                self.steering.update(rate / nominal_pct_per_s, dt_s)

    # ------------------------------------------------------------------ use

    @property
    def brake_decel_mps2(self) -> float:
        """Deceleration full brake is expected to give now (effectiveness x preset figure)."""
        return self.brake.value * self.params.max_brake_decel_mps2

    def steer_time_s(self) -> float:
        """Predicted time for the road wheels to reach the current target."""
        p = self.params
        rate_pct_per_s = 100.0 * p.steer_rate_rps * self.steering.value / p.max_steer_rad
        return abs(self.steer_target_pct - self.steer_actual_pct) / rate_pct_per_s + 3.0 * p.steer_lag_s

    def degraded(self) -> list[str]:
        cfg = self.config
        out = []
        if self.brake.value < cfg.degraded_brake:
            out.append("brake")
        if self.throttle.value < cfg.degraded_throttle:
            out.append("throttle")
        if self.steering.value < cfg.degraded_steering:
            out.append("steering")
        return out

    def message(self) -> ActuatorEstimates:
        return ActuatorEstimates(
            brake_effectiveness=self.brake.value, throttle_effectiveness=self.throttle.value,
            steering_rate_scale=self.steering.value, brake_raw=self.brake.fast,
            throttle_raw=self.throttle.fast, steering_raw=self.steering.fast,
            brake_decel_mps2=self.brake_decel_mps2, steer_time_s=self.steer_time_s(),
            uncertain=self.brake.uncertain or self.throttle.uncertain or self.steering.uncertain,
            degraded=",".join(self.degraded()))


__all__ = ["ESTIMATES_TOPIC", "ActuatorEstimates", "ActuatorModel", "AdaptiveConfig",
           "RatioEstimator"]
