"""A node that ignores SIGTERM at the end of a run says where it hangs before it is killed."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from overdrive.run import launch as launch_mod
from overdrive.run.launch import Launch, NodeProcess

pytestmark = pytest.mark.wallclock   # real processes and signals

WEDGED = textwrap.dedent("""
    import faulthandler, signal, sys, time
    from overdrive.runtime.processes import DUMP_SIGNAL
    signal.signal(signal.SIGTERM, signal.SIG_IGN)       # as a node stuck where no handler runs
    faulthandler.register(DUMP_SIGNAL, all_threads=True)
    print("ready", flush=True)
    def wedged_here():
        time.sleep(120)
    wedged_here()
""")


def test_a_node_still_up_after_the_grace_dumps_its_stacks_then_is_killed(
        tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(launch_mod, "STOP_GRACE_S", 1.0)
    popen = subprocess.Popen([sys.executable, "-c", WEDGED], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    assert popen.stdout is not None and popen.stdout.readline().strip() == "ready"
    proc = NodeProcess("vehicle-sim", "", [], tmp_path / "report.json", popen=popen)
    Launch._stop_proc(None, proc)    # type: ignore[arg-type]  # uses no launcher state
    _out, err = popen.communicate(timeout=10)
    assert proc.killed_at_stop and popen.returncode == -9
    assert "wedged_here" in err, err[-2000:]           # every thread's stack, the hang's frame too
