"""Launches of a 60 m MOVE with a process stalled, killed or restarted mid-MOVE, judged from the
simulated vehicle's own state (the vehicle-sim process's ``sim/truth`` in the launch's trace).

Used by tests/bus/test_launch_stalls.py (a sparse subset) and, as a script, for the whole sweep
(docs/multiprocess.md, "Injecting faults"):

    .venv/bin/python -m tests.bus.fault_launches [--out DIR] [--quick]
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from overdrive.run.launch import Launch, stall_actions
from overdrive.scenario.schema import Scenario, parse_scenario

DISTANCE_M = 60.0
MOVE_AT_S = 0.5
FAULT_AT_S = 8.0          # mid-MOVE at both speeds: cruising, 24-28 m done (lock-step run)
REST_MPS = 0.01           # at rest (ground truth, noise-free)
STILL_M = 0.02            # travel allowed once at rest after the fault (no new command comes)
SPEED_MARGIN_MPS = 0.1    # as tests/safety/test_unasked_stops.py
OVERRUN_MARGIN_M = 0.05
COMPLETE_M = 0.5          # "carried on to the end": within this of the MOVE's end
WATCH_AFTER_S = 6.0       # the run goes on this long after the fault ends (a drive-on shows)
END_BY_S = {4.0: 21.0, 8.0: 16.0}   # the undisturbed MOVE has ended by then (lock-step run)


def move_scenario(speed_mps: float, duration_s: float) -> Scenario:
    return parse_scenario({
        "name": f"move60-{speed_mps:g}", "vehicle": "escape-hybrid", "start": "ready", "seed": 1,
        "duration_s": duration_s,
        "events": [{"at_s": MOVE_AT_S, "move": {"distance_m": DISTANCE_M,
                                                "maxspeed_mps": speed_mps, "curvature_1pm": 0}}],
    }, f"move60-{speed_mps:g}")


@dataclass(frozen=True)
class Fault:
    node: str            # CLI name: vehicle-sim, speed, driving, move
    kind: str            # stall, kill (with --restart), restart
    speed_mps: float
    for_s: float = 0.0   # stall length

    @property
    def label(self) -> str:
        length = f" {self.for_s:g} s" if self.kind == "stall" else ""
        return f"{self.node} {self.kind}{length} at {self.speed_mps:g} m/s"


@dataclass
class Outcome:
    fault: str
    exit_code: int
    max_speed_mps: float
    final_odometer_m: float
    rest_after_fault_s: float | None
    travel_after_rest_m: float
    completed: bool
    interrupted: list[str]
    hung_reported_after_s: float | None
    judge_rules: list[str]
    process_lines: list[str]
    ok: bool
    why: str


def run_fault(fault: Fault, out_dir: Path) -> tuple[Outcome, dict[str, Any]]:
    """One launch of the 60 m MOVE with ``fault`` at ``FAULT_AT_S``; judged from ground truth."""
    end_s = FAULT_AT_S + fault.for_s + WATCH_AFTER_S
    duration_s = max(end_s, END_BY_S[fault.speed_mps] + 1.0)
    scenario = move_scenario(fault.speed_mps, duration_s)
    if fault.kind == "stall":
        actions = stall_actions(fault.node, FAULT_AT_S, fault.for_s)
    elif fault.kind == "kill":
        actions = [(FAULT_AT_S, "kill", fault.node)]
    else:
        actions = [(FAULT_AT_S, "restart", fault.node)]
    with Launch(scenario, out_dir, listen="", plot=False, actions=actions,
                restart=fault.kind == "kill") as launch:
        launch.start()
        result = launch.run()
    return judge(fault, result.summary, out_dir / "trace.csv", result.exit_code), result.summary


def judge(fault: Fault, summary: dict[str, Any], trace: Path, exit_code: int) -> Outcome:
    """No speed above the MOVE's limit, no overrun, and once at rest after the fault no motion
    (no new command is ever sent), unless the MOVE carried on to its end."""
    with trace.open(encoding="utf-8") as f:
        rows = [(float(r["t_s"]), float(r["speed_mps"]), float(r["odometer_m"]))
                for r in csv.DictReader(f)]
    max_speed = max(abs(v) for _, v, _ in rows)
    final_odo = max(o for _, _, o in rows)
    rest = next((i for i, (t, v, o) in enumerate(rows) if t >= FAULT_AT_S and abs(v) < REST_MPS
                 and o < DISTANCE_M - COMPLETE_M), None)
    rest_s = None if rest is None else rows[rest][0]
    after = [o for _, _, o in rows[rest:]] if rest is not None else []
    travel = (max(after) - min(after)) if after else 0.0     # from the first row at rest on
    completed = abs(final_odo - DISTANCE_M) <= COMPLETE_M
    events = summary["events"]
    interrupted = sorted({e.get("code", "") for e in events if e["kind"] == "interrupted"})
    hung = [e for e in events if e["kind"] == "process_hung"]
    signals = [e for e in events if e["kind"] == "process_signal"]
    hung_after = (round(hung[0]["t_s"] - signals[0]["t_s"], 3) if hung and signals else None)
    rules = sorted({d["rule"] for d in summary.get("violation_details", [])})
    process_lines = [v for v in summary["violations"] if v.startswith("process:")]
    why = []
    if max_speed > fault.speed_mps + SPEED_MARGIN_MPS:
        why.append(f"speed {max_speed:.2f} m/s over the limit {fault.speed_mps:g}")
    if final_odo > DISTANCE_M + OVERRUN_MARGIN_M:
        why.append(f"overrun: {final_odo:.2f} m of {DISTANCE_M:g}")
    if rest_s is not None and travel > STILL_M:
        why.append(f"moved {travel:.2f} m after coming to rest at t={rest_s:.2f} s")
    if rest_s is None and not completed:
        why.append(f"neither at rest nor at the end ({final_odo:.2f} m)")
    for rule in ("authorization", "speed", "unintended_motion"):
        if rule in rules:
            why.append(f"judge: {rule}")
    outcome = Outcome(fault.label, exit_code, round(max_speed, 3), round(final_odo, 3),
                      rest_s, round(travel, 3), completed, interrupted, hung_after, rules,
                      process_lines, not why, "; ".join(why))
    return outcome


def sweep(quick: bool) -> list[Fault]:
    nodes = ("vehicle-sim", "speed", "driving", "move")
    stalls = (0.1, 0.3, 1.0, 2.0)
    faults = [Fault(n, "stall", 8.0, s) for n in nodes for s in stalls]
    faults += [Fault(n, "stall", 4.0, s) for n in nodes for s in (0.3, 2.0)]
    faults += [Fault(n, "kill", 8.0) for n in ("speed", "driving", "move")]
    faults += [Fault(n, "restart", v) for n in ("speed", "driving", "move") for v in (4.0, 8.0)]
    return faults[:4] if quick else faults


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, help="keep the run folders and sweep.json here")
    parser.add_argument("--quick", action="store_true", help="the first four faults only")
    parser.add_argument("--rejudge", action="store_true",
                        help="judge the run folders already in --out again, launch nothing")
    parser.add_argument("--only", type=int, nargs="*", help="these fault numbers only")
    args = parser.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="overdrive-fault-sweep-"))
    out.mkdir(parents=True, exist_ok=True)
    results = []
    print("| fault | exit | max speed m/s | final m | at rest after | moved after rest m | "
          "interrupted | hang reported after s | judge | verdict |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for i, fault in enumerate(sweep(args.quick)):
        if args.only is not None and i not in args.only:
            continue
        run_dir = out / f"{i:02d}"
        started = time.monotonic()
        if args.rejudge:
            summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
            outcome = judge(fault, summary, run_dir / "trace.csv", 1 if summary["violations"] else 0)
        else:
            outcome, _summary = run_fault(fault, run_dir)
        results.append({**asdict(outcome), "wall_s": round(time.monotonic() - started, 1)})
        rest = "-" if outcome.rest_after_fault_s is None else f"{outcome.rest_after_fault_s:.2f} s"
        print(f"| {fault.label} | {outcome.exit_code} | {outcome.max_speed_mps:.2f} | "
              f"{outcome.final_odometer_m:.2f} | {rest} | {outcome.travel_after_rest_m:.3f} | "
              f"{', '.join(outcome.interrupted) or '-'} | "
              f"{'-' if outcome.hung_reported_after_s is None else outcome.hung_reported_after_s} | "
              f"{', '.join(outcome.judge_rules) or '-'} | "
              f"{'ok' if outcome.ok else 'FAIL: ' + outcome.why} |", flush=True)
        if args.out is None:
            shutil.rmtree(run_dir, ignore_errors=True)
    if args.rejudge or args.only is not None:
        return 1 if [r for r in results if not r["ok"]] else 0
    (out / "sweep.json").write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    failed = [r for r in results if not r["ok"]]
    print(f"{len(results) - len(failed)} of {len(results)} held; results: {out / 'sweep.json'}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
