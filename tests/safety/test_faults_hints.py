"""Issue 16 case 7, whole runs: hints heard. A vehicle lugging up a grade its drive gear cannot
climb stops, shifts to low and climbs (judged from ground truth); without acting on the hint it
stalls. An upshift comes only at speed, and stops a move only when that pays. Healthy runs are
unchanged by either."""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import load_scenario, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers import gear_hints
from overdrive.servers.speed_hints import HintMonitor
from tests.conftest import PRESET_NAMES

pytestmark = pytest.mark.variants

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "scenarios" / "faults" / "lugging-downshift.yaml"
STEEP_RANGER = math.tan(0.5 * PRESETS["ranger-6x6"].max_pitch_rad) * 100.0   # 17.0 %: the
# driving module's own steep threshold (DrivingConfig.steep_pitch_fraction); below it only
# the hint knows that high cannot climb


def run(vehicle: Any, grades: list[tuple[float, float]], distance_m: float = 60.0,
        speed_mps: float = 5.0, duration_s: float = 60.0) -> Any:
    data = {"name": "hints", "vehicle": vehicle, "start": "ready", "duration_s": duration_s,
            "world": {"friction": 0.8, "grade_percent": [
                {"from_m": f, "grade_percent": g} for f, g in grades]},
            "events": [{"at_s": 0.5, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                               "curvature_1pm": 0}}]}
    return run_scenario(parse_scenario(data), None)


def deaf(monkeypatch) -> None:
    """The driving module's hint handling disabled: hints are published, nobody acts."""
    monkeypatch.setattr(gear_hints.GearHints, "update", lambda self, *a, **k: None)


def xs(result) -> list[float]:
    return [float(r["x_m"]) for r in result.trace]


def reached_s(result, x_m: float) -> float:
    return next((float(r["t_s"]) for r in result.trace if float(r["x_m"]) >= x_m), math.inf)


def hints_of(result, name: str) -> list[float]:
    return [e["t_s"] for e in result.summary["events"]
            if e["kind"] == "hint" and e["hint"] == name]


def shifts(result) -> int:
    """Gear changes engaged (from the trace's gear column)."""
    gears = [r["gear"] for r in result.trace]
    return sum(1 for a, b in itertools.pairwise(gears) if a != b)


def speed_at(result, t_s: float) -> float:
    return next(float(r["speed_mps"]) for r in result.trace if float(r["t_s"]) >= t_s - 1e-9)


def assert_upshifts_only_at_speed(result, preset: str) -> None:
    """No suggest_upshift below 85 % of the low gear's top speed (never at 0 m/s)."""
    p = PRESETS[preset]
    top = p.gear(p.low_gear).max_speed_mps
    for t in hints_of(result, "suggest_upshift"):
        assert abs(speed_at(result, t)) >= 0.85 * top - 0.05, t


def high_gain_mps2(mass_kg: float, grade_percent: float) -> float:
    """ranger-6x6 high gear at full throttle, low speed (force-limited): the plant's model."""
    p = PRESETS["ranger-6x6"]
    pitch = math.atan(grade_percent / 100.0)
    return (p.gear("high").max_force_n / mass_kg - p.rolling_resistance * G_MPS2 * math.cos(pitch)
            - G_MPS2 * math.sin(pitch))


# --------------------------------------------------------------------------- the scenario

def test_the_scenario_climbs_by_acting_on_the_downshift_hint() -> None:
    result = run_scenario(load_scenario(SCENARIO), None)
    assert result.summary["violations"] == []
    assert result.exit_code == 0
    assert max(xs(result)) >= 59.3                      # the end of the 60 m MOVE
    assert hints_of(result, "suggest_downshift")
    assert result.summary["final"]["gear"] == "low6wd"
    assert shifts(result) == 1
    assert high_gain_mps2(1600.0, 15.0) < 0.0           # high cannot climb it at this mass


def test_without_acting_on_the_hint_the_scenario_stalls(monkeypatch) -> None:
    deaf(monkeypatch)
    result = run_scenario(load_scenario(SCENARIO), None)
    assert max(xs(result)) < 35.0                       # stalled on the grade, 25 m short
    assert result.summary["final"]["gear"] == "high"
    assert hints_of(result, "suggest_downshift")        # the hint was right, nobody heard it
    assert result.exit_code == 1                        # the scenario's expectations fail


