"""Stops the stack did not ask for (a watchdog e-stop, the vehicle's command timeout, a stalled
node) are latched like the seed-000 interruptions: the command in force is discarded, nothing
moves until a new command, and a resumed process never jumps. Judged from ground truth (the
trace's x / odometer / speed) and the judge's violations; whole runs of a 60 m MOVE."""

from __future__ import annotations

import itertools
from typing import Any

import pytest

from overdrive.messages import (
    MoveCommand,
    MoveReply,
    Notice,
    PedalCommand,
    PowertrainCommand,
    SetSpeed,
    SpeedState,
    Topic,
    Truth,
)
from overdrive.observe.judge import Monitor
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import ScenarioError, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingModule
from overdrive.servers.speed import SpeedServer
from overdrive.vehicle.plant import World
from overdrive.vehicle.sim_node import VehicleSim
from tests.conftest import PRESET_NAMES, reachable_mps
from tests.safety.fault_runs import move, run

DISTANCE_M = 60.0
REST_MPS = 0.01


def stall(at_s: float, node: str, for_s: float) -> dict:
    return {"at_s": at_s, "stall": {"node": node, "for_s": for_s}}


def drop(at_s: float, channel: str, for_s: float) -> dict:
    return {"at_s": at_s, "drop": {"channel": channel, "for_s": for_s}}


def rows(result: Any, from_s: float = 0.0, to_s: float = 1e9) -> list[dict]:
    return [r for r in result.trace if from_s - 1e-9 <= float(r["t_s"]) <= to_s + 1e-9]


def first_rest_s(result: Any, after_s: float) -> float:
    """When the vehicle first stands (ground truth) after ``after_s``."""
    return next(float(r["t_s"]) for r in rows(result, after_s)
                if abs(float(r["speed_mps"])) < REST_MPS)


def travel_m(result: Any, from_s: float, to_s: float = 1e9) -> float:
    odo = [float(r["odometer_m"]) for r in rows(result, from_s, to_s)]
    return max(odo) - min(odo)


def interruptions(result: Any) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == "interrupted"]


# --------------------------------------------------------------------------- the latch

