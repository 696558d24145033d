"""The clock edge of the wall-clock runtime, without processes: a peer's stamps reach a node
moved onto its clock with the earliest plausible offset (unknown: as they are), and the test
hook's skewed clock."""

from __future__ import annotations

import pytest

from overdrive.bus.local import Stamped
from overdrive.bus.zenoh_bus import SafeInbox
from overdrive.messages import AdvanceAuthorization, MoveCommand, SetSpeed, Topic
from overdrive.runtime.wall import WallRuntime, _drain, skewed_clock
from overdrive.servers.clock_offset import OffsetEstimate


def _inbox(*envelopes: Stamped) -> SafeInbox:
    inbox = SafeInbox()
    for e in envelopes:
        inbox.append(e)
    return inbox


SPSS = SetSpeed(speed_mps=2.0, accel_mps2=1.0, gear="drive", state="run")


def test_a_peers_send_stamp_and_authorization_date_reach_the_node_on_its_clock_earliest():
    adv = AdvanceAuthorization(source="move", distance_m=5.0, issued_s=4.0)   # move's now_s
    move = MoveCommand(kind="move", issued_s=4.0)
    inbox = _inbox(Stamped(Topic.SET_SPEED, SPSS, 105.0, "driving"),
                   Stamped(Topic.ADVANCE, adv, 105.0, "move"),
                   Stamped(Topic.MOVE_COMMAND, move, 105.0, "scenario"))
    offsets = {"driving": OffsetEstimate(0.178, 0.182), "move": OffsetEstimate(-0.081, -0.079),
               "scenario": OffsetEstimate(0.01, 0.02)}
    spss, advance, command = _drain(inbox, 100.0, offsets)
    assert spss.sent_s == pytest.approx(5.178) and spss.sender == "driving"
    assert advance.sent_s == pytest.approx(4.919)
    assert advance[1].issued_s == pytest.approx(3.919)      # distance counts from earlier
    assert command[1] is move                                # the planner's date: the move server's
    assert inbox.drain() == []


def test_an_unknown_offset_leaves_the_stamps_as_one_clock():
    adv = AdvanceAuthorization(source="move", distance_m=5.0, issued_s=4.0)
    inbox = _inbox(Stamped(Topic.ADVANCE, adv, 105.0, "move"), (Topic.ADVANCE, adv))
    (stamped, plain) = _drain(inbox, 100.0, {"move": None})
    assert stamped.sent_s == pytest.approx(5.0) and stamped[1] is adv
    assert plain == (Topic.ADVANCE, adv) and not isinstance(plain, Stamped)
    assert _drain(_inbox(Stamped(Topic.ADVANCE, adv, 105.0, "move")), 100.0)[0].sent_s == 5.0


def test_the_runtime_converts_with_the_buses_offsets():
    class Bus:
        def __init__(self) -> None:
            self.inbox = _inbox(Stamped(Topic.SET_SPEED, SPSS, 105.0, "driving"))

        def subscribe(self, _topics):
            return self.inbox

        def publish(self, _topic, _msg):
            pass

        def clock_offsets(self):
            return {"driving": OffsetEstimate(-0.5, -0.4)}

    seen = []

    class Node:
        name, period_s, subscriptions, triggers = "speed", 0.01, (Topic.SET_SPEED,), ()

        def step(self, now_s, inbox):
            seen.extend(inbox)
            return []

    ticks = iter(range(1000))
    runtime = WallRuntime([Node()], Bus(), clock=lambda: 100.0 + next(ticks) * 0.004,
                          sleep=lambda _s: None, spin_s=0.0)
    runtime.start_s = 100.0
    runtime.run(0.005)
    assert [e.sent_s for e in seen] == [pytest.approx(4.5)]


def test_the_skewed_clock_is_offset_and_drifts_from_its_start():
    now = [50.0]
    clock = skewed_clock(0.1, 300.0, base=lambda: now[0])
    assert clock() == pytest.approx(50.1)
    now[0] = 150.0
    assert clock() == pytest.approx(150.1 + 300e-6 * 100.0)
    assert skewed_clock(-0.08, base=lambda: 10.0)() == pytest.approx(9.92)
