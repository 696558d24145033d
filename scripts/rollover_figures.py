"""The figures behind docs/driving-module.md's "Rollover" table and measurements: each preset's
static stability factor, its static and planning rollover limits against the derated grip, and
a curve (10 m radius, friction 0.9, the drive gear's capped top speed as the limit, 60 m
authorized) driven with the centre of gravity swept from 0.9 to 1.4 x the height at which
rollover starts to bind. Judged from ground truth (the plant's peak lateral acceleration, the
judge's violations). One line per run; exit 1 if a peak exceeded its planning limit.

    .venv/bin/python scripts/rollover_figures.py
"""

from __future__ import annotations

import sys

from overdrive.dynamics.ellipse import ellipse_for, rollover_lat_mps2
from overdrive.dynamics.vehicle_params import G_MPS2, with_overrides
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS

FRICTION = 0.9
CURVATURE_1PM = 0.1
FACTORS = (0.9, 0.99, 1.01, 1.1, 1.4)


def peak_lat_mps2(preset: str, cg_height_m: float) -> tuple[float, list[str]]:
    p = PRESETS[preset]
    top = round(p.gear(p.drive_gear).max_speed_mps * 0.9, 2)
    spec = {"name": "rollover-figures",
            "vehicle": {"preset": preset, "cg_height_m": cg_height_m},
            "start": "ready", "seed": 1, "duration_s": 20, "world": {"friction": FRICTION},
            "events": [{"at_s": 0.5, "steer": {"curvature_1pm": CURVATURE_1PM}},
                       {"at_s": 1, "advance": {"source": "lidar", "distance_m": 60}},
                       {"at_s": 1, "max_speed": {"source": "map", "speed_mps": top}}]}
    summary = run_scenario(parse_scenario(spec, "rollover-figures"), None, plot=False,
                           keep_trace=False).summary
    return summary["peaks"]["max_lateral_accel_mps2"], summary["violations"]


def main() -> int:
    failed = False
    for preset in sorted(PRESETS):
        p = PRESETS[preset]
        grip = ellipse_for(p, FRICTION).lat_mps2
        crossover = p.cg_height_m * rollover_lat_mps2(p) / grip   # the limit goes as 1 / h_cg
        print(f"{preset}: SSF {p.static_stability_factor:.2f}, static "
              f"{G_MPS2 * p.static_stability_factor:.2f} m/s^2, planning "
              f"{rollover_lat_mps2(p):.2f} m/s^2, grip (derated, mu {FRICTION}) {grip:.2f} m/s^2, "
              f"rollover binds above cg {crossover:.3f} m")
        for factor in FACTORS:
            cg = round(crossover * factor, 3)
            q = with_overrides(p, {"cg_height_m": cg})
            limit = ellipse_for(q, FRICTION).lat_mps2
            peak, violations = peak_lat_mps2(preset, cg)
            failed |= peak > limit or bool(violations)
            print(f"  cg {cg:.3f} m: peak {peak:.2f} m/s^2, planning limit {limit:.2f}, static "
                  f"{G_MPS2 * q.static_stability_factor:.2f}, violations {violations}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