@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_after_a_watchdog_stop_nothing_moves_until_a_new_command(preset: str) -> None:
    speed = reachable_mps(preset, 8.0)
    result = run(preset, [move(0.5, DISTANCE_M, speed), drop(8.0, "set_speed", 0.3),
                          move(20.0, 5.0, 3.0)], duration_s=40.0)
    assert result.summary["violations"] == []
    [interrupted] = interruptions(result)
    assert interrupted["code"] == "watchdog" and interrupted["source"] == "move"
    assert 8.0 <= interrupted["t_s"] <= 8.35
    rest_s = first_rest_s(result, 8.0)
    assert travel_m(result, rest_s, 20.0) < 0.01          # the old MOVE never resumes
    assert float(rows(result, 8.0)[0]["odometer_m"]) < DISTANCE_M - 10.0
    # the new command drives, through the runwaits (paused -> runwait -> idle -> runwait -> run,
    # as after a seed-000 interruption), and only its own 5 m
    moving = [float(r["t_s"]) for r in rows(result, 20.0) if float(r["speed_mps"]) > 0.05]
    assert moving and moving[0] >= 25.0
    assert 4.0 < travel_m(result, 20.0) <= 5.0 + 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_the_move_server_reports_the_interruption_in_its_status(preset: str) -> None:
    result = run(preset, [move(0.5, DISTANCE_M, reachable_mps(preset, 6.0)),
                          drop(6.0, "set_speed", 0.5)], duration_s=12.0)
    move_server = result.nodes["move"]
    assert move_server.phase == "interrupted" and move_server.active is None
    assert result.summary["final"]["speed_state"] == "paused"


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_stalled_driving_module_is_latched_like_a_watchdog_stop(preset: str) -> None:
    result = run(preset, [move(0.5, DISTANCE_M, reachable_mps(preset, 8.0)),
                          stall(8.0, "driving", 0.3)], duration_s=22.0)
    assert result.summary["violations"] == []
    assert [e["code"] for e in interruptions(result)] == ["watchdog"]
    assert travel_m(result, first_rest_s(result, 8.0)) < 0.01


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_stalled_speed_server_resumes_without_a_throttle_jump(preset: str) -> None:
    """A 0.3 s stall: past the vehicle's 200 ms command timeout, which brakes; on resume the
    speed server steps once over the whole stall and must not wind up (before: 100 % throttle
    for 330 ms, 8.20 m/s on an 8 m/s MOVE). It stops, latched, reported as command_timeout."""
    speed = reachable_mps(preset, 8.0)
    result = run(preset, [move(0.5, DISTANCE_M, speed), stall(8.0, "speed", 0.3)],
                 duration_s=22.0)
    assert result.summary["violations"] == []
    before = max(float(r["throttle_cmd_pct"]) for r in rows(result, 7.9, 8.0))
    after = max(float(r["throttle_cmd_pct"]) for r in rows(result, 8.3, 9.0))
    assert after <= before + 1e-6
    assert max(float(r["speed_mps"]) for r in result.trace) <= speed + 0.05
    assert [e["code"] for e in interruptions(result)] == ["command_timeout"]
    assert travel_m(result, first_rest_s(result, 8.0)) < 0.01


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_short_speed_server_stall_carries_on_with_no_harder_a_throttle(preset: str) -> None:
    """0.1 s, under every timeout: the MOVE carries on; the first throttle after the gap is no
    more than the one before it, and the loop then rises at no more than its slew limit."""
    speed = reachable_mps(preset, 6.0)
    result = run(preset, [move(0.5, DISTANCE_M, speed), stall(3.0, "speed", 0.1)],
                 duration_s=25.0)
    assert result.summary["violations"] == []
    assert interruptions(result) == []
    before = float(rows(result, 2.99, 2.99)[0]["throttle_cmd_pct"])
    trail = [float(r["throttle_cmd_pct"]) for r in rows(result, 3.1, 3.3)]
    assert trail[0] <= before + 1e-6
    assert all(b - a <= 300.0 * 0.01 + 1e-6 for a, b in itertools.pairwise(trail))
    assert result.summary["odometer_m"] == pytest.approx(DISTANCE_M, abs=0.5)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_stop_whose_speed_state_reports_were_all_lost_still_latches(preset: str) -> None:
    """SpeedState is a droppable state topic: every report of a watchdog stop lost. Was: the
    speed server cleared its stop on the driving module's next non-moving request and the old
    MOVE drove on (26.6 m, the judge's unintended motion). Now the move server latches on the
    rise of ``SpeedState.unasked_stops`` it sees after the loss."""
    result = run(preset, [move(0.5, DISTANCE_M, reachable_mps(preset, 8.0)),
                          drop(7.9, "speed_state", 3.0), drop(8.0, "set_speed", 0.3)],
                 duration_s=30.0)
    assert result.summary["violations"] == []
    [interrupted] = interruptions(result)
    assert interrupted["source"] == "move" and 10.9 <= interrupted["t_s"] <= 11.0
    assert travel_m(result, first_rest_s(result, 8.0)) < 0.01


class RestartingNode:
    """A node replaced by a fresh instance at ``at_s``, as a process restarted between two of
    its steps (lock-step: no gap, so no watchdog of anyone else sees it)."""

    def __init__(self, node: Any, at_s: float, fresh: Any) -> None:
        self.node, self.at_s, self.fresh = node, at_s, fresh
        self.name, self.period_s, self.subscriptions = node.name, node.period_s, node.subscriptions

    def step(self, now_s: float, inbox: Any) -> list:
        if self.fresh is not None and now_s >= self.at_s - 1e-9:
            self.node, self.fresh = self.fresh(), None
        return self.node.step(now_s, inbox)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.node, name)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("initial_state", ["run", "parked"])
