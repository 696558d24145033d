"""A planner on another machine, judged on whole runs from ground truth (both presets, offsets
swept from -0.5 to +0.5 s, constant and drifting): within the tolerance the mission completes
and a replacement issued at speed ends no further than asked (at most speed x round trip
short); beyond it nothing moves and a fault says why; never a stop without a reason."""

from __future__ import annotations

import pytest

from overdrive.servers.clock_offset import MAX_CLOCK_OFFSET_S
from tests.conftest import PRESET_NAMES, reachable_mps
from tests.servers.move_harness import move
from tests.servers.move_harness import run_events as run

DONE_TOLERANCE_M = 0.5        # MoveServerConfig.done_tolerance_m


def _at(result, t_s: float) -> dict:
    return min(result.trace, key=lambda r: abs(float(r["t_s"]) - t_s))


def _faults(result, code: str) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == "fault" and e.get("code") == code]


@pytest.mark.variants            # 60 whole runs: `make test` runs one in four, test-variants all
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("offset_s", [-0.2, -0.03, 0.0, 0.03, 0.2])
@pytest.mark.parametrize("drift_ppm", [0.0, 500.0, -500.0])
@pytest.mark.parametrize("machine", ["same", "separate"])
def test_within_tolerance_a_replacement_at_speed_ends_where_the_planner_asked(
        preset: str, offset_s: float, drift_ppm: float, machine: str) -> None:
    """Was: a planner 30 ms ahead had every command refused; the vehicle stopped after 0.67 m
    and never moved again."""
    speed_mps = reachable_mps(preset, 8.0)
    replace_s, distance_m = 9.0, 12.0
    result = run([{"at_s": 0.0, "planner_clock": {"offset_s": offset_s, "drift_ppm": drift_ppm}},
                  move(0.5, 120.0, speed_mps), move(replace_s, distance_m, speed_mps)],
                 duration_s=replace_s + 12.0, vehicle=preset, planner_machine=machine)
    assert result.exit_code == 0, result.summary["violations"]
    clocks = result.summary["clocks"]["planner"]
    assert clocks["refusals"] == 0
    assert clocks["lo_s"] - 1e-6 <= -offset_s - drift_ppm * 1e-6 * replace_s <= clocks["hi_s"] + 1e-6
    at_issue = _at(result, replace_s)
    issued_odo_m = float(at_issue["odometer_m"])
    travelled_m = result.summary["odometer_m"] - issued_odo_m
    worst_short_m = float(at_issue["speed_mps"]) * clocks["worst_uncertainty_s"]
    assert travelled_m <= distance_m + 0.05, (travelled_m, distance_m)
    assert travelled_m >= distance_m - DONE_TOLERANCE_M - worst_short_m, (travelled_m, distance_m)
    assert result.summary["final"]["speed_mps"] < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("offset_s", [-0.5, -0.3, 0.3, 0.5])
