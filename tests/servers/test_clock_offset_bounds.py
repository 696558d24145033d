"""The clock-offset bounds (servers.clock_offset): they always contain the true offset when
delays are >= 0 and the clocks drift within the allowance, their width is the best round trip,
and a step of a clock is survived (older samples dropped, then the new offset bounded)."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive.servers.clock_offset import DRIFT_RATE, ClockOffset


def test_no_estimate_until_both_directions():
    clock = ClockOffset()
    assert clock.estimate(0.0) is None
    assert clock.received(1.0, 0.9)
    assert clock.upper_only and clock.estimate(1.0) is None
    assert clock.echoed(1.0, 1.05)
    est = clock.estimate(1.0)
    assert est is not None and not clock.upper_only
    assert math.isclose(est.hi_s, 0.1) and math.isclose(est.lo_s, -0.05)
    assert math.isclose(est.uncertainty_s, 0.15) and math.isclose(est.offset_s, 0.025)


def test_non_finite_times_are_not_samples():
    clock = ClockOffset()
    for bad in (math.nan, math.inf, -math.inf):
        assert not clock.received(1.0, bad) and not clock.received(bad, 1.0)
        assert not clock.echoed(1.0, bad) and not clock.echoed(bad, 1.0)
    assert clock.estimate(1.0) is None


def test_bounds_widen_with_age_by_the_drift_allowance():
    clock = ClockOffset()
    clock.received(0.0, 0.0)
    clock.echoed(0.0, 0.0)
    est = clock.estimate(10.0)
    assert est is not None
    assert math.isclose(est.hi_s, 10.0 * DRIFT_RATE) and math.isclose(est.lo_s, -10.0 * DRIFT_RATE)


def test_a_clock_step_drops_the_older_samples_and_bounds_the_new_offset():
    clock = ClockOffset()
    for k in range(10):                      # offset 0, delays 5 ms
        t = k * 0.1
        clock.received(t + 0.005, t)
        clock.echoed(t, t + 0.005)
    assert clock.estimate(1.0) is not None
    # the peer's clock steps 0.3 s ahead: offset -0.3
    clock.received(1.005, 1.3)               # upper bound -0.295 < older lower bounds -0.005
    assert clock.estimate(1.005) is None and clock.contradicted   # which lied? none kept
    clock.echoed(1.01, 1.315)                # lower bound -0.305
    assert clock.estimate(1.01) is None      # one direction only
    clock.received(1.016, 1.31)              # upper bound -0.294
    est = clock.estimate(1.02)
    assert est is not None and est.lo_s <= -0.3 <= est.hi_s
    assert clock.resets >= 1


@settings(max_examples=300, deadline=None)
@given(offset_s=st.floats(-0.5, 0.5), drift=st.floats(-DRIFT_RATE, DRIFT_RATE),
       delays=st.lists(st.tuples(st.floats(0.0, 0.05), st.floats(0.0, 0.05),
                                 st.floats(0.001, 0.5)), min_size=1, max_size=40))
def test_the_bounds_always_contain_the_true_offset(offset_s, drift, delays):
    """The peer's clock reads ``t - offset - drift * t`` at this side's ``t``; messages each way
    with delays >= 0; the true offset at the time asked is inside [lo, hi], and the width is
    no less than the best round trip's share that cannot be told apart."""
    def peer(t):
        return t - offset_s - drift * t

    clock = ClockOffset()
    t = 1.0
    for up_s, down_s, gap_s in delays:
        clock.received(t + up_s, peer(t))            # peer sent at t, arrived up_s later
        clock.echoed(t, peer(t + down_s))            # ours sent at t, the peer got it down_s later
        t += gap_s
    est = clock.estimate(t)
    assert est is not None
    true_offset = t - peer(t)
    assert est.lo_s - 1e-9 <= true_offset <= est.hi_s + 1e-9
