"""``make bench``: run every ``bench/bench_*.py`` and print one table; also bench/results.json.

Each benchmark module has ``main() -> dict[str, float]``. A module whose subsystem is not in
this build (ImportError) is listed as skipped, never silently dropped.
"""

from __future__ import annotations

import importlib.util
import json
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def load(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> int:
    results: dict[str, dict[str, float]] = {}
    skipped: dict[str, str] = {}
    for path in sorted(HERE.glob("bench_*.py")):
        print(f"== {path.stem}", flush=True)
        try:
            module = load(path)
            results[path.stem] = module.main()
        except ImportError as exc:
            skipped[path.stem] = f"not in this build: {exc}"
            print(f"   skipped: {exc}")
    machine = {"python": platform.python_version(), "machine": platform.machine(),
               "processor": platform.processor() or platform.machine(),
               "cpus": __import__("os").cpu_count(), "date": time.strftime("%Y-%m-%d")}
    print()
    print(f"{'benchmark':22s} {'figure':46s} {'value':>14s}")
    for bench, figures in results.items():
        for key, value in figures.items():
            print(f"{bench:22s} {key:46s} {value:14,.1f}")
    for bench, reason in skipped.items():
        print(f"{bench:22s} {'skipped':46s} {reason}")
    (HERE / "results.json").write_text(json.dumps(
        {"machine": machine, "results": results, "skipped": skipped}, indent=2) + "\n")
    print(f"\nwritten: {HERE / 'results.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
