"""The planner's clock as the move server places it (servers.move_clock): a command counts from
its earliest plausible issue time on the server's clock, never later than the truth and never
earlier than the truth minus the offset bounds' width; out of tolerance, unknown on another
machine, or ahead without an echo: refused with the reason, and a fault when that lasts."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive.messages import MoveCommand
from overdrive.servers.clock_offset import MAX_CLOCK_OFFSET_S, MAX_CLOCK_UNCERTAINTY_S
from overdrive.servers.move_clock import FAULT_AFTER_REFUSALS, PlannerClock


def command(issued_s: float | None, echo: tuple[float, float] | None = None) -> MoveCommand:
    sent, received = echo if echo is not None else (None, None)
    return MoveCommand(kind="move", command_id=1, distance_m=10.0, maxspeed_mps=5.0,
                       issued_s=issued_s, status_sent_s=sent, status_received_s=received)


@settings(max_examples=300, deadline=None)
@given(offset_s=st.floats(-0.2, 0.2), machine=st.sampled_from(["same", "separate"]),
       steps=st.lists(st.tuples(st.floats(0.0, 0.02), st.floats(0.0, 0.02),
                                st.floats(0.0, 0.01), st.floats(0.05, 2.0)),
                      min_size=1, max_size=20))
def test_a_command_never_counts_from_later_than_it_was_issued(offset_s, machine, steps):
    """Planner clock = server clock + offset. Each command: the newest MoveStatus (sent at
    ``t``) reached the planner ``down`` later, the planner issued ``dwell`` after that, the
    command arrived ``up`` later. The placed time is never after the true issue time (an end
    further than asked) and never before it by more than the bounds' width."""
    clock = PlannerClock(machine)
    t = 1.0
    for down_s, up_s, dwell_s, gap_s in steps:
        status_sent = t
        received_p = t + down_s + offset_s
        issued_true = t + down_s + dwell_s            # server clock
        issued_p = issued_true + offset_s             # planner clock
        now = issued_true + up_s
        assert clock.observe(now, command(issued_p, (status_sent, received_p))) == ""
        at_s, why = clock.issue_time(issued_p, now)
        est = clock.offset.estimate(now)
        assert est is not None
        if est.uncertainty_s <= MAX_CLOCK_UNCERTAINTY_S:
            assert at_s is not None, why
            assert at_s <= issued_true + 1e-9
            if machine == "same" and est.lo_s - 0.02 <= 0.0 <= est.hi_s + 0.02:
                assert at_s == min(issued_p + min(est.lo_s, 0.0), now)   # one clock, as set
            else:
                assert at_s >= issued_true - est.uncertainty_s - 1e-9
        t = now + gap_s


def test_the_worst_case_anchoring_error_is_speed_times_the_round_trip():
    """A 10 ms round trip at 8 m/s: the end is at most 0.08 m short, never past."""
    clock = PlannerClock("separate")
    offset = 0.1                        # planner 0.1 s ahead
    # status sent at 5.000, planner got it 4 ms later, issued 1 ms later, arrived 6 ms later
    clock.observe(5.011, command(5.005 + offset, (5.000, 5.004 + offset)))
    at_s, _ = clock.issue_time(5.005 + offset, 5.011)
    est = clock.offset.estimate(5.011)
    assert est is not None and est.uncertainty_s == pytest.approx(0.010, abs=1e-5)
    assert 5.005 - est.uncertainty_s <= at_s <= 5.005
    assert 8.0 * (5.005 - at_s) <= 0.08 + 1e-9


@pytest.mark.parametrize("offset_s", [-0.5, -0.26, 0.26, 0.5])
def test_an_offset_beyond_tolerance_is_refused_at_once_with_a_fault(offset_s):
    clock = PlannerClock("separate")
    clock.observe(2.0, command(1.995 + offset_s, (1.99, 1.993 + offset_s)))
    at_s, why = clock.issue_time(1.995 + offset_s, 2.0)
    assert at_s is None and f"beyond {MAX_CLOCK_OFFSET_S} s" in why
    assert clock.refused(why) and clock.fault_reason == why


