"""Time from the source on the JAUS link: report time stamps, their age, gaps and loss. Sans-IO.

The XGV stamps its reports (reference §5: ms, s, min, h, day of month, on its own clock). The
client counts distance and time between reports from those stamps, not from when it read them,
so a receiver that stalls and then reads a queue of reports at once loses nothing. Three things
the stamps cannot account for are reported for the client to act on (docs/xgv.md, "Time from
the source"):

- a **gap** in the stamps longer than ``GAP_S`` (reports lost: what happened between is known
  only as a chord between two poses);
- a **receiver stall**: the receiver's own steps further apart than ``RECEIVER_STALL_S`` (its
  clock follows the wall clock, ``run.sim``'s ``follow_wall_clock``): the vehicle went that
  long without fresh commands, whatever the reports say;
- an **old report**: its age beyond a bound (``XgvClient`` acts on ``AGE_DEGRADED_S`` and
  ``AGE_STOP_S``).

**Age.** The XGV's clock and ours differ by an unknown offset. Every report bounds it from below
(a report is received after it was stamped: offset >= stamp - receipt); the largest such bound
is the fastest delivery seen, so ``excess`` = receipt - stamp + that bound is the age beyond the
fastest delivery. The fastest delivery itself is bounded by the shortest round trip measured
(a tagged probe's, below, or Query Component Control to its Report, ``round_trip``):
age <= excess + shortest round trip.
That upper bound is the report's ``age_s``: it never reads younger than the report is, and it
sees a delay present from the first report as well as one that comes later.

**Round trip.** A delay on the way to the vehicle only leaves the reports fresh: the age cannot
see it, yet every command acts late (0.5 s: 9.17 m/s on an 8 m/s MOVE in wrench mode). JAUS 3.3
queries carry no request id, so ``RoundTrips`` tags them: each probe is a Query Velocity State
whose presence vector is one of ``PROBE_TAGS``, and the report answering it has exactly those
fields. An answer is matched to its own probe, so loss never lengthens a round trip (timing
from the oldest unanswered query does: one lost query in five reads as 0.2 s more).
"""

from __future__ import annotations

import math
import statistics
from typing import Any, Final

from overdrive.jaus import JausTimestamp

DAY_S: Final = 86_400.0              # the stamp's hour/min/s/ms fields wrap daily; the day of
                                     # month is not used (months differ in length): gaps are
                                     # taken modulo a day, never longer than half of one
GAP_S: Final = 0.25                  # reports missing longer than this (a lost link, not jitter;
                                     # 25 periods at 100 Hz): the odometer takes the chord
RECEIVER_STALL_S: Final = 0.2        # steps further apart than this: we were not stepped
                                     # (SIGSTOP, a scheduler stall) for longer than the stack
                                     # promises a stop after silence (SPSS watchdog, 200 ms)
PROBE_TAGS: Final = tuple(range(2, 0x200, 2))   # Velocity State presence vectors: any of its
                                     # 9 fields but velocity x (bit 0), so an answer is never
                                     # taken for a speed sample and never equals the stream's
                                     # (every field); 255 tags
PROBE_PERIOD_S: Final = 0.05         # a probe every 50 ms once the vehicle answers them (100 Hz
                                     # starved OpenJAUS's 50 Hz Velocity State Sensor loop: it
                                     # sent no reports); tags come round after 12.75 s
PROBE_UNARMED_PERIOD_S: Final = 0.1  # until the first answer: tags come round after 25.5 s, so
                                     # a link delayed from the start is measured, not aliased
PROBE_MIN_TAGS: Final = 63           # fewer tags than this (the vehicle sends fewer than six of the
                                     # report's fields besides the speed): no probes, as tags
                                     # would come round within 3.2 s
PROBE_WINDOW_S: Final = 0.5          # the round trip is the lower median of those answered in
                                     # the last this (10 probes): one late answer, a host
                                     # hiccup, is not a delay, and one prompt answer does not
                                     # hide a delay on most commands (the shortest did: 0.5 s
                                     # on five commands in six read as prompt, 8.82 m/s on an
                                     # 8 m/s MOVE); none answered, as often at 50 % loss, is no
                                     # verdict
MAX_AGE_SAMPLES: Final = 200_000     # ages kept for the summary (over half an hour at 100 Hz)
SEQUENCE_SPAN: Final = 0x10000       # JAUS header sequence numbers are u16


def stamp_s(stamp: JausTimestamp | None) -> float | None:
    """Seconds of the day of a reference §5 time stamp; None when absent or out of range (day 0
    is an unset stamp: OpenJAUS's Velocity State sensor sends all zeros)."""
    if stamp is None:
        return None
    if not (1 <= stamp.day <= 31 and 0 <= stamp.hour < 24 and 0 <= stamp.minute < 60 and 0 <= stamp.second < 60
            and 0 <= stamp.millisecond < 1000):
        return None
    return (((stamp.hour * 60 + stamp.minute) * 60 + stamp.second) * 1000
            + stamp.millisecond) / 1000.0


