"""``make bench``: run every ``bench/bench_*.py`` and print one table; also bench/results.json.

Each benchmark module has ``main() -> dict``: figures by name, possibly nested (a nested dict's
keys are joined with ``.`` in the table; lists are shown by their length). A module whose
subsystem is not in this build (ImportError) is listed as skipped, and one that fails is listed
with its error; neither is silently dropped, and the others still run.
"""

from __future__ import annotations

import importlib.util
import json
import os
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent


def load(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def flatten(figures: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """``(name, value)`` rows of a benchmark's result, nested dicts joined with ``.``."""
    if not isinstance(figures, dict):
        return [(prefix or "result", figures)]
    rows: list[tuple[str, Any]] = []
    for key, value in figures.items():
        name = f"{prefix}.{key}" if prefix else str(key)
        if isinstance(value, dict):
            rows.extend(flatten(value, name))
        else:
            rows.append((name, value))
    return rows


def shown(value: Any) -> str:
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, (int, float)):
        return f"{value:14,.1f}" if abs(value) < 1e15 else f"{value:14.3g}"
    if isinstance(value, (list, tuple)):
        return f"{len(value):>14d} items"
    return f"{value!s:>14s}"


def main() -> int:
    results: dict[str, Any] = {}
    skipped: dict[str, str] = {}
    failed: dict[str, str] = {}
    argv = sys.argv
    for path in sorted(HERE.glob("bench_*.py")):
        print(f"== {path.stem}", flush=True)
        sys.argv = [str(path)]   # modules that parse arguments see none
        try:
            module = load(path)
            results[path.stem] = module.main()
        except ImportError as exc:
            skipped[path.stem] = f"not in this build: {exc}"
            print(f"   skipped: {exc}")
        except Exception as exc:   # report it and run the other benchmarks
            failed[path.stem] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
        finally:
            sys.argv = argv
    machine = {"python": platform.python_version(), "machine": platform.machine(),
               "processor": platform.processor() or platform.machine(),
               "cpus": os.cpu_count(), "date": time.strftime("%Y-%m-%d")}
    print()
    print(f"{'benchmark':14s} {'figure':66s} {'value':>14s}")
    for bench, figures in results.items():
        for key, value in flatten(figures):
            print(f"{bench:14s} {key:66s} {shown(value)}")
    for bench, reason in skipped.items():
        print(f"{bench:14s} {'skipped':66s} {reason}")
    for bench, reason in failed.items():
        print(f"{bench:14s} {'FAILED':66s} {reason}")
    (HERE / "results.json").write_text(json.dumps(
        {"machine": machine, "results": results, "skipped": skipped, "failed": failed},
        indent=2, default=str) + "\n")
    print(f"\nwritten: {HERE / 'results.json'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
