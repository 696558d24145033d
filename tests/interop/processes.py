"""Processes for the interop tests: started, read, and always stopped by their PID."""

from __future__ import annotations

import contextlib
import os
import re
import selectors
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

STOP_GRACE_S = 5.0
VENV_BIN = Path(sys.executable).parent


def stop(proc: subprocess.Popen[str]) -> None:
    """Terminate ``proc`` (its PID only), then kill it if it does not exit in time."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(STOP_GRACE_S)


@contextlib.contextmanager
def started(args: list[str], **kwargs: object) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(args, text=True, **kwargs)  # type: ignore[call-overload]
    try:
        yield proc
    finally:
        stop(proc)


def read_line_matching(stream: object, pattern: str, timeout_s: float) -> re.Match[str]:
    """The first line of ``stream`` matching ``pattern`` within ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    selector = selectors.DefaultSelector()
    selector.register(stream, selectors.EVENT_READ)  # type: ignore[arg-type]
    seen = []
    try:
        while (left := deadline - time.monotonic()) > 0:
            if not selector.select(left):
                continue
            line = stream.readline()  # type: ignore[attr-defined]
            if not line:
                break
            seen.append(line)
            if match := re.search(pattern, line):
                return match
    finally:
        selector.close()
    raise AssertionError(f"no line matching {pattern!r} in {timeout_s} s; got {seen!r}")


@contextlib.contextmanager
def xgv_sim(host: str = "127.0.0.1", port: int = 0, duration_s: float = 60.0,
            extra: tuple[str, ...] = ()) -> Iterator[tuple[subprocess.Popen[str], int]]:
    """``overdrive xgv-sim`` in a process; yields it and its bound port."""
    args = [str(VENV_BIN / "overdrive"), "xgv-sim", "--host", host, "--port", str(port),
            "--duration-s", str(duration_s), *extra]
    with started(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                 env={**os.environ, "PYTHONUNBUFFERED": "1"}) as proc:
        bound = read_line_matching(proc.stderr, r"on [\d.]+:(\d+)", 20.0)
        yield proc, int(bound.group(1))


def free_udp_port(host: str) -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


VEHICLE_SIM_START_S = 4.0   # node manager and vehicle up (kit example script: 2 s + 4 s)


@contextlib.contextmanager
def openjaus_vehicle_sim(run_dir: Path, kit: Path, build: Path) -> Iterator[None]:
    """ojNodeManager and ojVehicleSim (under ``script``: it needs a terminal) started in
    ``run_dir`` from the kit's configuration, up after ``VEHICLE_SIM_START_S``; both told to quit
    (Escape on their stdin) and stopped on exit."""
    import shutil

    shutil.copy(kit / "nodeManager_vsim.conf", run_dir / "nodeManager.conf")
    shutil.copytree(build / "openjaus/ojVehicleSim/config", run_dir / "config")
    for fifo in ("nm_in", "vsim_in"):
        os.mkfifo(run_dir / fifo)
    nm_in = os.open(run_dir / "nm_in", os.O_RDWR)
    vsim_in = os.open(run_dir / "vsim_in", os.O_RDWR)
    try:
        with open(run_dir / "nm.log", "w") as nm_log, started(
                [str(build / "ojNodeManager")], cwd=run_dir, stdin=nm_in, stdout=nm_log,
                stderr=subprocess.STDOUT), started(
                ["script", "-qfc", str(build / "ojVehicleSim"), str(run_dir / "vsim.log")],
                cwd=run_dir, stdin=vsim_in, stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL, env={**os.environ, "TERM": "xterm"}):
            time.sleep(VEHICLE_SIM_START_S)
            yield
            os.write(vsim_in, b"\x1b")
            os.write(nm_in, b"\x1b")
            time.sleep(0.5)
    finally:
        os.close(nm_in)
        os.close(vsim_in)
