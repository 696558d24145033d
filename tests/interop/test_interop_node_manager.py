"""A real OpenJAUS node manager (ojNodeManager, subsystem 2) and an OpenJAUS component
(ojcmpt, 2.1.4.1) driving the simulated XGV: control held until released, and every report the
XGV sends over the component's service connections delivered, as are the heartbeats.

OpenJAUS answers on the sender's IP at port 3794 (kit README), so the XGV is on
127.0.0.1:3794 and the node manager's JUDP on 127.0.0.2:3794; both are fixed ports and the
test skips if they are taken. The XGV runs in this process (a thread) so the test can count
what it sends; OpenJAUS's programs are processes stopped by PID.
"""

from __future__ import annotations

import collections
import contextlib
import os
import re
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from processes import started

from overdrive.jaus import JausDecodeError, JausId, TerminateServiceConnection, decode_datagram
from overdrive.run.xgv_sim import XgvServer
from tests.xgv.xgv_helpers import ready_scenario, serving

pytestmark = [pytest.mark.interop, pytest.mark.wallclock]   # real processes and time: serial

XGV = ("127.0.0.1", 3794)
NM_HOST = "127.0.0.2"
CLIENT = JausId(2, 1, 4, 1)
NODE_MANAGER = JausId(2, 1, 1, 1)
WRENCH_S = 3.0
OJCMPT_TIMEOUT_S = 40.0
TERMINATE_IN_FLIGHT_S = 0.2   # a Terminate's trip ojcmpt -> ojNodeManager -> XGV on a loaded host
NM_START_S = 3.0   # the node manager's interfaces up (kit example script waits 3 s)


