"""The offset between two clocks, NTP-style, from traffic the two sides already exchange.

``offset = this clock - the peer's clock``. Every delay is >= 0, so

- a message the peer stamped ``sent_s`` on its clock and this side received at ``now_s`` on its
  own gives ``now_s - sent_s = offset + delay``: an **upper** bound on the offset;
- a stamp of this side's (``own_sent_s``) that the peer reports having received at
  ``peer_received_s`` on its clock gives ``peer_received_s - own_sent_s = -offset + delay``:
  ``-(that)`` is a **lower** bound.

The offset lies in ``[lo_s, hi_s]``, the tightest bounds kept, each widened by what the clocks
may have drifted since it was measured (``DRIFT_RATE``). The width is the best round trip: no
assumption that the two directions' delays are equal (NTP's midpoint takes that assumption;
the bounds do not). A caller that must not overestimate how recent a peer's stamp is converts
it with ``lo_s`` (the earliest it can have been on this clock); one that must not
underestimate, with ``hi_s``.

Bounds that cross (``lo_s > hi_s``) mean a clock stepped or drifted faster than allowed: the
older samples are dropped and the newest pair judged alone; crossing again, the offset is
unknown (``None``) until new samples agree. Pure: times are passed in.
"""

from __future__ import annotations

import math
from collections import deque

import msgspec

DRIFT_RATE = 500e-6
"""Relative rate the two clocks may drift apart (500 ppm): above a crystal's tolerance (typically
+-50..100 ppm) and ntpd's maximum slew (500 ppm). chrony slews faster when correcting a large
offset unless ``maxslewrate 500`` is set (docs/multiprocess.md, "Clocks across machines")."""

MAX_CLOCK_OFFSET_S = 0.25
"""Beyond this the clocks are not synchronised: chrony or PTP keep machines on one network
within a millisecond, so a quarter of a second means synchronisation is not running (a machine
booted without it, or before it converged). Stamps could still be corrected, but every other
use of time across the machines (sensor stamps, logs, recorded bags) would be wrong: refused,
with a fault the operator sees."""

MAX_CLOCK_UNCERTAINTY_S = 0.05
"""Widest offset bounds accepted (the round trip plus the drift allowance): a command anchored
at the earliest plausible time stops at most ``speed x this`` short (0.4 m at 8 m/s)."""

SAMPLES_KEPT = 64
"""Bounds kept per direction; with DRIFT_RATE widening them, older ones stop mattering."""


class OffsetEstimate(msgspec.Struct, frozen=True):
    """``lo_s <= offset <= hi_s`` (this clock minus the peer's) at the time asked."""

    lo_s: float
    hi_s: float

    @property
    def offset_s(self) -> float:
        """The midpoint: the estimate NTP would report (equal delays both ways)."""
        return 0.5 * (self.lo_s + self.hi_s)

    @property
    def uncertainty_s(self) -> float:
        """``hi_s - lo_s``: the best round trip plus the drift allowance."""
        return self.hi_s - self.lo_s


class ClockOffset:
    """Bounds on one peer's clock offset from samples in both directions (module docstring)."""

    __slots__ = ("_lower", "_upper", "drift_rate", "resets")

    def __init__(self, drift_rate: float = DRIFT_RATE, kept: int = SAMPLES_KEPT) -> None:
        self.drift_rate = drift_rate
        self._upper: deque[tuple[float, float]] = deque(maxlen=kept)   # (measured at, bound)
        self._lower: deque[tuple[float, float]] = deque(maxlen=kept)
        self.resets = 0       # times the bounds crossed and older samples were dropped

    def received(self, now_s: float, sent_s: float) -> bool:
        """The peer's stamp ``sent_s`` arrived at ``now_s``: an upper bound. False (and nothing
        kept) for a time that is not finite."""
        if not (math.isfinite(now_s) and math.isfinite(sent_s)):
            return False
        self._upper.append((now_s, now_s - sent_s))
        return True

    def echoed(self, own_sent_s: float, peer_received_s: float) -> bool:
        """The peer received this side's ``own_sent_s`` at ``peer_received_s`` (its clock): a
        lower bound, dated at ``own_sent_s`` (the earliest it can be: the widest drift)."""
        if not (math.isfinite(own_sent_s) and math.isfinite(peer_received_s)):
            return False
        self._lower.append((own_sent_s, own_sent_s - peer_received_s))
        return True

    @property
    def upper_only(self) -> bool:
        """Stamps came one way only: the offset has an upper bound and no lower one."""
        return bool(self._upper) and not self._lower

    def upper_s(self, now_s: float) -> float | None:
        """The tightest upper bound at ``now_s``, or None without a sample."""
        rate = self.drift_rate
        return min((b + rate * max(0.0, now_s - t) for t, b in self._upper), default=None)

    def lower_s(self, now_s: float) -> float | None:
        """The tightest lower bound at ``now_s``, or None without a sample."""
        rate = self.drift_rate
        return max((b - rate * max(0.0, now_s - t) for t, b in self._lower), default=None)

    def estimate(self, now_s: float) -> OffsetEstimate | None:
        """The bounds at ``now_s``; None while a direction has no sample or the newest samples
        contradict each other (a clock stepped between them)."""
        hi, lo = self.upper_s(now_s), self.lower_s(now_s)
        if hi is None or lo is None:
            return None
        if lo > hi:
            # a clock stepped, or drifted faster than DRIFT_RATE: only the newest pair counts
            self.resets += 1
            newest_up, newest_low = self._upper[-1], self._lower[-1]
            self._upper.clear()
            self._lower.clear()
            self._upper.append(newest_up)
            self._lower.append(newest_low)
            hi, lo = self.upper_s(now_s), self.lower_s(now_s)
            assert hi is not None and lo is not None
            if lo > hi:
                return None
        return OffsetEstimate(lo, hi)


__all__ = ["DRIFT_RATE", "MAX_CLOCK_OFFSET_S", "MAX_CLOCK_UNCERTAINTY_S", "SAMPLES_KEPT", "ClockOffset", "OffsetEstimate"]