@pytest.mark.parametrize("gap_s", [0.0, 0.3])
def test_a_restarted_speed_server_does_not_drive_the_old_command_on(
        preset: str, initial_state: str, gap_s: float) -> None:
    """The speed server restarts mid-MOVE (a fresh process, built as a run builds it: in run
    for a ready vehicle, else parked) with its client still in run. Was: the fresh server, with
    no latch of its own, took the old run (at once, or after its runwait) and the MOVE went on.
    Now its later ``SpeedState.started_s`` is an unasked stop to the move server: interrupted,
    at rest for good."""
    params = PRESETS[preset]
    events = [move(0.5, DISTANCE_M, reachable_mps(preset, 8.0))]
    if gap_s:   # down for a while: the vehicle's command timeout brakes meanwhile
        events.append(stall(8.0, "speed", gap_s))
    data = {"name": "restart", "vehicle": preset, "start": "ready", "duration_s": 25.0,
            "seed": 7, "events": events}
    scenario = parse_scenario(data)
    nodes = [RestartingNode(n, 8.0 + gap_s, lambda: SpeedServer(
        params, initial_state=initial_state,
        initial_gear=params.drive_gear if initial_state == "run" else None))
             if n.name == "speed" else n for n in build_nodes(scenario)]
    result = run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)
    assert travel_m(result, first_rest_s(result, 8.0)) < 0.01
    assert result.summary["odometer_m"] < DISTANCE_M - 10.0
    assert [e["code"] for e in interruptions(result)] == ["restart"]
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("gap_s", [0.0, 0.3])
def test_a_restarted_driving_module_never_drives_on_by_itself(preset: str, gap_s: float) -> None:
    """The driving module holds no command of its own (the move server's is in force and it
    re-sends it). Restarted with no gap: no stop happened, the MOVE carries on to its end, no
    overrun. Restarted after 0.3 s down: the SPSS watchdog's stop, which the move server
    latches (1001): at rest for good."""
    params = PRESETS[preset]
    events = [move(0.5, DISTANCE_M, reachable_mps(preset, 8.0))]
    if gap_s:
        events.append(stall(8.0, "driving", gap_s))
    scenario = parse_scenario({"name": "restart", "vehicle": preset, "start": "ready",
                               "duration_s": 25.0, "seed": 7, "events": events})
    nodes = [RestartingNode(n, 8.0 + gap_s, lambda n=n: DrivingModule(
        params, config=n.config, friction=scenario.spec.world.friction))
             if n.name == "driving" else n for n in build_nodes(scenario)]
    result = run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)
    assert result.summary["violations"] == []
    assert result.summary["odometer_m"] <= DISTANCE_M + 0.05
    if gap_s:
        assert [e["code"] for e in interruptions(result)] == ["watchdog"]
        assert travel_m(result, first_rest_s(result, 8.0)) < 0.01
    else:
        assert interruptions(result) == []
        assert result.summary["odometer_m"] == pytest.approx(DISTANCE_M, abs=0.5)


# --------------------------------------------------------------------------- sweep

@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("speed_mps", [4.0, 8.0])
@pytest.mark.parametrize("for_s", [0.1, 0.25, 0.5, 1.0, 2.0])
@pytest.mark.parametrize("node", ["speed", "driving", "move"])
@pytest.mark.parametrize("at_s", [4.0, 7.5])
def test_a_stalled_node_never_overruns_speeds_or_drives_on_by_itself(
        preset: str, speed_mps: float, for_s: float, node: str, at_s: float) -> None:
    speed = reachable_mps(preset, speed_mps)
    result = run(preset, [move(0.5, DISTANCE_M, speed), stall(at_s, node, for_s)],
                 duration_s=22.0 + for_s)
    assert result.summary["violations"] == []       # judge: no overrun, no unintended motion
    assert max(float(r["speed_mps"]) for r in result.trace) <= speed + 0.1
    assert result.summary["odometer_m"] <= DISTANCE_M + 0.05
    stopped = interruptions(result)
    if stopped:   # a stop it did not ask for: at rest for good
        assert travel_m(result, first_rest_s(result, at_s)) < 0.01
    else:         # under every timeout: the MOVE carries on to its end
        assert for_s < 0.2
        assert result.summary["odometer_m"] == pytest.approx(DISTANCE_M, abs=0.5)


# --------------------------------------------------------------------------- the vehicle

def test_the_vehicles_command_timeout_brake_holds_until_a_runwait() -> None:
    params = PRESETS["escape-hybrid"]
    vehicle = VehicleSim(params, World(), 1, ready=True)
    go = PedalCommand(throttle_pct=20.0, brake_pct=0.0, source="speed")
    drive = PowertrainCommand(gear=params.drive_gear, engine_on=True, source="speed")
    horn = PowertrainCommand(gear=params.drive_gear, engine_on=True, horn=True, park_brake=True,
                             source="speed")
    t = 0.0
    for _ in range(10):
        vehicle.step(t, [(Topic.PEDALS, go), (Topic.POWERTRAIN, drive)])
        t += 0.01
    out = []
    for _ in range(25):                       # silence past 200 ms: the timeout brakes
        out += vehicle.step(t, [])
        t += 0.01
    assert any(isinstance(m, Notice) and m.code == "command_timeout" for _, m in out)
    assert vehicle.timeout_latched
    for _ in range(20):                       # commands resume: still braked, still reported
        out = vehicle.step(t, [(Topic.PEDALS, go), (Topic.POWERTRAIN, drive)])
        t += 0.01
    assert vehicle.brake_pct == 100.0 and vehicle.throttle_pct == 0.0
    assert next(m for _, m in out if _ == Topic.VEHICLE_STATUS).command_timeout
    vehicle.step(t, [(Topic.PEDALS, PedalCommand(throttle_pct=0.0, brake_pct=100.0,
                                                 source="speed")), (Topic.POWERTRAIN, horn)])
    assert not vehicle.timeout_latched        # the runwait is the deliberate restart


