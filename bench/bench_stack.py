"""Per-step cost of each node and of the whole stack, real-time factor, memory of a long drive.

Run: ``.venv/bin/python bench/bench_stack.py [SCENARIO]``. Targets (issue 10): whole stack
lock-step >= 300x real time on the demo; all servers together <= 30 us median per step;
a 1-hour simulated drive (trace streamed to disk) under 200 MB.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

from overdrive.bus.local import LocalBus
from overdrive.player import channel_faults
from overdrive.runtime import LockstepRuntime
from overdrive.scenario import load_scenario
from overdrive.sim import build_nodes

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "scenarios" / "demo.yaml"
SERVERS = ("move", "driving", "speed")


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def step_costs(scenario_path: Path) -> dict[str, float]:
    """Median and p99 of each node's step, in microseconds, over one run of the scenario."""
    scenario = load_scenario(scenario_path)
    nodes = build_nodes(scenario)
    samples: dict[str, list[float]] = {n.name: [] for n in nodes}
    clock = time.perf_counter_ns

    def timed(node):
        inner = node.step
        bucket = samples[node.name]

        def step(now_s, inbox):
            start = clock()
            out = inner(now_s, inbox)
            bucket.append((clock() - start) / 1000.0)
            return out
        node.step = step
        return node

    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    runtime = LockstepRuntime([timed(n) for n in nodes], bus)
    end_tick = round(scenario.spec.duration_s / runtime.period_s)
    ticks: list[float] = []
    while runtime.tick <= end_tick:
        faults.now_s = runtime.tick * runtime.period_s
        start = clock()
        runtime.step()
        ticks.append((clock() - start) / 1000.0)
    results: dict[str, float] = {}
    servers_per_tick = [0.0] * len(ticks)
    for name, values in samples.items():
        results[f"step_us[{name}] median"] = statistics.median(values)
        results[f"step_us[{name}] p99"] = percentile(values, 0.99)
        if name in SERVERS and len(values) == len(ticks):
            servers_per_tick = [a + b for a, b in zip(servers_per_tick, values, strict=True)]
    if any(servers_per_tick):
        results["step_us[all servers] median"] = statistics.median(servers_per_tick)
        results["step_us[all servers] p99"] = percentile(servers_per_tick, 0.99)
    results["step_us[whole tick] median"] = statistics.median(ticks)
    results["step_us[whole tick] p99"] = percentile(ticks, 0.99)
    return results


def real_time_factor(scenario_path: Path, repeats: int = 3) -> float:
    """``overdrive sim`` as users run it (trace.csv written, no plot), median of runs."""
    import tempfile

    from overdrive.sim import run_scenario

    scenario = load_scenario(scenario_path)
    factors = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            summary = run_scenario(scenario, tmp, keep_trace=False, plot=False).summary
        factors.append(summary["sim_time_s"] / summary["wall_time_s"])
    return statistics.median(factors)


LONG_DRIVE = """
import json, resource, sys, tempfile
import msgspec
from overdrive.scenario import load_scenario
from overdrive.sim import run_scenario
s = load_scenario(sys.argv[1])
s = msgspec.structs.replace(s, spec=msgspec.structs.replace(s.spec, duration_s=float(sys.argv[2])))
with tempfile.TemporaryDirectory() as tmp:
    run_scenario(s, tmp, keep_trace=False, plot=False)
print(json.dumps(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0))
"""


def peak_memory_mb(scenario_path: Path, duration_s: float) -> float:
    """Peak resident memory of a fresh process running ``duration_s`` of the scenario."""
    out = subprocess.run([sys.executable, "-c", LONG_DRIVE, str(scenario_path), str(duration_s)],
                         check=True, capture_output=True, text=True).stdout
    return float(json.loads(out.strip().splitlines()[-1]))


def main(scenario_path: Path = DEMO) -> dict[str, float]:
    results = step_costs(scenario_path)
    results["sim_real_time_factor[demo]"] = real_time_factor(scenario_path)
    results["peak_rss_mb[10 min drive]"] = peak_memory_mb(scenario_path, 600.0)
    for key, value in results.items():
        print(f"{key:40s} {value:12.1f}")
    return results


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEMO)
