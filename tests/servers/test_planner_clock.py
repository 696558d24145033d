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
from overdrive.servers.move_clock import FAULT_AFTER_REFUSALS, PlannerClock, earliest_issue_s


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
        cmd = command(issued_p, (status_sent, received_p))
        clock.status_sent(status_sent)
        assert clock.echo_problem(now, cmd) == ""
        clock.observe(now, cmd)
        at_s, why = clock.issue_time(cmd, now)
        est = clock.offset.estimate(now)
        assert est is not None
        if est.uncertainty_s <= MAX_CLOCK_UNCERTAINTY_S:
            assert at_s is not None, why
            assert at_s <= issued_true + 1e-9
            # short by at most the command's own round trip (and the drift over the dwell);
            # on one clock as configured, by the offset the bounds cannot tell from 0
            slack_s = down_s + up_s + 1e-3 * dwell_s
            if machine == "same":
                slack_s = max(slack_s, 0.02 + est.uncertainty_s)
            assert at_s >= issued_true - slack_s - 1e-9
        t = now + gap_s


def test_the_worst_case_anchoring_error_is_speed_times_the_round_trip():
    """A 10 ms round trip at 8 m/s: the end is at most 0.08 m short, never past."""
    clock = PlannerClock("separate")
    offset = 0.1                        # planner 0.1 s ahead
    # status sent at 5.000, planner got it 4 ms later, issued 1 ms later, arrived 6 ms later
    cmd = command(5.005 + offset, (5.000, 5.004 + offset))
    clock.observe(5.011, cmd)
    at_s, _ = clock.issue_time(cmd, 5.011)
    est = clock.offset.estimate(5.011)
    assert est is not None and est.uncertainty_s == pytest.approx(0.010, abs=1e-5)
    assert 5.005 - est.uncertainty_s <= at_s <= 5.005
    assert 8.0 * (5.005 - at_s) <= 0.08 + 1e-9


@pytest.mark.parametrize("offset_s", [-0.5, -0.26, 0.26, 0.5])
def test_an_offset_beyond_tolerance_is_refused_at_once_with_a_fault(offset_s):
    clock = PlannerClock("separate")
    cmd = command(1.995 + offset_s, (1.99, 1.993 + offset_s))
    clock.observe(2.0, cmd)
    at_s, why = clock.issue_time(cmd, 2.0)
    assert at_s is None and f"beyond {MAX_CLOCK_OFFSET_S} s" in why
    assert clock.refused(why) and clock.fault_reason == why


def test_bounds_wider_than_the_tolerance_are_refused():
    clock = PlannerClock("separate")
    cmd = command(1.9, (1.8, 1.85))                     # a 150 ms round trip
    clock.observe(2.0, cmd)
    at_s, why = clock.issue_time(cmd, 2.0)
    assert at_s is None and f"more than {MAX_CLOCK_UNCERTAINTY_S} s" in why


def test_on_another_machine_a_command_without_an_echo_is_not_placed():
    clock = PlannerClock("separate")
    cmd = command(0.99)                                 # no echo: one direction only
    clock.observe(1.0, cmd)
    at_s, why = clock.issue_time(cmd, 1.0)
    assert at_s is None and "echoes no MoveStatus" in why
    assert not clock.refused(why)                       # one refusal: not yet a fault
    assert clock.refused(why) and FAULT_AFTER_REFUSALS == 2
    clock.placed()
    assert clock.fault_reason == "" and clock.refusals_in_row == 0 and clock.refusals == 2


def test_a_planner_ahead_without_an_echo_is_refused_saying_its_clock_is_not_this_ones():
    """Was: a planner 30 ms ahead had every command refused as "in the future" (20 ms skew),
    nothing but the replies said why."""
    clock = PlannerClock("same")
    cmd = command(1.03)
    clock.observe(1.0, cmd)
    at_s, why = clock.issue_time(cmd, 1.0)
    assert at_s is None and "ahead of this server's" in why and "echo MoveStatus" in why


