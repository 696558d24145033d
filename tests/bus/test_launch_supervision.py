"""Supervision of a launch sees hangs: a process whose liveness ticks stop and a dead tool gate
are reported (an event, a fault, a violation) within 1 s and the run exits non-zero; a process
that resumes is reported too. Real processes; the fault-injection flags are validated."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from overdrive.run.launch import Launch, stall_actions
from overdrive.runtime.ports import endpoint_port, free_port
from overdrive.runtime.supervision import HANG_BOUND_S
from tests.bus.fault_launches import move_scenario

ROOT = Path(__file__).resolve().parents[2]
REPORT_WITHIN_S = 1.0       # issue 38: a hung node and a dead gate are reported within 1 s
STALL_AT_S, STALL_FOR_S = 4.0, 1.0
HANG_AT_S, GATE_KILL_S = 8.0, 6.0


def _first(events: list[dict], kind: str, **fields: object) -> dict:
    found = [e for e in events if e["kind"] == kind and all(e.get(k) == v for k, v in fields.items())]
    assert found, (kind, fields, events)
    return found[0]


@pytest.mark.wallclock
def test_hung_resumed_and_dead_processes_are_reported_within_a_second_and_fail_the_run(
        run_dir: Path) -> None:
    """driving stalled 1 s (hung, then resumed), move hung to the end, the gate killed and
    restarted (``--restart``): each reported in time; the run exits 1; the vehicle, stopped by
    the SPSS watchdog, never moves again (ground truth)."""
    scenario = move_scenario(8.0, 11.0)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    listening: list[bool] = []
    actions = [*stall_actions("driving", STALL_AT_S, STALL_FOR_S),
               *stall_actions("move", HANG_AT_S), (GATE_KILL_S, "kill", "gate")]
    with Launch(scenario, run_dir / "run", listen=endpoint, plot=False, actions=actions,
                restart=True) as launch:
        def probe_public_port(now_s: float) -> None:
            if now_s > scenario.spec.duration_s - 0.5 and not listening:
                with socket.socket() as s:
                    s.settimeout(1.0)
                    listening.append(s.connect_ex(("127.0.0.1", endpoint_port(endpoint))) == 0)
        launch.start()
        result = launch.run(on_tick=probe_public_port)
    summary, events = result.summary, result.summary["events"]
    assert result.exit_code == 1

    stalled = _first(events, "process_signal", node="driving", signal="sigstop")
    hung = _first(events, "process_hung", node="driving")
    # hung = silent beyond the bound since its last tick, which may precede the SIGSTOP by up to
    # a tick period (seen: last tick 3.90 s, SIGSTOP 4.0 s, hung 4.40 s): judged from the tick
    assert hung["t_s"] - hung["last_tick_s"] > HANG_BOUND_S, (stalled, hung)
    assert hung["last_tick_s"] <= stalled["t_s"] + 0.05, (stalled, hung)
    assert hung["t_s"] - stalled["t_s"] <= REPORT_WITHIN_S, (stalled, hung)
    resumed = _first(events, "process_resumed", node="driving")
    assert resumed["silent_s"] == pytest.approx(STALL_FOR_S, abs=0.15) and resumed["lost_ticks"] == 0
    hung_move = _first(events, "process_hung", node="move")
    assert hung_move["t_s"] - HANG_AT_S <= REPORT_WITHIN_S
    assert not [e for e in events if e["kind"] == "process_resumed" and e["node"] == "move"]
    faults = [e for e in events if e["kind"] == "fault" and e["source"] == "scenario"]
    codes = {(e["code"], e["message"].split(":")[0].split()[0]) for e in faults}
    assert codes >= {("process_hung", "driving"), ("process_hung", "move"), ("process_exit", "gate")}

    gate_exit = _first(events, "process_exit", node="gate")
    assert gate_exit["t_s"] - GATE_KILL_S <= REPORT_WITHIN_S and gate_exit["code"] < 0
    assert any(e["code"] == "process_exit" and "public endpoint" in e["message"] for e in faults)
    _first(events, "process_restart", node="gate")
    assert listening == [True], "the restarted gate holds the public endpoint again"
    liveness = summary["launch"]["liveness"]["processes"]
    assert liveness["gate"]["hangs"] == [], "a restarted gate is judged from its first tick"

    process_lines = [v for v in summary["violations"] if v.startswith("process:")]
    assert [line.split(":")[1].split()[0] for line in process_lines] == ["driving", "gate", "move"]
    # ground truth: the watchdog stopped the vehicle during the stall and nothing moved after
    assert _first(events, "interrupted")["code"] == "watchdog"
    rows = [line.split(",") for line in (run_dir / "run" / "trace.csv").read_text().splitlines()]
    t_i, v_i, o_i = (rows[0].index(c) for c in ("t_s", "speed_mps", "odometer_m"))
    rest_s = next(float(r[t_i]) for r in rows[1:]
                  if float(r[t_i]) > STALL_AT_S and abs(float(r[v_i])) < 0.01)
    after = [float(r[o_i]) for r in rows[1:] if float(r[t_i]) >= rest_s]
    assert max(after) - min(after) < 0.02


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "overdrive.cli.bus", "launch",
                           str(ROOT / "scenarios" / "move-straight.yaml"), *args],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)


@pytest.mark.parametrize(("flag", "message"), [
    ("--stall=move@x", "expected NODE@AT_S"),
    ("--stall=move@1:nan", "FOR_S must be a positive number"),
    ("--restart-node=move@-1", "expected NODE@AT_S"),
    ("--kill=planner@3", "'planner' is not a process of this run"),
    ("--stall=move@9999:1", "--stall 'move@9999': AT_S 9999 s is not a time in the run"),
    ("--kill=move@9999", "--kill 'move@9999': AT_S 9999 s is not a time in the run"),
])
def test_fault_injection_flags_are_checked_before_anything_starts(tmp_path: Path, flag: str,
                                                                 message: str) -> None:
    done = _cli(flag, "--out", str(tmp_path / "run"))
    assert done.returncode == 2, done.stderr
    assert message in done.stderr


@pytest.mark.parametrize(("text", "actions"), [
    ("move@5", [(5.0, "stop", "move")]),                          # hung to the end
    ("move@5:100000", [(5.0, "stop", "move")]),                   # ends past the run: the same
    ("move@5:2", [(5.0, "stop", "move"), (7.0, "cont", "move")]),
    ("move@5:15", [(5.0, "stop", "move"), (20.0, "cont", "move")]),   # at the very end
])
def test_a_stall_ending_past_the_run_hangs_to_the_end(text: str, actions: list) -> None:
    """``--stall NODE@AT_S:FOR_S`` with AT_S + FOR_S past the run's end is a hang to the end, as
    a stall without FOR_S (docs/multiprocess.md), not an error naming an internal action."""
    from overdrive.cli.bus import _parse_stall

    assert _parse_stall(text, 20.0) == actions
    assert stall_actions("move", 5.0, 100000.0, end_s=20.0) == [(5.0, "stop", "move")]
    assert stall_actions("move", 5.0) == [(5.0, "stop", "move")]      # no FOR_S, no end given
