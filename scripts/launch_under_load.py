"""``make launch-under-load`` (issue 20): ``overdrive launch`` while busy loops occupy every core.

For each scenario (default: the demo and the 60 s ``move-long``): the embedded run
(``overdrive sim``), then ``overdrive launch`` with ``--load`` busy-loop processes running for its
whole length; prints the launch's exit code, violations, and the distance between the two final
positions. Exit 0 only when every launch exits 0, has no violation and ends within
``--tolerance-m`` (0.5 m, the issue's figure) of its embedded run. Bounded: each launch has a
time limit, and the busy loops carry their own and are stopped by PID on every exit.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from overdrive.runtime.ports import free_port

ROOT = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
SCENARIOS = ("scenarios/demo.yaml", "scenarios/move-long.yaml")
TOLERANCE_M = 0.5          # issue 20: final position within 0.5 m of the embedded run
LAUNCH_OVERHEAD_S = 120.0  # start-up, shutdown and plotting on a loaded host, beyond the run


def busy_loops(count: int, limit_s: float) -> list[subprocess.Popen[bytes]]:
    """``count`` processes spinning on a core each, each ending by itself after ``limit_s``."""
    spin = f"import time\nend = time.monotonic() + {limit_s:.0f}\nwhile time.monotonic() < end: pass"
    return [subprocess.Popen([sys.executable, "-c", spin], stdin=subprocess.DEVNULL)
            for _ in range(count)]


def final(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


def one(scenario: str, load: int, out: Path) -> dict:
    embedded_dir, launched_dir = out / "embedded", out / "launched"
    shutil.rmtree(out, ignore_errors=True)   # never judge an earlier run's summary
    subprocess.run([str(BIN / "overdrive"), "sim", scenario, "--out", str(embedded_dir), "--quiet"],
                   check=False, cwd=ROOT, stdout=subprocess.DEVNULL)
    embedded = final(embedded_dir)
    limit_s = embedded["sim_time_s"] + LAUNCH_OVERHEAD_S
    loops = busy_loops(load, limit_s + 10)
    try:
        try:
            code: int | str = subprocess.run(
                [str(BIN / "overdrive"), "launch", scenario, "--out", str(launched_dir), "--quiet",
                 "--no-plot", "--listen", f"tcp/127.0.0.1:{free_port()}"],
                cwd=ROOT, timeout=limit_s, stdout=subprocess.DEVNULL).returncode
        except subprocess.TimeoutExpired:
            code = "timeout"
    finally:
        for p in loops:
            p.kill()
        for p in loops:
            p.wait()
    launched = final(launched_dir) if (launched_dir / "summary.json").exists() else None
    result = {"scenario": scenario, "exit": code, "load_processes": load,
              "embedded": [embedded["final"]["x_m"], embedded["final"]["y_m"]]}
    if launched is not None:
        result["launched"] = [launched["final"]["x_m"], launched["final"]["y_m"]]
        result["offset_m"] = round(math.dist(result["embedded"], result["launched"]), 3)
        result["violations"] = launched["violations"]
        nodes = launched["launch"]["nodes"]
        for key in ("p99", "max"):
            result[f"late_{key}_ms"] = {name: report.get("runtime", {}).get(f"lateness_{key}_ms")
                                        for name, report in nodes.items()}
        result["scheduling"] = sorted({report.get("scheduling", "?") for report in nodes.values()})
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", default=list(SCENARIOS))
    parser.add_argument("--load", type=int, default=2, help="busy-loop processes (default 2)")
    parser.add_argument("--tolerance-m", type=float, default=TOLERANCE_M)
    parser.add_argument("--keep", type=Path, help="keep the run folders here (default: removed)")
    args = parser.parse_args()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))   # run the finally blocks: stop the loops
    ok = True
    with tempfile.TemporaryDirectory(prefix="launch-under-load-") as tmp:
        for i, scenario in enumerate(args.scenarios):
            out = (args.keep or Path(tmp)) / f"{i}-{Path(scenario).stem}"
            result = one(scenario, args.load, out)
            passed = (result["exit"] == 0 and not result.get("violations", ["no summary"])
                      and result.get("offset_m", math.inf) <= args.tolerance_m)
            ok &= passed
            print(json.dumps({**result, "passed": passed}), flush=True)
    print(f"launch-under-load: {'passed' if ok else 'FAILED'} (load average "
          f"{os.getloadavg()[0]:.1f})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
