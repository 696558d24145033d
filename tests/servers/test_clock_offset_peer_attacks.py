"""Attacks on the clock offsets between processes (servers.clock_offset), judged from the truth:
the clocks are simulated here, so every stamp's true time on the receiver's clock is known.
The rule: a peer's stamp converted to this clock (``earliest_s``: what ``runtime.wall._drain``
does to ``sent_s`` and ``issued_s``) is never later than when it was really sent; a malformed
or forged ``ClockReport`` crashes nothing and moves no bound unsafely; the launcher's table
never judges an unknowable pair within tolerance. Pure."""

from __future__ import annotations

import math

from overdrive.servers.clock_offset import (
    ClockReport,
    ClockSample,
    PeerBound,
    PeerClocks,
    earliest_s,
    pair_table,
)

DELAY_S = 0.0002     # one way, loopback


class _Pair:
    """``speed`` (the receiver, true clock ``t``) and ``driving``, whose clock reads
    ``ahead(t)`` more; frames both ways every 10 ms, reports each way every 200 ms."""

    def __init__(self, ahead) -> None:
        self.ahead = ahead
        self.me, self.peer = PeerClocks("speed"), PeerClocks("driving")
        self.t = 0.0
        self.k = 0

    def peer_clock(self, t: float) -> float:
        return t + self.ahead(t)

    def step(self) -> tuple[float, float]:
        """One 10 ms exchange; returns (the peer's stamp, its true time on this clock)."""
        t = self.t
        stamp = self.peer_clock(t)
        self.peer.sent(stamp)                                              # the bus's publish
        self.me.sent(t)
        self.me.received("driving", t + DELAY_S, stamp)                    # the bus's _admit
        self.peer.received("speed", self.peer_clock(t + DELAY_S), t)
        if self.k % 20 == 0:
            self.me.report(self.peer.make_report(self.peer_clock(t)))
            self.peer.report(self.me.make_report(t))
        self.t += 0.01
        self.k += 1
        return stamp, t

    def converted(self, stamp: float) -> float:
        """What the runtime hands the node: ``sent_s + lo_s`` (unknown: as it is)."""
        return earliest_s(stamp, self.me.estimates(self.t).get("driving"))


def test_a_forged_clock_report_never_makes_a_stamp_later_than_sent():
    """One frame on clock/report claiming to be driving's (nothing polices that topic's sender,
    and under --open-bus anyone can publish): its stamp gives an upper bound of +2 s, its sample
    of speed's frame a lower bound of +1 s. They cross the genuine bounds, the reset keeps the
    newest pair, the forged one: every genuine SPSS stamp is then moved a second later."""
    pair = _Pair(lambda _t: 0.1)                    # driving's clock 100 ms ahead
    for _ in range(100):
        pair.step()
    est = pair.me.estimates(pair.t)["driving"]
    assert est is not None and est.lo_s <= -0.1 <= est.hi_s          # genuine: holds the truth
    now = pair.t
    forged = ClockReport(source="driving", samples=(ClockSample("speed", now - 0.05, now - 1.05),))
    pair.me.received("driving", now, now - 2.0)      # _admit: the frame's (forged) stamp first,
    pair.me.report(forged)                           # then the report it carries
    stamp, sent_true = pair.peer_clock(now), now      # the next genuine SPSS, before any other
    assert pair.converted(stamp) <= sent_true, (
        f"converted {pair.converted(stamp) - sent_true:+.3f} s from the truth "
        f"(bounds {pair.me.estimates(pair.t)['driving']})")


def test_a_forged_sample_under_the_upper_bound_never_makes_a_stamp_later_than_sent():
    """Without crossing anything: a forged sample claiming speed's frame arrived the instant it
    was sent pulls lo_s up to hi_s, and hi_s includes the one-way delay."""
    pair = _Pair(lambda _t: 0.1)
    for _ in range(100):
        pair.step()
    hi = pair.me.estimates(pair.t)["driving"].hi_s
    now = pair.t
    pair.me.report(ClockReport(source="driving",
                               samples=(ClockSample("speed", now, now - hi + 1e-7),)))
    stamp, sent_true = pair.peer_clock(now), now
    assert pair.converted(stamp) <= sent_true + 1e-9, pair.converted(stamp) - sent_true