def stamp_delta_s(later_s: float, earlier_s: float) -> float:
    """``later - earlier`` across midnight (within half a day either way)."""
    return (later_s - earlier_s + DAY_S / 2.0) % DAY_S - DAY_S / 2.0


class SourceClock:
    """One report stream's stamps, unwrapped onto a continuous source time (seconds)."""

    __slots__ = ("last_raw_s", "source_s")

    def __init__(self) -> None:
        self.last_raw_s: float | None = None
        self.source_s = 0.0

    def advance(self, raw_s: float) -> float:
        """The source time of a stamp; the step since the last one may be negative (reordered)."""
        if self.last_raw_s is not None:
            self.source_s += stamp_delta_s(raw_s, self.last_raw_s)
        self.last_raw_s = raw_s
        return self.source_s


class LinkTime:
    """Ages, gaps, receiver stalls, round trips and loss of the reports of one link."""

    def __init__(self) -> None:
        self.offset_lo_s: float | None = None   # XGV clock minus ours, lower bound
        # the shortest round trip since the link came up, not of a recent window: any round
        # trip bounds the fastest delivery behind ``offset_lo_s`` (kept since then too), and a
        # window would forget the short ones once a delay sets in and take 2x the delay for it
        self.shortest_round_trip: float | None = None
        self.last_round_trip: float | None = None
        self.ages_s: list[float] = []
        self.sequences: dict[tuple[Any, int], list[int]] = {}   # (source, code) -> counts
        self.stalls = 0
        self.sent_before = self.received_before = 0   # counts of connections before a reset

    def reset(self) -> None:
        """The link went down: the other end may come back on another clock, and its
        connections with new sequence numbers (the counts so far are kept)."""
        self.offset_lo_s = None
        self.shortest_round_trip = self.last_round_trip = None
        for _, got, span in self.sequences.values():
            self.sent_before += span
            self.received_before += got
        self.sequences.clear()

    def round_trip(self, seconds: float) -> None:
        if math.isfinite(seconds) and seconds >= 0.0:
            self.last_round_trip = seconds
            if self.shortest_round_trip is None or seconds < self.shortest_round_trip:
                self.shortest_round_trip = seconds

    def shortest_round_trip_s(self) -> float | None:
        return self.shortest_round_trip

    def arrival(self, raw_s: float, read_s: float) -> float:
        """The age (upper bound) of a report stamped ``raw_s`` read at ``read_s`` (our clock,
        any origin: only differences count)."""
        seen = stamp_delta_s(raw_s, read_s % DAY_S)   # stamp - receipt, within half a day
        lo = self.offset_lo_s
        if lo is None or stamp_delta_s(seen, lo) > 0.0:
            self.offset_lo_s = lo = seen
        age_s = stamp_delta_s(lo, seen) + (self.shortest_round_trip_s() or 0.0)
        if len(self.ages_s) < MAX_AGE_SAMPLES:
            self.ages_s.append(age_s)
        return age_s

    def sequence(self, source: Any, code: int, number: int) -> None:
        """Count a service-connection report by its sequence number (loss = numbers skipped)."""
        entry = self.sequences.get((source, code))
        if entry is None:
            self.sequences[(source, code)] = [number, 1, 1]   # last, received, sent
            return
        step = (number - entry[0]) % SEQUENCE_SPAN
        if 0 < step < SEQUENCE_SPAN // 2:   # newer; an older or repeated one is not counted
            entry[0] = number
            entry[1] += 1
            entry[2] += step

    def report(self) -> dict[str, Any]:
        """``summary.json`` ``link``: report age in ms (median, p95, max), round trip in ms
        (shortest, last), and the reports the XGV sent (by sequence number) against those
        received."""
        sent, received = self.sent_before, self.received_before
        for _, got, span in self.sequences.values():
            sent += span
            received += got
        ages = sorted(self.ages_s)

        def ms(value: float | None) -> float | None:
            return None if value is None else round(1000.0 * value, 1)

        p95 = ages[min(len(ages) - 1, math.ceil(0.95 * len(ages)) - 1)] if ages else None
        return {
            "latency_ms": {"median": ms(statistics.median(ages)) if ages else None,
                           "p95": ms(p95), "max": ms(ages[-1]) if ages else None,
                           "samples": len(ages)},
            "round_trip_ms": {"shortest": ms(self.shortest_round_trip_s()),
                              "last": ms(self.last_round_trip) if self.last_round_trip is not None
                              else None},
            "loss": {"sent": sent, "received": received,
                     "lost_fraction": round((sent - received) / sent, 4) if sent else None},
            "receiver_stalls": self.stalls,   # counted by the client (its own step gaps)
        }