# --------------------------------------------------------------------------- variants

LOADED = [(mass, grade) for mass in (1500.0, 1600.0, 1700.0) for grade in (14.0, 15.0, 16.0)
          if high_gain_mps2(mass, grade) < 0.0]


VARIANTS = ([(m, g, 10.0, 5.0) for m, g in LOADED]
            + [(1600.0, 15.0, 3.0, 3.0), (1600.0, 15.0, 25.0, 8.0), (1700.0, 16.0, 25.0, 8.0),
               (1500.0, 16.0, 25.0, 8.0)])   # grade met at once, slowly; with momentum


@pytest.mark.parametrize(("mass_kg", "grade_percent", "from_m", "speed_mps"), VARIANTS)
def test_loaded_ranger_climbs_below_the_steep_threshold(mass_kg, grade_percent, from_m,
                                                         speed_mps) -> None:
    assert grade_percent < STEEP_RANGER
    result = run({"preset": "ranger-6x6", "mass_kg": mass_kg},
                 [(0.0, 0.0), (from_m, grade_percent)], speed_mps=speed_mps)
    assert result.summary["violations"] == []
    assert max(xs(result)) >= 59.3
    assert result.summary["final"]["gear"] == "low6wd"
    assert_upshifts_only_at_speed(result, "ranger-6x6")


@pytest.mark.parametrize(("mass_kg", "grade_percent"), [(1600.0, 14.0), (1500.0, 16.0),
                                                        (1700.0, 15.0)])
def test_loaded_ranger_deaf_to_the_hint_stalls(monkeypatch, mass_kg, grade_percent) -> None:
    deaf(monkeypatch)
    result = run({"preset": "ranger-6x6", "mass_kg": mass_kg},
                 [(0.0, 0.0), (10.0, grade_percent)])
    assert max(xs(result)) < 59.3
    assert result.summary["final"]["gear"] == "high"


@pytest.mark.parametrize("grade_percent", [23.0, 26.0, 30.0])
def test_ranger_on_grades_high_cannot_climb_gets_up_no_later_than_without_the_hint(
        monkeypatch, grade_percent) -> None:
    """Above the steep threshold the driving module changes gear at a standstill anyway; the
    hint stops it sooner (the vehicle keeps its momentum less long)."""
    heard = run("ranger-6x6", [(0.0, 0.0), (10.0, grade_percent)])
    assert heard.summary["violations"] == []
    assert max(xs(heard)) >= 59.3
    assert_upshifts_only_at_speed(heard, "ranger-6x6")
    deaf(monkeypatch)
    unheard = run("ranger-6x6", [(0.0, 0.0), (10.0, grade_percent)])
    assert reached_s(heard, 59.3) <= reached_s(unheard, 59.3) + 0.05


@pytest.mark.parametrize("grade_percent", [13.0, 14.0, 15.0, 16.0])
def test_towing_escape_acts_only_when_low_gear_pays(monkeypatch, grade_percent) -> None:
    """escape-hybrid at 3,400 kg: drive crawls up 13-14 % (low adds only 15 % of force: not worth
    a stop and a 5 s runwait), cannot climb 16 %; from 14.7 % the grade is steep anyway."""
    vehicle = {"preset": "escape-hybrid", "mass_kg": 3400.0}
    heard = run(vehicle, [(0.0, 0.0), (10.0, grade_percent)])
    assert heard.summary["violations"] == []
    assert max(xs(heard)) >= 59.3
    assert_upshifts_only_at_speed(heard, "escape-hybrid")
    deaf(monkeypatch)
    unheard = run(vehicle, [(0.0, 0.0), (10.0, grade_percent)])
    assert reached_s(heard, 59.3) <= reached_s(unheard, 59.3) + 0.05


