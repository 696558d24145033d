"""Clock offsets between processes (servers.clock_offset): the per-peer table fed by frames and
reports, the conversion of a peer's dates to this clock (earliest plausible), and the launcher's
pair table with its tolerance. Pure: the clocks are numbers passed in."""

from __future__ import annotations

import math

import pytest

from overdrive.messages import AdvanceAuthorization, MaxSpeed, MoveCommand
from overdrive.servers.clock_offset import (
    MAX_CLOCK_OFFSET_S,
    MAX_CLOCK_UNCERTAINTY_S,
    OffsetEstimate,
    PeerBound,
    PeerClocks,
    describe_pair,
    earliest_s,
    out_of_tolerance,
    pair_table,
    restamped,
)


def _exchange(a: PeerClocks, b: PeerClocks, b_ahead_s: float, steps: int = 20,
              delay_ab_s: float = 0.002, delay_ba_s: float = 0.003) -> float:
    """Frames both ways every 10 ms and a report each way every 100 ms; ``b``'s clock reads
    ``b_ahead_s`` more than ``a``'s. Returns ``a``'s time at the end."""
    t = 10.0
    for k in range(steps):
        b.sent(t + b_ahead_s)                                       # each publishes ...
        a.sent(t)
        a.received("b", t + delay_ba_s, t + b_ahead_s)              # b sent at t (its clock)
        b.received("a", t + delay_ab_s + b_ahead_s, t)              # a sent at t
        if k % 10 == 9:
            b.report(a.make_report(t))
            a.report(b.make_report(t + b_ahead_s))
        t += 0.01
    return t


def test_each_side_bounds_the_other_from_frames_and_the_others_report():
    a, b = PeerClocks("a"), PeerClocks("b")
    assert a.estimates(0.0) == {}
    t = _exchange(a, b, b_ahead_s=0.1)
    est_a, est_b = a.estimates(t)["b"], b.estimates(t + 0.1)["a"]
    assert est_a is not None and est_b is not None
    assert est_a.lo_s <= -0.1 <= est_a.hi_s and est_b.lo_s <= 0.1 <= est_b.hi_s
    # the width is the round trip (2 + 3 ms) plus the drift allowance since the samples
    assert est_a.uncertainty_s == pytest.approx(0.005, abs=0.001)
    assert set(a.latest) == {"b"} and a.latest["b"].source == "b"


def test_one_direction_alone_leaves_the_offset_unknown():
    a = PeerClocks("a")
    a.received("b", 1.0, 0.9)
    assert a.estimates(1.0) == {"b": None}


def test_own_frames_and_own_reports_are_not_samples():
    a = PeerClocks("a")
    a.received("a", 1.0, 0.5)
    a.report(a.make_report(1.0))
    assert a.peers == {} and a.latest == {}


def test_a_report_carries_the_fastest_frame_since_the_last_one():
    a = PeerClocks("a")
    a.received("b", 1.010, 1.000)
    a.received("b", 1.021, 1.020)        # the fastest: 1 ms
    a.received("b", 1.035, 1.030)
    report = a.make_report(1.04)
    assert [(s.peer, s.sent_s, s.received_s) for s in report.samples] == [("b", 1.020, 1.021)]
    assert report.bounds == ()            # no lower bound yet: nothing to report of b
    assert a.make_report(1.05).samples == ()


def test_a_peers_date_is_converted_to_the_earliest_it_can_have_been():
    est = OffsetEstimate(lo_s=0.178, hi_s=0.182)
    assert earliest_s(1.0, est) == pytest.approx(1.178)
    assert earliest_s(1.0, None) == 1.0   # unknown: one host, one clock
    adv = AdvanceAuthorization(source="move", distance_m=5.0, issued_s=2.0)
    limit = MaxSpeed(source="move", speed_mps=3.0, issued_s=2.0)
    assert restamped(adv, est).issued_s == pytest.approx(2.178)
    assert restamped(limit, est).issued_s == pytest.approx(2.178)
    assert restamped(limit, est).speed_mps == 3.0
    undated = AdvanceAuthorization(source="move", distance_m=5.0)
    assert restamped(undated, est) is undated
    assert restamped(adv, None) is adv
    move = MoveCommand(kind="move", issued_s=2.0)      # the move server handles the planner's clock
    assert restamped(move, est) is move


def test_tolerance_needs_a_known_small_offset_and_a_narrow_uncertainty():
    assert out_of_tolerance(None) == "offset unknown"
    assert out_of_tolerance(OffsetEstimate(0.099, 0.101)) == ""
    assert out_of_tolerance(OffsetEstimate(-0.401, -0.399)).startswith("offset beyond")
    wide = OffsetEstimate(0.0, MAX_CLOCK_UNCERTAINTY_S + 0.01)
    assert out_of_tolerance(wide).startswith("uncertainty beyond")
    edge = MAX_CLOCK_OFFSET_S
    assert out_of_tolerance(OffsetEstimate(edge - 0.001, edge + 0.001)) == ""


def test_the_pair_table_gives_b_minus_a_from_both_ends_and_says_why_a_pair_may_not_engage():
    views = {
        "launch": {"speed": PeerBound("speed", -0.102, -0.099), "driving": PeerBound("driving", 0.079, 0.081)},
        "speed": {"launch": PeerBound("launch", 0.0995, 0.1015, resets=1),
                  "driving": PeerBound("driving", 0.179, 0.181)},
        "driving": {"launch": PeerBound("launch", -0.081, -0.079)},  # no bound on speed yet
    }
    rows = {(r["a"], r["b"]): r for r in pair_table(["launch", "speed", "driving"], views)}
    assert list(rows) == [("launch", "speed"), ("launch", "driving"), ("speed", "driving")]
    ls = rows[("launch", "speed")]
    assert (ls["lo_s"], ls["hi_s"]) == pytest.approx((0.0995, 0.1015))   # both ends intersected
    assert ls["offset_s"] == pytest.approx(0.1005) and ls["uncertainty_s"] == pytest.approx(0.002)
    assert ls["resets"] == 1 and ls["reason"] == ""
    assert rows[("launch", "driving")]["offset_s"] == pytest.approx(-0.08)
    sd = rows[("speed", "driving")]
    assert sd["offset_s"] == pytest.approx(-0.18) and sd["reason"] == "offset unknown"  # driving's end
    assert describe_pair(ls) == ("clocks launch-speed: speed's clock 100.5 ms ahead of launch's "
                                 "(uncertainty 2.0 ms)")
    assert "behind speed's" in describe_pair(sd) and sd["reason"] in describe_pair(sd)


def test_a_pair_nobody_measured_is_unknown():
    (row,) = pair_table(["a", "b"], {})
    assert row["offset_s"] is None and row["reason"] == "offset unknown"
    assert describe_pair(row) == "clocks a-b: offset unknown"
    assert not math.isnan(row["resets"])
