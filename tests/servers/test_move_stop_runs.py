"""A STOP binds when issued, on whole runs (escape-hybrid, seed 1, ``start: ready``): sent
during a SafeStop pause or as one begins (the pause's own braking must not make it weaker than
the same STOP without it), and delayed on the move channel (latency is not judged as distance).
Each docstring says how the case was found and the figures measured then."""

from __future__ import annotations

from tests.servers.move_harness import move
from tests.servers.move_harness import run_events as run


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
