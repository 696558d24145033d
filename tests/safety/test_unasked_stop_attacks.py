"""Attacks on the unasked-stop latch and the stall handling (issue 38), judged from ground truth
(the trace's odometer / speed), never from what the stack believes. Lock-step whole runs."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingConfig
from overdrive.servers.speed import SpeedServer
from tests.conftest import PRESET_NAMES, reachable_mps
from tests.safety.fault_runs import move, run
from tests.safety.test_unasked_stops import RestartingNode, first_rest_s, stall, travel_m

DISTANCE_M = 60.0


def _truth_odometer_m(result: Any) -> float:
    return float(result.trace[-1]["odometer_m"])


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("speed_mps", "at_s", "for_s"), [(4.0, 12.0, 3.0), (8.0, 7.0, 3.0),
                                                          (8.0, 7.0, 5.0)])
def test_a_move_server_stall_never_reports_done_short_of_the_distance(
        preset: str, speed_mps: float, at_s: float, for_s: float) -> None:
    """The move server stalls mid-MOVE (no other node does). Found: it resumes, reports the MOVE
    done (phase idle, remaining 0, no notice) while the vehicle stands 6.2-20.2 m short (escape
    4 m/s, 3 s at 12 s: 53.33 m of 60, the server believes 59.81; 8 m/s, 5 s at 7 s: 39.79 m).
    The planner's idea of where the vehicle is is then wrong by that much (a REVERSE back to
    the start overshoots it by the same). Either the MOVE ends at its distance, or the move
    server says it did not (an interruption / failure notice, not ``done``).

    Now: queued sensor samples count at their own time (``servers.move_arrivals``), so the
    server's progress is the vehicle's (within 0.01 m), and the stall is an interruption
    (the driving module stopped the vehicle 0.2 s into it: loss of command traffic)."""
    result = run(preset, [move(0.5, DISTANCE_M, reachable_mps(preset, speed_mps)),
                          stall(at_s, "move", for_s)], duration_s=at_s + for_s + 15.0)
    server = result.nodes["move"]
    reported = [e for e in result.summary["events"]
                if e["kind"] in ("interrupted", "move_failed", "fault")]
    odometer_m = _truth_odometer_m(result)
    believed_m = server.progress_m("forward")
    assert abs(believed_m - odometer_m) <= 0.5 or reported, (odometer_m, believed_m)
    assert odometer_m >= DISTANCE_M - 0.5 or server.phase != "idle" or reported, odometer_m
    # and both: the distance counted is the vehicle's, and the stall is reported
    assert abs(believed_m - odometer_m) <= 0.05, (odometer_m, believed_m)
    assert server.phase == "interrupted" and any(e["kind"] == "interrupted" for e in reported)


@pytest.mark.parametrize("gap_s", [0.0, 0.15])
def test_the_judge_flags_a_set_speed_run_driving_on_after_a_speed_server_restart(
        gap_s: float) -> None:
    """A set_speed run from parked (the scenario is the speed server's client, repeating the same
    ``run``); at 40 s the speed server restarts (a fresh process, built as the run builds it:
    parked), down for less than the vehicle's 200 ms command timeout (an XGV's is 0.5 s). Found:
    the fresh server brings the vehicle to rest (41.06 s), then takes the repeated old run
    through its runwait and drives 61-62 m on by itself; no e-stop, no violation. The docs leave
    the latch to the client (it must watch ``started_s``); the judge must then flag the motion
    (the client never changed its request: no new command)."""
    params = PRESETS["escape-hybrid"]
    events: list[dict] = [{"at_s": 1.0, "set_speed": {"speed_mps": 8.0, "accel_mps2": 1.5,
                                                      "gear": "drive", "state": "run"}}]
    if gap_s:
        events.append(stall(40.0, "speed", gap_s))
    scenario = parse_scenario({"name": "restart", "vehicle": "escape-hybrid", "start": "parked",
                               "duration_s": 60.0, "seed": 7, "events": events})
    nodes = [RestartingNode(n, 40.0 + gap_s, lambda: SpeedServer(params, initial_state="parked"))
             if n.name == "speed" else n for n in build_nodes(scenario)]
    result = run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)
    moved_m = travel_m(result, first_rest_s(result, 40.0))
    assert moved_m > 10.0                              # ground truth: it drove on by itself
    rules = {d["rule"] for d in result.summary["violation_details"]}
    assert "unintended_motion" in rules, (moved_m, result.summary["violations"])


@pytest.mark.parametrize("for_s", [1.0, 2.0])
def test_a_stop_issued_while_the_move_server_is_stalled_still_stops_within_its_distance(
        for_s: float) -> None:
    """8 m/s, the move server stalls at 7.0 s, the planner's STOP comes at 7.05 s. Found: the
    vehicle passes the STOP's end (the judge's authorization invariant) by 6.02 m (1 s stall)
    and 9.69 m (2 s): the STOP acts only when the move server resumes. The same STOP after the
    stall (8.9 s) is honoured with no violation.

    A stalled process cannot read a STOP: no fix makes this overrun 0 (the STOP may come 1 ms
    into the stall). What the stack can bound is the time it drives on without command
    traffic: the driving module stops the vehicle as a STOP would (hard braking) once the move
    server's stream (every 10 ms) has been quiet for ``command_silence_s`` (0.2 s). So the
    vehicle stops within the STOP's distance plus what it travels in that bound (and the one
    10 ms period in which the stop is sent) at the STOP's speed; this test holds it to exactly
    that (measured: 0.95 m past, 7.48 m/s at the STOP, bound 1.57 m; the STOP came 0.05 s into
    the stall, so 0.16 s of the bound, 1.2 m, was expected), with the loss reported by the
    driving module and latched by the move server, and the vehicle at rest for good after."""
    result = run("escape-hybrid", [move(0.5, DISTANCE_M, 8.0), stall(7.0, "move", for_s),
                                   {"at_s": 7.05, "stop": {}}], duration_s=25.0)
    at_stop = next(r for r in result.trace if float(r["t_s"]) >= 7.05 - 1e-9)
    bound_m = float(at_stop["speed_mps"]) * (DrivingConfig().command_silence_s + 0.01)
    overruns = [d for d in result.summary["violation_details"]
                if d["rule"].startswith("authorization")]
    assert all(d["amount"] <= bound_m for d in overruns), (bound_m, result.summary["violations"])
    codes = {(e["kind"], e.get("source"), e.get("code")) for e in result.summary["events"]}
    assert ("fault", "driving", "command_silence") in codes
    assert any(kind == "interrupted" and source == "move" for kind, source, _ in codes)
    rest_s = first_rest_s(result, 7.05)
    assert travel_m(result, rest_s) < 0.01            # nothing moves after the stop


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_the_judge_flags_a_set_speed_run_driving_on_after_an_engine_stall(preset: str) -> None:
    """A set_speed run (the scenario repeats one ``run``); the engine stalls at 10 s. Found: the
    vehicle comes to rest (11.06 s escape, 11.25 s ranger), the speed server restarts the
    engine, goes through its runwait and drives the unchanged old run on: 152 m (escape), 127 m
    (ranger) by 40 s, with no new command, no e-stop, no violation. ``SpeedState.unasked_stops`` counts
    the stall (docs/speed-server.md: a client latches on any rise); the client here does not,
    and the judge must say so as it does for a watchdog stop."""
    gear = PRESETS[preset].drive_gear
    result = run(preset, [{"at_s": 1.0, "set_speed": {"speed_mps": 8.0, "accel_mps2": 1.5,
                                                      "gear": gear, "state": "run"}},
                          {"at_s": 10.0, "engine_stall": {}}], duration_s=40.0)
    moved_m = travel_m(result, first_rest_s(result, 10.0))
    assert moved_m > 10.0                              # ground truth: it drove on by itself
    rules = {d["rule"] for d in result.summary["violation_details"]}
    assert "unintended_motion" in rules, (moved_m, result.summary["violations"])


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("for_s", [3.0, 5.0])
def test_after_a_move_server_stall_stopped_the_vehicle_nothing_moves_until_a_new_command(
        preset: str, for_s: float) -> None:
    """4 m/s, the move server stalls at 5 s. The driving module uses up the authorization it
    holds and stops the vehicle (escape: at rest 7.69 s at 17.43 m): a stop nobody asked for.
    Found: when the move server resumes (8 s, 10 s) it drives the old MOVE on by itself: 36.2 m
    after 0.31 s at rest, 28.4 m after 2.31 s at rest (ranger 36.5 / 28.8 m), with no new
    command, no notice and no violation. H59: once stopped by a stall, the command in force is
    discarded and the vehicle stays until a new command. Now: the driving module stops the
    vehicle 0.2 s into the silence (escape at rest 5.75 s at 13.91 m) and holds the move
    server's authorization at 0 until it sends 0; the resumed server latches its own stall
    (``interrupted``, ``move_stall``)."""
    result = run(preset, [move(0.5, DISTANCE_M, reachable_mps(preset, 4.0)),
                          stall(5.0, "move", for_s)], duration_s=5.0 + for_s + 20.0)
    rest_s = first_rest_s(result, 5.0)
    assert rest_s < 5.0 + for_s                        # at rest during the stall (ground truth)
    assert travel_m(result, rest_s) < 0.01, (rest_s, travel_m(result, rest_s))
