"""The fault display recorded in run.mcap (its ``display`` channel) and printed by the
wall-clock runners (``observe.display.DisplayLines``: one line per change)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from overdrive.messages import DISPLAY_REFRESH_S, Display, Topic
from overdrive.observe.display import DisplayLines
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.speed_table import fault_message
from tests.obs.obs_helpers import record_run

FAULT_AT_S, CLEAR_AT_S, CODE = 3.0, 6.0, 7


def client_fault_run(preset: str) -> dict:
    gear = PRESETS[preset].drive_gear
    run = {"speed_mps": 4, "accel_mps2": 1.5, "gear": gear, "state": "run"}
    return {"name": f"display-{preset}", "vehicle": preset, "start": "ready", "seed": 3,
            "duration_s": 10, "events": [
                {"at_s": 0.2, "set_speed": run},
                {"at_s": FAULT_AT_S, "set_speed": {**run, "fault": CODE}},
                {"at_s": CLEAR_AT_S, "set_speed": {**run, "state": "idle", "speed_mps": 0}}]}


def recorded(path: Path, topic: str) -> list[tuple[float, dict]]:
    with path.open("rb") as f:
        return [(m.log_time / 1e9, json.loads(m.data))
                for _s, _c, m in make_reader(f).iter_messages(topics=[topic])]


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_run_mcap_records_the_display_from_the_fault_to_its_clearing(preset, tmp_path):
    path = record_run(client_fault_run(preset), tmp_path)
    displays = recorded(path, Topic.DISPLAY)
    states = recorded(path, Topic.SPEED_STATE)
    assert displays and displays[0][1] == {"text": "", "code": 0, "also_in_force": []}
    shown = [(t, d) for t, d in displays if d["text"]]
    assert shown[0] == (pytest.approx(FAULT_AT_S, abs=0.02),
                        {"text": fault_message(CODE), "code": CODE,
                         "also_in_force": []})
    # from the last status carrying the fault, the very next display is blank
    last_fault_s = max(t for t, s in states if s.get("fault", 0) == CODE)
    blank = next(t for t, d in displays if t > last_fault_s and not d["text"])
    assert blank == pytest.approx(last_fault_s + 0.01, abs=1e-6)
    assert CLEAR_AT_S <= blank <= CLEAR_AT_S + 5.0
    # on change plus the refresh: about one a second, never one a period
    assert len(displays) <= 10 / DISPLAY_REFRESH_S + 4


def test_console_prints_one_line_per_change_and_nothing_for_a_refresh():
    lines: list[str] = []
    console = DisplayLines(lines.append)
    feed = [(0.0, Display(text="")), (1.0, Display(text="")),          # blank, refresh
            (2.5, Display(text="client fault 7: brakes on", code=7)),
            (3.5, Display(text="client fault 7: brakes on", code=7)),  # refresh
            (4.0, Display(text="no SPSS for 0.200 s", code=1001)),
            (6.0, Display(text=""))]
    for t, msg in feed:
        console.set_time(t)
        console.observe(Topic.DISPLAY, msg)
        console.observe(Topic.NOTICE, msg)                             # other topics ignored
    assert len(lines) == console.lines == 3
    assert "2.50 s" in lines[0] and "fault 7: client fault 7: brakes on" in lines[0]
    assert "4.00 s" in lines[1] and "fault 1001: no SPSS" in lines[1]
    assert "6.00 s" in lines[2] and "(clear)" in lines[2]
