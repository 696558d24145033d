"""``overdrive drive`` (the real CLI, a subprocess) against OpenJAUS's own vehicle: ojNodeManager
(subsystem 1, node 1, JUDP on 127.0.0.2:3794) hosting ojVehicleSim, driven with Set Wrench
Effort through the plain JAUS profile (``--profile plain``: safety mode from the Primitive
Driver's component status, pose from Global Pose, speed from Velocity State; docs/xgv.md).

Issue 19's last acceptance point: control held for the whole drive, the OpenJAUS vehicle moves
as commanded, no heartbeat faults. The movement is checked twice: from the run folder (the
vehicle's own Global Pose reports as the client projected them) and from ojVehicleSim's screen
(its UTM position, printed by the program itself, which nothing of overdrive computes).

OpenJAUS answers on the sender's IP at port 3794, so the client binds 127.0.0.3:3794; the test
skips if a port it needs is taken. ojVehicleSim is an ncurses program: it runs under ``script``
with stdin on a FIFO (kit README). Every process is stopped by its PID.
"""

from __future__ import annotations

import csv
import json
import math
import re
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest
from processes import VENV_BIN, openjaus_vehicle_sim

pytestmark = [pytest.mark.interop, pytest.mark.wallclock]   # real processes and time: serial

PROJECT = Path(__file__).resolve().parents[2]
SCENARIO = PROJECT / "scenarios" / "openjaus-wrench-drive.yaml"
NODE_JUDP = ("127.0.0.2", 3794)
CLIENT_BIND = ("127.0.0.3", 3794)
DRIVE_TIMEOUT_S = 30.0     # the scenario's 12 s in wall-clock time, plus start and exit
COMMANDED_M = 12.0         # the scenario's move: 12 m straight ahead, sent at 1 s
MOVE_AT_S = 1.0
STOP_TOLERANCE_M = 1.0     # where it stops: ojVehicleSim is not the preset the stack expects
                           # (seen: 11.84 m); the judge checks the authorization itself
LATERAL_M = 0.3            # off the straight line: 0.07 m seen, all of it UTM grid convergence
                           # (ojVehicleSim moves along grid east, 0.34 deg off true east here)
AGREE_M = 0.3              # the client's projection against ojVehicleSim's own UTM position
HEADING_RAD = 0.0          # ojVehicleSim's config: INITIAL_HEADING_DEGREES 0 (UTM +x, east)
ANSI = r"(?:\s|\x1b\[[0-9;?]*[A-Za-z])*"   # what ncurses puts between a label and its value


def _port_free(address: tuple[str, int]) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            sock.bind(address)
        except OSError:
            return False
    return True


def _screen_positions(log: str) -> list[tuple[float, float]]:
    """ojVehicleSim's UTM (x east, y north) on every screen it drew, in order; screens drawn
    before its vehicle thread set the position print 0, 0 and are left out."""
    xs = re.findall(r"VS Vehicle X:" + ANSI + r"([+-]?\d+\.\d+)", log)
    ys = re.findall(r"VS Vehicle Y:" + ANSI + r"([+-]?\d+\.\d+)", log)
    return [(float(x), float(y)) for x, y in zip(xs, ys, strict=False)
            if (float(x), float(y)) != (0.0, 0.0)]


