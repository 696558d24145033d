"""Wall-clock runtime: steps nodes at their rates on the monotonic clock, in one thread.

The same nodes as the lock-step runtime (``step(now_s, inbox) -> outputs``); only this runtime
reads the clock. ``now_s`` is ``clock() - start``: seconds since the runtime started, so node
watchdogs measure wall time. Each node has an absolute schedule (``start + k * period_s``, no
drift); the rate keeper sleeps until shortly before a deadline and spins the rest, because
``time.sleep`` overshoots by 50-100 us on Linux. A node more than one period behind skips the
missed steps (it runs once, late, and the schedule re-anchors) rather than bursting.

Lag: the mean period over a sliding window of steps is compared with ``period_s``; more than
``lag_threshold`` (2 %) slow is reported once as a ``Notice(kind="lag")`` on ``events``, and
again only after it has recovered (mean back under half the threshold).

Inboxes come from the bus: a ``SafeInbox`` (filled from Zenoh threads) is drained atomically;
a plain list (``LocalBus``) is copied and cleared. A bus with ``pump()`` (taps, queued notices)
is pumped on this thread before each round of steps. Envelopes stamped with their send time
(``Stamped``, from the Zenoh bus) reach the node with ``sent_s`` on its ``now_s`` axis: moved from
the sender's clock to this one with the earliest plausible offset (``lo_s`` of the bus's
``clock_offsets()``; unknown: unchanged), as are the ``issued_s`` dates of authorizations and
speed limits (``servers.clock_offset.restamped``). The clock itself is ``clock`` (a test may
inject an offset and drift: ``skewed_clock``); no node reads it.

Event-driven steps (issue 20): a node also steps as soon as one of its *triggers* arrives
(``node.triggers`` if it has that attribute, else the chain commands it subscribes to:
``overdrive.bus.delivery.CHAIN_TOPICS``), so a command crosses a chain of processes without waiting a period
per hop. Its periodic schedule then re-anchors one period after that step, so a node fed at its
own rate runs once per period, in phase with its input, and never more than a period goes by
without a step. Only inboxes that can wake the runtime (``SafeInbox``) trigger; with
``LocalBus`` (and in the lock-step runtime) nothing changes. On a pull-mode Zenoh bus (the
launcher's) samples enter the inboxes only when the runtime pumps, so a trigger is seen at the
next scheduled step, not at once.
"""

from __future__ import annotations

import math
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from overdrive.bus.delivery import trigger_topics
from overdrive.bus.local import Stamped
from overdrive.messages import Notice, Topic
from overdrive.runtime.lockstep import Node
from overdrive.servers.clock_offset import CLOCK_REPORT_PERIOD_S, restamped

LAG_WINDOW_STEPS = 100     # 1 s at 100 Hz: long enough to average scheduler jitter out
LAG_THRESHOLD = 0.02       # issue 8: report when the mean period is more than 2 % slow
SPIN_S = 0.0005            # busy-wait the last 0.5 ms (sleep overshoot ~0.05-0.1 ms, 2-core host)
LATENESS_SAMPLES = 100_000  # lateness kept for percentiles (1000 s at 100 Hz)
TRIGGER_BURST_S = 0.0005
"""After a trigger wakes a node woken by several command topics, wait this long before
stepping: a server publishes its step's commands back to back (the move server: steering, max
speed, authorization, mode), and one step should read them all. Stepping on each, the driving
module stepped at 245 Hz fed at 100 Hz, which multiplied its outputs and the load on every link
(measured with 0.5 ms: 101 Hz; with 0.25 ms: 118 Hz). A node with one trigger topic (move,
speed) steps at once: only the driving module's hop pays the 0.5 ms."""
CATCH_UP_S = 0.001
"""After a stall of more than a period (a loaded host did not run us), yield this long before
stepping so the bus threads, starved with us, hand over what arrived meanwhile: otherwise the
step reads a stale inbox and a watchdog times out on messages already received (issue 20)."""


