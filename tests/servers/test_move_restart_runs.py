"""A planner that restarts, judged on whole runs from ground truth (both presets, swept): every
STOP acts at once whatever its id or session; a restarted planner's shorter MOVE binds; a late
command of the planner's earlier run never moves the vehicle further."""

from __future__ import annotations

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.scenario.vehicles import PRESETS
from tests.servers.move_harness import move
from tests.servers.move_harness import run_events as run

PRESET_NAMES = ("escape-hybrid", "ranger-6x6")


def _at(result, t_s: float) -> dict:
    """The trace row at ``t_s`` (ground truth)."""
    return min(result.trace, key=lambda r: abs(float(r["t_s"]) - t_s))


def _shortest_stop_m(preset: str, speed_mps: float, friction: float = 0.8) -> float:
    """The hardest stop the vehicle can make: a period and the brake's lag, then full braking
    at the tyres' limit (the judge's bound, with 10 % for the brake's ramp)."""
    p = PRESETS[preset]
    decel = min(p.max_brake_decel_mps2, friction * G_MPS2)
    return speed_mps * (0.01 + p.brake_lag_s + 0.05) + 1.1 * speed_mps ** 2 / (2.0 * decel)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("restart_s", [3.0, 6.0])
@pytest.mark.parametrize("speed_mps", [4.0, 8.0])
@pytest.mark.parametrize("new_session", [True, False], ids=["new-session", "no-session"])
def test_every_stop_after_a_restart_acts_at_once(preset: str, restart_s: float, speed_mps: float,
                                                 new_session: bool) -> None:
    """Was: the restarted planner's ids (1, 2, ...) were ``stale`` against the old run's, STOPs
    included: three STOPs refused, the vehicle drove on 69.7 m to the old MOVE's end."""
    speed_mps = min(speed_mps, 0.9 * PRESETS[preset].gear(PRESETS[preset].drive_gear).max_speed_mps)
    stop_s = restart_s + 0.3
    result = run([move(0.5, 80.0, speed_mps),
                  {"at_s": restart_s, "planner_restart": {"new_session": new_session}},
                  {"at_s": stop_s, "stop": {}}], duration_s=stop_s + 8.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    at_stop = _at(result, stop_s + 0.01)
    travel_m = result.summary["odometer_m"] - float(at_stop["odometer_m"])
    bound_m = _shortest_stop_m(preset, float(at_stop["speed_mps"]))
    assert travel_m <= bound_m, (travel_m, bound_m)
    assert result.summary["final"]["speed_mps"] < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("new_session", [True, False], ids=["new-session", "no-session"])
@pytest.mark.parametrize("distance_m", [2.0, 10.0])
def test_a_restarted_planners_shorter_move_binds(preset: str, new_session: bool,
                                                 distance_m: float) -> None:
    """Was: a shorter MOVE after the restart was refused as stale (about 8 m further)."""
    result = run([move(0.5, 80.0, 5.0),
                  {"at_s": 5.0, "planner_restart": {"new_session": new_session}},
                  move(5.2, distance_m, 5.0)], duration_s=15.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    issued = _at(result, 5.2)
    end_m = float(issued["odometer_m"]) + max(
        distance_m, _shortest_stop_m(preset, float(issued["speed_mps"])))
    assert result.summary["odometer_m"] <= end_m + 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_late_command_of_the_planners_earlier_run_never_extends(preset: str) -> None:
    """The old run's MOVE 100 m and the new run's MOVE 20 m swap on the way (``reorder``): the
    new session's arrives first and binds; the old one, arriving after it, extends nothing."""
    result = run([move(0.5, 80.0, 5.0),
                  {"at_s": 4.95, "reorder": {"channel": "move", "for_s": 0.2}},
                  move(5.0, 100.0, 5.0),
                  {"at_s": 5.0, "planner_restart": {}},
                  move(5.01, 20.0, 5.0)], duration_s=16.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    issued = _at(result, 5.01)
    assert result.summary["odometer_m"] <= float(issued["odometer_m"]) + 20.0 + 0.05
    stale = [e for e in result.summary["events"] if e["kind"] == "rejected"]
    assert stale, "the old run's MOVE is answered stale"


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_earlier_runs_late_first_message_never_outranks_the_restarted_planner(preset) -> None:
    """Found attacking sessions: the earlier run's MOVE 40 m, delayed 1 s, arrived after the
    restarted planner's MOVE 10 m; the server had never heard of the earlier session, took it
    as the newest and drove on to 39.8 m (the judge, binding what was accepted, passed it).
    A session first heard of now but issued before the current session's newest is stale."""
    result = run([{"at_s": 0.45, "delay": {"channel": "move", "for_s": 0.1, "delay_s": 1.0}},
                  move(0.5, 40.0, 6.0), {"at_s": 0.6, "planner_restart": {}},
                  move(0.7, 10.0, 6.0)], duration_s=20.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    issued = _at(result, 0.7)
    assert result.summary["odometer_m"] <= float(issued["odometer_m"]) + 10.0 + 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("new_session", [False], ids=["no-session"])
def test_a_stale_shortening_that_cannot_be_placed_stops_the_vehicle(preset, new_session) -> None:
    """Found attacking sessions: a restarted planner without sessions sends MOVE 8 m (id 1:
    stale), delivered 2 s late, past the 1 s odometer history; counted from the earliest
    reading kept (a later, further point) it let the vehicle stop 1.9 m past the end. Where a
    stale command cannot be placed, the vehicle stops, as for a new one."""
    result = run([move(0.5, 60.0, 8.0), move(1.0, 60.0, 8.0),
                  {"at_s": 2.9, "planner_restart": {"new_session": new_session}},
                  {"at_s": 2.95, "delay": {"channel": "move", "for_s": 0.1, "delay_s": 2.0}},
                  move(3.0, 8.0, 8.0)], duration_s=20.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    issued = _at(result, 3.0)
    end_m = float(issued["odometer_m"]) + max(
        8.0, _shortest_stop_m(preset, float(issued["speed_mps"])))
    assert result.summary["odometer_m"] <= end_m


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_late_authorization_that_cannot_be_placed_holds_its_source(preset) -> None:
    """Found attacking sessions: lidar's advance 8 m arrived 2 s late, after its 60 m, and was
    counted from the earliest reading kept: the vehicle stopped 1.9 m past its end. Now the
    source holds at 0 until it is heard in order again."""
    result = run([{"at_s": 1.0, "advance": {"source": "lidar", "distance_m": 60.0}},
                  {"at_s": 1.0, "max_speed": {"source": "map", "speed_mps": 8.0}},
                  {"at_s": 3.45, "delay": {"channel": "advance", "for_s": 0.1, "delay_s": 2.0}},
                  {"at_s": 3.5, "advance": {"source": "lidar", "distance_m": 8.0}},
                  {"at_s": 3.7, "advance": {"source": "lidar", "distance_m": 60.0}}],
                 duration_s=20.0, vehicle=preset)
    assert result.exit_code == 0, result.summary["violations"]
    issued = _at(result, 3.5)
    end_m = float(issued["odometer_m"]) + max(
        8.0, _shortest_stop_m(preset, float(issued["speed_mps"])))
    assert result.summary["odometer_m"] <= end_m
