"""Stop before the tests when the environment is not the lock: ``make test`` and ``make run`` run
this first. Exit 0 when every pin that applies here is installed at its version and ``pip check``
finds nothing; exit 3 with one line per difference otherwise.

Usage: ``python scripts/check_env.py [requirements.lock]``
"""

from __future__ import annotations

import importlib.metadata
import subprocess
import sys
from pathlib import Path

import overdrive
from overdrive.observe.provenance import (
    LOCK_NAME,
    installed_versions,
    lock_drift,
    lock_entries,
    normalize,
    unlocked,
    unlocked_requirements,
)

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str]) -> int:
    lock = Path(argv[0]) if argv else ROOT / LOCK_NAME
    installed = installed_versions()
    try:
        entries = lock_entries(lock.read_text(encoding="utf-8"))
        problems = lock_drift(entries, installed)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        print(f"check-env: {lock}: {exc}", file=sys.stderr)
        return 3
    problems += [f"{name}: required by pyproject.toml, not in {lock.name} (run make lock)"
                 for name in unlocked_requirements(entries)]
    pip = subprocess.run([sys.executable, "-m", "pip", "check"], capture_output=True, text=True,
                         check=False)
    if pip.returncode != 0:
        said = [line for line in (pip.stdout + pip.stderr).splitlines() if line.strip()]
        problems += [f"pip check: {line}" for line in said] or [
            f"pip check: exit {pip.returncode} with nothing said"]
    extra = unlocked(entries, installed)
    plugins = {normalize(ep.dist.name) for ep in importlib.metadata.entry_points(group="pytest11")
               if ep.dist is not None}
    problems += [f"{line}: a pytest plugin not in {lock.name} (it changes how tests run)"
                 for line in extra if line.split()[0] in plugins]
    imported = Path(overdrive.__file__).resolve()
    if not imported.is_relative_to(ROOT / "src"):
        problems.append(f"overdrive: imported from {imported.parent}, not from this checkout "
                        f"({ROOT / 'src'}): reinstall (rm {ROOT / '.venv/.installed-stamp'})")
    if extra:
        print(f"check-env: installed but not in {lock.name} (left alone): {', '.join(extra)}",
              file=sys.stderr)
    if problems:
        print(f"check-env: the environment differs from {lock.name}:", file=sys.stderr)
        for line in problems:
            print(f"  {line}", file=sys.stderr)
        print("check-env: reinstall from the lock (rm .venv/.installed-stamp && make test), or "
              "change the lock on purpose (make lock, or make lock-upgrade)", file=sys.stderr)
        return 3
    print(f"check-env: {len(entries)} pins of {lock.name} hold, pip check clean")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
