"""A short steady delay present from link-up is rated as the same delay arriving later
(lock-step, ``interface: jaus``, real UDP on loopback): no degraded link, no slower MOVE,
no failed run, when the round trip is within ``ROUND_TRIP_DEGRADED_S`` and no report is
older than ``AGE_DEGRADED_S``.
"""

from __future__ import annotations

import pytest

from overdrive.vehicle.xgv_client import AGE_DEGRADED_S, ROUND_TRIP_DEGRADED_S
from tests.xgv.test_xgv_command_delay import STEP_S
from tests.xgv.test_xgv_link_loss import MOVE_M, codes, run, truth


def delay(delay_s: float, direction: str) -> dict[str, object]:
    return {"at_s": 0.0, "delay": {"channel": "jaus", "for_s": 30, "delay_s": delay_s,
                                   "direction": direction}}


@pytest.mark.xfail(strict=True, reason="a report's age bound adds the whole shortest round trip "
                   "(both legs) to its excess and is judged against the one-way 50 ms bound: a "
                   "delay present from link-up reads as old reports")
@pytest.mark.parametrize(("delay_s", "direction", "report_delay_s"),
                         [(0.06, "to_vehicle", 0.0), (0.03, "both", 0.03)])
def test_a_short_delay_present_from_link_up_is_not_a_degraded_link(
        delay_s: float, direction: str, report_delay_s: float) -> None:
    """Measured 2026-11-26 (60 m MOVE at 8 m/s, wrench): 60 ms towards the vehicle only, from
    link-up: round trip 60 ms, reports undelayed, yet ``xgv_link_degraded`` at 0.18 s
    ("Velocity State 60 ms old"), max speed lowered (ground truth 6.69 m/s), exit 1; the same
    60 ms opened at 8 s: no fault, exit 0. 30 ms each way from link-up: round trip 60 ms,
    reports 30 ms late, same degraded fault, 6.69 m/s, exit 1 (docs/xgv.md's table: "20-30
    ms: nothing" holds only for a delay opened at cruise). Suspected cause:
    ``LinkTime.arrival`` returns excess + ``shortest_round_trip`` (an upper bound on the
    fastest delivery that counts both legs), while ``_age_check`` halves the probes' round
    trip for the same bound."""
    round_trip_s = 2 * delay_s if direction == "both" else delay_s
    assert round_trip_s <= ROUND_TRIP_DEGRADED_S and report_delay_s + STEP_S <= AGE_DEGRADED_S
    result, _, trace = run([delay(delay_s, direction)], control="wrench")
    summary = result.summary
    assert summary["link"]["probes"]["round_trip_ms"]["max"] == pytest.approx(
        1000.0 * round_trip_s, abs=0.5)
    assert "xgv_link_degraded" not in codes(summary, "fault")
    assert result.exit_code == 0
    assert truth(trace)[1][-1] > MOVE_M - 1.0


@pytest.mark.xfail(strict=True, reason="the age bound of an undelayed report is the whole "
                   "round trip when the delay was there from link-up: fresh reports read 200 "
                   "ms old")
def test_fresh_reports_over_a_link_delayed_towards_the_vehicle_from_link_up_are_not_old(
        ) -> None:
    """200 ms towards the vehicle only, from link-up (wrench): the reports are not delayed, the
    round trip is 200 ms, so the link is degraded (slower), as the same delay opened at
    cruise is (test_xgv_command_delay.py: degraded, MOVE completed). Measured 2026-11-26:
    ``xgv_report_age`` at 0.6 s ("Velocity State 200 ms old"), fault 1011/1012, the MOVE
    refused, the vehicle never moves (0.00 m). Safe, but the cause is false and the same
    link is rated two ways depending on when its delay began."""
    result, _, trace = run([delay(0.2, "to_vehicle")], control="wrench")
    summary = result.summary
    assert summary["link"]["probes"]["round_trip_ms"]["max"] == pytest.approx(200.0, abs=0.5)
    assert "xgv_report_age" not in codes(summary, "fault")
    assert max(truth(trace)[1]) > 10.0