def test_a_peer_restarted_with_its_clock_ahead_never_has_its_stamps_later_than_sent():
    """driving's process dies and another starts on another machine (``--restart``), its clock
    80 ms ahead of the old one's. Its first frames contradict the old lower bounds, the offset
    becomes unknown, and an unknown offset converts nothing: its stamps pass 80 ms late (the
    speed server caps them at its own now, so its watchdog runs from reception, not sending;
    an authorization's issued_s within the driving module's 20 ms skew anchors later)."""
    pair = _Pair(lambda t: 0.0 if t < 1.0 else 0.08)
    worst = -math.inf
    for _ in range(150):
        stamp, sent_true = pair.step()
        worst = max(worst, pair.converted(stamp) - sent_true)
    assert worst <= 1e-9, f"a stamp converted {worst * 1e3:.1f} ms later than it was sent"


def test_a_peer_drifting_beyond_the_allowance_never_has_its_stamps_later_than_sent():
    """2000 ppm (chrony slews up to 83 333 ppm unless ``maxslewrate 500``): the lower bounds
    from driving's reports age faster than the 500 ppm allowance, the bounds cross, the reset
    pair crosses too, the offset is unknown most of the time and the stamps pass unconverted,
    100 ms late (driving's clock ahead). Now crossed bounds are all dropped and a peer known
    before converts fail-safe (an hour early) until measured again; before the crossing shows,
    the excess drift over a report's age is the residual: (2000 - 500) ppm x 0.2 s = 0.3 ms."""
    pair = _Pair(lambda t: 0.1 + 2000e-6 * t)
    worst = -math.inf
    for _ in range(1000):
        stamp, sent_true = pair.step()
        worst = max(worst, pair.converted(stamp) - sent_true)
    residual_s = (2000e-6 - 500e-6) * 0.2 + DELAY_S
    assert worst <= residual_s, f"a stamp converted {worst * 1e3:.2f} ms later than it was sent"


def test_a_report_with_huge_finite_times_moves_no_bound():
    """ClockSample(sent_s=1e308, received_s=-1e308) is finite, passes the wire, and its
    difference overflows to an infinite lower bound: the bounds cross, the offset turns
    unknown (so the stamps pass unconverted). A malformed sample must be rejected."""
    pair = _Pair(lambda _t: 0.1)
    for _ in range(100):
        pair.step()
    before = pair.me.estimates(pair.t)["driving"]
    pair.me.report(ClockReport(source="driving", samples=(ClockSample("speed", 1e308, -1e308),)))
    after = pair.me.estimates(pair.t)["driving"]
    assert after == before, (before, after)


def test_a_report_with_nan_bounds_is_never_judged_within_tolerance():
    """A node's report is one end of the launcher's pair table. NaN bounds (msgpack carries
    them) compare False with every limit: the pair is judged fine, silently."""
    views = {"launcher": {"speed": PeerBound("speed", -0.0002, 0.0002)},
             "speed": {"launcher": PeerBound("launcher", math.nan, math.nan)}}
    (row,) = pair_table(["launcher", "speed"], views)
    assert row["reason"] != "", row


def test_a_report_with_inverted_bounds_is_never_judged_within_tolerance():
    """lo_s > hi_s is no bound at all (a negative uncertainty); judged fine today."""
    views = {"launcher": {"speed": PeerBound("speed", -0.0002, 0.0002)},
             "speed": {"launcher": PeerBound("launcher", 0.2, -0.2)}}
    (row,) = pair_table(["launcher", "speed"], views)
    assert row["reason"] != "", row
