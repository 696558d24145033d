"""Closed loop (driving module + speed server + simulated vehicle): the seed-003 acceptance cases."""

from __future__ import annotations

from pathlib import Path

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import load_scenario, parse_scenario
from overdrive.scenario.vehicles import PRESETS

PRESET_NAMES = tuple(PRESETS)
SCENARIOS = sorted((Path(__file__).parents[2] / "scenarios").glob("driving-*.yaml"))
LIMIT = [{"at_s": 1, "max_speed": {"source": "map", "speed_mps": 8}}]
ADVANCE_30 = [{"at_s": 1, "advance": {"source": "lidar", "distance_m": 30}}]


def run(preset: str, events: list, grade: float = 0.0, duration_s: float = 20.0):
    data = {"name": "driving-acceptance", "vehicle": preset, "start": "ready",
            "duration_s": duration_s, "world": {"grade_percent": grade, "friction": 0.8},
            "events": events}
    return run_scenario(parse_scenario(data, source="<test>"), keep_trace=True)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade", [0.0, -10.0])
def test_single_authorization_stops_just_short_of_its_end(preset, grade):
    result = run(preset, ADVANCE_30 + LIMIT, grade)
    s = result.summary
    assert 29.7 <= s["odometer_m"] <= 30.0
    assert abs(s["final"]["speed_mps"]) < 0.05
    assert s["peaks"]["max_speed_mps"] < 8.2
    assert not [e for e in s["events"] if e["kind"] in ("fault", "estop", "rejected")]
    # the authorization shown in the trace is used up as the vehicle moves
    rows = [r for r in result.trace if r["authorized_m"]]
    assert float(rows[0]["authorized_m"]) == pytest.approx(30.0, abs=0.01)
    assert float(rows[-1]["authorized_m"]) == pytest.approx(30.0 - s["odometer_m"], abs=0.01)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_two_sources_the_shorter_wins(preset):
    radar = [{"at_s": 1, "advance": {"source": "radar", "distance_m": 22}}]
    s = run(preset, ADVANCE_30 + radar + LIMIT).summary
    assert 21.5 <= s["odometer_m"] < 22.0
    assert abs(s["final"]["speed_mps"]) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_streamed_authorizations_hold_the_limit(preset):
    stream = [{"at_s": round(1 + 0.25 * i, 2), "advance": {"source": "lidar", "distance_m": 30}}
              for i in range(60)]
    result = run(preset, stream + LIMIT, duration_s=16.0)
    # from 9 s: the launch includes the once-a-run brake probe (issue 16), ~1.5 s
    after_ramp = [abs(float(r["speed_mps"])) for r in result.trace if 9.0 <= float(r["t_s"]) <= 16]
    assert after_ramp
    assert max(abs(v - 8.0) for v in after_ramp) <= 0.2


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_driving_scenarios_meet_their_expectations(path):
    result = run_scenario(load_scenario(path), keep_trace=False)
    assert result.summary["violations"] == []
    assert result.exit_code == 0


def test_there_are_driving_scenarios():
    assert len(SCENARIOS) >= 4
