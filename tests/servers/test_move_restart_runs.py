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
