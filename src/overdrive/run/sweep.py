"""Monte Carlo validation: ``overdrive sweep SCENARIO --runs N``.

Each run takes the scenario with its own seed and sampled parameters (friction, grade,
obstacle placement, the times of fault and safety events), runs it on one core of a process
pool, and keeps the safety-invariant violations the independent monitor found, the final
authorization margin (stopping error) and the peak accelerations. The worst runs are written
out as complete scenario files, so ``overdrive sim out/worst/run-N.yaml`` replays each exactly.

The sampling ranges come from the scenario's optional ``sweep:`` block (docs/scenarios.md);
expectations (``expect``) are reported but only invariant violations fail the sweep: sampled
conditions legitimately move the figures an expectation pins down.
"""

from __future__ import annotations

import copy
import math
import os
import random
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import yaml

from overdrive.observe.plot import plot_distributions
from overdrive.observe.provenance import run_provenance
from overdrive.observe.run_files import finite_json, make_out_dir
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import (
    Scenario,
    ScenarioError,
    SweepSpec,
    parse_scenario,
    read_scenario_data,
)
from overdrive.scenario.vehicles import names_a_file

JITTERED_KINDS = frozenset({
    "drop", "loss", "delay", "duplicate", "reorder", "sensor", "actuator", "engine_stall", "safestop",
    "manual_override", "emergency_manual_override", "estop_button", "internal_error", "door",
    "world",
})
"""Event kinds whose times are sampled: faults and safety devices, never the commands."""


NOISE_SIGMA: dict[str, tuple[float, float]] = {
    "gps": (0.1, 3.0),           # m: RTK fix changes to a multipath-hit standalone fix
    "wheel_speed": (0.05, 1.0),  # m/s: a loose or dirty tone-wheel pickup
    "imu": (0.1, 2.0),           # m/s^2: vibration on a badly mounted unit
    "radar": (0.5, 5.0),         # m: clutter, a second target
}
"""Noise a swept ``sensor_noise`` fault adds, per sensor, in the sensor's units (uniform)."""


def fault_event(kind: str, at_s: float, rng: random.Random) -> dict[str, Any]:
    """The scenario event of one swept fault kind, its parameters drawn from ``rng``."""
    for_s = round(rng.uniform(0.5, 5.0), 3)
    if kind in ("sensor_freeze", "sensor_dropout"):
        body: dict[str, Any] = {"sensor": {"name": rng.choice(("gps", "wheel_speed", "imu", "radar")),
                                           "fault": kind.removeprefix("sensor_"), "for_s": for_s}}
    elif kind == "sensor_noise":
        name = rng.choice(tuple(NOISE_SIGMA))
        body = {"sensor": {"name": name, "fault": "noise", "for_s": for_s,
                           "sigma": round(rng.uniform(*NOISE_SIGMA[name]), 3)}}
    elif kind in ("throttle_stuck", "brake_stuck"):
        body = {"actuator": {kind.removesuffix("_stuck"): {"stuck": True}}}
    elif kind in ("throttle_weak", "brake_weak"):
        pedal = kind.removesuffix("_weak")
        body = {"actuator": {pedal: {"effectiveness": round(rng.uniform(0.2, 0.8), 3)}}}
    elif kind == "brake_slow":
        body = {"actuator": {"brake": {"lag_scale": round(rng.uniform(2.0, 5.0), 3)}}}
    elif kind == "steering_stuck":
        body = {"actuator": {"steering": {"stuck": True}}}
    elif kind == "steering_slow":
        body = {"actuator": {"steering": {"rate_scale": round(rng.uniform(0.2, 0.6), 3)}}}
    elif kind in ("delay_move", "delay_advance"):
        body = {"delay": {"channel": kind.removeprefix("delay_"), "for_s": for_s,
                          "delay_s": round(rng.uniform(0.05, 0.5), 3)}}
    else:   # reorder_move
        body = {"reorder": {"channel": "move", "for_s": for_s}}
    return {"at_s": round(at_s, 3), **body}


