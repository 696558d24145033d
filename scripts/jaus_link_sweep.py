"""The lock-step sweep behind docs/xgv.md's "A lossy link" and "A delay towards the vehicle"
figures: a 60 m MOVE at 8 m/s from rest over ``interface: jaus`` (real UDP on loopback), with
loss (5-50 % in steps of 5 %, seeds 0-4, from 0.4 s), a cut (0.1-2.0 s in steps of 0.1 s, at
4 s and 6.5 s) or a delay towards the vehicle only (0.05-0.5 s in steps of 0.05 s, 1 s and 2 s,
at 4 s while accelerating and at 8 s at cruise), judged from the simulated XGV's own state. One
line per run, then a summary; exit 1 if any run was violated (for ``delay``: by anything but
the link faults it is meant to raise: ``xgv_round_trip``, ``xgv_link_degraded``, and from
0.5 s the XGV's own timeouts, ``xgv_error_pause`` and ``xgv_not_following``).

    .venv/bin/python scripts/jaus_link_sweep.py loss|cut|delay [--control wrench|motion-profile]
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario


def one_run(seed: int, fault: dict[str, Any], control: str) -> dict[str, Any]:
    scenario = parse_scenario({
        "name": "jaus-link-sweep", "interface": "jaus", "control": control,
        "vehicle": "escape-hybrid", "start": "ready", "seed": seed, "duration_s": 18.0,
        "events": [{"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 8,
                                          "curvature_1pm": 0}}, fault]}, "sweep")
    result = run_scenario(scenario, None, keep_trace=True, nodes=build_nodes(scenario),
                          plot=False)
    summary = result.summary
    return {"violations": summary["violations"], "final_x_m": summary["final"]["x_m"],
            "peak_mps": max(float(r["speed_mps"]) for r in result.trace),
            "events": [(e["kind"], e.get("code"), e["t_s"]) for e in summary["events"]
                       if e["kind"] in ("fault", "interrupted")]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("kind", choices=["loss", "cut", "delay"])
    parser.add_argument("--control", choices=["wrench", "motion-profile"], default="wrench")
    args = parser.parse_args()
    runs: list[tuple[str, dict[str, Any]]] = []
    if args.kind == "loss":
        cases = [(f"loss {5 * i} % seed {seed}", seed,
                  {"at_s": 0.4, "loss": {"channel": "jaus", "for_s": 18, "fraction": 0.05 * i}})
                 for i in range(1, 11) for seed in range(5)]
    elif args.kind == "delay":
        cases = [(f"delay {d:.2f} s at {at} s", 1,
                  {"at_s": at, "delay": {"channel": "jaus", "for_s": 18, "delay_s": d,
                                         "direction": "to_vehicle"}})
                 for d in [round(0.05 * i, 2) for i in range(1, 11)] + [1.0, 2.0]
                 for at in (4.0, 8.0)]
    else:
        cases = [(f"cut {0.1 * i:.1f} s at {at} s", 1,
                  {"at_s": at, "drop": {"channel": "jaus", "for_s": round(0.1 * i, 1)}})
                 for i in range(1, 21) for at in (4.0, 6.5)]
    for name, seed, fault in cases:
        got = one_run(seed, fault, args.control)
        runs.append((name, got))
        print(name, got, flush=True)
    if args.kind == "delay":   # the faults it is meant to cause fail the run: not violations
        meant = ("link fault xgv_round_trip", "link fault xgv_link_degraded",
                 "link fault xgv_error_pause",    # from 0.5 s: the XGV's own wrench timeout
                 "link fault xgv_not_following")  # and its motion lapsing (400 ms)
        for _, got in runs:
            got["violations"] = [v for v in got["violations"] if not v.startswith(meant)]
    violated = [name for name, got in runs if got["violations"]]
    finals = [got["final_x_m"] for _, got in runs]
    print(f"{len(runs)} runs, {len(violated)} violated {violated}; final x "
          f"{min(finals):.2f}-{max(finals):.2f} m; peak "
          f"{max(got['peak_mps'] for _, got in runs):.3f} m/s; runs with a fault or "
          f"interruption {sum(1 for _, got in runs if got['events'])}")
    return 1 if violated else 0


if __name__ == "__main__":
    sys.exit(main())
