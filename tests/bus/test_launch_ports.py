"""The launcher's listening ports: distinct, free, and never where the kernel hands out ports
for outgoing connections (a node that could not bind its port failed a run under load), found on
any ephemeral range; and a launch whose public endpoint cannot be had refuses to run."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from overdrive.run.launch import Launch
from overdrive.runtime import ports as ports_mod
from overdrive.runtime.ports import LISTEN_PORTS, endpoint_port, free_port, free_ports
from overdrive.scenario.schema import load_scenario

ROOT = Path(__file__).resolve().parents[2]


def test_ports_are_distinct_free_and_outside_the_ephemeral_range() -> None:
    lo, hi = ports_mod.ephemeral_range()
    for _ in range(20):
        ports = free_ports(6)
        assert len(set(ports)) == 6
        assert all(LISTEN_PORTS[0] <= p < LISTEN_PORTS[1] and not lo <= p <= hi for p in ports)
        for port in ports:
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                s.bind(("127.0.0.1", port))


def test_a_port_in_use_or_reserved_is_never_picked(monkeypatch: pytest.MonkeyPatch) -> None:
    busy = 25000
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        try:
            held.bind(("127.0.0.1", busy))
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
                probe.bind(("127.0.0.1", busy + 2))
        except OSError:
            pytest.skip(f"port {busy} or {busy + 2} is in use on this host")
        held.listen()
        monkeypatch.setattr(ports_mod, "LISTEN_PORTS", (busy, busy + 3))
        assert free_ports(1, taken=frozenset({busy + 1})) == [busy + 2]
        first, second = free_ports(2, taken=frozenset({busy + 1}))   # the window has one
        assert first == busy + 2 and second not in (busy, busy + 1, busy + 2)   # then bind(0)


def test_a_host_whose_ephemeral_range_covers_the_window_gets_bind_zero_ports(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ports_mod, "ephemeral_range", lambda: (1024, 65535))
    ports = free_ports(6)
    assert len(set(ports)) == 6 and all(1024 <= p <= 65535 for p in ports)


@pytest.mark.parametrize("eph", [(20010, 65535), (20001, 60999), (20000, 32766), (1024, 65535)])
def test_free_ports_finds_ports_whatever_the_ephemeral_range(monkeypatch, eph) -> None:
    """Found (issue 20): on a host whose ephemeral range covers most, not all, of 20000-32767
    too few ports were found and the launch failed with a traceback; now ``bind(0)`` fills in."""
    monkeypatch.setattr(ports_mod, "ephemeral_range", lambda: eph)
    ports = free_ports(5)      # a launch of four nodes and a gate
    assert len(set(ports)) == 5


def test_endpoint_port() -> None:
    assert endpoint_port("tcp/127.0.0.1:7447") == 7447
    assert endpoint_port("") is None and endpoint_port("tcp/[::1]:x") is None


# --------------------------------------------------------------------------- endpoint taken
# Found (issue 20): with its ``--listen`` port taken (or the gate's own port taken between picking
# and spawning) the tool gate died at start-up, nothing supervised it, and the run played the
# whole scenario (the vehicle moved 7.4 m) and exited 0; with ``--open-bus`` a taken port ended
# in a bare traceback. The launcher now waits for the gate to listen and refuses with a message.

SHORT_MOVE = """\
name: short-move
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


@pytest.mark.wallclock
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


@pytest.mark.wallclock
def test_the_gate_port_taken_between_pick_and_spawn_refuses_the_run(
        scenario: Path, tmp_path: Path) -> None:
    run = Launch(load_scenario(scenario), tmp_path / "run",
                 listen=f"tcp/127.0.0.1:{free_port()}", plot=False)
    squatter = socket.socket()
    squatter.bind(("127.0.0.1", int(run.gate_listen.rpartition(":")[2])))
    squatter.listen()
    try:
        with pytest.raises(RuntimeError, match="tool gate exited during start-up"):
            run.start()
    finally:
        # the squatter first: the launcher's session is mid-handshake with it (a listener that
        # never speaks Zenoh), and closing the session waited ~9 s for that handshake; with the
        # squatter gone it ends at once (0.02 s, 2026-11-26)
        squatter.close()
        run.close()