def presence_vector(message: Any) -> int:
    """The presence vector of a decoded report: the bits of the fields it holds."""
    names = type(message).layout.names
    return sum(1 << bit for bit, name in enumerate(names) if getattr(message, name) is not None)


class RoundTrips:
    """Round trips of tagged probes, each answer matched to its own probe (sans-IO).

    ``probe`` says when a probe is due and with which tag; ``answer`` takes the tag of an
    answer (its presence vector). ``round_trip_s`` is the lower median of the round trips
    answered in the last ``PROBE_WINDOW_S``: a delay on either way shows in full, loss not at
    all. A vehicle
    that never answers leaves it unmeasured (None) and is never faulted for it; unanswered
    probes say nothing (lost, or a cut the client's other checks see)."""

    def __init__(self) -> None:
        self.sent_s: dict[int, float] = {}    # tag -> when the probe with it went out
        self.tags: tuple[int, ...] = ()       # those the vehicle can answer exactly (``support``)
        self.presence: int | None = None      # the stream's presence vector they came from
        self.next_tag = 0
        self.next_s = -math.inf
        self.armed = False                    # the vehicle has answered a probe
        self.answers: list[tuple[float, float]] = []   # (arrival, round trip), last window
        self.probes = self.answered = 0
        self.unmatched = 0                    # answers with the speed in them: not to a tag
        self.round_trips_s: list[float] = []  # for the summary (bounded like the ages)

    def support(self, presence: int) -> None:
        """The fields the vehicle's own Velocity State stream carries: tags are drawn from
        them only, since a vehicle answers with the fields asked that it supports (a tag
        asking for others would come back as another tag). A change starts afresh; the same
        stream (every report, 100 Hz) costs one comparison."""
        if presence == self.presence:
            return
        self.presence = presence
        tags = tuple(tag for tag in PROBE_TAGS if tag & ~presence == 0)
        if tags != self.tags:
            self.reset()
            self.tags = tags if len(tags) >= PROBE_MIN_TAGS else ()
            self.next_tag = 0

    def reset(self) -> None:
        """The link or control went down: probes out may never be answered to us."""
        self.sent_s.clear()
        self.answers.clear()
        self.armed = False
        self.next_s = -math.inf

    def probe(self, now_s: float) -> int | None:
        """The tag of a probe to send now, or None when none is due (or the vehicle's stream
        is not known yet, or carries too few fields for tags)."""
        if not self.tags or now_s < self.next_s - 1e-9:
            return None
        tag = self.tags[self.next_tag % len(self.tags)]
        self.next_tag = (self.next_tag + 1) % len(self.tags)
        self.sent_s[tag] = now_s
        self.probes += 1
        self.next_s = now_s + (PROBE_PERIOD_S if self.armed else PROBE_UNARMED_PERIOD_S)
        return tag

    def answer(self, tag: int, now_s: float) -> float | None:
        """The round trip of the probe ``tag`` answers; None for a tag not out (a repeat, a
        stranger's, a reply to another client's query)."""
        sent_s = self.sent_s.pop(tag, None)
        if sent_s is None or now_s < sent_s:
            return None
        round_trip_s = now_s - sent_s
        if not self.armed:   # it answers: probe at the full rate from now on
            self.armed = True
            self.next_s = min(self.next_s, now_s)
        self.answered += 1
        self.answers = [a for a in self.answers if now_s - a[0] <= PROBE_WINDOW_S]
        self.answers.append((now_s, round_trip_s))
        if len(self.round_trips_s) < MAX_AGE_SAMPLES:
            self.round_trips_s.append(round_trip_s)
        return round_trip_s

    def round_trip_s(self, now_s: float) -> float | None:
        """The lower median of the round trips answered in the last ``PROBE_WINDOW_S`` (None:
        none answered)."""
        self.answers = [a for a in self.answers if now_s - a[0] <= PROBE_WINDOW_S]
        if not self.answers:
            return None
        trips = sorted(rt for _, rt in self.answers)
        return trips[(len(trips) - 1) // 2]

    def report(self) -> dict[str, Any]:
        """``summary.json`` ``link.probes``: probes sent, answered, round trips in ms."""
        trips = sorted(self.round_trips_s)

        def ms(value: float) -> float:
            return round(1000.0 * value, 1)

        return {"sent": self.probes, "answered": self.answered, "unmatched": self.unmatched,
                "round_trip_ms": ({"median": ms(statistics.median(trips)),
                                   "p95": ms(trips[min(len(trips) - 1,
                                                       math.ceil(0.95 * len(trips)) - 1)]),
                                   "max": ms(trips[-1])} if trips else None)}


__all__ = ["GAP_S", "PROBE_TAGS", "RECEIVER_STALL_S", "LinkTime", "RoundTrips", "SourceClock",
           "presence_vector", "stamp_delta_s", "stamp_s"]