def test_bounds_wider_than_the_tolerance_are_refused():
    clock = PlannerClock("separate")
    clock.observe(2.0, command(1.9, (1.8, 1.85)))       # a 150 ms round trip
    at_s, why = clock.issue_time(1.9, 2.0)
    assert at_s is None and f"more than {MAX_CLOCK_UNCERTAINTY_S} s" in why


def test_on_another_machine_nothing_is_placed_until_the_offset_is_measured():
    clock = PlannerClock("separate")
    clock.observe(1.0, command(0.99))                   # no echo: one direction only
    at_s, why = clock.issue_time(0.99, 1.0)
    assert at_s is None and "not measured yet" in why
    assert not clock.refused(why)                       # one refusal: not yet a fault
    assert clock.refused(why) and FAULT_AFTER_REFUSALS == 2
    clock.placed()
    assert clock.fault_reason == "" and clock.refusals_in_row == 0 and clock.refusals == 2


def test_a_planner_ahead_without_an_echo_is_refused_saying_its_clock_is_not_this_ones():
    """Was: a planner 30 ms ahead had every command refused as "in the future" (20 ms skew),
    nothing but the replies said why."""
    clock = PlannerClock("same")
    clock.observe(1.0, command(1.03))
    at_s, why = clock.issue_time(1.03, 1.0)
    assert at_s is None and "ahead of this server's" in why and "echo MoveStatus" in why


def test_a_planner_ahead_that_echoes_is_measured_and_placed():
    clock = PlannerClock("same")
    clock.observe(1.0, command(1.025, (0.99, 1.025)))   # 30 ms ahead, 5 ms each way
    at_s, why = clock.issue_time(1.025, 1.0)
    assert why == "" and at_s is not None and 0.985 <= at_s <= 0.995 + 1e-9


@pytest.mark.parametrize("echo", [(math.nan, 1.0), (1.0, math.inf), (5.0, 5.0)])
def test_a_malformed_echo_is_refused_with_its_reason(echo):
    clock = PlannerClock("separate")
    assert clock.observe(2.0, command(1.99, echo))
    assert clock.offset.estimate(2.0) is None


def test_half_an_echo_is_refused():
    clock = PlannerClock()
    cmd = MoveCommand(kind="move", command_id=1, distance_m=1.0, maxspeed_mps=1.0,
                      status_sent_s=1.0)
    assert "come together" in clock.observe(2.0, cmd)


def test_a_clock_step_is_re_measured_and_then_placed():
    clock = PlannerClock("separate")
    for k in range(5):
        t = 1.0 + 0.1 * k
        clock.observe(t + 0.006, command(t + 0.005, (t, t + 0.004)))
    assert clock.issue_time(1.405, 1.406)[0] is not None
    # the planner's clock steps 0.1 s ahead; its next command still echoes an old status
    clock.observe(1.606, command(1.705, (1.4, 1.404)))
    at_s, why = clock.issue_time(1.705, 1.606)
    assert at_s is None and "stepped" in why
    clock.observe(1.806, command(1.905, (1.7, 1.804)))   # a fresh echo on the new clock
    at_s, why = clock.issue_time(1.905, 1.806)
    assert why == "" and at_s is not None and 1.795 <= at_s <= 1.805 + 1e-9


def test_reports_are_published_when_the_bounds_move():
    clock = PlannerClock("separate")
    assert clock.report(1.0) is None
    clock.observe(1.006, command(1.005, (1.0, 1.004)))
    first = clock.report(1.006)
    assert first is not None and first.peer == "planner" and first.lo_s <= 0.0 <= first.hi_s
    assert clock.report(1.007) is None                  # bounds unchanged within 1 ms
