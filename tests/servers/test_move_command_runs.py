"""The move server's commands on whole runs (escape-hybrid unless named, seed 1, ``start:
ready``): a MOVE it accepts is driven, or refused or announced, never left waiting; a MOVE
reordered around a STOP is not lost; a late MOVE shortening the one in force does not leave the
longer one driving. Each docstring says how the case was found and the figures measured then.
"""

from __future__ import annotations

from tests.servers.move_harness import events_of, move
from tests.servers.move_harness import run_events as run


def test_a_downhill_move_the_ranger_accepts_either_moves_or_is_refused() -> None:
    """Attack: hard braking / steep downhill on low friction: a stuck MOVE.

    ranger-6x6, grade -15 %, friction 0.4: MOVE 60 m at 5 m/s at t=0.5. The move server accepts
    it (no ``rejected`` event, ``authorized_m`` 60 in the trace) but the driving module's braking
    plan (plan_decel_fraction 0.6 x A' 1.98 = 1.19 m/s^2) is weaker than gravity along the slope
    (1.45 m/s^2), so ``_authorized_speed`` is 0 every period: goal speed 0, brake 50 %, odometer
    0.000 m after 15 s, and no notice, rejection or speed reduction tells the planner why. The
    same MOVE at -10 % drives 38.7 m and escape-hybrid at -15 %/0.4 drives 41.8 m. The planner
    waits forever on a command the stack will never execute: it must be refused (infeasible) or
    driven (or at least announced).
    """
    result = run([move(0.5, 60, 5)], duration_s=15, vehicle="ranger-6x6",
                 world={"grade_percent": -15, "friction": 0.4})
    refused = events_of(result, "rejected")
    told = [e for e in result.summary["events"]
            if e["kind"] in ("speed_reduction", "hint", "fault") and e["t_s"] < 5.0]
    assert result.summary["odometer_m"] > 1.0 or refused or told, (
        "MOVE accepted, never executed, nothing reported")


def test_a_reordered_move_after_a_stop_is_not_lost() -> None:
    """Attack: ``reorder`` on the move channel around a STOP (command ids).

    MOVE 60 m at 6 m/s (t=0.5), MOVE#2 60 m (5.00), STOP#3 (5.01), MOVE#4 60 m (5.02), with
    ``reorder: {channel: move, for_s: 0.3}`` from 4.9. #2 and #3 swap (#2 is ``stale``: right),
    but #4, the last message of the window, is held for a partner that never comes and is never
    delivered (``faults.ChannelFaults`` releases a reorder slot only on the next message of the
    topic), against docs/scenarios.md "consecutive messages in the window are swapped (none is
    lost)". The vehicle stops at x=16.87 m and stands in ``run`` until the end (20 s) with
    authorized_m 0, instead of driving #4's 60 m (to x ~ 74 m): no reply for #4 ever reaches
    the planner.
    """
    result = run([move(0.5, 60, 6), move(5.0, 60, 6), {"at_s": 5.01, "stop": {}},
                  move(5.02, 60, 6), {"at_s": 4.9, "reorder": {"channel": "move", "for_s": 0.3}}],
                 duration_s=20)
    assert result.summary["odometer_m"] > 40.0, result.summary["odometer_m"]


def test_a_late_shortening_move_does_not_leave_the_longer_one_in_force() -> None:
    """Attack: anchoring, a MOVE delayed past the 1 s history (``delay_s`` 1.2 on ``move``).

    MOVE#1 80 m at 6 m/s (t=0.5); at t=5.0 (x=14.3 m, 6 m/s) the planner shortens to MOVE#2
    8 m, delivered 1.2 s late. The move server refuses #2 as ``stale`` ("issued 1.200 s ago,
    older than 1.0 s") and keeps #1 in force: the vehicle drives on at 6 m/s, odometer 68.05 m
    and still 6.0 m/s at t=14 s, 46 m past the end the planner asked for. The driving module
    holds a source at 0 for the same condition ("stale ... holds its source at 0 (fail-safe)",
    docs/driving-module.md), and the same late authorization on ``advance`` stops the vehicle
    (hard brake at 6.2 s, odometer 23.9 m); docs/move-server.md tells the planner that a
    ``stale`` reply needs "nothing: the newer command stands", so no one stops it. The judge
    lets it pass (a refused command does not bind), so this test checks the motion itself: the
    vehicle should not run to the old 80 m end (at most the 8 m end plus the delay's travel
    plus a stop: x < 30 m).
    """
    result = run([move(0.5, 80, 6),
                  {"at_s": 4.9, "delay": {"channel": "move", "for_s": 0.3, "delay_s": 1.2}},
                  move(5.0, 8, 6)], duration_s=14)
    assert result.summary["odometer_m"] < 30.0, result.summary["odometer_m"]
