"""The sweep behind docs/driving-module.md's "Grip lost in a curve" figures: a MOVE on an arc at
its speed cap (or 0.7 of it), the friction dropping once the vehicle cruises, each preset, curve
and drop of tests/safety/test_grip_lost_in_curve.py. Judged from ground truth: the largest
distance of the rear-axle centre from the commanded arc, the path driven after the drop, the
shortest physical stop at the new friction (the judge's), and the bound
``sqrt(R^2 + d^2) - R`` with ``d`` = that stop + 0.3 s at the drop's speed. One line per run;
exit 1 if a run exceeded its bound or was violated.

    .venv/bin/python scripts/grip_lost_sweep.py
"""

from __future__ import annotations

import itertools
import math
import sys

from overdrive.dynamics.ellipse import Ellipse, ellipse_for, lateral_speed_limit_mps
from overdrive.observe.judge import shortest_stop_m
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingConfig

DETECTION_S = 0.3     # as the tests: travel allowed for a slow slide to be seen
TRACKING_M = 0.1      # the arc's own tracking error (the steering ramp from rest)


def one_run(preset: str, k: float, friction: float, dropped: float, fraction: float) -> dict:
    params = PRESETS[preset]
    e = ellipse_for(params, friction)
    cap = lateral_speed_limit_mps(
        Ellipse(lon_mps2=e.lon_mps2, lat_mps2=e.lat_mps2 * DrivingConfig().lateral_use_fraction), k)
    speed = round(min(cap, 10.0) * fraction, 3)
    drop_s = round(1.0 + speed / 1.2 + 1.5, 2)
    data = {"name": "grip-lost-sweep", "vehicle": preset, "start": "ready", "seed": 3,
            "duration_s": drop_s + 15.0, "world": {"friction": friction},
            "events": [{"at_s": 0.5, "move": {"distance_m": 200.0, "maxspeed_mps": speed,
                                              "curvature_1pm": k}},
                       {"at_s": drop_s, "world": {"friction": dropped}}]}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)
    rows = result.trace
    radius = abs(1.0 / k)
    deviation = max(abs(math.hypot(float(r["x_m"]), float(r["y_m"]) + 1.0 / k) - radius)
                    for r in rows)
    at = next(i for i, r in enumerate(rows) if float(r["t_s"]) >= drop_s - 1e-9)
    after = sum(math.hypot(float(b["x_m"]) - float(a["x_m"]), float(b["y_m"]) - float(a["y_m"]))
                for a, b in itertools.pairwise(rows[at:]))
    v_drop = abs(float(rows[at]["speed_mps"]))
    shortest = shortest_stop_m(v_drop, params, dropped, 0.0, 0.01)
    lost = any(ev.get("code") == "grip_lost" and ev["kind"] == "hard_brake"
               for ev in result.summary["events"])
    travel = shortest + DETECTION_S * v_drop
    bound = math.hypot(radius, travel) - radius if lost else TRACKING_M
    return {"v_drop": v_drop, "lost": lost, "deviation": deviation, "bound": max(bound, TRACKING_M),
            "after": after, "shortest": shortest, "violations": result.summary["violations"]}


def main() -> int:
    bad = 0
    print("preset         k_1pm  mu      v_mps  grip_lost  dev_m  bound_m  after_m  shortest_m")
    for preset in PRESETS:
        for k, (mu0, mu1), fraction in itertools.product(
                (0.1, -0.1, 0.05, -0.05), ((0.8, 0.25), (0.8, 0.1), (0.6, 0.3)), (1.0, 0.7)):
            r = one_run(preset, k, mu0, mu1, fraction)
            ok = r["deviation"] <= r["bound"] and not r["violations"]
            bad += not ok
            print(f"{preset:14s} {k:+.2f}  {mu0}->{mu1:<4} {r['v_drop']:5.2f}  {r['lost']!s:9s}  "
                  f"{r['deviation']:5.2f}  {r['bound']:7.2f}  {r['after']:7.2f}  "
                  f"{r['shortest']:10.2f}{'' if ok else '  EXCEEDED'}", flush=True)
    print(f"{bad} run(s) beyond their bound")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
