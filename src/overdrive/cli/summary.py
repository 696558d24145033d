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
    takeover = [e for e in summary["events"] if e["kind"] == "takeover"]
    if takeover:   # the safety driver must drive (issue 30 item 4): first, in bold red
        rows.insert(0, ("TAKE OVER", f"[bold red]{takeover[0].get('reason', '')} "
                                     f"(t={takeover[0].get('t_s', 0.0):.2f} s)[/]"))
    audit = summary.get("secondary_braking")
    if audit:
        rows.append(("secondary braking", _secondary(audit)))
    for key, value in rows:
        table.add_row(key, value)
    console.print(table)
    click.echo(f"results: {out}")


def _secondary(audit: dict) -> str:
    """The judge's audit of a stop on a lost service brake, in one line."""
    distance = "no stop" if audit["distance_m"] is None else f"{audit['distance_m']:.2f} m"
    allowed = "none possible" if audit["allowed_m"] is None else f"{audit['allowed_m']:.2f} m"
    missing = ", ".join(audit["missing"]) or "none"
    return (f"from {audit['speed_mps']:.2f} m/s at {audit['at_s']:.2f} s: {distance} of "
            f"{allowed} allowed; means unused: {missing}")
