"""The watchdog rule shared by the speed server (SPSS, seed 001) and the vehicle (commands).

A periodic input must arrive at least every ``timeout_s``. ``check`` is True exactly once, on
the step at which the silence reaches the timeout; it re-arms when the input is fed again.
Time is passed in; nothing here reads a clock.
"""

from __future__ import annotations

TIME_EPS_S = 1e-9   # float slack: simulated times are tick * period


class Watchdog:
    __slots__ = ("last_s", "lost", "timeout_s")

    def __init__(self, timeout_s: float) -> None:
        if not timeout_s > 0.0:
            raise ValueError(f"timeout_s must be positive, got {timeout_s}")
        self.timeout_s = timeout_s
        self.last_s: float | None = None    # None: never fed, nothing to watch yet
        self.lost = False

    def feed(self, now_s: float) -> None:
        self.last_s = now_s
        self.lost = False

    def silent(self, now_s: float) -> bool:
        """The input has been silent for the timeout or longer (False before the first feed)."""
        return self.last_s is not None and now_s - self.last_s >= self.timeout_s - TIME_EPS_S

    def check(self, now_s: float) -> bool:
        """True on the first step of a silence; updates ``lost``."""
        silent = self.silent(now_s)
        edge = silent and not self.lost
        self.lost = silent
        return edge
