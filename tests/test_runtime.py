"""Lock-step runtime and in-process bus: ordering, rates, delivery, channel faults."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.bus.local import LocalBus
from overdrive.runtime.lockstep import LockstepRuntime


class Recorder:
    def __init__(self, name: str, period_s: float, subscriptions=(), publish=None) -> None:
        self.name, self.period_s, self.subscriptions = name, period_s, tuple(subscriptions)
        self.publish = publish
        self.calls: list[tuple[float, list[tuple[str, Any]]]] = []

    def step(self, now_s: float, inbox):
        self.calls.append((now_s, list(inbox)))
        return [(self.publish, now_s)] if self.publish else []


def test_nodes_step_at_their_rates_on_integer_ticks() -> None:
    fast, slow = Recorder("fast", 0.01), Recorder("slow", 0.1)
    runtime = LockstepRuntime([fast, slow], period_s=0.01)
    runtime.run(1.0)
    assert len(fast.calls) == 101 and len(slow.calls) == 11
    assert [t for t, _ in slow.calls] == [pytest.approx(0.1 * i) for i in range(11)]
    assert fast.calls[-1][0] == 1.0, "time is tick * period, no accumulated drift"


def test_messages_reach_later_nodes_same_tick_and_earlier_nodes_next_tick() -> None:
    early = Recorder("early", 0.01, subscriptions=["b"], publish="a")
    late = Recorder("late", 0.01, subscriptions=["a"], publish="b")
    runtime = LockstepRuntime([early, late])
    runtime.step()
    runtime.step()
    assert late.calls[0][1] == [("a", 0.0)], "published earlier in the same tick"
    assert early.calls[0][1] == [] and early.calls[1][1] == [("b", 0.0)]


def test_inbox_holds_everything_since_last_step_in_order() -> None:
    pub = Recorder("pub", 0.01, publish="x")
    sub = Recorder("sub", 0.05, subscriptions=["x"])
    runtime = LockstepRuntime([pub, sub])
    for _ in range(6):
        runtime.step()
    assert [m for _, m in sub.calls[1][1]] == pytest.approx([0.01, 0.02, 0.03, 0.04, 0.05])


def test_period_must_be_a_multiple_of_the_base_period() -> None:
    with pytest.raises(ValueError, match="multiple"):
        LockstepRuntime([Recorder("odd", 0.015)], period_s=0.01)
    with pytest.raises(ValueError):
        LockstepRuntime([], period_s=0.0)


def test_channel_model_routes_and_taps_see_everything() -> None:
    class EvenOnlyDoubleThree:
        def route(self, topic, msg):
            return (msg, msg) if msg == 3 else ((msg,) if msg % 2 == 0 else ())

        def due(self):
            return [("t", 99)]

    bus = LocalBus()
    inbox = bus.subscribe(["t"])
    seen = []
    bus.tap(lambda topic, msg: seen.append(msg))
    bus.channel = EvenOnlyDoubleThree()
    for i in range(4):
        bus.publish("t", i)
    assert [m for _, m in inbox] == [0, 2, 3, 3] and seen == [0, 1, 2, 3]
    bus.pump()
    assert inbox[-1] == ("t", 99)
