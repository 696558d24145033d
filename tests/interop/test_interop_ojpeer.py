"""ojpeer (OpenJAUS's JUDP framing and libjaus messages, playing an XGV client) against
``overdrive xgv-sim``: every check passes and no report is lost to OpenJAUS's
first-message-only receive."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from processes import free_udp_port, xgv_sim

pytestmark = [pytest.mark.interop, pytest.mark.wallclock]   # real processes and time: serial

WRENCH_S = 2.0      # Set Wrench Effort at 20 Hz for this long: enough to move (> 0.5 m/s)
OJPEER_TIMEOUT_S = 60.0  # ojpeer's own pumps add up to ~12 s + WRENCH_S


def test_ojpeer_against_xgv_sim(openjaus: Path) -> None:
    peer_host = "127.0.0.3"
    with xgv_sim(duration_s=OJPEER_TIMEOUT_S) as (_, port):
        result = subprocess.run(
            [str(openjaus / "ojpeer"), "-b", f"{peer_host}:{free_udp_port(peer_host)}",
             "-x", f"127.0.0.1:{port}", "-m", "2.1.4.1", "-s", str(WRENCH_S), "-v", "0"],
            capture_output=True, text=True, timeout=OJPEER_TIMEOUT_S, check=False)
    out = result.stdout
    fails = [line for line in out.splitlines() if line.startswith("FAIL")]
    assert not fails, out
    checks = re.search(r"SUMMARY checks: (\d+) pass, (\d+) fail", out)
    assert checks is not None and int(checks.group(1)) >= 15 and checks.group(2) == "0", out
    delivered = re.search(r"received (\d+) datagrams, (\d+) messages in all; (\d+) datagrams held "
                          r"more than one message; OpenJAUS's JudpInterface would deliver (\d+) "
                          r"messages \(drops (\d+)\)", out)
    assert delivered is not None, out
    datagrams, messages, multi, oj_delivered, dropped = map(int, delivered.groups())
    assert messages > 100 and multi == 0 and dropped == 0 and oj_delivered == messages, out
    assert datagrams == messages
    assert result.returncode == 0, out
