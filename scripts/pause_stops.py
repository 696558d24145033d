"""How the shipped vehicles stop from 8 m/s when paused, stopped or e-stopped (issue 31 item 2),
as a Markdown table for docs/drive-your-own-vehicle.md and docs/safety-case.md (H76): the
interruption at 9 s of a 120 m MOVE (or of a driving-module authorization alone), judged from
the simulated plant's speed and x.

Usage: ``python scripts/pause_stops.py``
"""

from __future__ import annotations

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS

ON_S = 9.0
STOPPED_MPS = 0.05
EVENTS = {"pause": {"safestop": "pause"}, "door": {"door": "open"},
          "e-stop": {"safestop": "stop"}}


def stop(preset: str, via: str, kind: str) -> tuple[float, float, float]:
    """(speed at the interruption, seconds and metres to a standstill)."""
    if via == "move server":
        start = [{"at_s": 0.5, "move": {"distance_m": 120, "maxspeed_mps": 8,
                                        "curvature_1pm": 0}}]
    else:
        start = [{"at_s": 0.5, "advance": {"source": "lidar", "distance_m": 120}},
                 {"at_s": 0.5, "max_speed": {"source": "map", "speed_mps": 8}}]
    data = {"name": "pause-stops", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": ON_S + 6.0, "events": [*start, {"at_s": ON_S, **EVENTS[kind]}]}
    rows = [r for r in run_scenario(parse_scenario(data), None, plot=False,
                                    record_mcap=False).trace if float(r["t_s"]) >= ON_S - 1e-9]
    v0, x0 = float(rows[0]["speed_mps"]), float(rows[0]["x_m"])
    end = next(r for r in rows if abs(float(r["speed_mps"])) < STOPPED_MPS)
    return v0, float(end["t_s"]) - ON_S, float(end["x_m"]) - x0


def main() -> None:
    print("| vehicle | through | interruption | speed (m/s) | time (s) | distance (m) "
          "| mean deceleration (m/s^2) |")
    print("|---|---|---|---|---|---|---|")
    for preset in PRESETS:
        for via in ("move server", "driving module alone"):
            for kind in EVENTS:
                v0, t_s, d_m = stop(preset, via, kind)
                print(f"| {preset} | {via} | {kind} | {v0:.2f} | {t_s:.2f} | {d_m:.2f} "
                      f"| {v0 / t_s:.2f} |")


if __name__ == "__main__":
    main()
