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

Bounds that cross (``lo_s > hi_s``) mean a clock stepped, drifted faster than allowed, or a
sample lied: every sample is dropped and the offset is unknown (``None``) until both directions
are measured again. Pure: times are passed in.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping
from typing import Any

import msgspec

from overdrive.messages import AdvanceAuthorization, MaxSpeed, Message

DRIFT_RATE = 500e-6
"""Relative rate the two clocks may drift apart (500 ppm): above a crystal's tolerance (typically
+-50..100 ppm) and ntpd's maximum slew (500 ppm). chrony slews faster when correcting a large
offset unless ``maxslewrate 500`` is set (docs/multiprocess.md, "Clocks across machines")."""

SAMPLES_KEPT = 64
"""Bounds kept per direction; with DRIFT_RATE widening them, older ones stop mattering."""

MAX_CLOCK_OFFSET_S = 0.25
"""Largest |offset| (the bounds' midpoint) between two processes' clocks at which a multi-process
run may engage. chrony or PTP keep the clocks of a LAN within ~1 ms (hardware time stamps: within
a microsecond); a quarter of a second means synchronisation is not working, whatever the
correction would make of it (docs/multiprocess.md, "Clocks across machines")."""
MAX_CLOCK_UNCERTAINTY_S = 0.05
"""Largest ``hi_s - lo_s`` at which an offset counts as known: a quarter of the 200 ms watchdogs.
A stamp converted with ``lo_s`` is early by at most this much, so a watchdog timed from it fires
at most this much sooner, and a distance anchored from it ends at most ``speed x this`` short
(0.4 m at 8 m/s); loopback and a LAN measure well under a millisecond."""
CLOCK_REPORT_TOPIC = "clock/report"
"""``ClockReport``: each process, every ``CLOCK_REPORT_PERIOD_S``, to every other (state)."""
CLOCK_REPORT_PERIOD_S = 0.2
"""Often enough that lower bounds are seconds fresh (drift widens them 0.1 ms a second)."""


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


CROSSING_EPS_S = 1e-9
"""Bounds crossing by less than this are float rounding of zero delays, not a clock step."""


class ClockOffset:
    """Bounds on one peer's clock offset from samples in both directions (module docstring).

    Crossed bounds are dealt with when a sample is added (one reset per step seen), so
    ``estimate`` is a pure read whoever calls it and when."""

    __slots__ = ("_contradicted", "_lower", "_upper", "drift_rate", "resets")

    def __init__(self, drift_rate: float = DRIFT_RATE, kept: int = SAMPLES_KEPT) -> None:
        self.drift_rate = drift_rate
        self._upper: deque[tuple[float, float]] = deque(maxlen=kept)   # (measured at, bound)
        self._lower: deque[tuple[float, float]] = deque(maxlen=kept)
        self.resets = 0       # times the bounds crossed and older samples were dropped
        self._contradicted = False   # bounds crossed, not measured both ways since

    def received(self, now_s: float, sent_s: float) -> bool:
        """The peer's stamp ``sent_s`` arrived at ``now_s``: an upper bound. False (and nothing
        kept) for a time that is not finite."""
        bound = now_s - sent_s
        if not (math.isfinite(now_s) and math.isfinite(bound)):
            return False         # (huge finite times overflow to an infinite bound)
        self._upper.append((now_s, bound))
        self._check(now_s)
        return True

    def echoed(self, own_sent_s: float, peer_received_s: float) -> bool:
        """The peer received this side's ``own_sent_s`` at ``peer_received_s`` (its clock): a
        lower bound, dated at ``own_sent_s`` (the earliest it can be: the widest drift)."""
        bound = own_sent_s - peer_received_s
        if not (math.isfinite(own_sent_s) and math.isfinite(bound)):
            return False
        self._lower.append((own_sent_s, bound))
        self._check(max(own_sent_s, self._upper[-1][0] if self._upper else own_sent_s))
        return True

    def _check(self, at_s: float) -> None:
        """After a new sample: bounds that cross mean a clock stepped, drifted faster than
        ``drift_rate``, or a sample lied. Which one is wrong cannot be told, so none is kept:
        the offset is unknown until both directions are measured again."""
        hi, lo = self.upper_s(at_s), self.lower_s(at_s)
        if hi is None or lo is None:
            return
        if lo <= hi + CROSSING_EPS_S:
            self._contradicted = False
            return
        self.resets += 1
        self._upper.clear()
        self._lower.clear()
        self._contradicted = True

    @property
    def upper_only(self) -> bool:
        """Stamps came one way only: the offset has an upper bound and no lower one."""
        return bool(self._upper) and not self._lower

    @property
    def contradicted(self) -> bool:
        """The bounds crossed (a clock stepped) and have not been measured both ways since."""
        return self._contradicted

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
        contradict each other. A pure read."""
        if self._contradicted:
            return None
        hi, lo = self.upper_s(now_s), self.lower_s(now_s)
        if hi is None or lo is None:
            return None
        return OffsetEstimate(min(lo, hi), max(lo, hi))   # within CROSSING_EPS_S: one value


# --------------------------------------------------------------------------- between processes

class ClockSample(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The reporter received ``peer``'s stamp ``sent_s`` (the peer's clock) at ``received_s``
    (its own): the fastest such frame since its last report. For ``peer`` that is a lower bound
    (``ClockOffset.echoed(sent_s, received_s)``)."""

    peer: str
    sent_s: float
    received_s: float