def test_a_planner_ahead_that_echoes_is_measured_and_placed():
    clock = PlannerClock("same")
    cmd = command(1.025, (0.99, 1.025))                 # 30 ms ahead, 5 ms each way
    clock.observe(1.0, cmd)
    at_s, why = clock.issue_time(cmd, 1.0)
    assert why == "" and at_s is not None and 0.985 <= at_s <= 0.995 + 1e-9


def test_an_echo_of_a_status_this_server_did_not_send_is_refused_with_its_reason():
    clock = PlannerClock()
    clock.status_sent(1.98)
    assert "not a MoveStatus this server sent" in clock.echo_problem(2.0, command(1.99, (5.0, 5.0)))
    assert "not a MoveStatus this server sent" in clock.echo_problem(
        2.0, command(1.99, (1.985, 1.99)))
    assert clock.echo_problem(2.0, command(1.99, (1.98, 1.985))) == ""


def test_an_echo_received_after_the_command_was_issued_is_refused():
    clock = PlannerClock()
    clock.status_sent(1.98)
    assert "not of a status received before" in clock.echo_problem(
        2.0, command(1.99, (1.98, 1.995)))


def test_the_stamps_an_echo_may_name_are_the_last_few_seconds_of_statuses():
    clock = PlannerClock()
    for k in range(600):
        clock.status_sent(k * 0.01)
    assert clock.echo_problem(6.0, command(5.99, (5.0, 5.005))) == ""
    assert "not a MoveStatus" in clock.echo_problem(6.0, command(5.99, (0.5, 0.505)))


def test_an_unknown_planner_machine_is_refused():
    with pytest.raises(ValueError, match="seperate"):
        PlannerClock("seperate")  # type: ignore[arg-type]


@pytest.mark.parametrize("echo", [(math.nan, 1.0), (1.0, math.inf)])
def test_non_finite_echoes_are_no_bounds(echo):
    clock = PlannerClock("separate")
    clock.observe(2.0, command(1.99, echo))
    assert clock.offset.estimate(2.0) is None


def test_half_an_echo_is_refused():
    cmd = MoveCommand(kind="move", command_id=1, distance_m=1.0, maxspeed_mps=1.0,
                      status_sent_s=1.0)
    assert "come together" in PlannerClock().echo_problem(2.0, cmd)


def test_a_clock_step_before_the_echoed_status_is_placed_by_the_commands_own_echo():
    """The planner's clock steps 0.1 s ahead; its next command echoes a status it received
    after the step. The older bounds (from before the step) would place it late; its own
    echo places it no later than issued."""
    clock = PlannerClock("separate")
    for k in range(5):
        t = 1.0 + 0.1 * k
        cmd = command(t + 0.005, (t, t + 0.004))
        clock.observe(t + 0.006, cmd)
    # stepped: status sent 1.70 arrives 1.704 (read 1.804), issued 1.705 (1.805), arrives 1.906
    cmd = command(1.805, (1.70, 1.804))
    clock.observe(1.906, cmd)
    at_s, why = clock.issue_time(cmd, 1.906)
    assert why == "" and at_s is not None and 1.70 <= at_s <= 1.705 + 1e-9
    assert earliest_issue_s(cmd) == pytest.approx(1.701, abs=1e-5)


def test_a_new_session_measures_the_planners_clock_again():
    clock = PlannerClock("separate")
    clock.observe(1.0, command(0.995, (0.99, 0.994)))
    assert clock.offset.estimate(1.0) is not None
    clock.new_session()
    assert clock.offset.estimate(1.0) is None


def test_reports_are_published_when_the_bounds_move():
    clock = PlannerClock("separate")
    assert clock.report(1.0) is None
    clock.observe(1.006, command(1.005, (1.0, 1.004)))
    first = clock.report(1.006)
    assert first is not None and first.peer == "planner" and first.lo_s <= 0.0 <= first.hi_s
    assert clock.report(1.007) is None                  # bounds unchanged within 1 ms
