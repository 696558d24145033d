"""The move server on a direction fault (issue 16): the command fails, it is never done."""

from __future__ import annotations

import msgspec
import pytest

from overdrive.messages import Topic
from overdrive.servers.direction_hold import DirectionFault
from overdrive.servers.move import EVENTS, TRANSITIONS, MoveServer, next_phase
from tests.servers.test_move_server import all_of, cmd, last, sensors

FAULT = int(DirectionFault.ROLLBACK_AT_FULL_DRIVE)


def step(node: MoveServer, t0: float, seconds: float, cmds: tuple = (), hold: str = "free",
         fault: int = 0, **kw) -> list:
    out: list = []
    for i in range(max(1, round(seconds / 0.01))):
        inbox = sensors(node.params, **kw)
        inbox = [(t, msgspec.structs.replace(m, direction_hold=hold, fault=fault,
                                             fault_message="rolled back" if fault else ""))
                 if t == Topic.SPEED_STATE else (t, m) for t, m in inbox]
        if i == 0:
            inbox += [(Topic.MOVE_COMMAND, c) for c in cmds]
        out += node.step(t0 + i * 0.01, inbox)
    return out


def test_the_failed_phase_is_in_the_table() -> None:
    assert "failed" in EVENTS
    for phase in ("starting", "shifting", "moving"):
        assert next_phase(phase, "failed") == "failed"
    assert next_phase("failed", "command_run") == "moving"
    assert next_phase("failed", "done") == "failed"        # never done
    assert set(TRANSITIONS["failed"]) >= {"command_start", "stop_cmd", "estop", "interrupt"}


def test_a_direction_fault_fails_the_command_never_done(preset) -> None:
    node = MoveServer(preset)
    step(node, 0.0, 0.5, (cmd(d=15.0, cid=1),))
    assert node.phase == "moving"
    out = step(node, 0.5, 0.02, hold="caught")
    assert node.phase == "moving"                          # a catch alone is not a failure
    out = step(node, 0.52, 0.01, hold="failed", fault=FAULT)
    assert node.phase == "failed" and node.active is None
    notice = last(out, Topic.NOTICE)
    assert (notice.kind, notice.code) == ("move_failed", "1") and "rolled back" in notice.reason
    status = last(out, Topic.MOVE_STATUS)
    assert status.phase == "failed" and "command 1 failed" in status.reason
    out = step(node, 0.53, 2.0, hold="failed", fault=FAULT)   # standing: never "done"
    assert node.phase == "failed"
    assert {m.distance_m for m in all_of(out, Topic.ADVANCE)} == {0.0}
    assert {m.speed_mps for m in all_of(out, Topic.MAX_SPEED)} == {0.0}
    assert last(out, Topic.DRIVE_MODE).state == "run"         # engaged: held in run, brakes on
    assert [m for m in all_of(out, Topic.NOTICE) if m.kind == "move_failed"] == []   # once


@pytest.mark.parametrize("hold", ["free", "holding", "caught"])
def test_no_failure_without_the_failed_hold(preset, hold: str) -> None:
    node = MoveServer(preset)
    step(node, 0.0, 0.5, (cmd(d=15.0, cid=1),), hold=hold)
    assert node.phase == "moving"


def test_a_new_command_after_the_failure_runs(preset) -> None:
    node = MoveServer(preset)
    step(node, 0.0, 0.5, (cmd(d=15.0, cid=1),))
    step(node, 0.5, 0.1, hold="failed", fault=FAULT)
    step(node, 0.6, 0.2)                                    # the hold cancelled (target 0)
    out = step(node, 0.8, 0.1, (cmd(d=15.0, cid=2),))
    assert last(out, Topic.MOVE_REPLY).accepted and node.phase == "moving"
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(15.0)


def test_a_stale_failed_hold_does_not_fail_a_new_command(preset) -> None:
    """Found (issue 16): a MOVE accepted before the speed server has seen target 0 still reads
    the previous command's "failed" hold; that is not this command's failure. A failure after
    the hold was seen clear again is."""
    node = MoveServer(preset)
    step(node, 0.0, 0.5, (cmd(d=15.0, cid=1),))
    step(node, 0.5, 0.1, hold="failed", fault=FAULT)
    assert node.phase == "failed"
    out = step(node, 0.6, 0.05, (cmd(d=15.0, cid=2),), hold="failed", fault=FAULT)
    assert last(out, Topic.MOVE_REPLY).accepted and node.phase == "moving"
    assert [m for m in all_of(out, Topic.NOTICE) if m.kind == "move_failed"] == []
    step(node, 0.65, 0.1)                                  # the speed server saw target 0
    assert node.phase == "moving"
    out = step(node, 0.75, 0.01, hold="failed", fault=FAULT)
    assert node.phase == "failed"
    assert [m.code for m in all_of(out, Topic.NOTICE) if m.kind == "move_failed"] == ["2"]
