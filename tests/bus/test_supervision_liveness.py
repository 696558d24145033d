"""Who is hung, from liveness ticks' send times (``runtime.supervision.Liveness``): no clock, no
processes; time is passed in."""

from __future__ import annotations

import pytest

from overdrive.messages import NODE_TICK_PERIOD_S, NodeTick, Topic
from overdrive.runtime.supervision import (
    FUTURE_TICK_TOLERANCE_S,
    HANG_BOUND_S,
    Hung,
    Liveness,
    Resumed,
    TickNode,
)

P = NODE_TICK_PERIOD_S


def _tick_until(live: Liveness, process: str | tuple[str, ...], from_s: float, to_s: float,
                seq: int = 0) -> int:
    """Ticks every period from ``from_s`` up to ``to_s``, checking after each; returns next seq."""
    t = from_s
    while t <= to_s + 1e-9:
        for name in (process,) if isinstance(process, str) else process:
            assert live.tick(name, seq, t) == []
        assert live.check(t + 0.01) == []
        seq += 1
        t += P
    return seq


def test_the_bound_is_five_ticks_and_reports_within_a_second() -> None:
    assert pytest.approx(5 * P) == HANG_BOUND_S
    supervision_period_s = 0.1        # launch.CLOCK_PERIOD_S: how often the launcher checks
    assert HANG_BOUND_S + supervision_period_s + P < 1.0


def test_a_process_that_keeps_ticking_with_jitter_is_never_hung() -> None:
    live = Liveness(["move"])
    t = 0.0
    for seq in range(200):                # gaps up to one period + 0.39 s (host stalls)
        t += P + (0.39 if seq % 50 == 7 else 0.0)
        assert live.tick("move", seq, t) == []
        assert live.check(t + 0.005) == []
    assert live.report()["processes"]["move"]["hangs"] == []


def test_silence_beyond_the_bound_is_reported_once_then_its_resumption() -> None:
    live = Liveness(["move", "speed"])
    seq = _tick_until(live, ("move", "speed"), 0.0, 3.0)
    last, at = 3.0, 3.0 + HANG_BOUND_S + 0.05
    assert live.check(last + HANG_BOUND_S - 0.01) == []
    found = live.check(at)
    assert found == [Hung("move", pytest.approx(last), pytest.approx(HANG_BOUND_S + 0.05), at),
                     Hung("speed", pytest.approx(last), pytest.approx(HANG_BOUND_S + 0.05), at)]
    assert live.check(last + 5.0) == [], "one report per episode"
    resumed = live.tick("move", seq, last + 1.5)
    assert resumed == [Resumed("move", pytest.approx(last), last + 1.5, pytest.approx(1.5), 0)]
    hangs = live.report()["processes"]["move"]["hangs"]
    assert hangs == [{"last_tick_s": 3.0, "reported_s": 3.55, "resumed_s": 4.5, "silent_s": 1.5,
                      "lost_ticks": 0}]


def test_a_hang_the_launcher_missed_is_reported_when_the_ticks_resume() -> None:
    live = Liveness(["driving"])
    seq = _tick_until(live, "driving", 0.0, 2.0)
    # the launcher itself was not run from 2.0 to 3.2: its next look sees the tick of 3.1 first
    found = live.tick("driving", seq, 3.1)
    assert [type(f) for f in found] == [Hung, Resumed]
    assert found[0].silent_s == pytest.approx(1.1) and found[1].lost == 0
    assert live.check(3.15) == []


def test_ticks_lost_on_the_way_are_told_apart_from_a_stalled_process() -> None:
    live = Liveness(["vehicle"])
    seq = _tick_until(live, "vehicle", 0.0, 1.0)
    assert live.check(1.7) == [Hung("vehicle", pytest.approx(1.0), pytest.approx(0.7), 1.7)]
    found = live.tick("vehicle", seq + 7, 1.8)          # 7 ticks were sent, none arrived
    assert found == [Resumed("vehicle", pytest.approx(1.0), 1.8, pytest.approx(0.8), 7)]


def test_a_tick_late_on_the_way_after_a_report_ends_the_episode() -> None:
    live = Liveness(["move"])
    seq = _tick_until(live, "move", 0.0, 1.0)
    assert len(live.check(1.6)) == 1
    found = live.tick("move", seq, 1.45)                # sent in time, arrived late
    assert found == [Resumed("move", pytest.approx(1.0), 1.45, pytest.approx(0.45), 0)]
    assert live.check(1.9) == []
    assert live.check(2.0) == [Hung("move", 1.45, pytest.approx(0.55), 2.0)], "judged again"


