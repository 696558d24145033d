"""``overdrive kit-sim pacmod3`` as a process on a CAN bus (the loopback socketcand hub), and
the kit server in process on python-can's virtual bus: the enable edge and brake-held engage
are seen, reports arrive at 30 Hz, and a stream that goes quiet is timed out after 100 ms with
no command frame after the timeout; the kit's JSON summary says so, judged from its own
odometry and ground truth."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from overdrive.kits.pacmod3 import Gear, GlobalRpt, Pacmod3Codec, VehicleSpeedRpt
from overdrive.run.kit_sim import KitSimServer
from overdrive.runtime.can_edge import CanPort, resolve_can_config
from overdrive.runtime.can_hub import CanHub
from overdrive.vehicle.pacmod3_kit import COMMAND_PERIOD_S, COMMAND_TIMEOUT_S, REPORT_PERIOD_S
from tests.kits.kit_driver import drive_stream

pytestmark = pytest.mark.wallclock
CODEC = Pacmod3Codec("v3")


def stream_for(port: CanPort, seconds: float, stream) -> list[tuple[float, object]]:
    """Send ``stream(t)`` every command period for ``seconds``; collect decoded reports."""
    reports: list[tuple[float, object]] = []
    start = time.monotonic()
    next_s = 0.0
    while (now := time.monotonic() - start) < seconds:
        if now >= next_s:
            port.send([CODEC.encode(m) for m in stream(now)], now)
            next_s += COMMAND_PERIOD_S
        for _stamp, frame in port.receive(timeout_s=min(0.005, max(0.0, next_s - now))):
            reports.append((time.monotonic(), CODEC.decode(frame)))
    return reports


def engage_and_drive(port: CanPort) -> list[tuple[float, object]]:
    off = drive_stream(brake=0.5, enable=False)
    reports = stream_for(port, 0.2, off)
    reports += stream_for(port, 0.5, drive_stream(brake=0.5, gear=Gear.FORWARD))
    reports += stream_for(port, 1.5, drive_stream(accel=0.5, gear=Gear.FORWARD))
    return reports


def test_the_kit_server_in_process_on_a_virtual_bus_engages_reports_and_times_out() -> None:
    channel = f"kitsim-{os.getpid()}"
    server = KitSimServer(resolve_can_config(interface="virtual", channel=channel))
    thread = threading.Thread(target=server.serve, kwargs={"duration_s": 10.0}, daemon=True)
    thread.start()
    client = CanPort(resolve_can_config(interface="virtual", channel=channel))
    try:
        reports = engage_and_drive(client)
        time.sleep(0.5)                     # the stack goes quiet
    finally:
        server.stop()
        thread.join(5.0)
        client.close()
        server.close()
    summary = server.summary()
    assert sorted(e["system"] for e in summary["enable_edges"]) == ["accel", "brake", "shift",
                                                                     "steering"]
    assert {t["system"] for t in summary["timeouts"]} == {"accel", "brake", "shift", "steering"}
    for t in summary["timeouts"]:
        gap = t["t_s"] - summary["last_command_s"][t["system"]]
        assert COMMAND_TIMEOUT_S < gap < COMMAND_TIMEOUT_S + 0.03
    assert summary["truth"]["odometer_m"] > 0.5 and summary["odometer_m"] > 0.5
    assert summary["bad_frames"] == {}
    speeds = [r for _, r in reports if isinstance(r, VehicleSpeedRpt)]
    globals_ = [(t, r) for t, r in reports if isinstance(r, GlobalRpt)]
    assert speeds[-1].speed_mps > 0.3
    span_s = globals_[-1][0] - globals_[0][0]
    rate_hz = (len(globals_) - 1) / span_s
    assert abs(rate_hz - 1.0 / REPORT_PERIOD_S) < 3.0, rate_hz


def test_kit_sim_as_a_process_over_the_hub_times_out_a_quiet_stack(tmp_path: Path) -> None:
    summary_path = tmp_path / "kit.json"
    with CanHub(port=0) as hub:
        proc = subprocess.Popen(
            [sys.executable, "-m", "overdrive.cli", "kit-sim", "pacmod3", "--can-interface",
             "socketcand", "--can-channel", "can0", "--can-option", "host=127.0.0.1",
             "--can-option", f"port={hub.port}", "--summary", str(summary_path),
             "--duration", "30"], stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 20.0
            while hub.clients < 1 and time.monotonic() < deadline and proc.poll() is None:
                time.sleep(0.05)
            client = CanPort(resolve_can_config(interface="socketcand", channel="can0",
                                                host="127.0.0.1", port=hub.port))
            try:
                reports = engage_and_drive(client)
                stream_for(client, 0.3, drive_stream(brake=0.6, gear=Gear.FORWARD))
                time.sleep(0.5)
            finally:
                client.close()
        finally:
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    summary = json.loads(summary_path.read_text())
    edges = {e["system"]: e["t_s"] for e in summary["enable_edges"]}
    assert set(edges) == {"accel", "brake", "shift", "steering"}
    assert {t["system"] for t in summary["timeouts"]} == set(edges)
    for t in summary["timeouts"]:
        assert t["t_s"] - summary["last_command_s"][t["system"]] > COMMAND_TIMEOUT_S
    assert summary["frames_seen"]["AccelCmd"] >= 60
    assert summary["odometer_m"] > 0.3
    assert any(isinstance(r, GlobalRpt) and r.enabled for _, r in reports)


def test_a_kit_sim_starved_of_cpu_judges_the_timeout_by_bus_arrival() -> None:
    """The kit-sim's loop stalls 0.3 s (a starved process) while the stack keeps sending at
    30 Hz: the frames waiting in its socket carry their bus time stamps, so no system times out
    (read late, they would all have: 0.3 s > 100 ms)."""
    channel = f"kitsim-stall-{os.getpid()}"
    stalled = threading.Event()
    start = time.monotonic()

    def clock() -> float:
        now = time.monotonic()
        if now - start > 1.2 and not stalled.is_set():
            stalled.set()
            time.sleep(0.3)
            now = time.monotonic()
        return now

    server = KitSimServer(resolve_can_config(interface="virtual", channel=channel))
    thread = threading.Thread(target=server.serve, kwargs={"duration_s": 10.0, "clock": clock},
                              daemon=True)
    thread.start()
    client = CanPort(resolve_can_config(interface="virtual", channel=channel))
    try:
        engage_and_drive(client)
    finally:
        server.stop()
        thread.join(5.0)
        client.close()
        server.close()
    summary = server.summary()
    assert stalled.is_set()
    assert len(summary["enable_edges"]) == 4
    assert summary["timeouts"] == []
