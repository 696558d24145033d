"""Issue 16 cases 2 and 7 together, whole runs: a hill start in a gear that cannot climb the
grade is held on the brakes by the direction hold, the downshift hint still comes, and the
driving module stops, shifts to the low gear and restarts before the hold's fault fails the
MOVE, without rolling back (the judge's direction rule, 0.10 m). Judged from ground truth."""

from __future__ import annotations

import math

import msgspec
import pytest

from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.direction_hold import DirectionHoldConfig

HOLD = DirectionHoldConfig()
DIRECTION_FAULTS = {"1121", "1122", "1123", "1124"}


def run(vehicle: dict, grade_percent: float, duration_s: float = 60.0):
    data = {"name": "hints-hold", "vehicle": vehicle, "start": "ready", "duration_s": duration_s,
            "world": {"friction": 0.8, "grade_percent": grade_percent},
            "events": [{"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 5,
                                               "curvature_1pm": 0}}]}
    return run_scenario(parse_scenario(data), None)


def margin(vehicle: dict, gear: str, grade_percent: float) -> float:
    """The gear's full drive over the pull, less one (the hold's model)."""
    p = msgspec.structs.replace(PRESETS[vehicle["preset"]], mass_kg=vehicle["mass_kg"])
    pull = resistance_mps2(p, 0.0, math.sin(math.atan(grade_percent / 100.0)))
    return drive_authority_mps2(p, p.gear(gear), 0.0) / pull - 1.0


def events(result, kind: str) -> list[dict]:
    return [e for e in result.summary["events"] if e["kind"] == kind]


def never_rolled_back(result) -> bool:
    return min(float(r["x_m"]) for r in result.trace) >= -HOLD.limit_m


HILL_STARTS = [({"preset": "ranger-6x6", "mass_kg": 1700.0}, 15.0),
               ({"preset": "ranger-6x6", "mass_kg": 1600.0}, 16.0),
               ({"preset": "ranger-6x6", "mass_kg": 1500.0}, 16.5),
               ({"preset": "escape-hybrid", "mass_kg": 3400.0}, 14.0),
               ({"preset": "escape-hybrid", "mass_kg": 3600.0}, 14.5),
               ({"preset": "escape-hybrid", "mass_kg": 3800.0}, 14.0)]
"""Below the driving module's steep thresholds (ranger 17 %, escape 14.7 %): there only the
hint knows that the drive gear cannot climb (steeper, low gear is chosen before the start)."""


@pytest.mark.parametrize(("vehicle", "grade_percent"), HILL_STARTS)
def test_a_held_hill_start_gets_the_hint_and_climbs_in_low(vehicle, grade_percent) -> None:
    p = PRESETS[vehicle["preset"]]
    assert margin(vehicle, p.drive_gear, grade_percent) < 100.0 / HOLD.full_drive_pct - 1.0
    result = run(vehicle, grade_percent)
    assert result.summary["violations"] == []
    assert never_rolled_back(result)
    downs = [e["t_s"] for e in events(result, "hint") if e["hint"] == "suggest_downshift"]
    assert downs and downs[0] < 0.5 + HOLD.hold_timeout_s     # before the hold's fault
    assert {e["code"] for e in events(result, "fault")} & DIRECTION_FAULTS == set()
    assert events(result, "move_failed") == []
    assert max(float(r["x_m"]) for r in result.trace) >= 59.3
    assert result.summary["final"]["gear"] == p.low_gear


@pytest.mark.parametrize(("grade_percent", "climbs"), [(15.9, True), (16.3, False),
                                                       (17.0, False)])
def test_the_loaded_escape_around_its_low_gears_limit(grade_percent, climbs) -> None:
    """escape-hybrid at 3,400 kg: low's drive at the hold's full throttle (95 %) beats the pull
    up to ~16.1 %. Below: climbs in low (released at full throttle, inside the 10 % margin);
    above: held on the brakes, the MOVE fails with a fault, never a rollback."""
    vehicle = {"preset": "escape-hybrid", "mass_kg": 3400.0}
    inside = margin(vehicle, "low", grade_percent) >= 100.0 / HOLD.full_drive_pct - 1.0
    assert inside is climbs
    result = run(vehicle, grade_percent)
    assert result.summary["violations"] == []
    assert never_rolled_back(result)
    if climbs:
        assert max(float(r["x_m"]) for r in result.trace) >= 59.3
        assert events(result, "move_failed") == []
    else:
        assert max(float(r["x_m"]) for r in result.trace) < 0.5
        assert events(result, "move_failed")


@pytest.mark.parametrize("preset", ["escape-hybrid", "ranger-6x6"])
@pytest.mark.parametrize("grade_percent", [5.0, 10.0, 15.0])
def test_healthy_hill_starts_get_no_hint_and_no_fault(preset, grade_percent) -> None:
    p = PRESETS[preset]
    result = run({"preset": preset, "mass_kg": p.mass_kg}, grade_percent, duration_s=40.0)
    assert result.summary["violations"] == []
    assert never_rolled_back(result)
    assert [e for e in events(result, "hint") if e["hint"] == "suggest_downshift"] == []
    assert events(result, "fault") == []
    assert max(float(r["x_m"]) for r in result.trace) >= 59.3


@pytest.mark.parametrize("effectiveness", [0.9, 0.96])
def test_a_weak_throttle_in_the_marginal_low_gear_never_rolls_back(effectiveness) -> None:
    """The loaded escape's low gear on 16 % is released at full throttle inside the 10 %
    margin; with a throttle weaker than the model it stalls (fault, MOVE failed) or creeps
    up, never back."""
    data = {"name": "hints-hold-weak", "vehicle": {"preset": "escape-hybrid", "mass_kg": 3400.0},
            "start": "ready", "duration_s": 30.0,
            "world": {"friction": 0.8, "grade_percent": 16.0},
            "events": [{"at_s": 0.2, "actuator": {"throttle": {"effectiveness": effectiveness}}},
                       {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 5,
                                              "curvature_1pm": 0}}]}
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["violations"] == []
    assert never_rolled_back(result)
