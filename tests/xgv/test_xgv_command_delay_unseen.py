"""Delays towards the vehicle the round-trip probes do not act on (lock-step, ``interface:
jaus``, real UDP on loopback), judged from ground truth (the simulated XGV's own x/speed in
the trace): an XGV whose Velocity State stamps are unset, an XGV that answers a probe with
every field, and a delay that lets one probe in six through promptly.

Each is a 0.5 s delay towards the vehicle on a 60 m MOVE at 8 m/s in wrench mode; the same
steady delay on a stamping, tag-answering XGV is stopped (``xgv_round_trip``, latched) before
any overspeed (tests/xgv/test_xgv_command_delay.py).
"""

from __future__ import annotations

from typing import Any

import pytest

import overdrive.vehicle.xgv as xgv_module
from overdrive.jaus import JausTimestamp, ReportVelocityState
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.vehicle.link_time import PROBE_TAGS
from tests.xgv.test_xgv_command_delay import assert_judged_safe, towards_vehicle
from tests.xgv.test_xgv_link_loss import (
    LIMIT_MPS,
    MOVE_M,
    SPEED_TOLERANCE_MPS,
    codes,
    run,
    truth,
)

ALL_FIELDS = 0x1FF         # every field of Velocity State (nine bits)
ACCELERATING_S = 5.5       # 7.4 m/s, still accelerating to the 8 m/s limit
SLOW_MOVE_M = 20.0
SLOW_LIMIT_MPS = 3.0


