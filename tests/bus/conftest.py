"""Fixtures of the multi-process tests."""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.bus.waits import LOADED_TIMEOUT_S


def _processes_mentioning(marker: str) -> list[int]:
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        with contextlib.suppress(OSError):
            if marker in Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace"):
                found.append(int(pid))
    return found


@pytest.fixture
def run_dir(tmp_path: Path) -> Iterator[Path]:
    """A run folder; afterwards no process may still mention it (nodes get it via --report)."""
    yield tmp_path
    deadline = time.monotonic() + LOADED_TIMEOUT_S
    while _processes_mentioning(str(tmp_path)) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = _processes_mentioning(str(tmp_path))
    for pid in left:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    assert not left, f"processes left behind: {left}"


STALL_LIMIT_MS = 60.0
"""A third of the 200 ms watchdogs, whose chains span up to three processes (sender, receiver,
and the launcher feeding a source): stalls this long in turn can rightly trip one (an emergency
stop), and the run is then no comparison with the embedded one."""
ATTEMPTS = 2


class HostStalled(Exception):
    """The host did not run a process of the run for ``STALL_LIMIT_MS`` or more."""


def check_undisturbed(summary: dict) -> None:
    """Raise ``HostStalled`` if any process of the run was late by ``STALL_LIMIT_MS`` or more."""
    late = {name: report["runtime"].get("lateness_max_ms", 0.0)
            for name, report in summary["launch"]["nodes"].items()}
    late.update({f"launcher {name}": stats["lateness_max_ms"]
                 for name, stats in summary["launch"]["launcher"]["runtime"].items()})
    stalled = {name: ms for name, ms in late.items() if ms >= STALL_LIMIT_MS}
    if stalled:
        raise HostStalled(f"steps late by {stalled} ms")


def retry_when_stalled(test):
    """Run a multi-process test again (in a clean ``run_dir``) when the host stalled one of its
    processes; skip, saying so, if it did in every attempt. Any other failure fails at once."""
    @functools.wraps(test)
    def wrapper(*args, **kwargs):
        reason = ""
        for _ in range(ATTEMPTS):
            try:
                return test(*args, **kwargs)
            except HostStalled as exc:
                reason = str(exc)
                run_dir = kwargs.get("run_dir")
                if run_dir is not None:
                    for child in Path(run_dir).iterdir():
                        shutil.rmtree(child, ignore_errors=True)
        pytest.skip(f"the host stalled a process in each of {ATTEMPTS} attempts: {reason}")
    return wrapper


def as_stranger() -> None:
    """``preexec_fn`` of a tool or attacker a test starts during a run: default priority, not
    the launcher's raised one (children inherit it), as any other process on the host."""
    with contextlib.suppress(OSError):
        os.setpriority(os.PRIO_PROCESS, 0, 0)
