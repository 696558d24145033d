"""Wall-clock runtime on a fake clock: schedule, skipping, lag detection, inbox hand-over."""

from __future__ import annotations

import threading
import time
from typing import Any

import pytest

from overdrive.bus.local import LocalBus
from overdrive.bus.zenoh_bus import SafeInbox
from overdrive.messages import Notice, Topic
from overdrive.runtime.wall import LAG_THRESHOLD, LagMonitor, WallRuntime

LOADED_SLACK_S = 5.0   # a 2-core host with both cores busy may not schedule us for seconds

pytestmark = pytest.mark.wallclock   # real time: run on an idle machine (Makefile)


class FakeClock:
    """A clock that only moves when the runtime sleeps or a node 'works'."""

    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        self.t += 1e-6          # every read costs a microsecond, so spins terminate
        return self.t

    def sleep(self, s: float) -> None:
        self.t += s


class Worker:
    def __init__(self, name: str, period_s: float, clock: FakeClock, cost_s: float = 0.0,
                 subscriptions=(), publish: str | None = None) -> None:
        self.name, self.period_s, self.subscriptions = name, period_s, tuple(subscriptions)
        self.clock, self.cost_s, self.publish = clock, cost_s, publish
        self.calls: list[tuple[float, list]] = []

    def step(self, now_s: float, inbox) -> list[tuple[str, Any]]:
        self.calls.append((now_s, list(inbox)))
        self.clock.t += self.cost_s
        return [(self.publish, now_s)] if self.publish else []


def test_nodes_run_at_their_rates_without_drift() -> None:
    clock = FakeClock()
    fast, slow = Worker("fast", 0.01, clock), Worker("slow", 0.1, clock)
    rt = WallRuntime([fast, slow], LocalBus(), clock=clock, sleep=clock.sleep)
    rt.run(2.0)
    assert len(fast.calls) == 201 and len(slow.calls) == 21
    assert fast.calls[-1][0] == pytest.approx(2.0, abs=1e-3), "absolute schedule, no drift"
    stats = rt.stats()["fast"]
    assert stats["skipped"] == 0 and stats["lag_reports"] == 0
    assert stats["lateness_max_ms"] < 0.1


def test_messages_flow_between_nodes_through_the_bus() -> None:
    clock = FakeClock()
    pub = Worker("pub", 0.01, clock, publish="x")
    sub = Worker("sub", 0.05, clock, subscriptions=["x"])
    WallRuntime([pub, sub], LocalBus(), clock=clock, sleep=clock.sleep).run(0.1)
    assert [m for _, m in sub.calls[0][1]] == pytest.approx([0.0], abs=1e-3), "same round, later node"
    assert [m for _, m in sub.calls[1][1]] == pytest.approx([0.01, 0.02, 0.03, 0.04, 0.05], abs=1e-3)


@pytest.mark.parametrize("slow_pct", [1.0, 3.0, 10.0])
def test_lag_is_reported_when_mean_period_is_over_two_percent_slow(slow_pct: float) -> None:
    clock = FakeClock()
    bus = LocalBus()
    notices = bus.subscribe([Topic.NOTICE])
    node = Worker("busy", 0.01, clock, cost_s=0.01 * (1 + slow_pct / 100))
    rt = WallRuntime([node], bus, clock=clock, sleep=clock.sleep)
    rt.run(3.0)
    lagging = slow_pct / 100 > LAG_THRESHOLD
    assert rt.stats()["busy"]["lag_reports"] == (1 if lagging else 0)
    kinds = [(m.kind, m.source) for _, m in notices if isinstance(m, Notice)]
    assert kinds == ([("lag", "busy")] if lagging else [])


def test_a_node_far_behind_skips_missed_steps_instead_of_bursting() -> None:
    clock = FakeClock()
    node = Worker("stall", 0.01, clock)
    rt = WallRuntime([node], LocalBus(), clock=clock, sleep=clock.sleep)
    original = node.step

    def stall_once(now_s: float, inbox):
        if len(node.calls) == 10:
            clock.t += 0.055                 # one 55 ms hiccup
        return original(now_s, inbox)

    node.step = stall_once  # type: ignore[method-assign]
    rt.run(0.5)
    assert rt.stats()["stall"]["skipped"] == 4, "0.11..0.14 skipped; 0.15 runs 5 ms late"
    gaps = [b[0] - a[0] for a, b in zip(node.calls, node.calls[1:], strict=False)]
    assert max(gaps) < 0.07 and sorted(gaps)[1] > 0.005, "no burst of back-to-back steps"


