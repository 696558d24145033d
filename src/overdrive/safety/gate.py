"""The command gate: the last check between any controller and the actuators.

Independent of the servers that produced the command, it re-applies every actuator limit
with pure limiters ``(new, last, limits) -> applied`` and reports what it had to change, so a
faulty controller cannot push an out-of-range, NaN, throttle-while-braking or too-fast steering
command into the vehicle.
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.control import rate_limit


class GateLimits(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    steer_rate_pct_per_s: float            # the steering actuator's own rate, in % of lock per s
    pedal_sources: frozenset[str] = frozenset({"speed", "scenario"})
    steer_sources: frozenset[str] = frozenset({"driving", "scenario"})
    powertrain_sources: frozenset[str] = frozenset({"speed", "scenario"})


def gate_pedals(throttle_pct: float, brake_pct: float) -> tuple[float, float, str]:
    """Clamp to 0..100 %; NaN throttle -> 0, NaN brake -> 100; brake wins over throttle."""
    reason = ""
    if not math.isfinite(brake_pct):
        brake_pct, reason = 100.0, "brake not finite"
    if not math.isfinite(throttle_pct):
        throttle_pct, reason = 0.0, "throttle not finite"
    if not 0.0 <= throttle_pct <= 100.0:
        throttle_pct, reason = min(max(throttle_pct, 0.0), 100.0), "throttle out of range"
    if not 0.0 <= brake_pct <= 100.0:
        brake_pct, reason = min(max(brake_pct, 0.0), 100.0), "brake out of range"
    if throttle_pct > 0.0 and brake_pct > 0.0:
        throttle_pct, reason = 0.0, "throttle while braking"
    return throttle_pct, brake_pct, reason


def gate_steer(steer_pct: float, last_pct: float, limits: GateLimits, dt_s: float) -> tuple[float, str]:
    """Clamp to +-100 % and to the actuator rate; a NaN command holds the last position."""
    if not math.isfinite(steer_pct):
        return last_pct, "steer not finite"
    reason = ""
    if not -100.0 <= steer_pct <= 100.0:
        steer_pct, reason = min(max(steer_pct, -100.0), 100.0), "steer out of range"
    applied = rate_limit(steer_pct, last_pct, limits.steer_rate_pct_per_s, dt_s)
    if abs(applied - steer_pct) > 1e-9 and not reason:
        reason = "steer rate"
    return applied, reason
