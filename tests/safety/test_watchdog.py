"""The shared watchdog rule: one edge per silence, swept around the timeout."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.safety.watchdog import Watchdog

DT = 0.01


def test_never_fed_is_never_silent() -> None:
    dog = Watchdog(0.2)
    assert not dog.silent(100.0) and not dog.check(100.0)


@pytest.mark.parametrize(("after_s", "silent"), [(0.19, False), (0.2 - 1e-6, False), (0.2, True),
                                                 (0.2 + 1e-6, True), (5.0, True)])
def test_silence_reaches_the_timeout(after_s: float, silent: bool) -> None:
    dog = Watchdog(0.2)
    dog.feed(1.0)
    assert dog.silent(1.0 + after_s) == silent
    assert dog.check(1.0 + after_s) == silent


def test_one_edge_per_silence_and_rearmed_by_feeding() -> None:
    dog = Watchdog(0.2)
    dog.feed(0.0)
    edges = [dog.check(round(i * DT, 6)) for i in range(1, 60)]
    assert edges.count(True) == 1 and edges.index(True) == 19   # at t = 0.20 s
    assert dog.lost
    dog.feed(0.6)
    assert not dog.lost and not dog.check(0.7) and dog.check(0.8)


def test_timeout_must_be_positive() -> None:
    with pytest.raises(ValueError):
        Watchdog(0.0)


@given(st.lists(st.floats(0.001, 0.5), min_size=1, max_size=40))
def test_edge_iff_a_gap_reaches_the_timeout(gaps: list[float]) -> None:
    """Fed after each gap, checked every 10 ms in between: an edge exactly for gaps >= 200 ms."""
    dog = Watchdog(0.2)
    t = 0.0
    dog.feed(t)
    for gap in gaps:
        ticks = int(gap / DT)
        edges = [dog.check(t + k * DT) for k in range(1, ticks + 1)]
        assert edges.count(True) == (1 if ticks * DT >= 0.2 - 1e-9 else 0)
        t += gap
        dog.feed(t)
