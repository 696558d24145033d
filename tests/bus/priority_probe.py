"""What this host lets a node's process do about its priority, probed in throw-away children."""

from __future__ import annotations

import os
import subprocess
import sys

from overdrive.runtime.scheduling import NODE_RT_PRIORITY, RUN_NICE


def _permitted(code: str) -> bool:
    return subprocess.run([sys.executable, "-c", code], capture_output=True).returncode == 0


RT_PERMITTED = _permitted("import os; os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))")
NICE_PERMITTED = _permitted(f"import os; os.setpriority(os.PRIO_PROCESS, 0, {RUN_NICE})")
STARTED_NICE = os.getpriority(os.PRIO_PROCESS, 0)
EXPECTED = (f"fifo:{NODE_RT_PRIORITY}" if RT_PERMITTED
            else f"other:nice={RUN_NICE if NICE_PERMITTED else STARTED_NICE}")
"""What every thread of a node reports on this host."""