class LagMonitor:
    """Sliding-window mean of a node's step period; flags when it runs ``threshold`` slow."""

    def __init__(self, period_s: float, window: int = LAG_WINDOW_STEPS,
                 threshold: float = LAG_THRESHOLD) -> None:
        self.period_s = period_s
        self.threshold = threshold
        self.window = window
        self._intervals: deque[float] = deque(maxlen=window)
        self._sum_s = 0.0
        self._last_s: float | None = None
        self.lagging = False
        self.lag_reports = 0
        self.worst_mean_period_s = 0.0

    @property
    def mean_period_s(self) -> float:
        return self._sum_s / len(self._intervals) if self._intervals else math.nan

    def observe(self, start_s: float) -> bool:
        """Record a step started at ``start_s``; True when the node has just started lagging."""
        last, self._last_s = self._last_s, start_s
        if last is None:
            return False
        if len(self._intervals) == self.window:
            self._sum_s -= self._intervals[0]
        interval = start_s - last
        self._intervals.append(interval)
        self._sum_s += interval
        if len(self._intervals) < self.window:
            return False
        mean = self._sum_s / self.window
        self.worst_mean_period_s = max(self.worst_mean_period_s, mean)
        if not self.lagging and mean > self.period_s * (1.0 + self.threshold):
            self.lagging = True
            self.lag_reports += 1
            return True
        if self.lagging and mean < self.period_s * (1.0 + self.threshold / 2.0):
            self.lagging = False
        return False


@dataclass
class NodeStats:
    """Timing of one node under the wall-clock runtime."""

    name: str
    period_s: float
    steps: int = 0
    triggered: int = 0                    # steps taken at once on a trigger's arrival
    skipped: int = 0                      # scheduled steps dropped because the node fell behind
    max_step_s: float = 0.0               # longest time spent inside step()
    lateness_s: deque[float] = field(default_factory=lambda: deque(maxlen=LATENESS_SAMPLES))

    def report(self, monitor: LagMonitor) -> dict[str, Any]:
        late = sorted(self.lateness_s)

        def pct(q: float) -> float:
            return round(late[min(len(late) - 1, int(q * len(late)))] * 1e3, 4) if late else 0.0

        return {
            "period_s": self.period_s, "steps": self.steps, "triggered": self.triggered,
            "skipped": self.skipped,
            "lateness_median_ms": round(statistics.median(late) * 1e3, 4) if late else 0.0,
            "lateness_p99_ms": pct(0.99), "lateness_max_ms": round(late[-1] * 1e3, 4) if late else 0.0,
            "max_step_ms": round(self.max_step_s * 1e3, 4),
            "mean_period_ms": round(monitor.mean_period_s * 1e3, 4)
            if not math.isnan(monitor.mean_period_s) else None,
            "worst_mean_period_ms": round(monitor.worst_mean_period_s * 1e3, 4),
            "lag_reports": monitor.lag_reports,
        }


class _Slot:
    __slots__ = ("anchor_s", "due_s", "inbox", "k", "monitor", "node", "stats")

    def __init__(self, node: Node, inbox: Any, due_s: float, window: int, threshold: float) -> None:
        self.node, self.inbox, self.due_s = node, inbox, due_s
        self.anchor_s = 0.0             # schedule origin: the run's start, or the last triggered step
        self.k = 0                      # step index: due_s = anchor_s + k * period_s, no float drift
        self.monitor = LagMonitor(node.period_s, window, threshold)
        self.stats = NodeStats(node.name, node.period_s)


def skewed_clock(offset_s: float, drift_ppm: float = 0.0,
                 base: Callable[[], float] = time.monotonic) -> Callable[[], float]:
    """``base`` shifted by ``offset_s`` and running ``drift_ppm`` fast from now: another
    machine's clock, for tests of the offset estimation (``overdrive launch --clock-offset``)."""
    rate, t0 = drift_ppm * 1e-6, base()

    def clock() -> float:
        t = base()
        return t + offset_s + rate * (t - t0)
    return clock


