"""Stopping a run's processes: SIGTERM to the process group, a stack dump of a process that
hangs, SIGKILL after a grace period; and the stop flag a node's signal handler sets."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time

STOP_GRACE_S = 10.0             # SIGTERM -> SIGKILL of the process group (a loaded host needs time)
DUMP_SIGNAL = signal.SIGUSR1    # a node still up after the grace dumps every thread's stack first
DUMP_WAIT_S = 0.5               # (faulthandler: needs no GIL, so it works in a wedged process)


def stop_process_group(popen: subprocess.Popen, sig: int = signal.SIGTERM,
                       grace_s: float | None = None, dump: bool = True) -> bool:
    """Send ``sig`` (then SIGCONT) to ``popen``'s process group and wait ``grace_s`` (``STOP_GRACE_S``); a
    process still up then dumps every thread's stack (``DUMP_SIGNAL``, when ``dump``) and the
    group is killed. Stragglers in the group are killed either way. True if it had to be killed."""
    grace_s = STOP_GRACE_S if grace_s is None else grace_s
    killed = False
    if popen.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(popen.pid, sig)
            os.killpg(popen.pid, signal.SIGCONT)    # a stopped process (SIGSTOP) handles it now
    try:
        popen.wait(grace_s)
    except subprocess.TimeoutExpired:
        killed = True
        if dump:
            with contextlib.suppress(ProcessLookupError):   # where it hangs, on its stderr
                os.kill(popen.pid, DUMP_SIGNAL)
                time.sleep(DUMP_WAIT_S)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(popen.pid, signal.SIGKILL)
        popen.wait(grace_s)
    with contextlib.suppress(ProcessLookupError):   # stragglers in the group
        os.killpg(popen.pid, signal.SIGKILL)
    return killed


class StopFlag:
    """Set by a signal handler: a plain attribute, no lock. A ``threading.Event`` deadlocked a
    node at stop: the launcher's second SIGTERM arrived while the first handler held the Event's
    lock in ``set()``, and the second handler waited on it forever (faulthandler dump)."""

    def __init__(self) -> None:
        self.flag = False

    def set(self) -> None:
        self.flag = True

    def is_set(self) -> bool:
        return self.flag
