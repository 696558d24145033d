"""Distances anchored in time (issue 17): "advance d metres from where the vehicle was when I
said so", whatever the message's latency.

A command or authorization carries ``issued_s``, the time its source fixed the distance, on the
run's clock (the lock-step clock, or in multi-process runs the launch's shared monotonic clock:
docs/multiprocess.md). A server keeps its odometer readings of the last ``max_age_s``; on
arrival the distance travelled since ``issued_s`` is the odometer now minus the reading at that
time. Older than ``max_age_s`` is stale, later than now plus ``skew_s`` is future-dated: both are
refused by the caller. Pure: time is passed in.
"""

from __future__ import annotations

import bisect
from collections import deque

MAX_AGE_S = 1.0      # a command older than this on arrival is stale (issue 17 asks for 0.5 s of
                     # latency to be absorbed; twice that is kept)
SKEW_S = 0.02        # "future" within this is clock phase, not a fault: two 10 ms periods between
                     # processes stepping on the same clock (docs/multiprocess.md)


class OdometerHistory:
    """Odometer readings by time, the last ``max_age_s`` of them (one per step)."""

    __slots__ = ("_odometers", "_times", "max_age_s", "skew_s")

    def __init__(self, max_age_s: float = MAX_AGE_S, skew_s: float = SKEW_S) -> None:
        self.max_age_s = max_age_s
        self.skew_s = skew_s
        self._times: deque[float] = deque()
        self._odometers: deque[float] = deque()

    def record(self, now_s: float, odometer_m: float) -> None:
        times, odos = self._times, self._odometers
        if times and now_s <= times[-1]:
            odos[-1] = odometer_m          # the same step again: the latest reading wins
            return
        times.append(now_s)
        odos.append(odometer_m)
        while len(times) > 1 and times[1] < now_s - self.max_age_s:
            times.popleft()
            odos.popleft()

    def dated(self, issued_s: float, now_s: float) -> str:
        """Why ``issued_s`` is future-dated or stale at ``now_s``, or ""."""
        if issued_s > now_s + self.skew_s:
            return f"issued at t={issued_s:.3f} s, in the future (now t={now_s:.3f} s)"
        if now_s - issued_s > self.max_age_s:
            return (f"issued {now_s - issued_s:.3f} s ago, older than "
                    f"{self.max_age_s:.1f} s: stale")
        return ""

    def anchor(self, issued_s: float, now_s: float) -> tuple[float | None, str]:
        """The odometer when ``issued_s`` was, or (None, why) for a stale or future-dated time.

        Between readings the earlier one counts (the reading the source saw); a time in the
        future within ``skew_s`` counts as now. A time before this server's first reading is
        refused: the travel since then is unknown, and guessing could hide some.
        """
        why = self.dated(issued_s, now_s)
        if why:
            return None, why
        times = self._times
        if not times or issued_s < times[0] - 1e-9:
            return None, f"issued at t={issued_s:.3f} s, before this server's first reading"
        i = bisect.bisect_right(times, issued_s + 1e-9) - 1
        return self._odometers[i], ""


__all__ = ["MAX_AGE_S", "SKEW_S", "OdometerHistory"]