# --------------------------------------------------------------------------- the judge

def _truth(x_m: float, speed_mps: float) -> Truth:
    return Truth(x_m=x_m, y_m=0.0, heading_rad=0.0, speed_mps=speed_mps, accel_mps2=0.0,
                 lat_accel_mps2=0.0, curvature_1pm=0.0, pitch_rad=0.0, roll_rad=0.0,
                 odometer_m=x_m, slip=False, contact=False)


@pytest.mark.parametrize("new_command", [False, True])
def test_the_judge_flags_motion_after_a_watchdog_stop_without_a_new_command(
        new_command: bool) -> None:
    monitor = Monitor(PRESETS["escape-hybrid"], 1.0, 0.01)
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, distance_m=100.0,
                                                    maxspeed_mps=5.0))
    monitor.observe(Topic.MOVE_REPLY, MoveReply(command_id=1, kind="move", accepted=True))
    monitor.observe_delivered(Topic.SET_SPEED, SetSpeed(speed_mps=1, accel_mps2=1, gear="drive",
                                                        state="run"))
    x = 0.0
    for tick in range(1, 300):                # SPSS lost at 0 s; at rest from 0.5 s ...
        now = round(tick * 0.01, 6)
        monitor.now_s = now
        speed = 0.0 if 0.5 <= now < 2.0 else 1.0   # ... then it moves on by itself
        if now >= 0.5 and speed:
            x += 0.01 * speed
        if new_command and tick == 150:
            monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=2,
                                                            distance_m=100.0, maxspeed_mps=5.0))
            monitor.observe(Topic.MOVE_REPLY, MoveReply(command_id=2, kind="move",
                                                        accepted=True))
        if now < 0.5:
            x += 0.01
        if now >= 1.0:                        # the SPSS stream is back (the stop holds)
            monitor.observe_delivered(Topic.SET_SPEED, SetSpeed(speed_mps=1, accel_mps2=1,
                                                                gear="drive", state="run"))
        monitor.observe(Topic.TRUTH, _truth(x, speed))
        monitor.tick(now)
    found = {d["rule"] for d in monitor.details()}
    assert ("unintended_motion" in found) == (not new_command)


# --------------------------------------------------------------------------- scenarios

def test_a_stall_of_a_node_the_run_does_not_have_is_refused() -> None:
    data = {"name": "s", "vehicle": "escape-hybrid", "start": "ready", "duration_s": 2,
            "events": [{"at_s": 0.5, "set_speed": {"speed_mps": 1, "accel_mps2": 1,
                                                   "gear": "drive", "state": "run"}},
                       stall(1.0, "move", 0.3)]}
    with pytest.raises(ScenarioError, match="no node 'move'"):
        run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def test_a_stall_of_an_unknown_node_is_a_scenario_error() -> None:
    data = {"name": "s", "vehicle": "escape-hybrid", "duration_s": 2,
            "events": [stall(1.0, "vehicle", 0.3)]}
    with pytest.raises(ScenarioError, match="stall"):
        parse_scenario(data)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("stall_s", [0.15, 0.5])