def test_lag_monitor_recovers_with_hysteresis() -> None:
    m = LagMonitor(0.01, window=10)
    t, reports = 0.0, 0
    for period in [0.0105] * 30 + [0.0100] * 30 + [0.0105] * 30:
        t += period
        reports += m.observe(t)
    assert reports == 2 and m.lag_reports == 2


def test_shared_epoch_in_the_past_joins_on_the_same_schedule() -> None:
    clock = FakeClock()
    node = Worker("late", 0.01, clock)
    rt = WallRuntime([node], LocalBus(), clock=clock, sleep=clock.sleep)
    rt.start_s = clock.t - 5.0043
    rt.run(5.1)
    first = node.calls[0][0]
    assert first == pytest.approx(5.01, abs=1e-4)
    assert len(node.calls) == 10


def test_safe_inbox_loses_nothing_under_concurrent_appends() -> None:
    n_threads, per_thread = 4, 5000
    inbox = SafeInbox(capacity=n_threads * per_thread)
    got: list = []

    def producer(k: int) -> None:
        for i in range(per_thread):
            inbox.append(("t", (k, i)))

    threads = [threading.Thread(target=producer, args=(k,)) for k in range(n_threads)]
    for th in threads:
        th.start()
    while any(th.is_alive() for th in threads):
        got.extend(inbox.drain())
    got.extend(inbox.drain())
    assert len(got) == n_threads * per_thread
    for k in range(n_threads):
        assert [i for _, (kk, i) in got if kk == k] == list(range(per_thread)), "per-producer order kept"


def test_real_clock_loop_keeps_100_hz_and_stops_on_request() -> None:
    node = Worker("real", 0.01, FakeClock())
    rt = WallRuntime([node], LocalBus())
    timer = threading.Timer(0.5, rt.stop)
    timer.start()
    t0 = time.monotonic()
    rt.run()
    elapsed = time.monotonic() - t0
    timer.cancel()
    assert 0.45 < elapsed < 0.5 + LOADED_SLACK_S
    stats = rt.stats()["real"]
    assert stats["steps"] == len(node.calls)
    # every scheduled step either ran or was counted as skipped (a loaded host skips, never bursts)
    assert abs(stats["steps"] + stats["skipped"] - round(elapsed / 0.01)) <= 3


class _ThreadedBus:
    """Inboxes filled from another thread, like the Zenoh bus (no network)."""

    def __init__(self) -> None:
        self.inboxes: dict[str, list[SafeInbox]] = {}
        self.published: list[tuple[str, Any]] = []

    def subscribe(self, topics) -> SafeInbox:
        inbox = SafeInbox()
        for topic in topics:
            self.inboxes.setdefault(topic, []).append(inbox)
        return inbox

    def deliver(self, topic: str, msg: Any) -> None:
        for inbox in self.inboxes.get(topic, ()):
            inbox.append((topic, msg))

    def publish(self, topic: str, msg: Any) -> None:
        self.published.append((topic, msg))


class _Recorder:
    def __init__(self, name: str, period_s: float, subscriptions, triggers=None) -> None:
        self.name, self.period_s, self.subscriptions = name, period_s, tuple(subscriptions)
        if triggers is not None:
            self.triggers = triggers
        self.calls: list[tuple[float, list]] = []

    def step(self, now_s: float, inbox) -> list:
        self.calls.append((now_s, list(inbox)))
        return []


LONG_PERIOD_S = 1.5   # far longer than any wake-up delay (ms), even on a loaded host; the
                      # run ends one period after stop() (a wait is not cut short by it)


def _run_until(rt: WallRuntime, done, timeout_s: float = 30.0) -> None:
    thread = threading.Thread(target=rt.run, args=(timeout_s,))
    thread.start()
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        time.sleep(0.001)
    rt.stop()
    thread.join(timeout_s)


def test_a_command_wakes_its_node_at_once_and_state_waits_for_the_period() -> None:
    bus = _ThreadedBus()
    node = _Recorder("speed", LONG_PERIOD_S, (Topic.SET_SPEED, Topic.WHEEL_SPEED))
    rt = WallRuntime([node], bus)
    started = threading.Event()
    thread = threading.Thread(target=lambda: (started.set(), rt.run(60.0)))
    thread.start()
    started.wait()
    while not node.calls:               # the first periodic step, at t = 0
        time.sleep(0.001)
    bus.deliver(Topic.WHEEL_SPEED, "state")      # periodic state: no wake-up
    bus.deliver(Topic.SET_SPEED, "command")      # a command: step now
    deadline = time.monotonic() + 30.0
    while len(node.calls) < 2 and time.monotonic() < deadline:
        time.sleep(0.001)
    rt.stop()
    thread.join(30.0)
    assert len(node.calls) == 2, "stepped once more, on the command"
    now_s, inbox = node.calls[1]
    assert now_s < LONG_PERIOD_S, "before its period came round"
    assert inbox == [(Topic.WHEEL_SPEED, "state"), (Topic.SET_SPEED, "command")]
    stats = rt.stats()["speed"]
    assert stats["triggered"] == 1 and stats["steps"] == 2