@pytest.mark.parametrize(("mass_kg", "grade_percent"), [(3600.0, 14.5), (3800.0, 14.0)])
def test_overloaded_escape_climbs_only_by_acting_on_the_hint(monkeypatch, mass_kg,
                                                              grade_percent) -> None:
    """escape-hybrid far beyond its towing rating (the mechanism on the second preset): drive
    cannot climb, low can, the grade is below its 14.7 % steep threshold."""
    vehicle = {"preset": "escape-hybrid", "mass_kg": mass_kg}
    grades = [(0.0, 0.0), (10.0, grade_percent)]
    heard = run(vehicle, grades)
    assert heard.summary["violations"] == []
    assert max(xs(heard)) >= 59.3
    assert heard.summary["final"]["gear"] == "low"
    deaf(monkeypatch)
    unheard = run(vehicle, grades)
    assert max(xs(unheard)) < 45.0
    assert unheard.summary["final"]["gear"] == "drive"


# --------------------------------------------------------------------------- upshift

HILL_THEN_FLAT = [(0.0, 0.0), (10.0, 15.0), (40.0, 0.0)]
LOADED_RANGER = {"preset": "ranger-6x6", "mass_kg": 1600.0}


def test_upshift_after_the_hill_when_the_rest_of_the_move_pays_for_the_stop(monkeypatch) -> None:
    result = run(LOADED_RANGER, HILL_THEN_FLAT, distance_m=200.0, speed_mps=8.0, duration_s=80.0)
    assert result.summary["violations"] == []
    assert max(xs(result)) >= 199.3
    assert shifts(result) == 2                         # down on the hill, up on the flat
    assert result.summary["final"]["gear"] == "high"
    assert_upshifts_only_at_speed(result, "ranger-6x6")
    monkeypatch.setattr(HintMonitor, "upshift_ready", lambda self, *a, **k: False)
    stays_low = run(LOADED_RANGER, HILL_THEN_FLAT, distance_m=200.0, speed_mps=8.0,
                    duration_s=80.0)
    assert reached_s(result, 199.3) < reached_s(stays_low, 199.3) - 3.0


def test_a_short_rest_is_finished_in_low_then_the_gear_changes_at_the_stop() -> None:
    """70 m: after the hill ~25 m are left, less than the ~94 m an upshift needs to pay."""
    result = run(LOADED_RANGER, HILL_THEN_FLAT, distance_m=70.0, speed_mps=8.0)
    assert result.summary["violations"] == []
    assert max(xs(result)) >= 69.3
    rows = [(float(r["x_m"]), float(r["speed_mps"])) for r in result.trace]
    assert min(v for x, v in rows if 45.0 <= x <= 66.0) > 1.0    # no stop after the hill
    assert_upshifts_only_at_speed(result, "ranger-6x6")


# --------------------------------------------------------------------------- healthy

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_percent", [-15.0, 0.0, 10.0, 15.0])
def test_healthy_runs_are_unchanged(monkeypatch, preset, grade_percent) -> None:
    heard = run(preset, [(0.0, grade_percent)], distance_m=40.0, duration_s=30.0)
    assert heard.summary["violations"] == []
    assert hints_of(heard, "suggest_downshift") == []
    assert_upshifts_only_at_speed(heard, preset)
    deaf(monkeypatch)
    unheard = run(preset, [(0.0, grade_percent)], distance_m=40.0, duration_s=30.0)
    assert heard.trace[-1] == unheard.trace[-1]


# --------------------------------------------------------------------------- around a downshift

HILL = [(0.0, 0.0), (10.0, 15.0)]


def run_events(vehicle: Any, grades: list[tuple[float, float]], events: list[dict],
               duration_s: float = 70.0, obstacles: list[dict] | None = None) -> Any:
    data = {"name": "hints-combined", "vehicle": vehicle, "start": "ready",
            "duration_s": duration_s,
            "world": {"friction": 0.8, "obstacles": obstacles or [], "grade_percent": [
                {"from_m": f, "grade_percent": g} for f, g in grades]},
            "events": events}
    return run_scenario(parse_scenario(data), None)


MOVE_60 = {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 5, "curvature_1pm": 0}}


def x_at(result, t_s: float) -> float:
    return next(float(r["x_m"]) for r in result.trace if float(r["t_s"]) >= t_s - 1e-9)


