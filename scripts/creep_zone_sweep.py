"""The sweep behind docs/driving-module.md's ``creep_zone_m`` figures (issue 31 item 9): single
MOVEs of 0.5-40 m at 2-12 m/s (the Ranger at most 10), on 0 and +-5 %, friction 0.8 and 0.3,
straight and on a 0.05 1/m arc, with the driving module's terminal creep zone set to each value
given. Judged from the run's judge and its stops: the authorization left where the vehicle
stood (never negative: never past the end) and the time from the command to the standstill.
One line per run, then per preset and creep zone the nearest stop to its end; exit 1 if a run
was violated or stopped past its end.

    .venv/bin/python scripts/creep_zone_sweep.py 1.0 0.5 0.3
"""

from __future__ import annotations

import itertools
import sys
from unittest import mock

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers import driving
from overdrive.servers.driving import DrivingConfig


def one_run(preset: str, creep_zone_m: float, d: float, v: float, grade: float, mu: float,
            k: float) -> tuple[float | None, float | None, list[str]]:
    """(authorization left at the stop, seconds from the command to rest, violations)."""
    data = {"name": "creep-sweep", "vehicle": preset, "start": "ready", "duration_s": 30.0,
            "world": {"grade_percent": grade, "friction": mu},
            "events": [{"at_s": 0.5, "move": {"distance_m": d, "maxspeed_mps": v,
                                              "curvature_1pm": k}}]}
    config = DrivingConfig(creep_zone_m=creep_zone_m)
    with mock.patch.object(driving, "DrivingConfig", lambda **kw: config):
        result = run_scenario(parse_scenario(data), keep_trace=True)
    margins = [s["authorization_margin_m"] for s in result.summary["stops"]
               if s.get("authorization_margin_m") is not None]
    rest_s, moving = None, False
    for row in result.trace or []:
        speed = abs(float(row["speed_mps"]))
        moving = moving or speed > 0.05
        if moving and speed < 0.005:
            rest_s = float(row["t_s"]) - 0.5
            break
    return (min(margins) if margins else None), rest_s, result.summary["violations"]


def main(zones: list[float]) -> int:
    bad = 0
    for preset, zone in itertools.product(PRESETS, zones):
        nearest = None
        for d, v, grade, mu, k in itertools.product([0.5, 1.5, 4.0, 12.0, 40.0], [2.0, 6.0, 12.0],
                                                    [0.0, 5.0, -5.0], [0.8, 0.3], [0.0, 0.05]):
            v = min(v, 10.0) if preset == "ranger-6x6" else v
            margin, rest_s, violations = one_run(preset, zone, d, v, grade, mu, k)
            print(f"{preset} creep_zone_m={zone} d={d} v={v} grade={grade} mu={mu} k={k}: "
                  f"left {margin} m, at rest after {rest_s} s, violations {violations}",
                  flush=True)
            bad += bool(violations) or (margin is not None and margin < 0.0)
            if margin is not None and (nearest is None or margin < nearest):
                nearest = margin
        print(f"== {preset} creep_zone_m={zone}: nearest stop {nearest} m short of its end")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main([float(a) for a in sys.argv[1:]] or [0.5]))