def unset_velocity_stamps(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulated XGV stamps its Velocity State all zeros (day 0), as OpenJAUS's Velocity
    State sensor does (docs/xgv.md, "Time from the source"); every other field as before."""
    present = xgv_module._present

    def zero_stamp(cls: type, values: dict[str, Any], presence: int) -> Any:
        if cls is ReportVelocityState and "timestamp" in values:
            values = {**values, "timestamp": JausTimestamp()}
        return present(cls, values, presence)

    monkeypatch.setattr(xgv_module, "_present", zero_stamp)


def answer_every_field(monkeypatch: pytest.MonkeyPatch) -> None:
    """The simulated XGV ignores a Query Velocity State's presence vector: every answer holds
    every field (a vendor component that answers queries with its full report)."""
    present = xgv_module._present

    def full(cls: type, values: dict[str, Any], presence: int) -> Any:
        if cls is ReportVelocityState and presence in PROBE_TAGS:
            presence = ALL_FIELDS
        return present(cls, values, presence)

    monkeypatch.setattr(xgv_module, "_present", full)


@pytest.mark.parametrize(("delay_s", "direction", "round_trip_s", "at_s"),
                         [(0.5, "to_vehicle", 0.5, 8.0), (0.15, "both", 0.3, ACCELERATING_S)])
def test_a_delay_on_a_link_to_an_xgv_with_unset_stamps_is_stopped_as_for_any_other(
        monkeypatch: pytest.MonkeyPatch, delay_s: float, direction: str,
        round_trip_s: float, at_s: float) -> None:
    """Measured 2026-11-26, delay from 5.5 s: 0.5 s towards the vehicle: the probes read it
    (321 sent, 311 answered, round trip median and max 500 ms), yet no fault, no stop: ground
    truth 9.17 m/s on the 8 m/s MOVE, 59.52 m; only the run's judge saw it (invariant speed).
    0.15 s each way (round trip 300 ms, read): no fault at all, 8.31 m/s, 58.78 m, exit 0 (a
    stamping XGV is stopped on the reports' age). Suspected cause: ``_age_check`` starts with
    ``if age_s is None: return`` (``report_age_s`` is set only from stamped reports), so the
    round-trip verdicts below it are unreachable: with unset stamps no delay is ever acted on.
    Fixed: the round trip is judged whether or not the age is known (0.5 s is taken at cruise:
    while still accelerating it is the documented residual of test_xgv_command_delay.py)."""
    unset_velocity_stamps(monkeypatch)
    event = towards_vehicle(delay_s, at_s=at_s)
    event["delay"]["direction"] = direction
    result, _, trace = run([event], control="wrench")
    summary = result.summary
    assert summary["link"]["probes"]["round_trip_ms"]["max"] == pytest.approx(
        1000.0 * round_trip_s, abs=0.5)
    assert "xgv_round_trip" in codes(summary, "fault")
    assert_judged_safe(trace, summary)


@pytest.mark.xfail(strict=True, reason="residual (docs/xgv.md): an XGV that answers probes with "
                   "every field leaves the round trip unmeasured (said once: "
                   "xgv_round_trip_unmeasured) and nothing else bounds a delay towards it")
def test_a_delay_towards_an_xgv_that_answers_probes_with_every_field_is_still_bounded(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Measured 2026-11-26: 160 probes sent, 0 answered as probes (the answers hold velocity x
    and are taken for speed samples), no fault: ground truth 9.17 m/s on the 8 m/s MOVE,
    59.50 m, exit 1 on the judge's invariant only. docs/xgv.md states the vehicle is then
    "left unmeasured"; the stack neither says so (no fault, no lower max speed) nor falls
    back to another bound, so the overspeed the probes were built for returns."""
    answer_every_field(monkeypatch)
    result, _, trace = run([towards_vehicle(0.5, at_s=ACCELERATING_S)], control="wrench")
    summary = result.summary
    assert summary["link"]["probes"]["answered"] == 0
    assert_judged_safe(trace, summary)


def test_an_xgv_that_answers_probes_with_every_field_is_said_to_be_unmeasured(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """No silent pass: the answers hold the speed (not a tag), so the client says once that a
    delay towards this vehicle is not measured; the run is not failed for it."""
    answer_every_field(monkeypatch)
    result, _, _ = run([], control="wrench")
    summary = result.summary
    assert summary["link"]["probes"]["answered"] == 0
    assert summary["link"]["probes"]["unmatched"] >= 10
    assert codes(summary, "fault") == ["xgv_round_trip_unmeasured"]
    assert summary["violations"] == []


def five_in_six_delayed(delay_s: float, from_s: float, until_s: float) -> list[dict[str, Any]]:
    """Delay windows 250 ms on, 50 ms off: of the six probes every 0.3 s one goes out in the
    gap and is answered promptly; five commands in six act ``delay_s`` late."""
    events = []
    at_s = from_s
    while at_s < until_s:
        events.append({"at_s": round(at_s, 3), "delay": {
            "channel": "jaus", "for_s": 0.25, "delay_s": delay_s, "direction": "to_vehicle"}})
        at_s += 0.3
    return events


def slow_move_run(events: list[dict[str, Any]]) -> tuple[Any, list[dict[str, Any]]]:
    """A 20 m MOVE at 3 m/s (wrench), otherwise as ``run``."""
    sc = parse_scenario({
        "name": "jaus-slow-move", "interface": "jaus", "control": "wrench",
        "vehicle": "escape-hybrid", "start": "ready", "seed": 1, "duration_s": 14.0,
        "events": [{"at_s": 0.5, "move": {"distance_m": SLOW_MOVE_M, "maxspeed_mps": SLOW_LIMIT_MPS,
                                          "curvature_1pm": 0}}, *events]}, "test")
    result = run_scenario(sc, None, keep_trace=True, nodes=build_nodes(sc), plot=False)
    return result, result.trace


@pytest.mark.parametrize(("limit_mps", "move_m"), [(LIMIT_MPS, MOVE_M),
                                                   (SLOW_LIMIT_MPS, SLOW_MOVE_M)])
def test_a_delay_on_five_commands_in_six_is_not_hidden_by_one_prompt_probe(
        limit_mps: float, move_m: float) -> None:
    """A link that delays towards the vehicle 0.5 s except for 50 ms in every 300 ms (a bonded
    or bursty radio link), from 0.5 s, wrench. Measured 2026-11-26: 60 m at 8 m/s: probes
    answered 312 of 321, round trip median 500 ms, p95 500 ms, yet never a window without a
    prompt answer, so no ``xgv_round_trip``, no ``xgv_link_degraded``, no stop: ground truth
    8.82 m/s on the 8 m/s MOVE (the judge's invariant only), 59.74 m. 20 m at 3 m/s: 4.44
    m/s (48 % over), 19.78 m, no link fault. Suspected cause: ``RoundTrips.round_trip_s``
    takes the minimum of the window, so the link is rated by its best probe; motion-profile
    mode held at 8 m/s (7.97 m/s) under the same link."""
    if limit_mps == LIMIT_MPS:
        result, _, trace = run(five_in_six_delayed(0.5, 0.5, 16.0), control="wrench")
    else:
        result, trace = slow_move_run(five_in_six_delayed(0.5, 0.5, 13.5))
    summary = result.summary
    assert summary["link"]["probes"]["round_trip_ms"]["median"] == pytest.approx(500.0, abs=0.5)
    assert "xgv_link_degraded" in codes(summary, "fault")
    _, x, v = truth(trace)
    assert max(x) <= move_m and max(v) <= limit_mps + SPEED_TOLERANCE_MPS, (max(x), max(v))
