"""Plots of runs: ``plot.png`` of a run folder, ``overdrive plot``, and sweep distributions.

A run is read either from ``trace.csv`` (plus ``summary.json``; what ``overdrive sim`` writes
into ``plot.png``) or from ``run.mcap``, which also has the driving module's acceleration
limits, speed limits and the scenario's obstacles. The figure shows speed against goal speed,
longitudinal acceleration against the acceleration-ellipse limits, pedal and steering efforts,
speed states, safety modes and gears as coloured bands, and the path in x-y with obstacles and
the end of the authorized distance.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from overdrive.messages import Topic
from overdrive.observe.mcap_log import decode_lenient, iter_ticks, read_info, resolve_type
from overdrive.observe.recorder import TRACE_COLUMNS, Recorder
from overdrive.scenario.schema import ScenarioError, load_scenario

SPEED_STATE_COLOURS = {
    "parked": "#8c8c8c", "reset": "#b07aa1", "starting": "#edc948", "startwait": "#ff9da7",
    "paused": "#f28e2b", "runwait": "#76b7b2", "idle": "#4e79a7", "shifting": "#9c755f",
    "run": "#59a14f",
}
SAFETY_MODE_COLOURS = {
    "drive-by-wire": "#8cd17d", "software-pause": "#edc948", "estop-pause": "#f28e2b",
    "manual-override": "#4e79a7", "emergency-manual-override": "#b07aa1",
    "estop-disable": "#e15759", "inactive": "#8c8c8c",
}
OTHER_COLOURS = ("#4e79a7", "#f28e2b", "#e15759", "#76b7b2", "#59a14f", "#edc948", "#b07aa1",
                 "#ff9da7", "#9c755f", "#bab0ac")
EVENT_MARKERS = {"fault": ("v", "#e15759"), "estop": ("X", "#b00020"),
                 "rejected": ("x", "#9c755f"), "contact": ("*", "#000000")}
AUTH_MARK_EVERY_S = 0.5     # authorization end points drawn at this interval on the path
TEXT_MIN_FRACTION = 0.04    # a band's label is written when the band spans this share of the run


@dataclass
class RunData:
    """A run as columns (one entry per control period) plus what is known around it."""

    columns: dict[str, list[Any]]
    name: str = ""
    summary: dict[str, Any] | None = None
    obstacles: list[tuple[float, float]] = field(default_factory=list)
    vehicle: dict[str, Any] | None = None
    events: list[dict[str, Any]] = field(default_factory=list)

    def floats(self, key: str) -> list[float] | None:
        values = self.columns.get(key)
        if values is None:
            return None
        out = []
        for v in values:
            if v is None or v == "":
                out.append(math.nan)
            else:
                try:
                    out.append(float(v))
                except ValueError:
                    out.append(math.nan)
        return out

    def labels(self, key: str) -> list[str] | None:
        values = self.columns.get(key)
        return None if values is None else ["" if v is None else str(v) for v in values]


# --------------------------------------------------------------------------- loading

def _scenario_world(source: str | None) -> tuple[list[tuple[float, float]], str | None]:
    """Obstacles of the scenario file at ``source`` (best effort: the file may have moved)."""
    if not source:
        return [], None
    try:
        scenario = load_scenario(source)
    except (ScenarioError, OSError, ImportError):
        return [], None
    return [(o.x_m, o.y_m) for o in scenario.spec.world.obstacles], scenario.name


def load_trace(trace_csv: str | Path, summary: dict[str, Any] | None = None) -> RunData:
    trace_csv = Path(trace_csv)
    with open(trace_csv, encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    columns: dict[str, list[Any]] = {k: [r[k] for r in rows] for k in (rows[0] if rows else {})}
    if summary is None and (trace_csv.parent / "summary.json").exists():
        summary = json.loads((trace_csv.parent / "summary.json").read_text(encoding="utf-8"))
    obstacles, _ = _scenario_world(summary.get("scenario") if summary else None)
    return RunData(columns=columns, name=summary["name"] if summary else trace_csv.parent.name,
                   summary=summary, obstacles=obstacles,
                   vehicle=summary.get("vehicle") if summary else None,
                   events=list(summary.get("events", [])) if summary else [])


def load_mcap(path: str | Path) -> RunData:
    """Columns of a ``run.mcap``: the trace's, plus the driving module's limits per period."""
    import yaml

    path = Path(path)
    info = read_info(path)
    obstacles: list[tuple[float, float]] = []
    name = info.metadata.get("scenario_name", path.parent.name)
    if info.scenario_yaml:
        world = (yaml.safe_load(info.scenario_yaml) or {}).get("world", {})
        obstacles = [(o["x_m"], o["y_m"]) for o in world.get("obstacles", [])]
    recorder = Recorder(None, keep_rows=True)
    extra_keys = ("accel_limit_mps2", "decel_limit_mps2", "speed_limit_mps")
    extra: dict[str, list[Any]] = {k: [] for k in extra_keys}
    spss_speed: list[Any] = []
    types: dict[str, Any] = {}
    wanted = {Topic.TRUTH, Topic.VEHICLE_STATUS, Topic.SPEED_STATE, Topic.DRIVING_STATUS,
              Topic.PEDALS, Topic.STEER, Topic.RADAR, Topic.NOTICE, Topic.MOVE_REPLY,
              Topic.SET_SPEED, "sim/world"}
    for tick in iter_ticks(path):
        recorder.now_s = tick.t_s
        for rec in tick.messages:
            if rec.topic not in wanted:
                continue
            if rec.schema_name not in types:
                types[rec.schema_name] = resolve_type(rec.schema_name)
            cls = types[rec.schema_name]
            if cls is None:
                continue
            msg = decode_lenient(rec.data, cls)
            recorder.observe(rec.topic, msg)
            if rec.topic == "sim/world":
                obstacles = sorted(set(obstacles) | set(getattr(msg, "obstacles", ())))
        before = len(recorder.rows or [])
        recorder.tick(tick.t_s)
        if len(recorder.rows or []) > before:
            driving = recorder.latest.get(Topic.DRIVING_STATUS)
            for k in extra_keys:
                extra[k].append(getattr(driving, k, None) if driving is not None else None)
            spss = recorder.latest.get(Topic.SET_SPEED)
            spss_speed.append(spss.speed_mps if spss is not None else None)
    rows = recorder.rows or []
    columns: dict[str, list[Any]] = {k: [r[k] for r in rows] for k in TRACE_COLUMNS}
    if any(v is not None for v in extra["accel_limit_mps2"]):
        columns.update(extra)
    if any(v is not None for v in spss_speed):
        columns["spss_speed_mps"] = spss_speed
    return RunData(columns=columns, name=name, obstacles=obstacles, vehicle=info.vehicle,
                   events=recorder.events)


def load_run(source: str | Path) -> RunData:
    """A run from a run folder (``run.mcap`` preferred, else ``trace.csv``), an MCAP or a CSV."""
    source = Path(source)
    if source.is_dir():
        if (source / "run.mcap").exists():
            return load_mcap(source / "run.mcap")
        if (source / "trace.csv").exists():
            return load_trace(source / "trace.csv")
        raise FileNotFoundError(f"{source}: neither run.mcap nor trace.csv in this folder")
    if source.suffix == ".mcap":
        return load_mcap(source)
    return load_trace(source)


# --------------------------------------------------------------------------- figures

def plot_run(trace_csv: Path, out_png: Path, summary: dict[str, Any] | None = None) -> Path:
    """``plot.png`` of a run folder from its ``trace.csv`` (``overdrive sim`` calls this)."""
    data = load_trace(trace_csv, summary)
    return plot_data(data, out_png)


def plot_source(source: str | Path, out_png: str | Path | None = None) -> Path:
    """Plot a run folder or ``run.mcap``; default output ``plot.png`` next to it."""
    source = Path(source)
    data = load_run(source)
    if out_png is None:
        out_png = (source if source.is_dir() else source.parent) / "plot.png"
    return plot_data(data, Path(out_png))


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_data(data: RunData, out_png: str | Path) -> Path:
    plt = _pyplot()
    t = data.floats("t_s") or []
    fig = plt.figure(figsize=(15, 10), constrained_layout=True)
    grid = fig.add_gridspec(4, 2, width_ratios=(3, 2), height_ratios=(3, 3, 2, 2))
    ax_speed = fig.add_subplot(grid[0, 0])
    _speed_panel(ax_speed, t, data)
    ax_acc = fig.add_subplot(grid[1, 0], sharex=ax_speed)
    _accel_panel(ax_acc, t, data)
    ax_ped = fig.add_subplot(grid[2, 0], sharex=ax_speed)
    for key, label, colour in (("throttle_pct", "throttle", "#59a14f"),
                               ("brake_pct", "brake", "#e15759"),
                               ("steer_pct", "steer (+ right)", "#4e79a7")):
        values = data.floats(key)
        if values is not None:
            ax_ped.plot(t, values, label=label, color=colour, lw=1)
    ax_ped.set_ylabel("effort (%)")
    ax_ped.legend(loc="upper right", fontsize=8, ncol=3)
    ax_ped.grid(True, alpha=0.3)
    ax_bands = fig.add_subplot(grid[3, 0], sharex=ax_speed)
    _bands_panel(ax_bands, t, data)
    for ax in (ax_speed, ax_acc, ax_ped):
        ax.tick_params(labelbottom=False)
    ax_path = fig.add_subplot(grid[:, 1])
    _path_panel(ax_path, data)
    title = data.name or "run"
    if data.summary is not None:
        n = len(data.summary.get("violations", []))
        title += f": {n} violation(s)"
    fig.suptitle(title)
    fig.savefig(out_png, dpi=80)
    plt.close(fig)
    return Path(out_png)


def _speed_panel(ax: Any, t: list[float], data: RunData) -> None:
    ax.plot(t, data.floats("speed_mps") or [], label="speed", color="#4e79a7", lw=1.5)
    goal = data.floats("goal_speed_mps")
    if goal is not None and any(not math.isnan(v) for v in goal):
        ax.plot(t, goal, "--", label="goal speed", color="#f28e2b", lw=1.2)
    spss = data.floats("spss_speed_mps")
    if spss is not None:
        ax.step(t, spss, where="post", ls=(0, (1, 1)), label="SPSS speed (magnitude)",
                color="#59a14f", lw=1.2)
    limit = data.floats("speed_limit_mps")
    if limit is not None and any(not math.isnan(v) and v < 1e3 for v in limit):
        ax.plot(t, [v if v < 1e3 else math.nan for v in limit], ":", label="speed limit",
                color="#e15759", lw=1)
    shown = [abs(v) for v in (data.floats("speed_mps") or []) + (goal or []) if not math.isnan(v)]
    top = max(shown, default=1.0)
    bottom = min((v for v in data.floats("speed_mps") or [] if not math.isnan(v)), default=0.0)
    ax.set_ylim(min(bottom, 0.0) - 0.05 * top - 0.1, 1.15 * top + 0.1)
    ax.axhline(0.0, color="black", lw=0.5)
    ax.set_ylabel("speed (m/s)")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(True, alpha=0.3)


def _accel_panel(ax: Any, t: list[float], data: RunData) -> None:
    up = data.floats("accel_limit_mps2")
    down = data.floats("decel_limit_mps2")
    if up is not None and down is not None:
        ax.fill_between(t, [-d for d in down], up, color="#59a14f", alpha=0.12, lw=0,
                        label="ellipse limits")
        ax.plot(t, up, color="#59a14f", lw=0.8)
        ax.plot(t, [-d for d in down], color="#59a14f", lw=0.8)
    ax.plot(t, data.floats("accel_mps2") or [], label="longitudinal", color="#4e79a7", lw=1)
    lat = data.floats("lat_accel_mps2")
    if lat is not None:
        ax.plot(t, lat, label="lateral", color="#b07aa1", lw=1)
    ax.axhline(0.0, color="black", lw=0.5)
    ax.set_ylabel("accel (m/s²)")
    ax.legend(loc="upper right", fontsize=8, ncol=3)
    ax.grid(True, alpha=0.3)


def _bands_panel(ax: Any, t: list[float], data: RunData) -> None:
    rows = [("speed_state", "speed state", SPEED_STATE_COLOURS),
            ("safety_mode", "safety mode", SAFETY_MODE_COLOURS),
            ("gear", "gear", {})]
    yticks, ylabels = [], []
    span = (t[-1] - t[0]) if len(t) > 1 else 1.0
    seen: dict[str, str] = {}
    for i, (key, label, colours) in enumerate(rows):
        labels = data.labels(key)
        if labels is None or not any(labels):
            continue                      # e.g. no speed server in an open-loop run
        y = len(rows) - 1 - i
        used = _bands(ax, t, labels, y, dict(colours), span)
        if key != "gear":
            seen.update(used)
        yticks.append(y + 0.4)
        ylabels.append(label)
    for event in data.events:
        marker = EVENT_MARKERS.get(event.get("kind", ""))
        if marker:
            ax.plot([event["t_s"]], [len(rows) - 0.05], marker=marker[0], color=marker[1],
                    ms=7, ls="none", clip_on=False)
    ax.set_yticks(yticks, ylabels)
    ax.set_ylim(-0.1, len(rows) + 0.1)
    ax.set_xlabel("t (s)")
    if seen:
        from matplotlib.patches import Patch

        ax.legend(handles=[Patch(color=c, label=n) for n, c in seen.items()], fontsize=7,
                  loc="upper center", bbox_to_anchor=(0.5, -0.32), ncol=min(len(seen), 8),
                  frameon=False)


def _bands(ax: Any, t: list[float], labels: list[str], y: float, colours: dict[str, str],
           span: float) -> dict[str, str]:
    """Draw the runs of equal labels at height ``y``; return the colours used, by label."""
    used: dict[str, str] = {}
    if not t:
        return used
    start = 0
    for i in range(1, len(labels) + 1):
        if i == len(labels) or labels[i] != labels[start]:
            label = labels[start] or "-"
            colour = colours.setdefault(label, OTHER_COLOURS[len(colours) % len(OTHER_COLOURS)])
            end = t[i] if i < len(t) else t[-1]
            width = max(end - t[start], 1e-3)
            ax.broken_barh([(t[start], width)], (y, 0.8), color=colour)
            used[label] = colour
            if width >= TEXT_MIN_FRACTION * span:
                ax.text(t[start] + 0.01 * span, y + 0.4, label, fontsize=7, va="center")
            start = i
    return used


def _path_panel(ax: Any, data: RunData) -> None:
    from matplotlib.patches import Circle, Polygon

    x = data.floats("x_m") or []
    y = data.floats("y_m") or []
    speed = data.floats("speed_mps") or []
    if x:
        points = ax.scatter(x, y, c=[abs(v) for v in speed], s=2, cmap="viridis",
                            label="rear axle path")
        cbar = ax.figure.colorbar(points, ax=ax, shrink=0.6, pad=0.01)
        cbar.set_label("|speed| (m/s)")
        ax.plot([x[0]], [y[0]], "o", color="#59a14f", ms=7, label="start")
        ax.plot([x[-1]], [y[-1]], "s", color="#e15759", ms=7, label="end")
        heading = data.floats("heading_rad") or []
        if data.vehicle and heading:
            ax.add_patch(Polygon(_footprint(x[-1], y[-1], heading[-1], data.vehicle),
                                 closed=True, fill=False, ec="#e15759", lw=1.2))
    auth = data.floats("authorized_m")
    heading = data.floats("heading_rad")
    t = data.floats("t_s") or []
    if auth is not None and heading is not None and x:
        ends_x, ends_y, next_t = [], [], -math.inf
        for i, a in enumerate(auth):
            if math.isnan(a) or t[i] < next_t:
                continue
            sign = -1.0 if (speed[i] < 0) else 1.0
            ends_x.append(x[i] + sign * a * math.cos(heading[i]))
            ends_y.append(y[i] + sign * a * math.sin(heading[i]))
            next_t = t[i] + AUTH_MARK_EVERY_S
        if ends_x:
            ax.plot(ends_x, ends_y, "|", color="#f28e2b", ms=8, alpha=0.7,
                    label="end of authorization")
    for i, (ox, oy) in enumerate(data.obstacles):
        ax.add_patch(Circle((ox, oy), 0.5, color="#e15759", alpha=0.25))
        ax.plot([ox], [oy], "x", color="#e15759", ms=9, mew=2,
                label="obstacle" if i == 0 else None)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("path (x-y)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)


def _footprint(x: float, y: float, heading: float, vehicle: Mapping[str, Any]) -> list[tuple[float, float]]:
    """Corners of the vehicle's outline; (x, y) is the centre of the rear axle."""
    length = float(vehicle.get("length_m", 4.0))
    width = float(vehicle.get("width_m", 1.8))
    rear = float(vehicle.get("rear_overhang_m", 1.0))
    c, s = math.cos(heading), math.sin(heading)
    corners = [(-rear, -width / 2), (length - rear, -width / 2), (length - rear, width / 2),
               (-rear, width / 2)]
    return [(x + c * px - s * py, y + s * px + c * py) for px, py in corners]


