"""``overdrive drive`` prints the fault display (seed 001's LED sign): one line when the text
changes, against the simulated XGV over real UDP, in wall-clock time; run.mcap records it."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest
from mcap.reader import make_reader

from overdrive.messages import Topic
from overdrive.run.drive import run_drive
from overdrive.run.xgv_sim import XgvServer
from overdrive.scenario.schema import parse_scenario
from overdrive.servers.speed_table import fault_message

FAULT_AT_S, CLEAR_AT_S, CODE = 1.5, 3.0, 7


@pytest.mark.wallclock
def test_drive_prints_a_line_when_the_fault_shows_and_one_when_it_clears(tmp_path: Path) -> None:
    run = {"speed_mps": 3, "accel_mps2": 1.5, "gear": "drive", "state": "run"}
    scenario = parse_scenario({
        "name": "drive-display", "interface": "jaus", "control": "wrench",
        "vehicle": "escape-hybrid", "start": "ready", "seed": 1, "duration_s": 5, "events": [
            {"at_s": 0.3, "set_speed": run},
            {"at_s": FAULT_AT_S, "set_speed": {**run, "fault": CODE}},
            {"at_s": CLEAR_AT_S, "set_speed": {**run, "state": "idle", "speed_mps": 0}}]},
        "drive-display")
    server = XgvServer("127.0.0.1", 0, scenario)
    thread = threading.Thread(target=server.serve, kwargs={"duration_s": 30.0}, daemon=True)
    thread.start()
    lines: list[str] = []
    try:
        run_drive(scenario, server.address, tmp_path / "run", plot=False, display=lines.append)
    finally:
        server.stop()
        thread.join(5.0)
        server.close()
    assert len(lines) == 2, lines
    assert f"fault {CODE}: {fault_message(CODE)}" in lines[0] and "(clear)" in lines[1]
    shown_s, cleared_s = (float(line.split()[1]) for line in lines)
    assert FAULT_AT_S <= shown_s <= FAULT_AT_S + 0.1
    assert CLEAR_AT_S <= cleared_s <= CLEAR_AT_S + 3.0
    with (tmp_path / "run" / "run.mcap").open("rb") as f:
        texts = [json.loads(m.data)["text"]
                 for _s, _c, m in make_reader(f).iter_messages(topics=[Topic.DISPLAY])]
    assert fault_message(CODE) in texts and texts[-1] == ""
