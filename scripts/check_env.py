"""Stop before the tests when the environment is not the lock: ``make test`` and ``make run`` run
this first. Exit 0 when every pin that applies here is installed at its version and ``pip check``
finds nothing; exit 3 with one line per difference otherwise.

Usage: ``python scripts/check_env.py [requirements.lock]``
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from overdrive.observe.provenance import (
    LOCK_NAME,
    installed_versions,
    lock_drift,
    lock_entries,
    unlocked,
)

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str]) -> int:
    lock = Path(argv[0]) if argv else ROOT / LOCK_NAME
    try:
        entries = lock_entries(lock.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        print(f"check-env: {lock}: {exc}", file=sys.stderr)
        return 3
    installed = installed_versions()
    problems = lock_drift(entries, installed)
    pip = subprocess.run([sys.executable, "-m", "pip", "check"], capture_output=True, text=True,
                         check=False)
    if pip.returncode != 0:
        problems += [f"pip check: {line}" for line in pip.stdout.splitlines() if line.strip()]
    extra = unlocked(entries, installed)
    if extra:
        print(f"check-env: installed but not in {lock.name} (left alone): {', '.join(extra)}",
              file=sys.stderr)
    if problems:
        print(f"check-env: the environment differs from {lock.name}:", file=sys.stderr)
        for line in problems:
            print(f"  {line}", file=sys.stderr)
        print("check-env: reinstall from the lock (rm .venv/.installed-stamp && make test), or "
              "change the lock on purpose (make lock-upgrade)", file=sys.stderr)
        return 3
    print(f"check-env: {len(entries)} pins of {lock.name} hold, pip check clean")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
