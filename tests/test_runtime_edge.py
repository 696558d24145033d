"""The runtime edge's small pieces: the one UDP socket opener, stopping a process group, the
run folder's two halves."""

from __future__ import annotations

import contextlib
import json
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from overdrive.observe.run_files import open_trace, write_summary
from overdrive.runtime.processes import stop_process_group
from overdrive.runtime.udp import open_udp


def test_a_udp_socket_is_bound_non_blocking_with_its_buffer() -> None:
    sock = open_udp(("127.0.0.1", 0), receive_buffer_bytes=1 << 20)
    try:
        assert sock.type == socket.SOCK_DGRAM and sock.gettimeout() == 0.0
        assert sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF) >= 1 << 20
        with pytest.raises(BlockingIOError):
            sock.recvfrom(100)
    finally:
        sock.close()
    timed = open_udp(("127.0.0.1", 0), timeout_s=0.05)
    try:
        assert timed.gettimeout() == 0.05
    finally:
        timed.close()


def test_a_failed_bind_raises_and_leaves_no_socket_open() -> None:
    held = open_udp(("127.0.0.1", 0))
    try:
        before = len(list(Path("/proc/self/fd").iterdir()))
        with pytest.raises(OSError):
            open_udp(held.getsockname())
        assert len(list(Path("/proc/self/fd").iterdir())) == before
    finally:
        held.close()


def _child(ignore_term: bool) -> subprocess.Popen:
    code = ("import signal, time\n"
            + ("signal.signal(signal.SIGTERM, signal.SIG_IGN)\n" if ignore_term else "")
            + "print('up', flush=True)\ntime.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                            start_new_session=True, text=True)
    assert proc.stdout is not None and proc.stdout.readline() == "up\n"
    return proc


@pytest.mark.wallclock
def test_a_process_that_stops_on_sigterm_is_not_killed() -> None:
    proc = _child(ignore_term=False)
    assert stop_process_group(proc, grace_s=10.0, dump=False) is False
    assert proc.returncode == -signal.SIGTERM


@pytest.mark.wallclock
def test_a_process_that_ignores_sigterm_is_killed_after_the_grace() -> None:
    proc = _child(ignore_term=True)
    start = time.monotonic()
    assert stop_process_group(proc, grace_s=0.5, dump=False) is True
    assert proc.returncode == -signal.SIGKILL and time.monotonic() - start < 5.0


def test_the_run_folder_is_made_with_its_trace_and_then_its_summary(tmp_path: Path) -> None:
    out = tmp_path / "a" / "run"
    with contextlib.ExitStack() as stack:
        trace = open_trace(stack, out)
        assert trace is not None
        trace.write("t_s\n0.0\n")
    assert (out / "trace.csv").read_text() == "t_s\n0.0\n"
    write_summary(out, {"x_m": float("nan"), "name": "t"}, plot=False)
    assert json.loads((out / "summary.json").read_text()) == {"x_m": None, "name": "t"}
    assert not (out / "plot.png").exists()
    with contextlib.ExitStack() as stack:
        assert open_trace(stack, None) is None
    write_summary(None, {}, plot=True)        # no folder: nothing written, nothing raised
