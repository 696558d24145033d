"""Node processes run real-time (``SCHED_FIFO``) where the OS permits it, else at ``RUN_NICE``.

Judged from the OS (the policy of every thread of the child, Zenoh's included), not from what the
launcher meant to set; the demo launch test checks the same in each node's report.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from overdrive.run import launch as launch_mod
from overdrive.run.launch import Launch
from overdrive.runtime.ports import free_port
from overdrive.runtime.scheduling import NODE_RT_PRIORITY, RUN_NICE
from overdrive.scenario.schema import load_scenario
from tests.bus.priority_probe import EXPECTED, NICE_PERMITTED, RT_PERMITTED, STARTED_NICE

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux scheduling")


REFUSE = """
    import os
    def refuse(*_args):
        raise PermissionError(1, "Operation not permitted")
"""
SESSION = """
    import zenoh
    config = zenoh.Config()
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", "[]")
    session = zenoh.open(config)
"""


def _child(body: str, timeout_s: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(body)], capture_output=True,
                          text=True, timeout=timeout_s, start_new_session=True)


def _priority_of_a_node(prelude: str = "", rt_priority: bool = True) -> str:
    """What a node process reports about all its threads once its session is open."""
    out = _child(prelude + f"""
    from overdrive.runtime.scheduling import node_child, node_priority, scheduling
    node_child()                        # as the launcher's preexec_fn
    node_priority({rt_priority})           # as run_node, before its session
    """ + SESSION + """
    print(scheduling())
    session.close()
    """)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_every_thread_of_a_node_runs_at_its_priority_zenoh_included() -> None:
    assert _priority_of_a_node() == EXPECTED


def test_without_real_time_permission_a_node_falls_back_to_run_nice() -> None:
    expected = f"other:nice={RUN_NICE if NICE_PERMITTED else STARTED_NICE}"
    assert _priority_of_a_node(REFUSE + "    os.sched_setscheduler = refuse\n") == expected


def test_without_any_permission_a_node_runs_as_it_was_started() -> None:
    prelude = REFUSE + "    os.sched_setscheduler = os.setpriority = refuse\n"
    assert _priority_of_a_node(prelude) == f"other:nice={STARTED_NICE}"


def test_no_rt_priority_asks_for_run_nice_only() -> None:
    assert _priority_of_a_node(rt_priority=False) == f"other:nice={RUN_NICE if NICE_PERMITTED else STARTED_NICE}"


@pytest.mark.skipif(not RT_PERMITTED, reason="this host does not permit SCHED_FIFO")
def test_a_runaway_real_time_node_is_ended_by_the_kernel_a_stepping_one_is_not() -> None:
    """RLIMIT_RTTIME: a thread spinning at FIFO priority would hold a CPU; the kernel ends it."""
    spinning = _child("""
        import time
        from overdrive.runtime.scheduling import node_priority
        node_priority()
        end = time.monotonic() + 20
        while time.monotonic() < end:
            pass
        print("survived")
    """)
    assert spinning.returncode in (-signal.SIGXCPU, -signal.SIGKILL), (spinning.returncode, spinning.stdout)
    stepping = _child("""
        import time
        from overdrive.runtime.scheduling import node_priority, scheduling
        node_priority()
        for _ in range(300):            # 3 s of 10 ms steps, each 2 ms of work, then a sleep
            end = time.monotonic() + 0.002
            while time.monotonic() < end:
                pass
            time.sleep(0.008)
        print(scheduling())
    """)
    assert stepping.returncode == 0 and stepping.stdout.strip() == f"fifo:{NODE_RT_PRIORITY}", stepping


@pytest.mark.parametrize("flag", [None, "--no-rt-priority"])
def test_overdrive_node_reports_the_scheduling_it_ran_at(tmp_path, flag: str | None) -> None:
    """The CLI path end to end: ``overdrive node`` as a user starts it, judged by its report."""
    report = tmp_path / "move.json"
    cmd = [sys.executable, "-m", "overdrive.cli.bus", "node", "move", "--duration-s", "1",
           "--report", str(report), "--listen", f"tcp/127.0.0.1:{free_port()}"]
    out = subprocess.run(cmd + ([flag] if flag else []), capture_output=True, text=True,
                         timeout=120, start_new_session=True)
    assert out.returncode == 0, out.stderr[-2000:]
    nice_only = f"other:nice={RUN_NICE if NICE_PERMITTED else STARTED_NICE}"
    assert json.loads(report.read_text())["scheduling"] == (nice_only if flag else EXPECTED)


@pytest.mark.parametrize("rt_priority", [True, False])
def test_a_launch_without_rt_priority_asks_its_nodes_for_niceness_only(tmp_path, monkeypatch,
                                                                     rt_priority: bool) -> None:
    commands: list[list[str]] = []

    class Recorded:
        def __init__(self, cmd: list[str], **_kwargs: object) -> None:
            commands.append(cmd)

    monkeypatch.setattr(launch_mod.subprocess, "Popen", Recorded)
    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / "move-straight.yaml")
    run = Launch(scenario, tmp_path / "run", rt_priority=rt_priority)
    run._scenario_path = tmp_path / "scenario.json"
    (run.work_dir / "nodes").mkdir(parents=True, exist_ok=True)   # as start() makes it
    for proc in run.procs.values():
        run._spawn(proc)
    assert len(commands) == len(run.procs) >= 3
    assert all(("--no-rt-priority" in cmd) is (not rt_priority) for cmd in commands)
