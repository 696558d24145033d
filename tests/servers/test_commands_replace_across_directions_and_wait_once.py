"""Availability (issue 31 item 9), judged from the simulated vehicle's own x and speed.

Seed 004: "If a subsequent command is received before the current one has completed, the new
command replaces the current one and gets immediately executed." Seed 001: "When ready to start
motion from idle, request run, specifying a gear. The state will then progress from idle to
runwait to shifting to run" and "To come out of pause, request idle. The state will change to
runwait for the required five second delay". A change of direction is accepted while moving
(it stops first), and the vehicle waits in runwait once before each motion, never twice.
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.messages import Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.move_radar import RadarConfig
from overdrive.servers.speed import SpeedServerConfig
from tests.conftest import PRESET_NAMES
from tests.servers.move_harness import run_events, simulate

MOVING_MPS = 0.02   # first motion: above the plant's noise-free standstill
RUNWAIT_S = SpeedServerConfig().runwait_s


def leg(at_s: float, kind: str, distance_m: float, maxspeed_mps: float) -> dict[str, Any]:
    return {"at_s": at_s, kind: {"distance_m": distance_m, "maxspeed_mps": maxspeed_mps,
                                 "curvature_1pm": 0.0}}


MANOEUVRE = [leg(1.0, "move", 12.0, 5.0), leg(13.0, "reverse", 6.0, 2.5),
             leg(25.0, "move", 10.0, 5.0), leg(37.0, "reverse", 5.0, 2.5)]
"""Forward 12 m, reverse 6 m, forward 10 m, reverse 5 m, one command every 12 s: x = 11 m."""


def column(rows: list[dict[str, str]], name: str) -> list[tuple[float, float]]:
    return [(float(r["t_s"]), float(r[name])) for r in rows if r[name] != ""]


def runwaits(events: list[dict[str, Any]]) -> list[float]:
    return [e["t_s"] for e in events if e["kind"] == "speed_state" and e["to"] == "runwait"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_forward_reverse_manoeuvre_finishes_where_its_commands_end(preset: str) -> None:
    """Every command accepted (none ``busy``), never past an authorization (the judge), the
    final x within 0.3 m of 12 - 6 + 10 - 5 = 11 m, and one runwait per change of direction."""
    result = run_events(MANOEUVRE, vehicle=preset, duration_s=60.0)
    events = result.summary["events"]
    assert [e for e in events if e["kind"] == "rejected"] == []
    assert result.summary["violations"] == []
    assert result.summary["final"]["x_m"] == pytest.approx(11.0, abs=0.3)
    assert abs(result.summary["final"]["speed_mps"]) < 0.05
    assert len(runwaits(events)) == 3       # three changes of direction, one wait each


@pytest.mark.xfail(strict=True, reason=(
    "issue 31 item 9 left open: the terminal approach crawls its last metre at 0.3 m/s "
    "(creep_zone_m 1.0, kept: shorter, a brake found stuck at the stop overruns), so the "
    "reverse and forward legs are replaced before they end (x 6.02 m at 25 s still rolling)"))
def test_on_the_escape_every_leg_of_the_manoeuvre_ends_before_the_next_command() -> None:
    """12 s a leg: 5 s of runwait, the 0.5 s shift, and the leg itself. Each leg stands within
    0.25 m short of its end before the next command (at creep_zone_m 0.3-0.5 they do)."""
    rows = run_events(MANOEUVRE, vehicle="escape-hybrid", duration_s=60.0).trace
    x = dict(column(rows, "x_m"))
    speed = dict(column(rows, "speed_mps"))
    ends = [(13.0, 12.0, 1), (25.0, 6.0, -1), (37.0, 16.0, 1)]
    for t_next, end_m, sign in ends:
        t = round(t_next - 0.01, 2)
        assert abs(speed[t]) < 0.05, f"still moving at {t} s"
        assert 0.0 <= sign * (end_m - x[t]) <= 0.25, (t, x[t])


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("speed_mps", [2.0, 8.0])
def test_a_reverse_at_speed_replaces_the_move_and_stops_within_the_shortest_stop(
        preset: str, speed_mps: float) -> None:
    """The forward authorization is void at once (a stop now, like a STOP: the judge allows
    the shortest physical stop from the speed at the REVERSE, no more), then the vehicle
    shifts from idle and backs up."""
    events = [leg(0.5, "move", 60.0, speed_mps), leg(9.0, "reverse", 4.0, 2.5)]
    result = run_events(events, vehicle=preset, duration_s=30.0)
    s = result.summary
    assert s["violations"] == [], s["violation_details"]
    assert [e for e in s["events"] if e["kind"] == "rejected"] == []
    x = column(result.trace, "x_m")
    turn = max(x, key=lambda p: p[1])
    at_cmd = next(xm for t, xm in x if t >= 9.0)
    assert turn[0] > 9.0 and s["final"]["x_m"] < turn[1] - 3.0   # it stopped, then reversed
    assert any(e["kind"] == "hard_brake" for e in s["events"]) == (turn[1] - at_cmd > 0.2)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_from_parked_the_first_motion_follows_one_runwait(preset: str) -> None:
    """parked -> reset -> starting -> paused (engine start) -> runwait -> shifting -> run: one
    runwait. First motion within engine start + runwait + 1 s, plus the preset's shift time
    beyond 0.5 s (seed 001's "runwait to shifting to run": the Ranger's shift takes 1.5 s)."""
    run = simulate({"vehicle": preset, "start": "parked", "duration_s": 16.0,
                    "events": [leg(1.0, "move", 10.0, 3.0)]})
    events = run.summary["events"]
    paused_s = next(e["t_s"] for e in events if e["kind"] == "speed_state" and e["to"] == "paused")
    first_s = next(t for t, v in run.column("speed_mps") if abs(v) > MOVING_MPS)
    shift_s = PRESETS[preset].shift_time_s
    assert len(runwaits(events)) == 1
    assert first_s - paused_s >= RUNWAIT_S
    assert first_s - 1.0 <= (paused_s - 1.0) + RUNWAIT_S + max(shift_s - 0.5, 0.0) + 1.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_out_of_a_pause_a_new_move_waits_one_runwait(preset: str) -> None:
    events = [leg(0.5, "move", 8.0, 3.0), {"at_s": 9.0, "safestop": "pause"},
              {"at_s": 10.0, "safestop": "run"}, leg(11.0, "move", 8.0, 3.0)]
    run = simulate({"vehicle": preset, "start": "ready", "duration_s": 24.0, "events": events},
                   keep=(Topic.SPEED_STATE,))
    waits = [t for t in runwaits(run.summary["events"]) if t > 10.0]
    first_s = next(t for t, v in run.column("speed_mps") if t > 11.0 and abs(v) > MOVING_MPS)
    assert len(waits) == 1
    assert RUNWAIT_S <= first_s - 11.0 <= RUNWAIT_S + PRESETS[preset].shift_time_s + 0.5


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("friction", "grade"), [
    pytest.param(0.8, 0.0, marks=pytest.mark.variant_edge), (0.8, 5.0), (0.8, -5.0),   # dry
    (0.3, 5.0), (0.3, 0.0),                # low grip: a fixed 2.5 m/s stopped in 0.96-1.28 m
    pytest.param(0.2, 0.0, marks=pytest.mark.variant_edge),
])
def test_a_stop_from_the_reverse_speed_ends_within_the_blind_allowance(
        preset: str, friction: float, grade: float) -> None:
    """A STOP sent while backing at the reverse speed stops the vehicle within
    ``reverse_blind_m`` (no rear sensor: the unverified ground a REVERSE may enter), on dry
    ground at 2.5 m/s and on low grip at the speed the braking then allows
    (``MoveServer._reverse_stop_cap_mps``)."""
    cfg = RadarConfig()
    world = {"grade_percent": grade, "friction": friction}
    base = [leg(0.5, "move", 20.0, 4.0), leg(12.0, "reverse", 15.0, cfg.reverse_max_speed_mps)]
    probe = run_events(base, vehicle=preset, duration_s=30.0, world=world)
    top = min(v for _, v in column(probe.trace, "speed_mps"))
    assert -cfg.reverse_max_speed_mps - 0.3 <= top < -1.0    # still a useful reverse
    at_s = next(t for t, v in column(probe.trace, "speed_mps") if v < 0.95 * top)
    result = run_events([*base, {"at_s": round(at_s, 2), "stop": {}}], vehicle=preset,
                        duration_s=30.0, world=world)
    x = column(result.trace, "x_m")
    x_stop = next(xm for t, xm in x if t >= round(at_s, 2))
    assert result.summary["violations"] == []
    assert 0.0 < x_stop - x[-1][1] <= cfg.reverse_blind_m
