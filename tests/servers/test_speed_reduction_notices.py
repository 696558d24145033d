"""Every speed reduction that slows a command is noticed (issue 31 item 8: "A speed reduction
already in force when a command arrives never gets its notice"): the move server stepped by
hand on a slope steep enough for its ``steep`` reduction (seed 004: "several factors can cause
that speed to be reduced"), the command arriving before, as and after the reduction starts."""

from __future__ import annotations

import pytest

from overdrive.messages import Topic
from overdrive.servers.move import MoveServer
from tests.servers.test_move_server import all_of, cmd, last, run

STEEP_FRACTION = 0.8   # of the vehicle's max pitch: beyond the 0.5 where ``steep`` starts


def reductions(out: list) -> list[str]:
    return [n.code for n in all_of(out, Topic.NOTICE) if n.kind == "speed_reduction"]


@pytest.mark.parametrize("before_s", [0.01, 0.02, 0.1, 0.5, 2.0])
def test_a_reduction_in_force_before_the_move_is_noticed_when_it_arrives(preset,
                                                                         before_s: float) -> None:
    node = MoveServer(preset)
    steep = preset.max_pitch_rad * STEEP_FRACTION
    quiet = run(node, 0.0, before_s, speed=0.0, pitch=steep)
    assert "steep" in node.monitor.active and reductions(quiet) == []   # nothing slowed yet
    out = run(node, before_s, 0.5, (cmd(d=50.0, v=4.0),), speed=0.0, pitch=steep)
    assert reductions(out) == ["steep"]              # once, on the command's arrival
    assert last(out, Topic.MAX_SPEED).speed_mps < 4.0


def test_commands_replacing_each_other_under_one_reduction_are_noticed_once(preset) -> None:
    node = MoveServer(preset)
    steep = preset.max_pitch_rad * STEEP_FRACTION
    run(node, 0.0, 1.0, speed=0.0, pitch=steep)
    out = []
    for i in range(5):
        out += run(node, 1.0 + i * 0.2, 0.2, (cmd(d=50.0, v=4.0, cid=i + 1),), speed=0.0,
                   pitch=steep)
    assert reductions(out) == ["steep"]


def test_a_reduction_that_ends_and_starts_again_is_noticed_again(preset) -> None:
    node = MoveServer(preset)
    steep = preset.max_pitch_rad * STEEP_FRACTION
    out = run(node, 0.0, 0.5, (cmd(d=50.0, v=4.0),), speed=0.0, pitch=steep)
    out += run(node, 0.5, 0.5, speed=0.0, pitch=0.0)
    assert "steep" not in node.monitor.active
    out += run(node, 1.0, 0.5, speed=0.0, pitch=steep)
    assert reductions(out) == ["steep", "steep"]


def test_a_reduction_that_began_while_stopping_is_noticed_to_the_next_move(preset) -> None:
    node = MoveServer(preset)
    steep = preset.max_pitch_rad * STEEP_FRACTION
    run(node, 0.0, 0.3, (cmd(d=50.0, v=4.0, cid=1),), speed=0.0)
    out = run(node, 0.3, 0.5, (cmd(kind="stop", cid=2),), speed=0.0, pitch=steep)
    assert reductions(out) == []                     # no command in force to slow
    out = run(node, 0.8, 0.5, (cmd(d=50.0, v=4.0, cid=3),), speed=0.0, pitch=steep)
    assert reductions(out) == ["steep"]
