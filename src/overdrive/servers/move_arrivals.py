"""Each queued sensor sample at its own time, not at its arrival (issue 38).

A node that stalls (SIGSTOP, a scheduler hiccup, a lock-step ``stall`` event) reads everything
queued meanwhile in one step. Handing every sample the step's time made the wheel-speed
integral credit the first queued reading for the whole stall: a move server stalled 3 s at
4 m/s while the vehicle stopped counted 12 m for ~3 m driven and reported a 60 m MOVE done at
53.33 m (``tests/safety/test_unasked_stop_attacks.py``).

The sensors are periodic (the vehicle publishes GPS/INS, IMU and wheel speed every 10 ms) and
arrive in the order they were sent, so the ``n`` samples of one topic queued since the node's
previous step were sent, one period apart, over the gap: sample ``k`` (1..n) is dated
``last_s + k (now_s - last_s) / n``. The newest is dated ``now_s``; one sample per step (every
normal step) keeps its arrival time exactly, so nothing changes outside a stall.

Residual: an inbox that overflowed during the stall (multi-process: the bus's bounded inbox drops
the oldest state samples) keeps only the newest; they are spread over the whole gap, so the
wheel integral credits their mean speed for it. The GPS/INS odometer is cumulative (exact across
any gap) and progress takes it whenever it says more (``safety.plausibility``).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import Any


def sample_times(inbox: Sequence[tuple[str, Any]], topics: Collection[str],
                 last_s: float | None, now_s: float) -> list[float]:
    """The time of each inbox entry: samples of ``topics`` spread over ``(last_s, now_s]`` per
    topic in arrival order, everything else (and everything on a first step) at ``now_s``."""
    times = [now_s] * len(inbox)
    if last_s is None or not now_s > last_s:
        return times
    counts: dict[str, int] = {}
    for topic, _ in inbox:
        if topic in topics:
            counts[topic] = counts.get(topic, 0) + 1
    if all(n == 1 for n in counts.values()):
        return times
    gap_s = now_s - last_s
    seen: dict[str, int] = {}
    for i, (topic, _) in enumerate(inbox):
        n = counts.get(topic)
        if n is not None and n > 1:
            k = seen.get(topic, 0) + 1
            seen[topic] = k
            times[i] = now_s if k == n else last_s + k * gap_s / n
    return times


__all__ = ["sample_times"]