def test_a_stalled_driving_module_resumes_without_a_steering_jump(preset: str,
                                                                  stall_s: float) -> None:
    """The driving module stalls just as a curved replacement arrives. Was: it took the stall
    as one step of its steering rate limit: the steering command jumped 11.2 % in one step
    (0.69 % normally) while the watchdog's full braking left the least lateral grip. Now a
    step after a stall moves the steering at most two periods' worth (dynamics.control
    MAX_CONTROL_STEP_S; the rate grows a little as the vehicle slows)."""
    speed_mps = reachable_mps(preset, 6.0)
    curved = {"at_s": 5.0, "move": {"distance_m": 60.0, "maxspeed_mps": speed_mps,
                                    "curvature_1pm": 0.04}}

    def worst_step_pct(events: list[dict]) -> float:
        result = run(preset, duration_s=12.0, events=events)
        steer = [(float(r["t_s"]), float(r["steer_cmd_pct"])) for r in rows(result, 4.9)
                 if r["steer_cmd_pct"] != ""]
        return max(abs(b - a) for (_, a), (_, b) in itertools.pairwise(steer))

    base = [move(0.5, 80.0, speed_mps), curved]
    normal_pct = worst_step_pct(base)
    stalled_pct = worst_step_pct([*base, stall(5.0, "driving", stall_s)])
    assert stalled_pct <= 3.0 * normal_pct, (stalled_pct, normal_pct)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_after_an_engine_stall_nothing_moves_until_a_new_command(preset: str) -> None:
    """The engine stalls mid-MOVE: the speed server restarts it (seed 001), which is no
    e-stop. Was: the move server took it for a lost speed state and drove the old MOVE on
    after the restart (at rest at 22.7 m, then on to 79.8 m), no event, no violation. Now the
    command is discarded (``interrupted``, ``engine_stall``) and the vehicle stays where it
    stopped until a new command."""
    result = run(preset, duration_s=30.0, events=[move(0.5, 80.0, reachable_mps(preset, 6.0)),
                                                  {"at_s": 6.0, "engine_stall": {}}])
    assert [e["code"] for e in interruptions(result)] == ["engine_stall"]
    rest_s = first_rest_s(result, 6.0)
    assert travel_m(result, rest_s) < 0.1, travel_m(result, rest_s)
    assert not result.summary["violations"], result.summary["violations"]


@pytest.mark.parametrize(("kind", "source", "code", "flagged"), [
    ("estop", "vehicle", "", True), ("estop", "speed", "1001", True),
    ("fault", "speed", "1009", True), ("estop", "vehicle", "command_timeout", True),
    ("estop", "xgv-client", "command_timeout", True), ("fault", "xgv-client", "xgv_control", True),
    ("fault", "xgv-client", "xgv_heartbeat", True), ("estop", "speed", "40", False),
    ("fault", "speed", "1003", False), ("fault", "xgv-client", "xgv_report_age", False),
    ("info", "speed", "1001", False)],
    ids=["vehicle-timeout", "speed-watchdog", "engine-stall", "vehicle-command-timeout",
         "xgv-command-timeout", "xgv-control-lost", "xgv-heartbeat-lost", "client-fault",
         "fault-no-stop", "xgv-degraded-no-stop", "not-a-stop-notice"])
def test_the_judge_holds_the_vehicle_after_an_emergency_stop_nobody_asked_for(
        kind: str, source: str, code: str, flagged: bool) -> None:
    """An ``estop`` notice from the vehicle, or from the speed server with its own code (above
    the clients' 1..999), an engine stall (fault 1009), the vehicle's command timeout and the
    JAUS client's lost control or heartbeat start the rule: once at rest, motion without a new
    command is a violation. A client's fault (it asked for the stop) does not, nor a fault
    notice that stops nothing."""
    monitor = Monitor(PRESETS["escape-hybrid"], 1.0, 0.01)
    monitor.observe(Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1, distance_m=100.0,
                                                    maxspeed_mps=5.0))
    monitor.observe(Topic.MOVE_REPLY, MoveReply(command_id=1, kind="move", accepted=True))
    x = 0.0
    for tick in range(1, 300):
        now = round(tick * 0.01, 6)
        monitor.now_s = now
        monitor.observe_delivered(Topic.SET_SPEED, SetSpeed(speed_mps=1, accel_mps2=1,
                                                            gear="drive", state="run"))
        if tick == 20:
            monitor.observe(Topic.NOTICE, Notice(kind=kind, source=source, code=code))
        speed = 0.0 if 0.5 <= now < 2.0 else 1.0
        x += 0.01 * speed
        monitor.observe(Topic.TRUTH, _truth(x, speed))
        monitor.tick(now)
    found = {d["rule"] for d in monitor.details()}
    assert ("unintended_motion" in found) == flagged, monitor.details()


