"""Closed-loop harness for the move-server tests: a scenario run that also keeps chosen topics,
and whole runs built from a list of events (the runner's own, with the judge)."""

from __future__ import annotations

from typing import Any

from overdrive.bus.local import LocalBus
from overdrive.messages import Topic
from overdrive.observe.recorder import Recorder
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.runtime.lockstep import DEFAULT_PERIOD_S, LockstepRuntime
from overdrive.scenario.player import channel_faults
from overdrive.scenario.schema import parse_scenario


class Run:
    def __init__(self, summary: dict[str, Any], rows: list[dict[str, str]],
                 series: dict[str, list[tuple[float, Any]]], nodes: dict[str, Any]) -> None:
        self.summary = summary
        self.rows = rows
        self.series = series
        self.nodes = nodes

    def column(self, name: str) -> list[tuple[float, float]]:
        return [(float(r["t_s"]), float(r[name])) for r in self.rows if r[name] != ""]

    def events(self, kind: str) -> list[dict[str, Any]]:
        return [e for e in self.summary["events"] if e["kind"] == kind]


def simulate(spec: dict[str, Any], keep: tuple[str, ...] = ()) -> Run:
    """Run ``spec`` (a scenario mapping) like ``overdrive sim``; keep every message on ``keep``.

    Built from the runner's parts (nodes, bus, channel faults, recorder) so that the tests can
    also see the move server's own topics over time.
    """
    scenario = parse_scenario({"name": "move-test", **spec})
    nodes = build_nodes(scenario)
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    recorder = Recorder(None, keep_rows=True)
    bus.tap(recorder.observe)
    series: dict[str, list[tuple[float, Any]]] = {t: [] for t in keep}
    clock = {"now": 0.0}

    def tap(topic: str, msg: Any) -> None:
        if topic in series:
            series[topic].append((clock["now"], msg))

    bus.tap(tap)
    runtime = LockstepRuntime(nodes, bus, DEFAULT_PERIOD_S)
    end_tick = round(scenario.spec.duration_s / DEFAULT_PERIOD_S)
    while runtime.tick <= end_tick:
        clock["now"] = faults.now_s = runtime.tick * DEFAULT_PERIOD_S
        now_s = runtime.step()
        recorder.tick(now_s)
    assert recorder.rows is not None
    truth = recorder.latest[Topic.TRUTH]
    summary = {
        "odometer_m": truth.odometer_m,
        "final": {"x_m": truth.x_m, "y_m": truth.y_m, "heading_rad": truth.heading_rad,
                  "speed_mps": truth.speed_mps},
        "peaks": {"max_speed_mps": recorder.max_speed_mps,
                  "max_lateral_accel_mps2": recorder.max_lat_accel_mps2,
                  "max_decel_mps2": recorder.max_decel_mps2},
        "contact": recorder.contact_at_s is not None,
        "events": recorder.events,
    }
    return Run(summary, recorder.rows, series, {n.name: n for n in nodes})


def run_events(events: list[dict], *, duration_s: float, vehicle: Any = "escape-hybrid",
               world: dict | None = None, start: str = "ready", **spec: Any) -> Any:
    """``events`` as a scenario run by ``overdrive sim``'s runner (judged, summarised);
    ``spec``: more top-level scenario fields."""
    data = {"name": "move-run", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "world": world or {}, "events": events, **spec}
    return run_scenario(parse_scenario(data), None)


def move(at_s: float, distance_m: float, maxspeed_mps: float, curvature_1pm: float = 0.0) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": maxspeed_mps,
                                   "curvature_1pm": curvature_1pm}}


def events_of(result: Any, kind: str) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == kind]
