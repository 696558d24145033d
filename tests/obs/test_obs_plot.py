"""Plots: run plots from run.mcap and trace.csv, the CLI, sweep distributions."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from click.testing import CliRunner
from obs_helpers import record_run, speed_scenario

from overdrive.cli.observe import plot as plot_command
from overdrive.observe.plot import (
    distributions_from_summaries,
    load_mcap,
    load_trace,
    plot_distributions,
    plot_run,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
MIN_PNG_BYTES = 20_000      # a figure with lines, bands and a path; an empty one is ~5 kB


def drive_scenario() -> dict:
    return {"name": "drive-plot", "vehicle": "escape-hybrid", "start": "ready", "seed": 2,
            "duration_s": 12, "world": {"obstacles": [{"x_m": 30, "y_m": 0.5}]},
            "events": [{"at_s": 0.5, "max_speed": {"source": "map", "speed_mps": 6}},
                       {"at_s": 0.5, "advance": {"source": "lidar", "distance_m": 25}},
                       {"at_s": 0.5, "steer": {"curvature_1pm": -0.01}}]}


def assert_png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > MIN_PNG_BYTES, f"{path}: {len(data)} bytes"


def test_plot_from_mcap_has_the_ellipse_limits_and_obstacles(tmp_path: Path) -> None:
    pytest.importorskip("overdrive.servers.driving")
    path = record_run(drive_scenario(), tmp_path)
    data = load_mcap(path)
    assert data.obstacles == [(30.0, 0.5)]
    rows = len(data.columns["t_s"])
    assert rows == 1201
    up, down = data.floats("accel_limit_mps2"), data.floats("decel_limit_mps2")
    assert up is not None and down is not None and len(up) == rows
    assert all(v > 0 for v in up[100:]) and all(v > 0 for v in down[100:])
    auth = data.floats("authorized_m")
    assert auth is not None and any(not math.isnan(a) for a in auth)
    result = CliRunner().invoke(plot_command, [str(tmp_path), "--out", str(tmp_path / "p.png")])
    assert result.exit_code == 0, result.output
    assert_png(tmp_path / "p.png")


def test_plot_from_trace_csv_and_mcap_agree(tmp_path: Path) -> None:
    path = record_run(speed_scenario(duration_s=12, events=speed_scenario()["events"][:2]),
                      tmp_path)
    from_csv = load_trace(tmp_path / "trace.csv")
    from_mcap = load_mcap(path)
    for key in ("t_s", "x_m", "speed_mps", "speed_state", "safety_mode", "gear", "brake_pct"):
        assert from_csv.columns[key] == from_mcap.columns[key], key
    assert from_mcap.floats("spss_speed_mps") is not None
    assert {e["kind"] for e in from_mcap.events} >= {"speed_state"}
    out = plot_run(tmp_path / "trace.csv", tmp_path / "plot.png")
    assert_png(out)


def test_plot_distributions(tmp_path: Path) -> None:
    summaries = [{"peaks": {"max_accel_mps2": 1.0 + 0.01 * i, "max_decel_mps2": 3.0 - 0.02 * i}}
                 for i in range(40)]
    samples = distributions_from_summaries(summaries)
    assert samples["max_accel_mps2"][3] == pytest.approx(1.03)
    samples["stopping_error_m"] = [0.05 * math.sin(i) for i in range(40)] + [math.nan]
    out = plot_distributions(samples, tmp_path / "dist.png", title="sweep",
                             limits={"stopping_error_m": 0.1})
    assert_png(out)


def test_plot_cli_rejects_a_folder_without_a_run(tmp_path: Path) -> None:
    result = CliRunner().invoke(plot_command, [str(tmp_path)])
    assert result.exit_code == 2 and "neither run.mcap nor trace.csv" in result.output
