"""Supervision of a multi-process run: liveness ticks and the judgement of who is hung.

Every process of a launch publishes a ``NodeTick`` every ``NODE_TICK_PERIOD_S`` from its
stepping loop (``TickNode`` in a node's ``WallRuntime``; the tool gate from its relay loop). The
launcher feeds each tick's send time (on the run's time axis) to ``Liveness`` and asks it, at
each supervision step, which processes have been silent for more than ``HANG_BOUND_S``.
``Liveness`` is a pure object: time is passed in, it reads no clock (docs/multiprocess.md,
"Supervision").

A process is *hung* when no tick of it was sent for more than the bound: reported once per
episode while it lasts (``Hung``) and, if it ticks again, once more when it resumes
(``Resumed``, with the silence measured between the send stamps on either side and how many
ticks were lost on the way rather than never sent). A gap longer than the bound that the
launcher only learns of when the ticks resume (the launcher itself was not run meanwhile) is
reported as both at once. A process known to be down (its exit is reported) or (re)starting is
not judged until its first tick, which must come within its start grace.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from overdrive.messages import NODE_TICK_PERIOD_S, NodeTick, Topic
from overdrive.servers.clock_offset import MAX_CLOCK_OFFSET_S

HANG_BOUND_S = 0.5
"""Silence that makes a process hung: five tick periods. A healthy process's gap is one period
plus what the host adds: stalls of 65-87 ms at niceness -10 and host-wide stalls of 70-240 ms
under two busy loops (docs/multiprocess.md, "Under load"), and ticks may drop (periodic state):
0.4 s of slack over the period. With the launcher's supervision every 0.1 s, a hang is reported
0.5-0.6 s after the last tick, within the 1 s asked of it (issue 38)."""

FUTURE_TICK_TOLERANCE_S = MAX_CLOCK_OFFSET_S
"""A tick may be stamped this much after the launcher received it (on the launcher's axis, from
the midpoint of the offset bounds): the processes' clocks agree within it or the launch never
engaged (servers.clock_offset). A later stamp is forged or broken."""


@dataclass(frozen=True)
class Hung:
    """``process`` sent no tick for ``silent_s`` (> the bound), the last at ``last_tick_s``."""

    process: str
    last_tick_s: float
    silent_s: float
    now_s: float


@dataclass(frozen=True)
class Resumed:
    """``process`` ticks again after ``silent_s`` between send stamps; ``lost`` of the ticks
    between were sent and lost on the way (0: the process itself did not run)."""

    process: str
    from_s: float
    to_s: float
    silent_s: float
    lost: int


Finding = Hung | Resumed


@dataclass
class _Watch:
    expected_from_s: float          # started (or restarted) then: no tick judged before it
    grace_s: float                  # its first tick is due within this of expected_from_s
    down: bool = False              # its exit was seen: not judged until it starts again
    last_sent_s: float | None = None
    last_seq: int = -1
    hung_since_s: float | None = None     # the last tick's time of the episode reported hung
    ticks: int = 0
    max_gap_s: float = 0.0
    episodes: list[dict[str, Any]] = field(default_factory=list)


class Liveness:
    """Which processes are hung, from their ticks' send times (module doc). No clock."""

    def __init__(self, processes: Iterable[str], bound_s: float = HANG_BOUND_S,
                 start_s: float = 0.0) -> None:
        if not bound_s > NODE_TICK_PERIOD_S:
            raise ValueError(f"hang bound {bound_s} s must exceed the tick period "
                             f"{NODE_TICK_PERIOD_S} s")
        self.bound_s = bound_s
        self._watch = {p: _Watch(start_s, bound_s) for p in processes}
        self.ignored = 0                  # ticks of processes not watched

    @property
    def processes(self) -> list[str]:
        return list(self._watch)

    def expect(self, process: str, from_s: float, grace_s: float) -> None:
        """``process`` was (re)started at ``from_s``: its first tick is due within ``grace_s``."""
        self._watch[process] = _Watch(from_s, grace_s, ticks=self._watch[process].ticks,
                                      max_gap_s=self._watch[process].max_gap_s,
                                      episodes=self._watch[process].episodes)

    def down(self, process: str) -> None:
        """``process`` exited (reported as such): no hang is judged until ``expect``."""
        self._watch[process].down = True

    def tick(self, process: str, seq: int, sent_s: float,
             now_s: float | None = None) -> list[Finding]:
        """A tick of ``process`` sent at ``sent_s``, received at ``now_s``; what it ends (a hang
        seen, or missed). A tick stamped later than its receipt (beyond the clocks' tolerance)
        is ignored: counted, it would make every true tick after it look out of order and
        switch the process's supervision off."""
        watch = self._watch.get(process)
        if (watch is None or not math.isfinite(sent_s)
                or (now_s is not None and sent_s > now_s + FUTURE_TICK_TOLERANCE_S)):
            self.ignored += 1
            return []
        if watch.down or sent_s < watch.expected_from_s:
            return []       # a dying process's last ticks, or the previous run's still in flight
        watch.ticks += 1
        last, last_seq = watch.last_sent_s, watch.last_seq
        if last is not None and sent_s <= last:
            return []       # out of order: a later tick already counted
        watch.last_sent_s, watch.last_seq = sent_s, seq
        if last is None:
            if watch.hung_since_s is None:
                return []
            # reported hung before its first tick: resumed, silent since it was started
            watch.hung_since_s = None
            gap_s = sent_s - watch.expected_from_s
            watch.max_gap_s = max(watch.max_gap_s, gap_s)
            watch.episodes[-1].update(resumed_s=round(sent_s, 4), silent_s=round(gap_s, 4),
                                      lost_ticks=0)
            return [Resumed(process, watch.expected_from_s, sent_s, gap_s, 0)]
        gap_s = sent_s - last
        watch.max_gap_s = max(watch.max_gap_s, gap_s)
        if gap_s <= self.bound_s and watch.hung_since_s is None:
            return []
        found: list[Finding] = []
        if gap_s > self.bound_s and watch.hung_since_s != last:
            # missed while it lasted (the launcher was not run): a hang all the same
            found.append(Hung(process, last, gap_s, sent_s))
            watch.episodes.append({"last_tick_s": round(last, 4), "reported_s": None})
        watch.hung_since_s = None            # (reported, but its ticks were only late on the way)
        lost = max(0, seq - last_seq - 1) if seq > last_seq else 0
        watch.episodes[-1].update(resumed_s=round(sent_s, 4), silent_s=round(gap_s, 4),
                                  lost_ticks=lost)
        found.append(Resumed(process, last, sent_s, gap_s, lost))
        return found

    def check(self, now_s: float) -> list[Hung]:
        """Processes silent for more than the bound at ``now_s`` and not yet reported."""
        found: list[Hung] = []
        for process, watch in self._watch.items():
            if watch.down or watch.hung_since_s is not None:
                continue
            if watch.last_sent_s is None:
                if now_s - watch.expected_from_s > watch.grace_s:   # never ticked since its start
                    watch.hung_since_s = watch.expected_from_s
                    silent = now_s - watch.expected_from_s
                    found.append(Hung(process, watch.expected_from_s, silent, now_s))
                    watch.episodes.append({"last_tick_s": None,
                                           "started_s": round(watch.expected_from_s, 4),
                                           "reported_s": round(now_s, 4)})
                continue
            silent = now_s - watch.last_sent_s
            if silent > self.bound_s:
                watch.hung_since_s = watch.last_sent_s
                found.append(Hung(process, watch.last_sent_s, silent, now_s))
                watch.episodes.append({"last_tick_s": round(watch.last_sent_s, 4),
                                       "reported_s": round(now_s, 4)})
        return found

    def report(self) -> dict[str, Any]:
        """``summary.json`` -> ``launch.liveness``."""
        return {"tick_period_s": NODE_TICK_PERIOD_S, "hang_bound_s": self.bound_s,
                "processes": {p: {"ticks": w.ticks, "max_gap_s": round(w.max_gap_s, 4),
                                  "hangs": list(w.episodes)}
                              for p, w in self._watch.items()}}


class TickNode:
    """A runtime node publishing this process's ``NodeTick`` every ``NODE_TICK_PERIOD_S``: it
    steps in the same loop as the process's server, so a hung loop stops the ticks."""

    name = "tick"
    period_s = NODE_TICK_PERIOD_S
    subscriptions: tuple[str, ...] = ()

    def __init__(self, process: str) -> None:
        self.process = process
        self.seq = 0

    def step(self, _now_s: float, _inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        tick = NodeTick(process=self.process, seq=self.seq)
        self.seq += 1
        return [(Topic.TICK, tick)]


__all__ = ["FUTURE_TICK_TOLERANCE_S", "HANG_BOUND_S", "Finding", "Hung", "Liveness", "Resumed", "TickNode"]
