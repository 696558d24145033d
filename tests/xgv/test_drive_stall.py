"""``overdrive drive`` (a subprocess, real UDP) stopped with SIGSTOP mid-MOVE, then resumed,
against the simulated XGV (``overdrive xgv-sim``'s server): no overrun, and the distance the
client counted is the XGV's own (its plant), because every queued report counts by its stamp.
Judged from the XGV's truth."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
import yaml

from overdrive.run.xgv_sim import XgvServer
from overdrive.scenario.schema import parse_scenario

MOVE_M = 60.0
MAXSPEED_MPS = 8.0
STALL_AT_M = 25.0            # at cruise
COUNT_TOLERANCE_M = 0.05     # measured: 0.0-1.1 mm, 0.3 and 3 s stalls
RUN_TIMEOUT_S = 90.0


def drive_stalled(tmp: Path, control: str, stall_s: float) -> dict[str, Any]:
    spec = {"name": f"drive-stall-{control}", "interface": "jaus", "control": control,
            "vehicle": "escape-hybrid", "start": "ready", "seed": 1, "duration_s": 17,
            "events": [{"at_s": 0.5, "move": {"distance_m": MOVE_M, "maxspeed_mps": MAXSPEED_MPS,
                                              "curvature_1pm": 0}}]}
    text = yaml.safe_dump(spec)
    path = tmp / f"{control}.yaml"
    path.write_text(text)
    server = XgvServer("127.0.0.1", 0, parse_scenario(yaml.safe_load(text), str(path)))
    thread = threading.Thread(target=server.serve, kwargs={"duration_s": RUN_TIMEOUT_S},
                              daemon=True)
    thread.start()
    host, port = server.address
    out = tmp / f"run-{control}"
    with (tmp / f"{control}.log").open("w") as log:
        proc = subprocess.Popen([sys.executable, "-m", "overdrive.cli.main", "drive", "--xgv",
                                 f"{host}:{port}", str(path), "--out", str(out), "--quiet"],
                                stdout=log, stderr=subprocess.STDOUT)
    plant = server.simulator.core.plant
    try:
        deadline = time.monotonic() + RUN_TIMEOUT_S / 2
        while plant.odometer_m < STALL_AT_M and time.monotonic() < deadline:
            time.sleep(0.005)
        stalled_at_m = plant.odometer_m
        os.kill(proc.pid, signal.SIGSTOP)
        time.sleep(stall_s)
        os.kill(proc.pid, signal.SIGCONT)
        proc.wait(RUN_TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        server.stop()
        thread.join(5.0)
        server.close()
    summary = json.loads((out / "summary.json").read_text())
    return {"stalled_at_m": stalled_at_m, "truth_odometer_m": plant.odometer_m,
            "truth_x_m": plant.x_m, "exit": proc.returncode, "summary": summary}


@pytest.mark.wallclock
def test_a_stalled_drive_counts_the_distance_driven_meanwhile_and_stops(tmp_path: Path) -> None:
    """0.3 s (wrench) and 3 s (motion profile) stalls at cruise, both runs at once: the counted
    distance is the XGV's, nothing past the MOVE's end, and the stall is an unasked stop that
    fails the run (no silent pass)."""
    cases = [("wrench", 0.3), ("motion-profile", 3.0)]
    with ThreadPoolExecutor(len(cases)) as pool:
        results = list(pool.map(lambda c: drive_stalled(tmp_path, *c), cases))
    for (control, stall_s), r in zip(cases, results, strict=True):
        s = r["summary"]
        assert r["stalled_at_m"] >= STALL_AT_M, (control, r)
        assert abs(s["odometer_m"] - r["truth_odometer_m"]) <= COUNT_TOLERANCE_M, (control, r)
        assert r["truth_x_m"] <= MOVE_M, (control, r)
        codes = {e.get("code") for e in s["events"] if e["kind"] == "fault"}
        assert "xgv_stall" in codes, (control, codes)
        assert any(e["kind"] == "interrupted" for e in s["events"]), control
        assert r["truth_x_m"] < MOVE_M - 5.0, (control, r)   # stopped, the MOVE discarded
        assert s["link"]["receiver_stalls"] >= 1
        assert s["wall_clock"]["longest_late_s"] >= stall_s * 0.9
        assert r["exit"] == 1 and any(v.startswith("link fault xgv_stall")
                                      for v in s["violations"]), (control, s["violations"])
