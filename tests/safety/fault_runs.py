"""Whole runs for the fault tests that are not sweeps: a scenario built from events, and what
the run is judged by (the judge's violations, ground truth from the trace, the events)."""

from __future__ import annotations

from typing import Any

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario


def run(vehicle: str, events: list[dict], world: dict | None = None, duration_s: float = 30.0,
        start: str = "ready", seed: int = 7) -> Any:
    data = {"name": "faults", "vehicle": vehicle, "start": start, "duration_s": duration_s,
            "seed": seed, "world": world or {}, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def move(at_s: float, distance_m: float, speed_mps: float, curvature_1pm: float = 0.0) -> dict:
    return {"at_s": at_s, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                   "curvature_1pm": curvature_1pm}}


def sensor(at_s: float, name: str, fault: str, for_s: float = 60.0, sigma: float = 1.0) -> dict:
    return {"at_s": at_s, "sensor": {"name": name, "fault": fault, "for_s": for_s, "sigma": sigma}}


def actuator(at_s: float, **body: Any) -> dict:
    return {"at_s": at_s, "actuator": body}


def rules_of(result: Any) -> set[str]:
    return {d["rule"] for d in result.summary["violation_details"]}


def peak_speed_mps(result: Any) -> float:
    return max(float(r["speed_mps"]) for r in result.trace)


def final_x_m(result: Any) -> float:
    return float(result.trace[-1]["x_m"])


def estops(result: Any) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == "estop"]