def test_a_process_that_never_ticks_is_hung_after_its_grace() -> None:
    live = Liveness(["move"])
    assert live.check(HANG_BOUND_S) == []
    assert live.check(HANG_BOUND_S + 0.1) == [Hung("move", 0.0, pytest.approx(0.6), 0.6)]


def test_a_dead_process_is_not_hung_and_a_restarted_one_gets_its_start_grace() -> None:
    live = Liveness(["speed"])
    seq = _tick_until(live, "speed", 0.0, 2.0)
    live.down("speed")                                  # its exit is reported instead
    assert live.check(10.0) == []
    assert live.tick("speed", seq, 2.05) == [], "a dying process's last tick"
    live.expect("speed", 10.0, grace_s=5.0)
    assert live.tick("speed", seq + 1, 9.9) == [], "the old process's tick, still in flight"
    assert live.check(14.9) == []
    _tick_until(live, "speed", 14.95, 16.0, seq=0)       # the new process counts from 0
    assert live.check(16.0 + HANG_BOUND_S + 0.01) == [
        Hung("speed", pytest.approx(15.95), pytest.approx(0.56), 16.0 + HANG_BOUND_S + 0.01)]


def test_a_restarted_process_that_never_ticks_is_hung_after_its_start_grace() -> None:
    live = Liveness(["driving"])
    _tick_until(live, "driving", 0.0, 1.0)
    live.expect("driving", 3.0, grace_s=20.0)
    assert live.check(22.9) == []
    assert live.check(23.1) == [Hung("driving", 3.0, pytest.approx(20.1), 23.1)]


def test_ticks_of_unknown_processes_and_bad_stamps_are_ignored_and_counted() -> None:
    live = Liveness(["move"])
    assert live.tick("rogue", 0, 0.1) == [] and live.tick("move", 0, float("nan")) == []
    assert live.ignored == 2


def test_a_bound_not_longer_than_the_tick_period_is_refused() -> None:
    with pytest.raises(ValueError, match="must exceed the tick period"):
        Liveness(["move"], bound_s=P)


def test_the_tick_node_counts_its_ticks() -> None:
    node = TickNode("move")
    assert node.period_s == P and node.subscriptions == ()
    assert [node.step(0.0, []) for _ in range(2)] == [
        [(Topic.TICK, NodeTick(process="move", seq=0))], [(Topic.TICK, NodeTick(process="move", seq=1))]]


def test_a_tick_older_than_one_already_seen_changes_nothing() -> None:
    live = Liveness(["move", "speed"])
    assert live.processes == ["move", "speed"]
    assert live.tick("move", 1, 0.2) == [] and live.tick("move", 0, 0.1) == []
    assert live.check(0.6) == [Hung("speed", 0.0, pytest.approx(0.6), 0.6)]
    assert live.check(0.69) == [], "judged from the newest tick, 0.2 s"


def test_a_tick_stamped_after_its_receipt_cannot_switch_supervision_off() -> None:
    """One forged tick stamped far ahead would make every true tick after it look out of
    order, and the process could hang unreported: it is ignored and counted."""
    live = Liveness(["move"])
    seq = _tick_until(live, "move", 0.0, 1.0)
    assert live.tick("move", seq, 1e9, now_s=1.05) == [] and live.ignored == 1
    assert live.tick("move", seq + 1, 1.1, now_s=1.11) == []
    assert live.check(1.1 + HANG_BOUND_S + 0.05) == [
        Hung("move", pytest.approx(1.1), pytest.approx(HANG_BOUND_S + 0.05), pytest.approx(1.65))]


def test_a_tick_stamped_within_the_clock_tolerance_ahead_counts() -> None:
    live = Liveness(["move"])
    assert live.tick("move", 0, FUTURE_TICK_TOLERANCE_S - 0.01, now_s=0.0) == []
    assert live.ignored == 0


def test_a_process_hung_before_its_first_tick_resumes_from_its_start() -> None:
    live = Liveness(["driving"])
    assert live.check(0.6) == [Hung("driving", 0.0, pytest.approx(0.6), 0.6)]
    assert live.tick("driving", 0, 2.0) == [Resumed("driving", 0.0, 2.0, 2.0, 0)]
    assert live.report()["processes"]["driving"]["hangs"][0]["silent_s"] == 2.0
    assert live.check(2.3) == []