def sample_run(data: dict[str, Any], run: int, base_seed: int,
               sweep: SweepSpec) -> tuple[dict[str, Any], str | None]:
    """The scenario data of run ``run`` and the fault kind it drew (None: no fault)."""
    out = sample_scenario(data, run, base_seed, sweep)
    spec = sweep.faults
    if spec is None:
        return out, None
    rng = random.Random(f"overdrive-sweep-fault/{base_seed + run}")
    if rng.random() >= spec.probability:
        return out, None
    kind = rng.choice(spec.kinds)
    low, high = min(spec.at_s), max(spec.at_s)
    at_s = min(rng.uniform(low, high), float(out.get("duration_s", 60.0)))
    out.setdefault("events", []).append(fault_event(kind, at_s, rng))
    return out, kind


def sample_scenario(data: dict[str, Any], run: int, base_seed: int, sweep: SweepSpec) -> dict[str, Any]:
    """The scenario data of run ``run``: its seed and sampled parameters (no drawn fault)."""
    seed = base_seed + run
    rng = random.Random(f"overdrive-sweep/{seed}")
    out = copy.deepcopy(data)
    out.pop("sweep", None)
    out.pop("expect", None) if sweep.drop_expectations else None
    out["seed"] = seed
    out["name"] = f"{data.get('name', 'sweep')}-run{run}"
    world = out.setdefault("world", {})
    if sweep.friction is not None:
        world["friction"] = round(rng.uniform(*sweep.friction), 4)
    if sweep.grade_percent is not None and not isinstance(world.get("grade_percent"), list):
        world["grade_percent"] = round(rng.uniform(*sweep.grade_percent), 3)
    if sweep.obstacle_jitter_m and world.get("obstacles"):
        world["obstacles"] = [
            {"x_m": round(o["x_m"] + rng.uniform(-1, 1) * sweep.obstacle_jitter_m, 3),
             "y_m": o["y_m"]} for o in world["obstacles"]]
    duration = float(out.get("duration_s", 60.0))
    if sweep.event_jitter_s:
        for event in out.get("events", []):
            if JITTERED_KINDS & set(event):
                shifted = event["at_s"] + rng.uniform(-1, 1) * sweep.event_jitter_s
                event["at_s"] = round(min(max(shifted, 0.0), duration), 3)
    return out


UNAVOIDABLE: dict[str, frozenset[str]] = {
    "brake_stuck": frozenset({"authorization", "contact", "speed"})}
"""Drawn faults after which these rules may be broken whatever the stack does (issue 16): with
the service brake stuck released only what the vehicle has left brakes it (issue 30 item 4:
engine braking, a downshift, the parking brake; downhill, gravity may beat them: the red team's
sweep, runs 50 and 68 of seed 91716). Such a run counts as unavoidable only if the stack
reacted as it must (an emergency stop, a fault notice, a takeover request) and the judge's
audit (``observe.secondary_audit``) says it used everything the vehicle has and stopped within
the distance that allows (or that no stop was possible); otherwise, and for any other rule, it
is an avoidable violation."""


BRAKE_LOST_CODES = frozenset({"1133", "1136"})
"""``safety.actuators.ActuatorFault`` BRAKE_NOT_APPLYING and BRAKE_FAILED (kept as strings: the
sweep reads summary.json events, whose codes are strings)."""


def unavoidable_cause(fault: str | None, rules: list[str], summary: dict[str, Any]) -> str | None:
    """Why a violating run's violations were physically unavoidable, or None when they were not:
    the drawn fault's own reaction must be in the events (the speed server's emergency stop,
    its fault saying the brake does not apply or failed, its takeover request) and the judge's
    secondary-braking audit must find every means used and the stop within its distance."""
    allowed = UNAVOIDABLE.get(fault or "")
    if not rules or allowed is None or not set(rules) <= allowed:
        return None
    events = summary["events"]
    reacted = all(any(e["kind"] == kind and e.get("source") == "speed"
                      and str(e.get("code")) in codes for e in events)
                  for kind, codes in (("estop", BRAKE_LOST_CODES), ("fault", BRAKE_LOST_CODES),
                                      ("takeover", BRAKE_LOST_CODES)))
    audit = summary.get("secondary_braking")
    if not reacted or not audit or not audit["all_used"]:
        return None
    if audit["within"]:
        return (f"{fault}: no service brake; every secondary means used, stopped in "
                f"{audit['distance_m']} m of the {audit['allowed_m']} m they allow")
    if audit["allowed_m"] is None:
        return f"{fault}: no service brake; every secondary means used, none can stop it here"
    return None


