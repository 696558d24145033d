"""Red team (issue 20): a launch whose public endpoint cannot be had must refuse to run.

Found: with its ``--listen`` port taken (or the gate's own port taken between picking and
spawning), the tool gate died at start-up, nothing supervised it, and the run played the whole
scenario (the vehicle moved 7.4 m) and exited 0. With ``--open-bus`` a taken port ended in a bare
traceback. Now the launcher waits for the gate to listen and refuses with a message."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from overdrive.run.launch import Launch
from overdrive.runtime.ports import free_port
from overdrive.scenario.schema import load_scenario

pytestmark = pytest.mark.wallclock

ROOT = Path(__file__).resolve().parents[2]
SHORT_MOVE = """\
name: rt20-short-move
description: a short MOVE, for launch start-up attacks
vehicle: escape-hybrid
start: ready
seed: 1
duration_s: 6
events:
  - {at_s: 0.5, move: {distance_m: 8, maxspeed_mps: 4, curvature_1pm: 0}}
"""


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "short-move.yaml"
    path.write_text(SHORT_MOVE, encoding="utf-8")
    return path


def _held_port() -> tuple[socket.socket, int]:
    port = free_port()
    holder = socket.socket()
    holder.bind(("127.0.0.1", port))
    holder.listen()
    return holder, port


@pytest.mark.parametrize("open_bus", [False, True], ids=["locked-down", "open-bus"])
def test_a_launch_whose_listen_port_is_taken_refuses_with_a_message(
        scenario: Path, tmp_path: Path, open_bus: bool) -> None:
    holder, port = _held_port()
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "overdrive.cli.bus", "launch", str(scenario), "--listen",
             f"tcp/127.0.0.1:{port}", "--out", str(tmp_path / "run"), "--quiet", "--no-plot",
             *(["--open-bus"] if open_bus else [])],
            cwd=ROOT, capture_output=True, text=True, timeout=120)
    finally:
        holder.close()
    assert proc.returncode != 0 and "Traceback" not in proc.stderr, proc.stderr
    assert "error:" in proc.stderr and str(port) in proc.stderr, proc.stderr
    assert not (tmp_path / "run" / "summary.json").exists(), "the scenario was played"


def test_the_gate_port_taken_between_pick_and_spawn_refuses_the_run(
        scenario: Path, tmp_path: Path) -> None:
    launch = Launch(load_scenario(scenario), tmp_path / "run",
                    listen=f"tcp/127.0.0.1:{free_port()}", plot=False)
    squatter = socket.socket()
    squatter.bind(("127.0.0.1", int(launch.gate_listen.rpartition(":")[2])))
    squatter.listen()
    try:
        with pytest.raises(RuntimeError, match="tool gate exited during start-up"):
            launch.start()
    finally:
        launch.close()
        squatter.close()