def plot_distributions(samples: Mapping[str, Sequence[float]], out_png: str | Path, *,
                       title: str = "", bins: int = 30,
                       limits: Mapping[str, float] | None = None) -> Path:
    """Histograms for a sweep: one panel per quantity (e.g. ``stopping_error_m``,
    ``max_accel_mps2``, ``max_decel_mps2``), with the median and, when given in ``limits``, the
    bound it must stay below. NaN samples are counted in the panel title, not drawn.
    """
    plt = _pyplot()
    names = list(samples)
    cols = min(3, max(1, len(names)))
    rows = max(1, math.ceil(len(names) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 3.6 * rows), squeeze=False,
                             constrained_layout=True)
    for ax in axes.flat[len(names):]:
        ax.set_visible(False)
    for ax, name in zip(axes.flat, names, strict=False):
        values = [float(v) for v in samples[name]]
        finite = sorted(v for v in values if math.isfinite(v))
        missing = len(values) - len(finite)
        if finite:
            ax.hist(finite, bins=bins, color="#4e79a7", alpha=0.85)
            median = finite[len(finite) // 2]
            ax.axvline(median, color="#f28e2b", lw=1.5, label=f"median {median:.3g}")
        if limits and name in limits:
            ax.axvline(limits[name], color="#e15759", ls="--", lw=1.5,
                       label=f"limit {limits[name]:.3g}")
        ax.set_title(f"{name} (n={len(finite)}" + (f", {missing} non-finite)" if missing else ")"),
                     fontsize=10)
        ax.set_xlabel(name)
        ax.set_ylabel("runs")
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.savefig(out_png, dpi=80)
    plt.close(fig)
    return Path(out_png)


def distributions_from_summaries(summaries: Sequence[Mapping[str, Any]]) -> dict[str, list[float]]:
    """Peak accelerations and speeds of many runs' ``summary.json``, for ``plot_distributions``."""
    out: dict[str, list[float]] = {}
    for summary in summaries:
        for key, value in summary.get("peaks", {}).items():
            out.setdefault(key, []).append(float(value))
    return out


__all__ = ["RunData", "distributions_from_summaries", "load_mcap", "load_run", "load_trace",
           "plot_data", "plot_distributions", "plot_run", "plot_source"]
