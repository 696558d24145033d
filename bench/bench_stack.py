"""The whole stack in lock-step: step costs, real-time factor, recording cost, memory.

Run: ``.venv/bin/python bench/bench_stack.py [SCENARIO]`` (default: the MOVE-driven demo).

Figures, each next to its baseline where one exists (timings: the best of ``REPEATS`` runs,
figure by figure, as the machine is shared):

- per-node step cost (median, p99 us) and all servers together (move + driving + speed) per tick;
- a whole tick on ``LockstepRuntime`` (bus, channel model, inboxes) next to a bare loop that
  calls the same nodes' ``step`` and hands their messages to the subscribers directly;
- ``overdrive sim`` real-time factor: as users run it (``run.mcap`` and ``trace.csv`` written),
  with ``trace.csv`` only, and with no recording at all (wall clock, median of 3 runs);
- MCAP: ``overdrive.observe.mcap_writer`` next to the ``mcap`` package's ``Writer`` on the same
  messages (us per message, JSON already encoded), and the whole ``McapRecorder`` tap per bus
  message (JSON encoding and the Foxglove pose included);
- peak resident memory (``VmHWM``, else ``ru_maxrss``) of a fresh process driving 10 minutes
  and 1 hour of simulated time with ``run.mcap`` and ``trace.csv`` streamed to disk.

Targets (issue 10, on the 2-core reference machine): >= 300x real time on the demo; all
servers together <= 30 us median per step; a 1-hour drive under 200 MB.
"""

from __future__ import annotations

import io
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from overdrive.bus.local import LocalBus
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.runtime.lockstep import LockstepRuntime
from overdrive.scenario.player import channel_faults
from overdrive.scenario.schema import Scenario, load_scenario

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "scenarios" / "demo.yaml"
SERVERS = ("move", "driving", "speed")
TARGET_REAL_TIME_FACTOR = 300.0
TARGET_SERVERS_MEDIAN_US = 30.0
TARGET_HOUR_RSS_MB = 200.0
REPEATS = 3


def best_of(measure: Any, scenario: Scenario, repeats: int = REPEATS) -> dict[str, float]:
    """Each figure's lowest value over ``repeats`` runs of ``measure`` (timings only go up with
    load from elsewhere)."""
    runs = [measure(scenario) for _ in range(repeats)]
    return {key: min(run[key] for run in runs) for key in runs[0]}


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def _ticks(scenario: Scenario) -> int:
    return round(scenario.spec.duration_s / 0.01) + 1


def step_costs(scenario: Scenario) -> dict[str, float]:
    """Median and p99 of each node's step and of the servers' sum per tick, in microseconds."""
    nodes = build_nodes(scenario)
    samples: dict[str, list[float]] = {n.name: [] for n in nodes}
    clock = time.perf_counter_ns

    def timed(node: Any) -> Any:
        inner = node.step
        bucket = samples[node.name]

        def step(now_s: float, inbox: Any) -> Any:
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
    for tick in range(_ticks(scenario)):
        faults.now_s = tick * runtime.period_s
        runtime.step()
    results: dict[str, float] = {}
    servers_per_tick: list[float] | None = None
    for name, values in samples.items():
        results[f"step_us[{name}] median"] = statistics.median(values)
        results[f"step_us[{name}] p99"] = percentile(values, 0.99)
        if name in SERVERS:
            servers_per_tick = values[:] if servers_per_tick is None else [
                a + b for a, b in zip(servers_per_tick, values, strict=True)]
    if servers_per_tick is not None:
        results["step_us[all servers] median"] = statistics.median(servers_per_tick)
        results["step_us[all servers] p99"] = percentile(servers_per_tick, 0.99)
    return results


def tick_costs(scenario: Scenario) -> dict[str, float]:
    """A whole tick on ``LockstepRuntime`` vs a bare loop over the same nodes (no faults, taps)."""
    clock = time.perf_counter_ns
    nodes = build_nodes(scenario)
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    runtime = LockstepRuntime(nodes, bus)
    runtime_us = []
    for tick in range(_ticks(scenario)):
        faults.now_s = tick * runtime.period_s
        start = clock()
        runtime.step()
        runtime_us.append((clock() - start) / 1000.0)

    nodes = build_nodes(scenario)
    subscribers: dict[str, list[list[Any]]] = {}
    inboxes = []
    for node in nodes:
        inbox: list[Any] = []
        inboxes.append(inbox)
        for topic in node.subscriptions:
            subscribers.setdefault(topic, []).append(inbox)
    bare_us = []
    for tick in range(_ticks(scenario)):
        start = clock()
        now_s = tick * 0.01
        for node, inbox in zip(nodes, inboxes, strict=True):
            received = inbox[:]
            inbox.clear()
            for topic, msg in node.step(now_s, received):
                for target in subscribers.get(topic, ()):
                    target.append((topic, msg))
        bare_us.append((clock() - start) / 1000.0)
    return {"step_us[whole tick, LockstepRuntime] median": statistics.median(runtime_us),
            "step_us[whole tick, LockstepRuntime] p99": percentile(runtime_us, 0.99),
            "step_us[whole tick, bare loop baseline] median": statistics.median(bare_us),
            "step_us[whole tick, bare loop baseline] p99": percentile(bare_us, 0.99)}


def real_time_factors(scenario: Scenario, repeats: int = 3) -> dict[str, float]:
    """``overdrive sim``'s loop (the summary's wall time; no plot), median of ``repeats`` runs."""
    results = {}
    for label, out, mcap in (("run.mcap + trace.csv", True, True), ("trace.csv only", True, False),
                             ("no recording", False, False)):
        factors = []
        for _ in range(repeats):
            with tempfile.TemporaryDirectory() as tmp:
                summary = run_scenario(scenario, tmp if out else None, keep_trace=False,
                                       plot=False, record_mcap=mcap).summary
            factors.append(summary["sim_time_s"] / summary["wall_time_s"])
        results[f"sim_real_time_factor[{label}]"] = statistics.median(factors)
    return results