def test_overdrive_drive_moves_openjaus_vehicle_sim(openjaus_vsim: Path, kit: Path,
                                                   tmp_path: Path) -> None:
    if shutil.which("script") is None:
        pytest.skip("`script` (util-linux) is needed to give ojVehicleSim a terminal")
    for address in (NODE_JUDP, CLIENT_BIND):
        if not _port_free(address):
            pytest.skip(f"{address[0]}:{address[1]} is taken; OpenJAUS needs the JUDP port 3794")
    run = tmp_path / "run"
    with openjaus_vehicle_sim(tmp_path, kit, openjaus_vsim):
        started_s = time.monotonic()
        drive = subprocess.run(
            [str(VENV_BIN / "overdrive"), "drive", "--profile", "plain", "--xgv",
             f"{NODE_JUDP[0]}:{NODE_JUDP[1]}", "--bind", f"{CLIENT_BIND[0]}:{CLIENT_BIND[1]}",
             "--out", str(run), "--quiet", str(SCENARIO)],
            capture_output=True, text=True, timeout=DRIVE_TIMEOUT_S, check=False, cwd=PROJECT)
        drive_s = time.monotonic() - started_s
        time.sleep(0.3)          # one more screen after the release
    assert (run / "summary.json").exists(), drive.stdout + drive.stderr
    summary = json.loads((run / "summary.json").read_text())
    with open(run / "trace.csv") as f:
        trace = list(csv.DictReader(f))
    events = summary["events"]
    faults = [e for e in events if e["kind"] in ("fault", "estop", "rejected")]
    heartbeat_faults = [e for e in faults if e.get("code") == "xgv_heartbeat"]
    modes = {row["safety_mode"] for row in trace}
    screen = _screen_positions((tmp_path / "vsim.log").read_text(errors="replace"))
    assert len(screen) >= 2, "ojVehicleSim drew no position"
    (x0, y0), (x1, y1) = screen[0], screen[-1]
    along_m = (x1 - x0) * math.cos(HEADING_RAD) + (y1 - y0) * math.sin(HEADING_RAD)
    across_m = -(x1 - x0) * math.sin(HEADING_RAD) + (y1 - y0) * math.cos(HEADING_RAD)
    final = summary["final"]
    print(f"drive {drive_s:.1f} s (scenario {summary['sim_time_s']} s); trace "
          f"{trace[0]['t_s']}..{trace[-1]['t_s']} s, modes {modes}, first drive-by-wire "
          f"{next((r['t_s'] for r in trace if r['safety_mode'] == 'drive-by-wire'), None)} s; moved {final['x_m']:.2f} m "
          f"ahead, {final['y_m']:.2f} m left (reports); ojVehicleSim {along_m:.2f} m ahead, "
          f"{across_m:.2f} m aside (its UTM); peak {summary['peaks']['max_speed_mps']:.2f} m/s; "
          f"heartbeat faults {len(heartbeat_faults)}; events {events}")
    # every expectation of the scenario held (no fault event, drive-by-wire at the end, ...)
    assert drive.returncode == 0, (drive.stdout + drive.stderr, summary["violations"])
    # control held for the whole drive: taken before the move is sent (OpenJAUS may reject
    # once while it registers us: retried quietly, software-pause meanwhile), then
    # drive-by-wire (control of a ready PD) on every row to the end, never lost
    held = [i for i, row in enumerate(trace) if row["safety_mode"] == "drive-by-wire"]
    assert held and float(trace[held[0]]["t_s"]) < MOVE_AT_S, modes
    assert {row["safety_mode"] for row in trace[held[0]:]} == {"drive-by-wire"}, modes
    assert float(trace[-1]["t_s"]) > summary["sim_time_s"] - 0.1
    changes = [e for e in events if e["kind"] == "safety_mode"]
    assert all(e["t_s"] < MOVE_AT_S and e["to"] == "drive-by-wire" for e in changes), changes
    # no heartbeat (or control, pose, link) fault, no e-stop, nothing rejected; judge satisfied
    assert faults == [] and heartbeat_faults == [], faults
    assert summary["violations"] == [], summary["violations"]
    # the vehicle moved as commanded: 12 m straight ahead, then stopped
    assert abs(final["x_m"] - COMMANDED_M) <= STOP_TOLERANCE_M, final
    assert abs(final["y_m"]) <= LATERAL_M and final["speed_mps"] < 0.05, final
    assert abs(along_m - COMMANDED_M) <= STOP_TOLERANCE_M and abs(across_m) <= LATERAL_M
    assert abs(math.hypot(x1 - x0, y1 - y0) - summary["odometer_m"]) <= AGREE_M
    assert drive_s < DRIVE_TIMEOUT_S