@pytest.mark.parametrize("machine", ["same", "separate"])
def test_beyond_tolerance_nothing_moves_and_a_fault_says_why(preset: str, offset_s: float,
                                                             machine: str) -> None:
    result = run([{"at_s": 0.0, "planner_clock": {"offset_s": offset_s}},
                  move(0.5, 30.0, reachable_mps(preset, 8.0))], duration_s=4.0, vehicle=preset,
                 planner_machine=machine)
    assert result.exit_code == 1
    assert any("refused everything" in v for v in result.summary["violations"])
    (fault,) = _faults(result, "planner_clock")
    assert f"beyond {MAX_CLOCK_OFFSET_S} s" in fault["message"]
    assert result.summary["odometer_m"] < 0.01


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_clock_drifting_out_of_tolerance_stops_the_vehicle_with_the_reason(preset: str) -> None:
    """0.2 s ahead and gaining 10 ms a second: beyond 0.25 s after 5 s. The planner's commands
    from then on are refused; the vehicle stops (its newest intent cannot be placed) and the
    fault says why."""
    speed_mps = reachable_mps(preset, 6.0)
    events = [{"at_s": 0.0, "planner_clock": {"offset_s": 0.2, "drift_ppm": 10_000.0}},
              move(0.5, 200.0, speed_mps)]
    events += [move(t, 200.0, speed_mps) for t in (2.0, 4.0, 6.0, 8.0)]
    result = run(events, duration_s=16.0, vehicle=preset, planner_machine="separate")
    (fault,) = _faults(result, "planner_clock")
    assert fault["t_s"] == pytest.approx(6.0, abs=0.02) and "beyond" in fault["message"]
    assert result.summary["final"]["speed_mps"] < 0.05
    refused = [e for e in result.summary["events"] if e["kind"] == "rejected"]
    assert [e["reason"] for e in refused] == ["clock", "clock"]
    assert not result.summary["violations"], result.summary["violations"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("step_s", [-0.15, 0.15])
def test_a_planner_clock_step_mid_run_is_re_measured(preset: str, step_s: float) -> None:
    """The planner's clock steps (an NTP step) while it drives: its next command is measured
    against the new offset; a replacement after the step still ends where asked."""
    speed_mps = reachable_mps(preset, 6.0)
    result = run([{"at_s": 0.0, "planner_clock": {"offset_s": 0.0}}, move(0.5, 100.0, speed_mps),
                  {"at_s": 6.0, "planner_clock": {"offset_s": step_s}},
                  move(8.0, 10.0, speed_mps)], duration_s=18.0, vehicle=preset,
                 planner_machine="separate")
    assert result.exit_code == 0, result.summary["violations"]
    travelled_m = result.summary["odometer_m"] - float(_at(result, 8.0)["odometer_m"])
    assert 10.0 - DONE_TOLERANCE_M - 0.2 <= travelled_m <= 10.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_planner_ahead_that_does_not_echo_is_refused_with_a_fault_saying_why(preset) -> None:
    """30 ms ahead on the same-machine setting, no echo: no offset can be measured, its stamps
    are in the future; every command refused with the reason, the fault once they persist,
    the run fails (no silent lock-out)."""
    result = run([{"at_s": 0.0, "planner_clock": {"offset_s": 0.03, "echo": False}},
                  move(0.5, 30.0, 5.0), move(1.5, 30.0, 5.0)], duration_s=4.0, vehicle=preset)
    assert result.exit_code == 1
    (fault,) = _faults(result, "planner_clock")
    assert "ahead of this server's" in fault["message"] and fault["t_s"] == pytest.approx(1.5)
    assert result.summary["odometer_m"] < 0.01


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_on_another_machine_the_vehicle_stays_parked_until_the_offset_is_known(preset) -> None:
    """``planner_machine: separate`` and a planner that echoes nothing: nothing engages."""
    result = run([{"at_s": 0.0, "planner_clock": {"echo": False}},
                  move(0.5, 30.0, 5.0), move(1.0, 30.0, 5.0)], duration_s=4.0, vehicle=preset,
                 start="parked", planner_machine="separate")
    assert result.exit_code == 1
    assert _faults(result, "planner_clock")
    assert result.summary["final"]["speed_state"] == "parked"
    assert result.summary["odometer_m"] < 0.01


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("offset_s", [-0.2, 0.2])
def test_a_stop_from_a_planner_with_any_clock_acts_at_once(preset: str, offset_s: float) -> None:
    """A STOP needs no time: obeyed within a period whatever the planner's clock says, also
    beyond tolerance (its MOVE was never placed, but a STOP is always obeyed)."""
    speed_mps = reachable_mps(preset, 8.0)
    result = run([{"at_s": 0.0, "planner_clock": {"offset_s": offset_s}},
                  move(0.5, 120.0, speed_mps),
                  {"at_s": 5.0, "planner_clock": {"offset_s": 3.0 * offset_s}},
                  {"at_s": 7.0, "stop": {}}], duration_s=15.0, vehicle=preset,
                 planner_machine="separate")
    assert result.exit_code == 0, result.summary["violations"]
    replies = [e for e in result.summary["events"] if e["kind"] == "rejected"]
    assert not replies
    assert result.summary["final"]["speed_mps"] < 0.05
