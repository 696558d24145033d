"""Control primitives: pure limiters and a PID with explicit ``dt``.

No clock is read here: every call gets the time step. Limiters are pure functions
``(new, last, limits) -> applied`` so that a controller and the independent command gate
downstream can apply the very same rule.
"""

from __future__ import annotations

import math

import msgspec

MAX_CONTROL_STEP_S = 0.02
"""Longest time step a controller or a rate limiter integrates: two control periods (10 ms),
room for one late step on a wall clock. A longer gap is a stall of the process (SIGSTOP, a
scheduler hiccup, a lock-step ``stall`` event): integrating it as one step would wind loops up
and let rate limits jump (100 % throttle after a 0.3 s speed-server stall; an 11 % steering
jump after a 0.15 s driving-module stall)."""


def clamp(value: float, low: float, high: float) -> float:
    """Clamp to ``[low, high]``; NaN maps to ``low`` (the safe end for efforts and speeds)."""
    if value != value:  # NaN
        return low
    return low if value < low else high if value > high else value


def rate_limit(new: float, last: float, max_rate_per_s: float, dt_s: float) -> float:
    """Move from ``last`` towards ``new`` by at most ``max_rate_per_s * dt_s``."""
    step = max_rate_per_s * dt_s
    if new > last + step:
        return last + step
    if new < last - step:
        return last - step
    return new


def first_order_lag(target: float, current: float, time_constant_s: float, dt_s: float) -> float:
    """Exact discretisation of ``tau * dx/dt = target - x`` over ``dt_s``."""
    if time_constant_s <= 0.0:
        return target
    return target + (current - target) * math.exp(-dt_s / time_constant_s)


class PidGains(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    kp: float
    ki: float = 0.0
    kd: float = 0.0
    kff: float = 0.0                  # feed-forward on the setpoint
    derivative_filter_s: float = 0.02  # first-order filter on the derivative term
    output_min: float = 0.0
    output_max: float = 100.0
    output_rate_per_s: float = math.inf  # output slew limit
    tracking_time_s: float = 0.1      # back-calculation anti-windup time constant (Astrom: ~sqrt(Ti*Td))


class Pid:
    """PID on error = setpoint - measurement, with back-calculation anti-windup.

    The integrator is corrected by ``(applied - unsaturated) * dt / tracking_time_s`` each step, so it stops
    winding when the output saturates or is slew-limited; the derivative acts on the
    measurement (no kick on setpoint steps) through a first-order filter.
    """

    __slots__ = ("_d_state", "_last_measurement", "gains", "integral", "output")

    def __init__(self, gains: PidGains, initial_output: float = 0.0) -> None:
        self.gains = gains
        self.reset(initial_output)

    def reset(self, output: float = 0.0) -> None:
        self.integral = 0.0
        self.output = output
        self._d_state = 0.0
        self._last_measurement: float | None = None

    def update(self, setpoint: float, measurement: float, dt_s: float,
               feedforward: float = 0.0) -> float:
        g = self.gains
        error = setpoint - measurement
        if self._last_measurement is None or dt_s <= 0.0:
            derivative = 0.0
        else:
            raw = -(measurement - self._last_measurement) / dt_s
            alpha = dt_s / (g.derivative_filter_s + dt_s)
            self._d_state += alpha * (raw - self._d_state)
            derivative = self._d_state
        self._last_measurement = measurement
        unsaturated = (g.kp * error + self.integral + g.kd * derivative
                       + g.kff * setpoint + feedforward)
        applied = clamp(unsaturated, g.output_min, g.output_max)
        applied = rate_limit(applied, self.output, g.output_rate_per_s, dt_s)
        if g.ki:
            self.integral += dt_s * (g.ki * error + (applied - unsaturated) / g.tracking_time_s)
        self.output = applied
        return applied
