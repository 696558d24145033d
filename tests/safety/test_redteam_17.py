"""Red team on issue 17 (latched interruptions, command ids, hard braking, anchoring).

Each test here failed against the first issue-17 implementation because of a defect found by
attacking it, and is kept; each docstring says what it attacks and the figures measured then
(escape-hybrid unless named, seed 1, ``start: ready``).
"""

from __future__ import annotations

from typing import Any

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario


def run(events: list[dict], *, duration_s: float, vehicle: Any = "escape-hybrid",
        world: dict | None = None, start: str = "ready") -> Any:
    data = {"name": "redteam-17", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "world": world or {}, "events": events}
    return run_scenario(parse_scenario(data), None)


def move(at_s: float, distance_m: float, maxspeed_mps: float, curvature_1pm: float = 0.0) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": maxspeed_mps,
                                   "curvature_1pm": curvature_1pm}}


def events_of(result: Any, kind: str) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == kind]


def test_a_stop_sent_during_a_safestop_pause_is_honoured() -> None:
    """Attack: SafeStop pause while cruising, then the planner's STOP during the pause.

    MOVE 40 m at 5 m/s (t=0.5), ``safestop: pause`` at 4.0, STOP at 4.5, ``run`` at 6.0.
    The move server accepts the STOP (phase stays ``interrupted``) and the driving module logs
    ``hard_brake`` at 4.01 ("braking with everything"), but in estop-pause the XGV's pause logic
    owns the pedals: the brake sits at 50 % and the vehicle decelerates at 4.6 m/s^2 only.
    At 4.5 s it does 3.05 m/s at x=10.60 m and stops at x=11.60 m (1.01 m), while the shortest
    physical stop is 0.86 m: the judge reports ``authorization[planner]: passed the end of
    STOP #2 (issued at t=4.50 s) by 0.141 m`` and the run exits 1. A STOP "binds when issued"
    (docs/reliability.md), so either the stack must make it good (full brake through the pause)
    or the STOP must be judged against what the pause lets the stack do; today neither holds.
    """
    result = run([move(0.5, 40, 5), {"at_s": 4.0, "safestop": "pause"},
                  {"at_s": 4.5, "stop": {}}, {"at_s": 6.0, "safestop": "run"}], duration_s=8)
    assert result.summary["violations"] == [], result.summary["violations"]
    assert result.exit_code == 0


def test_an_ordinary_uphill_move_ends_without_hard_braking() -> None:
    """Attack: spurious hard braking in normal driving (one MOVE, no cut, on a hill).

    MOVE 12 m at 5 m/s on a +5 % grade. The terminal approach arrives at 0.35 m/s with 0.21 m
    left and ``_hard_brake`` fires at 7.73 s: "0.21 m authorized at 0.35 m/s, a normal stop needs
    0.21 m: braking with everything" (the tail allowance ``stop_tail_m(v, 0.0, ...)`` ignores the
    slope that helps the stop). It fires at the end of every uphill MOVE tried: +5/10/15/20 %,
    escape-hybrid and ranger-6x6 (e.g. +15 % escape: 0.21 m at 0.38 m/s vs 0.23 m), and in a
    plain MOVE stream on +15 %. On the flat and downhill it does not. Nothing in the command
    asked for a stop shorter than the normal one.
    """
    result = run([move(0.5, 12, 5)], duration_s=15, world={"grade_percent": 5})
    assert result.exit_code == 0
    assert events_of(result, "hard_brake") == []


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


def test_a_stop_sent_as_a_safestop_pause_begins_is_honoured() -> None:
    """Attack: STOP and SafeStop pause in the same tick (the planner and the operator react to
    the same hazard).

    MOVE 60 m at 5 m/s (t=0.5); ``safestop: pause`` and STOP both at t=4.0; ``run`` at 7.0.
    The pause logic holds the brake at 50 % (4.6 m/s^2) although the stack logs ``hard_brake``
    ("braking with everything") at 4.01; the vehicle stops at odometer 11.53 m and the judge
    reports ``authorization[planner]: passed the end of STOP #2 (issued at t=4.00 s) by
    0.960 m``, exit 1. Same attack with the door (software pause) and the STOP at 4.3 s: 0.354 m;
    internal error: 0.354 m; at 8 m/s: 0.467 m; manual override: 1.772 m. The pause makes the
    STOP weaker than the same STOP without it (full brake, within the shortest stop).
    """
    result = run([move(0.5, 60, 5), {"at_s": 4.0, "safestop": "pause"},
                  {"at_s": 4.0, "stop": {}}, {"at_s": 7.0, "safestop": "run"}], duration_s=9)
    assert result.summary["violations"] == [], result.summary["violations"]
    assert result.exit_code == 0


def test_a_stop_delayed_on_the_move_channel_is_not_judged_as_an_overrun() -> None:
    """Attack: anchoring, a STOP delayed 0.1 s on the ``move`` channel (brief's 0.05-0.9 s range).

    MOVE 60 m at 6 m/s (t=0.5); ``delay: {channel: move, for_s: 0.3, delay_s: 0.1}`` from 4.9;
    STOP at 5.0 (5.97 m/s). The move server gets it at 5.1 and the driving module brakes with
    everything at once (``hard_brake`` at 5.10); the vehicle stops at odometer 17.39 m. The
    judge fixes the STOP's end where the vehicle was at 5.0 plus the shortest stop and reports
    ``authorization[planner]: passed the end of STOP #2 (issued at t=5.00 s) by 0.306 m``:
    exit 1 for 0.1 s of latency that no stack can beat (0.5 s: 2.658 m; 0.9 s: 5.027 m).
    ``test_delayed_authorizations_are_not_overrun`` covers MOVEs only; issue 17's "latency
    never becomes distance" does not hold for STOP: either the STOP's ``issued_s`` must be
    used (and the judge must credit the delivery delay the stack cannot see before arrival), or
    the contract must say what a late STOP owes. Today every delayed STOP fails the run.
    """
    result = run([move(0.5, 60, 6),
                  {"at_s": 4.9, "delay": {"channel": "move", "for_s": 0.3, "delay_s": 0.1}},
                  {"at_s": 5.0, "stop": {}}], duration_s=10)
    assert result.summary["violations"] == [], result.summary["violations"]
