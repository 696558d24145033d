"""How the OS schedules a run's processes: real-time priority for nodes where permitted, a
raised niceness otherwise, a CPU-time limit that ends a runaway, and a child that dies with its
launcher. Reports say what each thread got (``scheduling``)."""

from __future__ import annotations

import os
import signal
import sys

RUN_NICE = -10
"""Niceness of a run's processes where the OS permits raising it (root or CAP_SYS_NICE): on a
busy host the CFS scheduler then gives a 10 ms control loop ~10x the share of a default-priority
busy loop, so nodes are not starved into watchdog stops; without the permission, unchanged."""
NODE_RT_PRIORITY = 10
"""``SCHED_FIFO`` priority of a node's process (every thread) where the OS permits it (root,
``CAP_SYS_NICE``, or ``RLIMIT_RTPRIO`` >= 10), as openpilot runs its control processes: a node that
wakes for its step or a command runs at once instead of waiting for the CFS to pick it among busy
processes (at nice -10, launches under two busy loops still saw nodes stalled 65-87 ms and watchdog
stops). Low among real-time priorities, below the kernel's threaded interrupts (50). Set after the
imports (start-up is a CPU burst that must not hold running nodes back: FIFO has no time slice)."""
NODE_RT_CPU_LIMIT_S = (0.5, 1.0)
"""``RLIMIT_RTTIME`` (soft, hard) of a real-time node: a thread that runs this long without
blocking gets SIGXCPU, which ends the process (then SIGKILL at the hard limit); a node steps every
10 ms for well under a millisecond and sleeps between steps, so only a runaway hits it. The
kernel's real-time throttling alone would leave the rest of the host 5 % of a CPU meanwhile, and a
dead node is what the watchdogs are for."""


def raise_priority() -> int | None:
    """Run this thread (and the threads it starts later) at ``RUN_NICE`` when the OS allows it;
    the previous niceness, else None. On Linux niceness is per thread."""
    try:
        before = os.getpriority(os.PRIO_PROCESS, 0)
        if before > RUN_NICE:
            os.setpriority(os.PRIO_PROCESS, 0, RUN_NICE)
        return before
    except (OSError, AttributeError):   # not permitted (no CAP_SYS_NICE) or not POSIX: as is
        return None


def realtime_priority(priority: int = NODE_RT_PRIORITY) -> bool:
    """Run this thread (and the threads it starts later: call it before any) ``SCHED_FIFO`` at
    ``priority``, with ``NODE_RT_CPU_LIMIT_S``, where the OS permits it; True if it does."""
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_RTTIME,
                           tuple(round(s * 1e6) for s in NODE_RT_CPU_LIMIT_S))
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError, AttributeError, ImportError):  # not permitted, or not Linux: as is
        return False
    return True


def node_priority(rt_priority: bool = True) -> None:
    """A node's priority: ``SCHED_FIFO`` if ``rt_priority`` and permitted, else ``RUN_NICE`` if
    permitted, else as started."""
    if not (rt_priority and realtime_priority()):
        raise_priority()


def scheduling() -> str:
    """How the OS schedules this process's threads, for reports: ``fifo:10``,
    ``other:nice=-10``, or several joined by ``,`` when the threads differ."""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = [0]
    seen = set()
    for tid in tids:
        try:
            policy = os.sched_getscheduler(tid)
            if policy in (os.SCHED_FIFO, os.SCHED_RR):
                name = "fifo" if policy == os.SCHED_FIFO else "rr"
                seen.add(f"{name}:{os.sched_getparam(tid).sched_priority}")
            else:
                seen.add(f"other:nice={os.getpriority(os.PRIO_PROCESS, tid)}")
        except ProcessLookupError:    # a thread that ended meanwhile
            continue
        except (OSError, AttributeError):
            seen.add("unknown")
    return ",".join(sorted(seen))


def node_child() -> None:
    """In a node's child process: ``RUN_NICE`` where permitted (the node goes real-time itself,
    after its imports), die with the launcher."""
    raise_priority()
    die_with_parent()


def die_with_parent() -> None:
    """In the child: get SIGTERM when the launcher dies, even by SIGKILL (Linux)."""
    if sys.platform.startswith("linux"):
        import ctypes

        PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