def run_one(job: tuple[dict[str, Any], str, int, str | None]) -> dict[str, Any]:
    """Run one sampled scenario (in a worker process); return its figures."""
    data, source, run, fault = job
    scenario = parse_scenario(data, f"{source} (run {run})")
    summary = run_scenario(scenario, None, keep_trace=False, plot=False).summary
    invariants = [v for v in summary["violations"] if v.startswith("invariant ")]
    rules = sorted({d["rule"] for d in summary["violation_details"]})
    return {
        "run": run,
        "seed": data["seed"],
        "fault": fault,
        "rules": rules,
        "unavoidable": unavoidable_cause(fault, rules, summary),
        "friction": data["world"].get("friction"),
        "grade_percent": data["world"].get("grade_percent"),
        "invariant_violations": invariants,
        "expectation_failures": [v for v in summary["violations"] if not v.startswith("invariant ")],
        "authorization_margin_m": min((s["authorization_margin_m"] for s in summary["stops"]),
                                      default=None),
        "odometer_m": summary["odometer_m"],
        "final_speed_mps": summary["final"]["speed_mps"],
        "max_speed_mps": summary["peaks"]["max_speed_mps"],
        "max_accel_mps2": summary["peaks"]["max_accel_mps2"],
        "max_decel_mps2": summary["peaks"]["max_decel_mps2"],
        "max_lateral_accel_mps2": summary["peaks"]["max_lateral_accel_mps2"],
        "estops": sum(1 for e in summary["events"] if e["kind"] == "estop"),
        "data": data,
    }


def load_raw(path: Path) -> tuple[dict[str, Any], Scenario]:
    """Read and validate the scenario; return its raw data and the validated scenario. A
    vehicle file it names is replaced by the vehicle's parameters (``parse_scenario``), so the
    samples run in worker processes and are written out without the file."""
    data = read_scenario_data(path)
    scenario = parse_scenario(data, str(path), path.parent)
    if names_a_file(data.get("vehicle")):
        data = {**data, "vehicle": scenario.spec.vehicle}
    return data, scenario