@pytest.mark.parametrize("changed", [False, True])
def test_the_judge_holds_a_set_speed_client_to_a_stop_it_did_not_ask_for(changed: bool) -> None:
    """A set_speed run: the scenario is the speed server's client and repeats its request
    every 100 ms. Was: each repeat counted as a new command, so motion after a watchdog stop
    was never flagged there. Now only a change of request (state, gear, fault) is one: the
    repeated old ``run`` moving the vehicle is unintended motion; idle then run is not."""
    monitor = Monitor(PRESETS["escape-hybrid"], 1.0, 0.01, spss_is_command=True)
    run_spss = SetSpeed(speed_mps=1, accel_mps2=1, gear="drive", state="run")
    x = 0.0
    for tick in range(1, 400):
        now = round(tick * 0.01, 6)
        monitor.now_s = now
        if tick % 10 == 0:
            spss = run_spss
            if changed and tick == 250:
                spss = SetSpeed(speed_mps=0, accel_mps2=1, gear="drive", state="idle")
            monitor.observe(Topic.SET_SPEED, spss)
            monitor.observe_delivered(Topic.SET_SPEED, spss)
        if tick == 20:
            monitor.observe(Topic.NOTICE, Notice(kind="estop", source="speed", code="1001"))
        speed = 0.0 if 0.5 <= now < 3.0 else 1.0     # at rest, then it moves on
        x += 0.01 * speed
        monitor.observe(Topic.TRUTH, _truth(x, speed))
        monitor.tick(now)
    found = {d["rule"] for d in monitor.details()}
    assert ("unintended_motion" in found) == (not changed), monitor.details()


def _set_speed_run_after(event: Any) -> Monitor:
    """A set_speed run repeating one ``run`` request; ``event(monitor, tick)`` is called every
    tick; the vehicle is at rest from 0.5 s to 2.0 s, then moves on (no new request)."""
    monitor = Monitor(PRESETS["escape-hybrid"], 1.0, 0.01, spss_is_command=True)
    run_spss = SetSpeed(speed_mps=1, accel_mps2=1, gear="drive", state="run")
    x = 0.0
    for tick in range(1, 300):
        now = round(tick * 0.01, 6)
        monitor.now_s = now
        if tick % 10 == 0:
            monitor.observe(Topic.SET_SPEED, run_spss)
            monitor.observe_delivered(Topic.SET_SPEED, run_spss)
        event(monitor, tick)
        speed = 0.0 if 0.5 <= now < 2.0 else 1.0
        x += 0.01 * speed
        monitor.observe(Topic.TRUTH, _truth(x, speed))
        monitor.tick(now)
    return monitor


@pytest.mark.parametrize(("started_s", "unasked_stops", "flagged"), [
    (0.0, 0, False), (0.2, 0, True), (0.0, 1, True)],
    ids=["same-server", "restarted-server", "unasked-stop-counted"])
def test_the_judge_counts_a_speed_server_restart_or_a_rise_of_its_unasked_stops(
        started_s: float, unasked_stops: int, flagged: bool) -> None:
    """``SpeedState``: a changed ``started_s`` (a restarted server: nothing it latched survived)
    or a rise of ``unasked_stops`` is a stop the stack did not ask for, with no notice at all."""
    def event(monitor: Monitor, tick: int) -> None:
        later = tick >= 20
        monitor.observe(Topic.SPEED_STATE, SpeedState(
            speed_mps=0.0, accel_mps2=0.0, gear="drive", state="run",
            started_s=started_s if later else 0.0, unasked_stops=unasked_stops if later else 0))

    found = {d["rule"] for d in _set_speed_run_after(event).details()}
    assert ("unintended_motion" in found) == flagged


@pytest.mark.parametrize("code", ["\u00b2", "1\u00b2", "\u0661\u0660\u0660\u0661",
                                  "\uff11\uff10\uff10\uff11", "9" * 5000, "-1001", " 1001",
                                  "", "\x00", "1001\n"])
@pytest.mark.parametrize("kind", ["estop", "fault"])
def test_a_notice_with_a_hostile_code_never_crashes_the_judge_nor_stops_it(
        kind: str, code: str) -> None:
    """Notice is the one topic a tool may publish through the tool gate: a code of digits that
    are not ASCII ("\u00b2" is ``isdigit()`` but no ``int``), Arabic-Indic or full-width digits, a
    huge number, signs and blanks neither crash the judge nor count as the speed server's own
    stop (only a few ASCII digits are a fault code)."""
    def event(monitor: Monitor, tick: int) -> None:
        if tick == 20:
            monitor.observe(Topic.NOTICE, Notice(kind=kind, source="speed", code=code))

    found = {d["rule"] for d in _set_speed_run_after(event).details()}
    assert "unintended_motion" not in found