def test_every_command_triggers_a_step_in_order_and_fixed_rate_nodes_never_trigger() -> None:
    bus = _ThreadedBus()
    driven = _Recorder("driving", 0.05, ("cmd",), triggers=("cmd",))
    plant = _Recorder("vehicle", 0.05, ("cmd",), triggers=())
    rt = WallRuntime([driven, plant], bus)
    sent = 0

    def feed() -> bool:
        nonlocal sent
        if sent < 5 and len(driven.calls) > sent:
            bus.deliver("cmd", sent)
            sent += 1
        return sent >= 5 and len(driven.calls) >= 12
    _run_until(rt, feed)
    stats = rt.stats()
    assert stats["driving"]["triggered"] == 5 and stats["vehicle"]["triggered"] == 0
    received = [m for _, inbox in driven.calls for _, m in inbox]
    assert received == [0, 1, 2, 3, 4], "each command once, in order"


def test_a_burst_of_commands_published_together_is_read_in_one_step() -> None:
    """The move server publishes steering, max speed, authorization and mode back to back: the
    driving module steps once on them, not once each (it stepped at 245 Hz fed at 100 Hz). The
    rest of the burst arrives while the runtime waits ``TRIGGER_BURST_S`` after the first."""
    from overdrive.runtime.wall import TRIGGER_BURST_S

    bus = _ThreadedBus()
    driven = _Recorder("driving", LONG_PERIOD_S, ("a", "b", "c", "d"), triggers=("a", "b", "c", "d"))
    rest: list[str] = []

    def sleep(duration_s: float) -> None:
        if duration_s == TRIGGER_BURST_S:
            while rest:
                bus.deliver(rest[0], rest.pop(0))
        time.sleep(duration_s)
    rt = WallRuntime([driven], bus, sleep=sleep)

    def feed() -> bool:
        if len(driven.calls) == 1 and not fed:
            fed.append(True)
            rest.extend(("b", "c", "d"))
            bus.deliver("a", "a")
        return len(driven.calls) >= 2
    fed: list[bool] = []
    _run_until(rt, feed)
    assert rt.stats()["driving"]["triggered"] == 1
    assert [m for _, m in driven.calls[1][1]] == ["a", "b", "c", "d"]


def test_a_node_with_one_command_topic_steps_without_the_burst_wait() -> None:
    from overdrive.runtime.wall import TRIGGER_BURST_S

    bus = _ThreadedBus()
    node = _Recorder("speed", LONG_PERIOD_S, (Topic.SET_SPEED,))
    waits: list[float] = []
    rt = WallRuntime([node], bus, sleep=lambda s: (waits.append(s), time.sleep(s)))
    sent: list[int] = []

    def feed() -> bool:
        if len(node.calls) == 1 and not sent:
            sent.append(1)
            bus.deliver(Topic.SET_SPEED, 1)
        return len(node.calls) >= 2
    _run_until(rt, feed)
    assert rt.stats()["speed"]["triggered"] == 1 and TRIGGER_BURST_S not in waits


def test_event_driven_off_keeps_the_pure_periodic_schedule() -> None:
    bus = _ThreadedBus()
    node = _Recorder("speed", LONG_PERIOD_S, (Topic.SET_SPEED,))
    rt = WallRuntime([node], bus, event_driven=False)
    _run_until(rt, lambda: bool(node.calls) and (bus.deliver(Topic.SET_SPEED, 1) or True), 0.5)
    assert rt.stats()["speed"]["triggered"] == 0 and len(node.calls) == 1


def test_default_triggers_are_the_chain_commands_never_feedback_or_events() -> None:
    """A trigger on ``vehicle/steer`` looped move -> driving -> move at 3 kHz (found in a launch)."""
    from overdrive.run.launch import build_node, preset_scenario

    expected = {"move": (Topic.MOVE_COMMAND,),
                "driving": (Topic.STEERING, Topic.MAX_SPEED, Topic.ADVANCE, Topic.DRIVE_MODE),
                "speed": (Topic.SET_SPEED,)}
    for cli, topics in expected.items():
        node = build_node(cli, preset_scenario(cli, "escape-hybrid"))
        rt = WallRuntime([node], _ThreadedBus())
        assert rt._slots[0].inbox.triggers == frozenset(topics), cli
