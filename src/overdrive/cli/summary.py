"""The summary table a run prints on a terminal (``overdrive sim``, ``drive``, ``launch``)."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.table import Table


def print_summary(summary: dict, out: Path) -> None:
    """One table: vehicle, time, odometer, final state, peaks, events and violations."""
    console = Console()
    final, peaks = summary["final"], summary["peaks"]
    table = Table(title=f"overdrive sim: {summary['name']}", show_header=False)
    table.add_column(style="bold")
    table.add_column()
    rows = [
        ("vehicle", summary["vehicle"]["preset"]),
        ("simulated", f"{summary['sim_time_s']:.1f} s in {summary['wall_time_s']:.2f} s "
                      f"({summary['real_time_factor']}x real time)"),
        ("odometer", f"{summary['odometer_m']:.2f} m"),
        ("final position", f"x {final['x_m']:.2f} m, y {final['y_m']:.2f} m, "
                           f"heading {final['heading_rad']:.3f} rad"),
        ("final speed", f"{final['speed_mps']:.3f} m/s, gear {final['gear']}"),
        ("final states", f"speed server {final['speed_state']}, safety {final['safety_mode']}"),
        ("peaks", f"speed {peaks['max_speed_mps']:.2f} m/s, accel {peaks['max_accel_mps2']:.2f}, "
                  f"decel {peaks['max_decel_mps2']:.2f}, lateral "
                  f"{peaks['max_lateral_accel_mps2']:.2f} m/s^2"),
        ("events", str(len(summary["events"]))),
        ("violations", "none" if not summary["violations"] else "\n".join(summary["violations"])),
    ]
    for key, value in rows:
        table.add_row(key, value)
    console.print(table)
    click.echo(f"results: {out}")