class CountingServer(XgvServer):
    """xgv-sim counting what it sends, per (destination id, command code), when it sent each
    report, and when each service connection's Terminate Service Connection reached it."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.sent: collections.Counter[tuple[JausId, int]] = collections.Counter()
        self.sent_s: collections.defaultdict[tuple[JausId, int], list[float]] = \
            collections.defaultdict(list)
        self.terminated_s: dict[int, float] = {}
        self.controllers: list[JausId | None] = []

    def _read(self, clock: Any) -> list[Any]:
        batch = super()._read(clock)
        for data, _ in batch:
            with contextlib.suppress(JausDecodeError):
                for message in decode_datagram(data):
                    if isinstance(message, TerminateServiceConnection):
                        self.terminated_s.setdefault(message.command_code, time.monotonic())
        return batch

    def _send(self, outgoing: list[tuple[bytes, tuple[str, int]]]) -> None:
        now = time.monotonic()
        for data, _ in outgoing:
            for message in decode_datagram(data):
                self.sent[(message.header.destination, message.code)] += 1
                self.sent_s[(message.header.destination, message.code)].append(now)
        self.controllers.append(self.simulator.pd.controller)
        super()._send(outgoing)

    def sent_before(self, code: int, margin_s: float) -> tuple[int, int]:
        """Reports of ``code`` to the client sent more than ``margin_s`` before its Terminate
        arrived, and sent after it arrived."""
        end = self.terminated_s.get(code, float("inf"))
        times = self.sent_s[(CLIENT, code)]
        return sum(t < end - margin_s for t in times), sum(t > end for t in times)


@pytest.fixture
def xgv() -> Iterator[CountingServer]:
    try:
        server = CountingServer(*XGV, ready_scenario())
    except OSError as exc:
        pytest.skip(f"{XGV[0]}:{XGV[1]} is taken ({exc}); OpenJAUS needs the JUDP port 3794")
    with serving(server):
        yield server


def test_node_manager_and_component_drive_xgv_sim(openjaus: Path, kit: Path,
                                                  xgv: CountingServer, tmp_path: Path) -> None:
    # the XGV talks only to peers it has heard from and the node manager (multicast off) only
    # to subsystems it has heard from: say hello as the node manager, from its address
    hello = subprocess.run([str(openjaus / "ojpeer"), "-H", "-b", f"{NM_HOST}:3794", "-x",
                            f"{XGV[0]}:{XGV[1]}", "-m", str(NODE_MANAGER), "-v", "0"],
                           capture_output=True, text=True, timeout=10, check=False)
    assert hello.returncode == 0, hello.stdout + hello.stderr
    shutil.copy(kit / "nodeManager.conf", tmp_path / "nodeManager.conf")
    fifo = tmp_path / "in"
    os.mkfifo(fifo)
    hold = os.open(fifo, os.O_RDWR)   # keeps the console's stdin open (kit README)
    try:
        with open(tmp_path / "nm.log", "w") as nm_log, started(
                [str(openjaus / "ojNodeManager")], cwd=tmp_path, stdin=hold, stdout=nm_log,
                stderr=subprocess.STDOUT):
            time.sleep(NM_START_S)
            result = subprocess.run([str(openjaus / "ojcmpt"), "-s", str(WRENCH_S)],
                                    capture_output=True, text=True, timeout=OJCMPT_TIMEOUT_S,
                                    check=False)
            os.write(hold, b"\x1b")   # Esc: the node manager quits
            time.sleep(0.5)
    finally:
        os.close(hold)
    out = result.stdout
    summary = re.search(r"SUMMARY confirm=(-?\d+) rejects=(\d+) status=(-?\d+) velReports=(\d+) "
                        r"vx=(-?[\d.]+) vehModes=(\d+) statusReports=(\d+)", out)
    assert summary is not None, out
    confirm, rejects, _, velocity, vx, modes, statuses = summary.groups()
    assert result.returncode == 0 and confirm == "0" and float(vx) > 0.5, out
    received = {int(code, 16): int(n) for code, n in re.findall(r"0x([0-9A-F]{4}) x(\d+)", out)}
    # every report the XGV sent the component arrived, except one it sent while ojcmpt's
    # Terminate Service Connection was on its way: ojcmpt ends its connections a second before it
    # exits and OpenJAUS's scManager destroys a report for a connection it has ended
    # (scManagerReceiveMessage; seen once on a loaded host: 45 of 46). None is sent after the
    # Terminate arrived, and every report sent earlier than TERMINATE_IN_FLIGHT_S before it arrived
    for code in (0x4404, 0xE456, 0x4002):
        sent = xgv.sent[(CLIENT, code)]
        early, late = xgv.sent_before(code, TERMINATE_IN_FLIGHT_S)
        assert late == 0, (hex(code), "sent after the Terminate Service Connection arrived")
        assert sent > 0 and early <= received.get(code, 0) <= sent, (hex(code), early, sent, out)
    assert xgv.sent_before(0x4404, TERMINATE_IN_FLIGHT_S)[0] <= int(velocity) <= xgv.sent[(CLIENT, 0x4404)]
    assert xgv.sent_before(0xE456, TERMINATE_IN_FLIGHT_S)[0] <= int(modes) <= xgv.sent[(CLIENT, 0xE456)]
    assert int(statuses) >= xgv.sent_before(0x4002, TERMINATE_IN_FLIGHT_S)[0]
    # heartbeats: to the node manager, one per second, and to the component, all delivered
    assert xgv.sent[(NODE_MANAGER, 0x4202)] >= 5
    assert received.get(0x4202, 0) >= xgv.sent[(CLIENT, 0x4202)] > 0
    # the node manager's discovery was answered: Identification, Configuration, Services
    assert all(xgv.sent[(NODE_MANAGER, code)] > 0 for code in (0x4B00, 0x4B01, 0x4B03))
    assert xgv.simulator.stats.malformed == 0
    # control: confirmed once, held until ojcmpt released it (then one Reject)
    held = [c for c in xgv.controllers if c is not None]
    assert held and set(held) == {CLIENT}
    first, last = xgv.controllers.index(CLIENT), len(xgv.controllers) - 1 - \
        xgv.controllers[::-1].index(CLIENT)
    assert all(c == CLIENT for c in xgv.controllers[first:last + 1])
    assert rejects == "1" and xgv.sent[(CLIENT, 0x0010)] == 1
    print(f"ojcmpt received {received}; xgv-sim sent {dict(xgv.sent)}")
