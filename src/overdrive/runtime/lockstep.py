"""Runtimes that step nodes: deterministic lock-step on a simulated clock.

A node is a plain object with ``name``, ``period_s``, ``subscriptions`` and
``step(now_s, inbox) -> outputs``. It never reads a clock, never sleeps and never calls
another node: it gets the time and the messages received since its last step, and returns
``(topic, message)`` pairs to publish. The same node therefore runs unchanged in the
lock-step simulator, on a wall clock, or in its own process behind a network bus.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol, runtime_checkable

from overdrive.bus.local import Inbox, LocalBus

DEFAULT_PERIOD_S = 0.01  # 100 Hz control period (issue 2)

Output = tuple[str, Any]


@runtime_checkable
class Node(Protocol):
    name: str
    period_s: float
    subscriptions: tuple[str, ...]

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> Iterable[Output]: ...


class LockstepRuntime:
    """Steps nodes in a fixed order on one simulated clock; bit-for-bit deterministic.

    Time is ``tick * period_s`` (an integer tick count, so no drift accumulates). A node with
    ``period_s`` of k base periods is stepped on ticks divisible by k. Within a tick nodes run in
    list order; put the vehicle first so controllers see this tick's sensor data.
    """

    def __init__(self, nodes: Sequence[Node], bus: LocalBus | None = None,
                 period_s: float = DEFAULT_PERIOD_S,
                 stalls: Sequence[tuple[str, float, float]] = ()) -> None:
        """``stalls``: (node name, start, end) windows in which that node is not stepped and
        its inbox accumulates, as a process stopped (SIGSTOP) then resumed: on resume it steps
        once with everything queued and a time step as long as the stall."""
        if not period_s > 0:
            raise ValueError(f"period_s must be positive, got {period_s}")
        names = {node.name for node in nodes}
        for name, start_s, end_s in stalls:
            if name not in names:
                raise ValueError(f"stall: no node {name!r} in this run ({', '.join(sorted(names))})")
            if not end_s > start_s:
                raise ValueError(f"stall of {name}: ends at {end_s} s, not after {start_s} s")
        # in ticks: stepped again on the first tick at or after the end
        self._stalls = [(name, round(start_s / period_s), round(end_s / period_s))
                        for name, start_s, end_s in stalls]
        self.bus = bus or LocalBus()
        self.period_s = period_s
        self.tick = 0
        self._slots: list[tuple[Node, int, Inbox]] = []
        for node in nodes:
            every = round(node.period_s / period_s)
            if every < 1 or abs(every * period_s - node.period_s) > 1e-9:
                raise ValueError(
                    f"node {node.name}: period {node.period_s} s is not a multiple of {period_s} s")
            self._slots.append((node, every, self.bus.subscribe(node.subscriptions)))

    @property
    def now_s(self) -> float:
        return self.tick * self.period_s

    def step(self) -> float:
        """Run one tick; return its time."""
        tick = self.tick
        now_s = tick * self.period_s
        bus = self.bus
        bus.pump()
        publish_all = bus.publish_all
        stalls = self._stalls
        for node, every, inbox in self._slots:
            if tick % every:
                continue
            if stalls and any(name == node.name and start <= tick < end
                              for name, start, end in stalls):
                continue   # stalled: not stepped, its inbox accumulates
            received = inbox[:]
            inbox.clear()
            publish_all(node.step(now_s, received))
        self.tick = tick + 1
        return now_s

    def run(self, duration_s: float, after_tick: Callable[[float], Any] | None = None) -> None:
        """Run ticks until ``duration_s`` of simulated time has been stepped."""
        end_tick = round(duration_s / self.period_s)
        while self.tick <= end_tick:
            now_s = self.step()
            if after_tick is not None:
                after_tick(now_s)
