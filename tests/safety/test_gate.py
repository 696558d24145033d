"""The command gate: every actuator limit re-checked, swept densely around each limit."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.dynamics.control import clamp, rate_limit
from overdrive.safety.gate import GateLimits, gate_pedals, gate_steer

LIMITS = GateLimits(steer_rate_pct_per_s=50.0)
SWEEP = [v + d for v in (0.0, 100.0) for d in (-1e-6, -1e-9, 0.0, 1e-9, 1e-6)]
anything = st.floats(allow_nan=True, allow_infinity=True)


@pytest.mark.parametrize("value", [*SWEEP, -1.0, 101.0, math.nan, math.inf, -math.inf])
def test_pedals_always_in_range(value: float) -> None:
    for throttle, brake in ((value, 0.0), (0.0, value)):
        t, b, _ = gate_pedals(throttle, brake)
        assert 0.0 <= t <= 100.0 and 0.0 <= b <= 100.0


@given(anything, anything)
def test_never_throttle_and_brake_together(throttle: float, brake: float) -> None:
    t, b, _ = gate_pedals(throttle, brake)
    assert 0.0 <= t <= 100.0 and 0.0 <= b <= 100.0
    assert t == 0.0 or b == 0.0


def test_nan_brake_means_full_brake_and_nan_throttle_means_none() -> None:
    assert gate_pedals(30.0, math.nan)[:2] == (0.0, 100.0)
    assert gate_pedals(math.nan, 0.0)[:2] == (0.0, 0.0)


def test_valid_pedals_pass_unchanged() -> None:
    assert gate_pedals(42.0, 0.0) == (42.0, 0.0, "")
    assert gate_pedals(0.0, 42.0) == (0.0, 42.0, "")


@given(anything, st.floats(-100, 100), st.floats(1e-4, 0.1))
def test_steer_in_range_and_rate_limited(cmd: float, last: float, dt_s: float) -> None:
    applied, _ = gate_steer(cmd, last, LIMITS, dt_s)
    assert -100.0 <= applied <= 100.0
    assert abs(applied - last) <= LIMITS.steer_rate_pct_per_s * dt_s + 1e-9


@pytest.mark.parametrize("delta", [-1e-6, 0.0, 1e-6])
def test_steer_rate_boundary(delta: float) -> None:
    step = LIMITS.steer_rate_pct_per_s * 0.01
    applied, reason = gate_steer(step + delta, 0.0, LIMITS, 0.01)
    assert applied == pytest.approx(min(step + delta, step))
    assert (reason == "steer rate") == (delta > 0)


def test_rate_limit_and_clamp_are_pure() -> None:
    assert rate_limit(10.0, 0.0, 100.0, 0.01) == 1.0
    assert rate_limit(-10.0, 0.0, 100.0, 0.01) == -1.0
    assert rate_limit(0.5, 0.0, 100.0, 0.01) == 0.5
    assert clamp(math.nan, 0.0, 1.0) == 0.0 and clamp(2.0, 0.0, 1.0) == 1.0


PEDAL_CASES = [
    # (throttle, brake) -> (throttle, brake, reason): exact, including the reported reason
    ((100.0, 0.0), (100.0, 0.0, "")),
    ((0.0, 100.0), (0.0, 100.0, "")),
    ((0.0, 0.0), (0.0, 0.0, "")),
    ((100.5, 0.0), (100.0, 0.0, "throttle out of range")),
    ((-0.5, 0.0), (0.0, 0.0, "throttle out of range")),
    ((0.0, 100.5), (0.0, 100.0, "brake out of range")),
    ((0.0, -0.5), (0.0, 0.0, "brake out of range")),
    ((math.nan, 0.0), (0.0, 0.0, "throttle not finite")),
    ((math.inf, 0.0), (0.0, 0.0, "throttle not finite")),
    ((0.0, math.nan), (0.0, 100.0, "brake not finite")),
    ((0.0, -math.inf), (0.0, 100.0, "brake not finite")),
    ((20.0, 5.0), (0.0, 5.0, "throttle while braking")),
]


@pytest.mark.parametrize(("command", "expected"), PEDAL_CASES)
def test_pedal_gate_exact(command, expected) -> None:
    assert gate_pedals(*command) == expected


STEER_CASES = [
    # (command, last) -> (applied, reason) with a rate budget of 0.5 % per 10 ms
    ((100.0, 100.0), (100.0, "")),
    ((-100.0, -100.0), (-100.0, "")),
    ((150.0, 100.0), (100.0, "steer out of range")),
    ((-150.0, -100.0), (-100.0, "steer out of range")),
    ((-100.5, -100.0), (-100.0, "steer out of range")),
    ((math.nan, 12.0), (12.0, "steer not finite")),
    ((-math.inf, 12.0), (12.0, "steer not finite")),
    ((10.0, 0.0), (0.5, "steer rate")),
    ((0.5, 0.0), (0.5, "")),
]


@pytest.mark.parametrize(("command", "expected"), STEER_CASES)
def test_steer_gate_exact(command, expected) -> None:
    applied, reason = gate_steer(command[0], command[1], LIMITS, 0.01)
    assert (applied, reason) == (pytest.approx(expected[0]), expected[1])
