"""plot.png for a run: speed and goal speed, acceleration, pedals, states, and the path."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any


def _floats(rows: list[dict[str, str]], key: str) -> list[float]:
    return [float(r[key]) if r.get(key) else float("nan") for r in rows]


def plot_run(trace_csv: Path, out_png: Path, summary: dict[str, Any] | None = None) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(trace_csv, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    t = _floats(rows, "t_s")
    fig = plt.figure(figsize=(12, 9), constrained_layout=True)
    grid = fig.add_gridspec(4, 2, width_ratios=(3, 2))
    ax_speed = fig.add_subplot(grid[0, 0])
    ax_speed.plot(t, _floats(rows, "speed_mps"), label="speed")
    ax_speed.plot(t, _floats(rows, "goal_speed_mps"), "--", label="goal speed")
    ax_speed.set_ylabel("m/s")
    ax_speed.legend(loc="upper right")
    ax_speed.grid(True, alpha=0.3)
    ax_acc = fig.add_subplot(grid[1, 0], sharex=ax_speed)
    ax_acc.plot(t, _floats(rows, "accel_mps2"), label="longitudinal")
    ax_acc.plot(t, _floats(rows, "lat_accel_mps2"), label="lateral")
    ax_acc.set_ylabel("m/s^2")
    ax_acc.legend(loc="upper right")
    ax_acc.grid(True, alpha=0.3)
    ax_ped = fig.add_subplot(grid[2, 0], sharex=ax_speed)
    ax_ped.plot(t, _floats(rows, "throttle_pct"), label="throttle")
    ax_ped.plot(t, _floats(rows, "brake_pct"), label="brake")
    ax_ped.plot(t, _floats(rows, "steer_pct"), label="steer")
    ax_ped.set_ylabel("%")
    ax_ped.legend(loc="upper right")
    ax_ped.grid(True, alpha=0.3)
    ax_state = fig.add_subplot(grid[3, 0], sharex=ax_speed)
    _bands(ax_state, t, [r["speed_state"] for r in rows], 1.0, "speed state")
    _bands(ax_state, t, [r["safety_mode"] for r in rows], 0.0, "safety mode")
    ax_state.set_yticks([0.4, 1.4], ["safety mode", "speed state"])
    ax_state.set_ylim(-0.1, 1.9)
    ax_state.set_xlabel("t (s)")
    ax_path = fig.add_subplot(grid[:, 1])
    ax_path.plot(_floats(rows, "x_m"), _floats(rows, "y_m"), label="rear axle path")
    ax_path.set_aspect("equal", adjustable="datalim")
    ax_path.set_xlabel("x (m)")
    ax_path.set_ylabel("y (m)")
    ax_path.grid(True, alpha=0.3)
    if summary:
        fig.suptitle(f"{summary['name']}: {len(summary['violations'])} violation(s)")
    fig.savefig(out_png, dpi=80)
    plt.close(fig)
    return out_png


def _bands(ax: Any, t: list[float], labels: list[str], y: float, _name: str) -> None:
    if not t:
        return
    colours = {}
    palette = ["#4c72b0", "#dd8452", "#55a868", "#c44e52", "#8172b3", "#937860", "#da8bc3",
               "#8c8c8c", "#ccb974", "#64b5cd"]
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            label = labels[start] or "-"
            colour = colours.setdefault(label, palette[len(colours) % len(palette)])
            end = t[i] if i < len(t) else t[-1]
            ax.broken_barh([(t[start], max(end - t[start], 1e-3))], (y, 0.8), color=colour)
            ax.text(t[start], y + 0.4, label, fontsize=7, va="center")
            start = i
