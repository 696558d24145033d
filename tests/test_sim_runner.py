"""The scenario runner: run folder contents, exit codes, determinism."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.observe.recorder import TRACE_COLUMNS
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import scenario_dict

CONTRACT_COLUMNS = ("t_s", "x_m", "y_m", "heading_rad", "speed_mps", "accel_mps2",
                    "lat_accel_mps2", "curvature_1pm", "throttle_pct", "brake_pct", "steer_pct",
                    "gear", "speed_state", "safety_mode", "goal_speed_mps", "authorized_m")
DEMO = Path(__file__).resolve().parent.parent / "scenarios" / "demo.yaml"


def open_loop(**overrides) -> dict:
    data = {"duration_s": 12, "seed": 3, "events": [
        {"at_s": 0.2, "engine": "on"}, {"at_s": 2.0, "gear": "drive"},
        {"at_s": 3.0, "actuators": {"throttle_pct": 40, "steer_pct": 5}},
        {"at_s": 8.0, "actuators": {"brake_pct": 60}}]}
    data.update(overrides)
    return scenario_dict(**data)


def test_run_folder_has_contract_outputs(tmp_path: Path) -> None:
    result = run_scenario(parse_scenario(open_loop()), tmp_path)
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in ("name", "sim_time_s", "wall_time_s", "real_time_factor", "vehicle", "odometer_m",
                "final", "peaks", "events", "violations"):
        assert key in summary
    assert set(summary["vehicle"]) >= {"preset", "length_m", "width_m", "wheelbase_m", "rear_overhang_m"}
    assert set(summary["final"]) >= {"x_m", "y_m", "heading_rad", "speed_mps", "gear",
                                     "speed_state", "safety_mode"}
    assert set(summary["peaks"]) == {"max_speed_mps", "max_accel_mps2", "max_decel_mps2",
                                     "max_lateral_accel_mps2"}
    with open(tmp_path / "trace.csv") as f:
        rows = list(csv.DictReader(f))
    assert set(CONTRACT_COLUMNS) <= set(rows[0]) and tuple(rows[0]) == TRACE_COLUMNS
    assert len(rows) == round(12 / 0.01) + 1, "one row per control period"
    assert (tmp_path / "plot.png").stat().st_size > 10_000
    assert result.exit_code == 0
    assert summary["odometer_m"] > 5.0 and summary["final"]["speed_mps"] == 0.0
    assert summary["final"]["gear"] == "drive"


def test_same_seed_gives_byte_identical_trace(tmp_path: Path) -> None:
    for name in ("a", "b"):
        run_scenario(parse_scenario(open_loop()), tmp_path / name, plot=False)
    assert (tmp_path / "a" / "trace.csv").read_bytes() == (tmp_path / "b" / "trace.csv").read_bytes()


def test_different_seed_changes_sensor_noise_only(tmp_path: Path) -> None:
    a = run_scenario(parse_scenario(open_loop()), None)
    b = run_scenario(parse_scenario(open_loop(seed=4)), None)
    assert a.summary["final"] == b.summary["final"], "open-loop ground truth ignores sensor noise"


def test_violated_expectation_exits_1(tmp_path: Path) -> None:
    data = open_loop(expect=[{"peak_speed_below_mps": 0.5}, {"final_speed_below_mps": 0.05}])
    result = run_scenario(parse_scenario(data), None)
    assert result.exit_code == 1
    assert len(result.summary["violations"]) == 1
    assert "peak_speed_below_mps" in result.summary["violations"][0]


def test_expectation_kinds_hold_on_a_known_run() -> None:
    data = open_loop(expect=[
        {"final_speed_below_mps": 0.05}, {"odometer_between_m": [5, 200]},
        {"peak_accel_below_mps2": 5}, {"peak_decel_below_mps2": 9},
        {"peak_lat_accel_below_mps2": 3}, {"safety_mode_reached": "drive-by-wire"},
        {"final_safety_mode": "drive-by-wire"}, {"no_contact": True},
        {"no_event": {"kind": "contact"}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["violations"] == []


def test_safestop_pause_brakes_and_is_recorded() -> None:
    data = open_loop(events=[
        {"at_s": 0.2, "engine": "on"}, {"at_s": 2.0, "gear": "drive"},
        {"at_s": 3.0, "actuators": {"throttle_pct": 40}}, {"at_s": 7.0, "safestop": "pause"}],
        expect=[{"final_speed_below_mps": 0.01},
                {"event": {"kind": "safety_mode", "within_s": [6.9, 7.1],
                           "match": {"to": "estop-pause"}}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["violations"] == []
    assert result.trace[-1]["brake_pct"].startswith("50."), "pause holds 50 % brake once stopped"


def test_drop_channel_drops_messages() -> None:
    data = open_loop(events=[
        {"at_s": 0.2, "engine": "on"}, {"at_s": 2.0, "gear": "drive"},
        {"at_s": 2.5, "drop": {"channel": "pedals", "for_s": 2.0}},
        {"at_s": 3.0, "actuators": {"throttle_pct": 40}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["odometer_m"] == 0.0, "the throttle command was lost"


def test_cli_sim_writes_run_folder_and_prints_summary(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    result = CliRunner().invoke(main, ["sim", str(DEMO), "--out", str(out), "--seed", "7"])
    assert result.exit_code == 0, result.output
    assert "violations" in result.output and str(out) in result.output.replace("\n", "")
    assert json.loads((out / "summary.json").read_text())["seed"] == 7


def test_cli_help() -> None:
    result = CliRunner().invoke(main, ["--help"])
    assert result.exit_code == 0 and "sim" in result.output
    assert CliRunner().invoke(main, ["sim", "--help"]).exit_code == 0
    assert CliRunner().invoke(main, ["sim", "x.yaml", "--seed", "-1"]).exit_code == 2