def _drain(inbox: Any, start_s: float,
           offsets: dict[str, Any] | None = None) -> list[tuple[str, Any]]:
    """The envelopes received since the last step; send stamps (and the dates that anchor
    distances) moved onto the node's time axis from their sender's clock (module doc)."""
    drain = getattr(inbox, "drain", None)
    if drain is None:
        received = inbox[:]
        inbox.clear()
        return received
    out: list[tuple[str, Any]] = []
    for e in drain():
        if not isinstance(e, Stamped):
            out.append(e)
            continue
        estimate = offsets.get(e.sender) if offsets else None
        if estimate is None:
            out.append(Stamped(e[0], e[1], e.sent_s - start_s, e.sender))
        else:
            out.append(Stamped(e[0], restamped(e[1], estimate), e.sent_s + estimate.lo_s - start_s,
                               e.sender))
    return out


class ClockReporter:
    """A runtime node publishing the bus's ``ClockReport`` every ``CLOCK_REPORT_PERIOD_S``: the
    samples this process's peers need for their lower bounds (``ZenohBus.exchange_clocks``)."""

    name = "clock"
    period_s = CLOCK_REPORT_PERIOD_S
    subscriptions: tuple[str, ...] = ()

    def __init__(self, bus: Any) -> None:
        self.bus = bus

    def step(self, _now_s: float, _inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.bus.exchange_clocks()
        return []


class WallRuntime:
    """Steps ``nodes`` on the wall clock until ``stop()`` or ``duration_s`` (see module doc)."""

    def __init__(self, nodes: Sequence[Node], bus: Any, *,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep, spin_s: float = SPIN_S,
                 lag_window: int = LAG_WINDOW_STEPS, lag_threshold: float = LAG_THRESHOLD,
                 event_driven: bool = True) -> None:
        for node in nodes:
            if not node.period_s > 0:
                raise ValueError(f"node {node.name}: period_s must be positive")
        self.bus = bus
        self.clock, self.sleep, self.spin_s = clock, sleep, spin_s
        self._slots = [_Slot(n, bus.subscribe(n.subscriptions), 0.0, lag_window, lag_threshold)
                       for n in nodes]
        self._wake: threading.Event | None = None
        """Set by a bus thread when a trigger arrives (only with inboxes that support it)."""
        self._burst_slots: list[_Slot] = []
        """Nodes woken by several command topics: a wake-up of one waits ``TRIGGER_BURST_S``."""
        for slot in self._slots if event_driven else ():
            node = slot.node
            triggers = getattr(node, "triggers", None)
            triggers = trigger_topics(node.subscriptions) if triggers is None else tuple(triggers)
            if triggers and hasattr(slot.inbox, "wake"):
                if self._wake is None:
                    self._wake = threading.Event()
                slot.inbox.triggers = frozenset(triggers)
                slot.inbox.wake = self._wake
                if len(slot.inbox.triggers) > 1:
                    self._burst_slots.append(slot)
        self._offsets = getattr(bus, "clock_offsets", None)
        self.start_s: float | None = None
        self._stop = False
        self.lag_notices: list[Notice] = []

    def stop(self) -> None:
        """Ask ``run`` to return after the current step (safe from a signal handler)."""
        self._stop = True

    @property
    def now_s(self) -> float:
        return 0.0 if self.start_s is None else self.clock() - self.start_s

    def stats(self) -> dict[str, dict[str, Any]]:
        return {s.node.name: s.stats.report(s.monitor) for s in self._slots}

    def _wait_until(self, deadline_s: float) -> bool:
        """Sleep, then spin, until ``deadline_s``; True at once if a trigger arrives first."""
        clock, wake = self.clock, self._wake
        remaining = deadline_s - clock()
        if remaining > self.spin_s:
            if wake is None:
                self.sleep(remaining - self.spin_s)
            elif wake.wait(remaining - self.spin_s):
                return True
        while clock() < deadline_s and not self._stop:
            if wake is not None and wake.is_set():
                return True
        return False

    def run(self, duration_s: float | None = None,
            on_tick: Callable[[float], Any] | None = None,
            after_step: Callable[[Node, float], Any] | None = None) -> None:
        """Step nodes until ``stop()`` or until ``now_s`` passes ``duration_s``.

        Time zero is ``start_s`` if set before (a shared epoch, possibly in the future or the
        past: a late starter joins on the same schedule), else the moment ``run`` is called.
        ``on_tick(now_s)`` is called before each round of steps, ``after_step(node, now_s)``
        after each node step, both on this thread.
        """
        clock = self.clock
        now = clock()
        if self.start_s is None:
            self.start_s = now
        start = self.start_s
        end = math.inf if duration_s is None else start + duration_s
        pump = getattr(self.bus, "pump", None)
        publish = self.bus.publish
        slots = self._slots
        for slot in slots:
            period = slot.node.period_s
            slot.anchor_s = start
            slot.k = 0 if now <= start else math.ceil((now - start) / period - 1e-9)
            slot.due_s = start + slot.k * period
        wake = self._wake
        while not self._stop:
            due = min(s.due_s for s in slots)
            if due > end + 1e-9:
                break
            woken = self._wait_until(due)
            if self._stop:
                break
            if woken:
                assert wake is not None
                if any(s.inbox.triggered for s in self._burst_slots):
                    self.sleep(TRIGGER_BURST_S)
                wake.clear()
                t = clock()
                if t < start:              # before the shared epoch: the first step will read it
                    continue
                if pump is not None:
                    pump()
                for slot in slots:
                    if getattr(slot.inbox, "triggered", False):
                        slot.stats.triggered += 1
                        self._step(slot, t, start, publish, after_step, scheduled=False)
                continue
            if on_tick is not None:
                on_tick(due - start)
            if pump is not None:
                pump()
            for slot in slots:
                if slot.due_s > due + 1e-9:
                    continue
                self._step(slot, clock(), start, publish, after_step, scheduled=True)

    def _step(self, slot: _Slot, t: float, start: float, publish: Callable[[str, Any], None],
              after_step: Callable[[Node, float], Any] | None, scheduled: bool) -> None:
        """Step one node at clock time ``t``, publish its outputs, then schedule its next step."""
        clock = self.clock
        node, stats = slot.node, slot.stats
        period = node.period_s
        if scheduled:
            stats.lateness_s.append(t - slot.due_s)
            if t - slot.due_s > period and hasattr(slot.inbox, "drain"):
                self.sleep(CATCH_UP_S)
                t = clock()
        now_s = t - start
        offsets = self._offsets() if self._offsets is not None else None
        outputs = node.step(now_s, _drain(slot.inbox, start, offsets))
        for topic, msg in outputs:
            publish(topic, msg)
        if slot.monitor.observe(t):
            self._report_lag(slot, now_s)
        stats.steps += 1
        stats.max_step_s = max(stats.max_step_s, clock() - t)
        if after_step is not None:
            after_step(node, now_s)
        if scheduled:
            slot.k += 1
        else:                           # re-anchor: the next periodic step one period after this one
            slot.anchor_s, slot.k = t, 1
        slot.due_s = slot.anchor_s + slot.k * period
        behind = clock() - slot.due_s
        if behind > period:
            missed = int(behind // period)
            stats.skipped += missed
            slot.k += missed
            slot.due_s = slot.anchor_s + slot.k * period

    def _report_lag(self, slot: _Slot, now_s: float) -> None:
        m = slot.monitor
        slow_pct = 100.0 * (m.mean_period_s / m.period_s - 1.0)
        notice = Notice(kind="lag", source=slot.node.name, code="period",
                        reason=f"mean period {m.mean_period_s * 1e3:.2f} ms over {m.window} steps "
                               f"({slow_pct:.1f} % slow) at t={now_s:.2f} s")
        self.lag_notices.append(notice)
        self.bus.publish(Topic.NOTICE, notice)


__all__ = ["LAG_THRESHOLD", "LAG_WINDOW_STEPS", "ClockReporter", "LagMonitor", "NodeStats",
           "WallRuntime", "skewed_clock"]
