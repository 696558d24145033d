"""Bit-for-bit identity of every shipped scenario's run: a sha256 of each lock-step run's
``trace.csv``, ``summary.json`` (wall-clock and provenance fields dropped: they differ run to
run) and its events, written as JSON. Save one from the code before a change, one after, and
compare: a speed-up or refactor that claims "no behaviour change" must leave every hash equal.

    .venv/bin/python scripts/trace_identity.py OUT.json [--compare BASELINE.json] [-j 2]

Scenarios that do not load as one lock-step run (sweeps, scenarios needing a network peer) are
recorded with their error text, so a change in what loads is seen too. Exit 1 if ``--compare``
finds a difference.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import hashlib
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import load_scenario

ROOT = Path(__file__).resolve().parent.parent
# summary.json fields that depend on the wall clock or the checkout, not on the simulation
VOLATILE_FIELDS = ("wall_time_s", "real_time_factor", "provenance", "code", "wall_clock")


def sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def scenario_paths() -> list[Path]:
    return sorted((ROOT / "scenarios").glob("*.yaml")) + sorted(
        (ROOT / "scenarios" / "faults").glob("*.yaml"))


def run_hashes(path: Path) -> dict[str, Any]:
    """The hashes of one scenario's run (or its error text when it does not run lock-step)."""
    name = str(path.relative_to(ROOT))
    try:
        scenario = load_scenario(path)
        with tempfile.TemporaryDirectory() as tmp:
            result = run_scenario(scenario, Path(tmp) / "run", keep_trace=False, plot=False,
                                  record_mcap=False)
            trace = (Path(tmp) / "run" / "trace.csv").read_bytes()
    except Exception as exc:   # recorded: what fails must fail the same way
        return {"scenario": name, "error": f"{type(exc).__name__}: {exc}"}
    summary = {k: v for k, v in result.summary.items() if k not in VOLATILE_FIELDS}
    events = summary.get("events", [])
    return {"scenario": name, "exit_code": result.exit_code,
            "trace_sha256": sha(trace), "trace_bytes": len(trace),
            "summary_sha256": sha(json.dumps(summary, sort_keys=True, default=repr).encode()),
            "events_sha256": sha(json.dumps(events, sort_keys=True, default=repr).encode())}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--compare", type=Path, help="a baseline written by this script")
    parser.add_argument("-j", "--jobs", type=int, default=1)
    args = parser.parse_args()
    paths = scenario_paths()
    with concurrent.futures.ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(run_hashes, paths))
    args.out.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    ran = sum("error" not in r for r in results)
    print(f"{len(results)} scenarios, {ran} ran lock-step, hashes in {args.out}")
    if args.compare is None:
        return 0
    baseline = {r["scenario"]: r for r in json.loads(args.compare.read_text(encoding="utf-8"))}
    differ = [r["scenario"] for r in results if baseline.get(r["scenario"]) != r]
    missing = sorted(set(baseline) - {r["scenario"] for r in results})
    for name in differ + missing:
        print(f"DIFFERS: {name}")
    print("identical" if not differ and not missing else f"{len(differ) + len(missing)} differ")
    return 1 if differ or missing else 0


if __name__ == "__main__":
    sys.exit(main())