class PeerBound(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The reporter's bounds on ``its clock - peer's clock`` when it reported."""

    peer: str
    lo_s: float
    hi_s: float
    resets: int = 0


class ClockReport(Message, frozen=True):
    """What one process measured of the others' clocks (``CLOCK_REPORT_TOPIC``): the samples
    its peers need for their lower bounds, and its own bounds (for the launcher's table)."""

    source: str
    samples: tuple[ClockSample, ...] = ()
    bounds: tuple[PeerBound, ...] = ()


FAIL_SAFE_S = 3600.0
"""Bounds given for a peer whose offset was known and is no longer (bounds crossed: a clock
stepped or drifted beyond ``DRIFT_RATE``, a restarted process on another clock, a report that
does not fit): +-1 h, so its stamps convert to an hour early: older than any watchdog or
authorization accepts (the vehicle stops), never later than the truth; and beyond tolerance,
so the pair is reported. A peer never known yet is taken as one host, one clock."""

OWN_STAMPS_KEPT = 4096
"""This process's own recent send stamps (a few seconds of everything it publishes): a peer's
report may only name one of them (``PeerClocks.report``)."""


class PeerClocks:
    """One ``ClockOffset`` per peer (frame sender), fed from every stamped frame received and
    from the peers' ``ClockReport``s. Pure: times are passed in, on this process's clock (the
    raw clock, not a run's ``now_s`` axis: the offset is the same on both)."""

    __slots__ = ("_fastest", "_own", "_own_set", "drift_rate", "known", "latest", "name", "peers")

    def __init__(self, name: str, drift_rate: float = DRIFT_RATE) -> None:
        self.name = name
        self.drift_rate = drift_rate
        self.known: set[str] = set()          # peers whose offset has been known
        self._own: deque[float] = deque()
        self._own_set: set[float] = set()
        self.peers: dict[str, ClockOffset] = {}
        self.latest: dict[str, ClockReport] = {}     # each peer's newest report
        self._fastest: dict[str, tuple[float, float]] = {}   # peer -> (sent, received) since report

    def _peer(self, peer: str) -> ClockOffset:
        clock = self.peers.get(peer)
        if clock is None:
            clock = self.peers[peer] = ClockOffset(self.drift_rate)
        return clock

    def received(self, peer: str, now_s: float, sent_s: float) -> None:
        """A frame ``peer`` stamped ``sent_s`` arrived at ``now_s``."""
        if peer == self.name or not self._peer(peer).received(now_s, sent_s):
            return
        fastest = self._fastest.get(peer)
        if fastest is None or now_s - sent_s < fastest[1] - fastest[0]:
            self._fastest[peer] = (sent_s, now_s)

    def sent(self, sent_s: float) -> None:
        """This process stamped a frame ``sent_s``."""
        self._own.append(sent_s)
        self._own_set.add(sent_s)
        if len(self._own) > OWN_STAMPS_KEPT:
            self._own_set.discard(self._own.popleft())

    def report(self, report: ClockReport) -> None:
        """A peer's report: its fastest sample of our frames is a lower bound here, if it names
        a stamp this process sent (a report that does not is no sample: forged or garbled)."""
        if report.source == self.name:
            return
        self.latest[report.source] = report
        for sample in report.samples:
            if sample.peer == self.name and sample.sent_s in self._own_set:
                self._peer(report.source).echoed(sample.sent_s, sample.received_s)

    def estimates(self, now_s: float) -> dict[str, OffsetEstimate | None]:
        """Every peer's bounds at ``now_s``: None while never known; +-``FAIL_SAFE_S`` once
        known and no longer (fail-safe: its stamps are then an hour old)."""
        out: dict[str, OffsetEstimate | None] = {}
        for peer, clock in self.peers.items():
            est = clock.estimate(now_s)
            if est is not None:
                self.known.add(peer)
            elif peer in self.known:
                est = OffsetEstimate(-FAIL_SAFE_S, FAIL_SAFE_S)
            out[peer] = est
        return out

    def make_report(self, now_s: float) -> ClockReport:
        """This process's report; the fastest samples start again from here."""
        samples = tuple(ClockSample(p, s, r) for p, (s, r) in sorted(self._fastest.items()))
        self._fastest.clear()
        bounds = tuple(PeerBound(p, e.lo_s, e.hi_s, self.peers[p].resets)
                       for p, e in sorted(self.estimates(now_s).items()) if e is not None)
        return ClockReport(source=self.name, samples=samples, bounds=bounds)


def earliest_s(stamp_s: float, estimate: OffsetEstimate | None) -> float:
    """A peer's stamp on this clock, as early as it can have been (``stamp + lo_s``): a later
    one would extend a watchdog or a distance. Unknown offset: the stamp as it is (one host,
    one clock)."""
    return stamp_s if estimate is None else stamp_s + estimate.lo_s


def restamped(msg: Any, estimate: OffsetEstimate | None) -> Any:
    """``msg`` with the dates that anchor distances (``issued_s`` of ``AdvanceAuthorization``
    and ``MaxSpeed``) moved to this clock by ``earliest_s``: the distance then counts from
    earlier, the end comes closer. Other messages (``MoveCommand``: the move server handles the
    planner's clock) as they are."""
    if estimate is None or not isinstance(msg, (AdvanceAuthorization, MaxSpeed)) \
            or msg.issued_s is None:
        return msg
    return msgspec.structs.replace(msg, issued_s=msg.issued_s + estimate.lo_s)


def out_of_tolerance(estimate: OffsetEstimate | None, max_offset_s: float = MAX_CLOCK_OFFSET_S,
                     max_uncertainty_s: float = MAX_CLOCK_UNCERTAINTY_S) -> str:
    """Why two processes must not drive together on these bounds, or ""."""
    if estimate is None:
        return "offset unknown"
    if not (math.isfinite(estimate.lo_s) and math.isfinite(estimate.hi_s)) \
            or estimate.lo_s > estimate.hi_s:
        return "bounds invalid"
    if estimate.uncertainty_s >= 2.0 * FAIL_SAFE_S:
        return (f"offset lost (its bounds crossed: a clock stepped or drifted beyond "
                f"{DRIFT_RATE * 1e6:.0f} ppm, or a report did not fit)")
    if abs(estimate.offset_s) > max_offset_s:
        return f"offset beyond {max_offset_s * 1e3:.0f} ms"
    if estimate.uncertainty_s > max_uncertainty_s:
        return f"uncertainty beyond {max_uncertainty_s * 1e3:.0f} ms"
    return ""


def pair_table(names: Iterable[str],
               views: Mapping[str, Mapping[str, PeerBound]]) -> list[dict[str, Any]]:
    """Every pair ``a < b`` of ``names`` (in that order): ``offset_s`` = ``b``'s clock minus
    ``a``'s, from both ends' bounds (``views[x][y]``: x's bounds on x - y), intersected; with
    ``reason`` (why the pair must not engage: "" when fine) judged on each end's own bounds,
    which are what each converts stamps with."""
    names = list(names)
    rows: list[dict[str, Any]] = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ends: list[OffsetEstimate | None] = []
            resets = 0
            for x, y, sign in ((a, b, -1.0), (b, a, 1.0)):
                bound = views.get(x, {}).get(y)
                if bound is None:
                    ends.append(None)
                    continue
                resets += bound.resets
                lo, hi = (-bound.hi_s, -bound.lo_s) if sign < 0 else (bound.lo_s, bound.hi_s)
                ends.append(OffsetEstimate(lo, hi))
            reasons = [r for r in map(out_of_tolerance, ends) if r]
            # what is known beyond tolerance says more than an end that knows nothing
            reason = next((r for r in reasons if r != "offset unknown"), reasons[0] if reasons
                          else "")
            row: dict[str, Any] = {"a": a, "b": b, "offset_s": None, "uncertainty_s": None,
                                   "lo_s": None, "hi_s": None, "resets": resets, "reason": reason}
            known = [e for e in ends if e is not None]
            if known:
                lo, hi = max(e.lo_s for e in known), min(e.hi_s for e in known)
                if lo > hi:      # the two ends disagree: one reading is stale (a clock stepped)
                    lo, hi = min(e.lo_s for e in known), max(e.hi_s for e in known)
                row.update(offset_s=round(0.5 * (lo + hi), 6), uncertainty_s=round(hi - lo, 6),
                           lo_s=round(lo, 6), hi_s=round(hi, 6))
            rows.append(row)
    return rows


def describe_pair(row: Mapping[str, Any]) -> str:
    """One line: which processes, offset, uncertainty, why."""
    if row["offset_s"] is None:
        return f"clocks {row['a']}-{row['b']}: {row['reason'] or 'offset unknown'}"
    offset = row["offset_s"]
    return (f"clocks {row['a']}-{row['b']}: {row['b']}'s clock {abs(offset) * 1e3:.1f} ms "
            f"{'ahead of' if offset >= 0 else 'behind'} {row['a']}'s (uncertainty "
            f"{row['uncertainty_s'] * 1e3:.1f} ms)" + (f": {row['reason']}" if row["reason"] else ""))


__all__ = ["CLOCK_REPORT_PERIOD_S", "CLOCK_REPORT_TOPIC", "DRIFT_RATE", "FAIL_SAFE_S", "MAX_CLOCK_OFFSET_S",
           "MAX_CLOCK_UNCERTAINTY_S", "SAMPLES_KEPT", "ClockOffset", "ClockReport", "ClockSample",
           "OffsetEstimate", "PeerBound", "PeerClocks", "describe_pair", "earliest_s",
           "out_of_tolerance", "pair_table", "restamped"]