def sweep(path: Path, runs: int, jobs: int, out_dir: Path, base_seed: int | None = None,
          worst: int = 5) -> dict[str, Any]:
    """Run the sweep, write ``sweep.json``, ``runs.csv``, ``distributions.png`` and the worst runs."""
    data, scenario = load_raw(path)
    spec = scenario.spec.sweep
    base = int(data.get("seed", 1)) if base_seed is None else base_seed
    job_list = [(*sample_run(data, i, base, spec), i) for i in range(runs)]
    job_list = [(d, str(path), i, fault) for d, fault, i in job_list]
    for job in job_list:   # fail fast, before any worker starts, on an invalid sample
        parse_scenario(job[0], f"{path} (run {job[2]})")
    make_out_dir(out_dir)   # before the runs: a folder that cannot be made is a usage error
    jobs = max(1, min(jobs, runs))
    if jobs == 1:
        results = [run_one(job) for job in job_list]
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            results = list(pool.map(run_one, job_list, chunksize=max(1, runs // (jobs * 8))))
    violating = [r for r in results if r["invariant_violations"]]
    margins = [r["authorization_margin_m"] for r in results if r["authorization_margin_m"] is not None]

    def badness(r: dict[str, Any]) -> tuple:
        margin = r["authorization_margin_m"]
        return (len(r["invariant_violations"]), -(margin if margin is not None else math.inf),
                r["max_decel_mps2"])

    worst_runs = sorted(results, key=badness, reverse=True)[:worst]
    worst_dir = out_dir / "worst"
    worst_dir.mkdir(exist_ok=True)
    for r in worst_runs:
        (worst_dir / f"run-{r['run']}.yaml").write_text(
            yaml.safe_dump(r["data"], sort_keys=False), encoding="utf-8")
    report = {
        "scenario": str(path),
        "runs": runs,
        "base_seed": base,
        "violations": sum(len(r["invariant_violations"]) for r in results),
        "violating_runs": [r["run"] for r in violating],
        "avoidable_violating_runs": [r["run"] for r in violating if not r["unavoidable"]],
        "unavoidable": [{"run": r["run"], "rules": r["rules"], "cause": r["unavoidable"]}
                        for r in violating if r["unavoidable"]],
        "violations_by_rule": _by_rule(results),
        "runs_by_fault": _by_fault(results),
        "expectation_failures": sum(len(r["expectation_failures"]) for r in results),
        "authorization_margin_m": _stats(margins),
        "max_decel_mps2": _stats([r["max_decel_mps2"] for r in results]),
        "max_accel_mps2": _stats([r["max_accel_mps2"] for r in results]),
        "max_lateral_accel_mps2": _stats([r["max_lateral_accel_mps2"] for r in results]),
        "worst": [{k: r[k] for k in ("run", "seed", "fault", "friction", "grade_percent",
                                     "authorization_margin_m", "max_decel_mps2",
                                     "invariant_violations")}
                  | {"replay": "overdrive sim " + str(worst_dir / "run-{}.yaml".format(r["run"]))}
                  for r in worst_runs],
        "provenance": run_provenance(scenario.spec, scenario.vehicle),
    }
    (out_dir / "sweep.json").write_text(finite_json(report), encoding="utf-8")
    columns = ("run", "seed", "fault", "friction", "grade_percent", "authorization_margin_m",
               "odometer_m",
               "final_speed_mps", "max_speed_mps", "max_accel_mps2", "max_decel_mps2",
               "max_lateral_accel_mps2", "estops")
    lines = [",".join(columns)]
    lines += [",".join("" if r[c] is None else str(r[c]) for c in columns)
              + "," + str(len(r["invariant_violations"])) for r in results]
    lines[0] += ",invariant_violations"
    (out_dir / "runs.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    _plot(results, out_dir / "distributions.png")
    return report


def _by_rule(results: list[dict[str, Any]]) -> dict[str, int]:
    """How many runs broke each rule of the judge."""
    counts: dict[str, int] = {}
    for r in results:
        for rule in r["rules"]:
            counts[rule] = counts.get(rule, 0) + 1
    return dict(sorted(counts.items()))


def _by_fault(results: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per drawn fault kind: runs, violating runs, and the rules they broke."""
    table: dict[str, dict[str, Any]] = {}
    for r in results:
        row = table.setdefault(r["fault"] or "none", {"runs": 0, "violating": 0, "rules": {}})
        row["runs"] += 1
        row["violating"] += bool(r["invariant_violations"])
        for rule in r["rules"]:
            row["rules"][rule] = row["rules"].get(rule, 0) + 1
    return dict(sorted(table.items()))


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    ordered = sorted(values)
    return {"min": ordered[0], "median": ordered[len(ordered) // 2],
            "p95": ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))], "max": ordered[-1]}


def _plot(results: list[dict[str, Any]], out_png: Path) -> None:
    samples = {
        "smallest authorization margin at a stop (m)": [r["authorization_margin_m"] for r in results
                                                if r["authorization_margin_m"] is not None],
        "peak deceleration (m/s^2)": [r["max_decel_mps2"] for r in results],
        "peak acceleration (m/s^2)": [r["max_accel_mps2"] for r in results],
        "peak lateral acceleration (m/s^2)": [r["max_lateral_accel_mps2"] for r in results],
    }
    plot_distributions({k: v for k, v in samples.items() if v}, out_png)


def default_jobs() -> int:
    return os.cpu_count() or 1


__all__ = ["ScenarioError", "fault_event", "sample_run", "sample_scenario", "sweep"]