def bus_messages(scenario: Scenario) -> list[tuple[int, str, Any]]:
    """``(tick, topic, message)`` of everything the stack publishes on the scenario."""
    nodes = build_nodes(scenario)
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    runtime = LockstepRuntime(nodes, bus)
    seen: list[tuple[int, str, Any]] = []
    bus.tap(lambda topic, msg: seen.append((runtime.tick, topic, msg)))
    for tick in range(_ticks(scenario)):
        faults.now_s = tick * runtime.period_s
        runtime.step()
    return seen


def mcap_costs(scenario: Scenario, repeats: int = 3) -> dict[str, float]:
    """us per message: our writer vs the mcap package's on the same encoded messages; and the
    whole ``McapRecorder`` tap per bus message."""
    import msgspec
    from mcap.writer import CompressionType, Writer

    from overdrive.observe.mcap_log import McapRecorder
    from overdrive.observe.mcap_writer import McapWriter

    messages = bus_messages(scenario)
    encode = msgspec.json.encode
    topics = sorted({topic for _, topic, _ in messages})
    encoded = [(topics.index(topic) + 1, round(tick * 0.01 * 1e9), encode(msg))
               for tick, topic, msg in messages]

    def write_all(make: Any) -> float:
        best = float("inf")
        for _ in range(repeats):
            writer = make(io.BytesIO())
            writer.start(profile="", library="bench")
            schema = writer.register_schema("S", "jsonschema", b"{}")
            for topic in topics:
                writer.register_channel(topic, "json", schema, {})
            add = writer.add_message
            start = time.process_time()
            for sequence, (channel, t, data) in enumerate(encoded, 1):
                add(channel, t, data, t, sequence)
            writer.finish()
            best = min(best, time.process_time() - start)
        return best / len(encoded) * 1e6

    def recorder() -> float:
        best = float("inf")
        for _ in range(repeats):
            with McapRecorder(io.BytesIO(), scenario=scenario) as rec:
                observe, set_time = rec.observe, rec.set_time
                start = time.process_time()
                last = -1
                for tick, topic, msg in messages:
                    if tick != last:
                        set_time(tick * 0.01)
                        last = tick
                    observe(topic, msg)
                rec.close()
                best = min(best, time.process_time() - start)
        return best / len(messages) * 1e6

    return {
        "mcap_us_per_message[overdrive.observe.mcap_writer]": write_all(McapWriter),
        "mcap_us_per_message[mcap package Writer, baseline]": write_all(
            lambda stream: Writer(stream, compression=CompressionType.ZSTD)),
        "mcap_us_per_bus_message[McapRecorder: JSON, pose, writer]": recorder(),
    }


LONG_DRIVE = """
import json, resource, sys, tempfile
import msgspec
from overdrive.scenario.schema import load_scenario
from overdrive.run.sim import run_scenario
s = load_scenario(sys.argv[1])
s = msgspec.structs.replace(s, spec=msgspec.structs.replace(s.spec, duration_s=float(sys.argv[2])))
with tempfile.TemporaryDirectory() as tmp:
    run_scenario(s, tmp, keep_trace=False, plot=False)
peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
try:   # ru_maxrss survives exec: it can be the parent's at fork; VmHWM is this program's own
    with open("/proc/self/status") as f:
        peak_kb = next(int(line.split()[1]) for line in f if line.startswith("VmHWM:"))
except (OSError, StopIteration):
    pass
print(json.dumps(peak_kb / 1024.0))
"""


def peak_memory_mb(scenario_path: Path, duration_s: float) -> float:
    """Peak resident memory of a fresh process running ``duration_s`` of the scenario, with
    ``run.mcap`` and ``trace.csv`` written (streamed) as ``overdrive sim`` does.

    The child's own high-water mark (``VmHWM`` on Linux): ``ru_maxrss`` is kept across
    ``exec``, so a child of this (large) benchmark process would report at least its size.
    """
    out = subprocess.run([sys.executable, "-c", LONG_DRIVE, str(scenario_path), str(duration_s)],
                         check=True, capture_output=True, text=True).stdout
    return float(json.loads(out.strip().splitlines()[-1]))


def main(scenario_path: Path = DEMO) -> dict[str, Any]:
    scenario = load_scenario(scenario_path)
    results: dict[str, Any] = {}
    results.update(best_of(step_costs, scenario))
    results.update(best_of(tick_costs, scenario))
    results.update(real_time_factors(scenario))
    results.update(mcap_costs(scenario))
    results["peak_rss_mb[10 min drive]"] = peak_memory_mb(scenario_path, 600.0)
    results["peak_rss_mb[1 h drive]"] = peak_memory_mb(scenario_path, 3600.0)
    results["meets target[>= 300x real time, no recording]"] = (
        results["sim_real_time_factor[no recording]"] >= TARGET_REAL_TIME_FACTOR)
    results["meets target[servers <= 30 us median]"] = (
        results.get("step_us[all servers] median", float("inf")) <= TARGET_SERVERS_MEDIAN_US)
    results["meets target[1 h drive < 200 MB]"] = (
        results["peak_rss_mb[1 h drive]"] < TARGET_HOUR_RSS_MB)
    for key, value in results.items():
        shown = ("yes" if value else "NO") if isinstance(value, bool) else f"{value:12.1f}"
        print(f"{key:60s} {shown:>12s}")
    return results


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEMO)
