"""Attacks on the supervision of a launch (issue 38): who may speak for a process's liveness.

The launcher judges a hang from ``NodeTick`` on ``process/tick`` and takes ``NodeTick.process``
on trust. Found: ``process/tick`` is owned by nobody (not in ``PUBLISHERS``), so the generated
access rules, the shipped locked-down config (default allow, no rule for it) and the bus's
sender policy all let any mesh user put it. A launch (``--open-bus``) whose move server was
SIGSTOPped from 8 s to the end of a 20 s run, with a second process publishing
``NodeTick(process="move")`` every 50 ms: move's ticks 445 (the others' 201), no
``process_hung``, no violation, exit 0, the vehicle stood at 44.9 m of a 60 m MOVE. The same run
without the forger: hung reported, exit 1."""

from __future__ import annotations

from pathlib import Path

import pytest

from overdrive.bus.access import owners
from overdrive.messages import NodeTick, Notice, Topic
from overdrive.run.launch import own_tick
from tests.bus.fault_launches import Fault, run_fault
from tests.bus.test_bus_access import USERS, _delivered, _open, speed_node  # noqa: F401

FORGED = NodeTick(process="move", seq=1)


def test_only_the_run_processes_may_publish_liveness_ticks() -> None:
    """The generated access rules deny every topic a user does not own; ``process/tick`` must
    be one of them, owned by the processes of a launch (nodes and gate), not the planner's or a
    tool's to write."""
    tick_owners = owners().get(Topic.TICK)
    assert tick_owners is not None
    assert "planner" not in tick_owners and "tool" not in tick_owners


@pytest.mark.parametrize(("topic", "msg", "sender", "counted"), [
    (Topic.TICK, NodeTick(process="move", seq=1), "move", True),
    (Topic.TICK, NodeTick(process="gate", seq=1), "gate", True),
    (Topic.TICK, FORGED, "speed", False),          # a run process speaking for another
    (Topic.TICK, FORGED, "planner", False),
    (Topic.TICK, FORGED, "", False),               # no sender known
    (Topic.NOTICE, Notice(kind="info", source="move"), "move", False)])
def test_the_launcher_counts_a_liveness_tick_only_in_its_senders_own_name(
        topic: str, msg: object, sender: str, counted: bool) -> None:
    assert own_tick(topic, msg, sender) is counted


@pytest.mark.wallclock
@pytest.mark.parametrize("user", ["planner", "observer"])
def test_a_planner_or_observer_cannot_forge_a_liveness_tick_in_the_locked_down_config(
        speed_node, user: str) -> None:  # noqa: F811
    listener, endpoint = speed_node
    dialler = _open(user, USERS[user], connect=[endpoint])
    try:
        assert _delivered(listener, dialler, Topic.TICK, FORGED) is False
    finally:
        dialler.close()


@pytest.mark.wallclock
def test_a_move_server_stalled_until_the_vehicle_stands_never_drives_the_old_move_on(
        run_dir: Path) -> None:
    """Real processes: a 60 m MOVE at 4 m/s, the move server SIGSTOPped 5 s at 8 s (the sweep
    in docs/multiprocess.md stops at 2 s, before the vehicle stands). Found (--stall move@5:5,
    the same MOVE): hang reported, exit 1, but the vehicle at rest at 7.67 s (17.41 m) moved
    again at 10.39 s by itself, 27.9 m more, no new command, no interruption."""
    outcome, summary = run_fault(Fault("move", "stall", 4.0, 5.0), run_dir / "run")
    assert outcome.rest_after_fault_s is not None, outcome     # it stood during the stall
    assert outcome.travel_after_rest_m <= 0.02, (outcome, summary["violations"])