@pytest.mark.parametrize("stop_s", [7.7, 8.5, 10.0, 13.0])   # stopping, shifting, runwait
def test_a_stop_during_the_gear_change_holds_and_the_next_move_climbs(stop_s) -> None:
    result = run_events(LOADED_RANGER, HILL, [
        MOVE_60, {"at_s": stop_s, "stop": {}},
        {"at_s": 20.0, "move": {"distance_m": 40, "maxspeed_mps": 5, "curvature_1pm": 0}}])
    assert result.summary["violations"] == []
    assert x_at(result, 19.9) - x_at(result, stop_s) < 1.0       # held after the STOP
    assert xs(result)[-1] - x_at(result, 20.0) >= 39.3
    assert abs(result.summary["final"]["speed_mps"]) < 0.05


def test_a_new_move_during_the_runwait_is_driven_in_low() -> None:
    result = run_events(LOADED_RANGER, HILL, [
        MOVE_60, {"at_s": 11.0, "move": {"distance_m": 30, "maxspeed_mps": 4,
                                         "curvature_1pm": 0}}])
    assert result.summary["violations"] == []
    assert xs(result)[-1] - x_at(result, 11.0) >= 29.3
    assert result.summary["final"]["gear"] == "low6wd"


def test_an_obstacle_on_the_hill_after_the_downshift_is_not_hit() -> None:
    result = run_events(LOADED_RANGER, HILL, [MOVE_60], obstacles=[{"x_m": 45.0, "y_m": 0.0}])
    assert result.summary["violations"] == []
    assert "suggest_downshift" in [e.get("hint") for e in result.summary["events"]]


def test_lugging_in_a_curve_on_the_hill() -> None:
    result = run_events(LOADED_RANGER, HILL, [
        {"at_s": 0.5, "move": {"distance_m": 60, "maxspeed_mps": 5, "curvature_1pm": 0.02}}])
    assert result.summary["violations"] == []
    assert result.summary["odometer_m"] >= 59.3
    assert result.summary["final"]["gear"] == "low6wd"


@pytest.mark.parametrize(("preset", "effectiveness"), [("ranger-6x6", 0.2),
                                                       ("escape-hybrid", 0.1)])
def test_a_weak_throttle_lugs_on_the_flat_and_the_low_gear_gets_there(preset, effectiveness):
    """A weak engine lugs like a load: the hint helps it too (the model does not know the
    weakness, so an upshift may be hinted later; it only lifts the preference)."""
    result = run_events(preset, [(0.0, 0.0)], [
        MOVE_60, {"at_s": 0.2, "actuator": {"throttle": {"effectiveness": effectiveness}}}])
    assert result.summary["violations"] == []
    assert max(xs(result)) >= 59.3
    assert_upshifts_only_at_speed(result, preset)


@pytest.mark.parametrize(("mass_kg", "grade_percent"), [(1700.0, 15.0), (1600.0, 16.0)])
def test_a_hill_start_in_high_that_cannot_climb_downshifts(mass_kg, grade_percent) -> None:
    result = run_events({"preset": "ranger-6x6", "mass_kg": mass_kg},
                        [(0.0, grade_percent)], [MOVE_60])
    assert result.summary["violations"] == []
    assert max(xs(result)) >= 59.3
    assert result.summary["final"]["gear"] == "low6wd"


def test_reversing_after_a_downshift_and_forward_again() -> None:
    result = run_events(LOADED_RANGER, HILL, [
        MOVE_60, {"at_s": 35.0, "reverse": {"distance_m": 5, "maxspeed_mps": 1,
                                            "curvature_1pm": 0}},
        {"at_s": 55.0, "move": {"distance_m": 10, "maxspeed_mps": 5, "curvature_1pm": 0}}],
        duration_s=80.0)
    assert result.summary["violations"] == []
    assert x_at(result, 54.9) == pytest.approx(x_at(result, 35.0) - 5.0, abs=0.5)   # reversed 5 m
    assert xs(result)[-1] == pytest.approx(x_at(result, 54.9) + 10.0, abs=0.7)
    assert result.summary["final"]["gear"] == "low6wd"           # still preferred going forward


def test_throttle_stuck_closed_during_the_gear_change_does_not_roll_back() -> None:
    """Found by attacking the downshift: the throttle sticks at 0 while the vehicle stands for
    the shift; the restart in low6wd releases the brake on the 15 % grade."""
    result = run_events(LOADED_RANGER, HILL, [
        MOVE_60, {"at_s": 9.0, "actuator": {"throttle": {"stuck": True}}}])
    assert result.summary["violations"] == []
