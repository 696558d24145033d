"""``--can-interface socketcand`` pointed at a TCP port where something listens but never speaks
the socketcand protocol (the wrong service on that port, a hub wedged): the CAN commands must
say so and exit non-zero within seconds. The reachability check only connects; python-can then
waits for the server's ``< hi >`` with no timeout."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.wallclock
OVERDRIVE = str(Path(sys.executable).parent / "overdrive")
PATIENCE_S = 15.0   # CONNECT_CHECK_TIMEOUT_S is 2 s; python-can's own connect retries 10 s


@pytest.mark.parametrize("command", ["drive", "can-monitor"])
def test_a_silent_tcp_listener_is_refused_in_seconds(tmp_path, command) -> None:
    """Measured 2026-11-26: against a listener that accepts and says nothing, `overdrive
    drive --can pacmod3` was still waiting after 45 s (can.json and vehicle.yaml written,
    nothing else) and `overdrive can-monitor --duration 1` after 40 s; both killed by
    timeout. (kit-sim gave up after 19.6 s with 'Connection reset by peer'.)"""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(50)
    port = listener.getsockname()[1]
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump({"name": "s", "start": "ready", "seed": 1,
                                        "duration_s": 1.0, "events": []}))
    head = (["drive", "--can", "pacmod3", str(scenario), "--out", str(tmp_path / "run")]
            if command == "drive" else ["can-monitor", "--duration", "1"])
    argv = [OVERDRIVE, *head, "--can-interface", "socketcand", "--can-channel", "can0",
            "--can-option", "host=127.0.0.1", "--can-option", f"port={port}"]
    try:
        done = subprocess.run(argv, capture_output=True, timeout=PATIENCE_S, cwd=tmp_path)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{command} still waiting after {PATIENCE_S} s")
    finally:
        listener.close()
    assert done.returncode != 0 and b"Traceback" not in done.stderr, done.stderr[-800:]
