"""The speed server's hints (seed 001): downshift when lugging, upshift only when speed *and* rpm
are high and the drive gear can carry the vehicle, swept around every threshold on both presets;
then closed loop against the plant (set_speed scenarios: the speed server alone)."""

from __future__ import annotations

import math
import typing

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive import messages
from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.speed import SpeedServerConfig
from overdrive.servers.speed_hints import HINTS, HintConfig, HintInputs, HintMonitor
from tests.conftest import PRESET_NAMES

PERIOD_S = 0.01
CFG = HintConfig()
CAP = SpeedServerConfig().gear_cap_fraction
EPS = 1e-3


def monitor(preset: str) -> HintMonitor:
    return HintMonitor(PRESETS[preset], CFG, CAP)


def rpm_at(params: VehicleParams, fraction: float) -> float:
    return params.idle_rpm + fraction * (params.redline_rpm - params.idle_rpm)


def lugging_view(preset: str, **over) -> HintInputs:
    """Inside every lugging threshold: the drive gear at full throttle, 1 m/s behind its target,
    not gaining, at half the low gear's cap, on a 10 % grade."""
    p = PRESETS[preset]
    speed = 0.5 * p.gear(p.low_gear).max_speed_mps * CAP
    fields = dict(gear=p.gear(p.drive_gear), speed_mps=speed, wheel_mps=speed, accel_mps2=0.0,
                  target_mps=speed + 1.0, sin_pitch=math.sin(math.atan(0.10)),
                  engine_rpm=rpm_at(p, speed / p.gear(p.drive_gear).max_speed_mps),
                  throttle_pct=100.0, traction_control=False)
    fields.update(over)
    return HintInputs(**fields)


def upshift_view(preset: str, **over) -> HintInputs:
    """Inside every upshift threshold: the low gear at its cap (0.9 of its top speed: rpm and
    ground speed 0.9 of the range), asked for the cap, on flat ground."""
    p = PRESETS[preset]
    low = p.gear(p.low_gear)
    speed = CAP * low.max_speed_mps
    fields = dict(gear=low, speed_mps=speed, wheel_mps=speed, accel_mps2=0.0, target_mps=speed,
                  sin_pitch=0.0, engine_rpm=rpm_at(p, CAP), throttle_pct=40.0,
                  traction_control=False)
    fields.update(over)
    return HintInputs(**fields)


def hint_after(m: HintMonitor, view: HintInputs | None, seconds: float, start_s: float = 0.0) -> str:
    """Step ``view`` every period from ``start_s`` for ``seconds`` (inclusive); the last hint."""
    hint = m.hint
    for i in range(round(seconds / PERIOD_S) + 1):
        hint = m.update(start_s + i * PERIOD_S, view)
    return hint


# --------------------------------------------------------------------------- downshift (lugging)

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("throttle_pct", "fires"), [
    (50.0, False), (79.9, False), (80.0 - EPS, False), (80.0, True), (80.0 + EPS, True),
    (100.0, True)])
def test_downshift_needs_full_throttle(preset, throttle_pct, fires):
    hint = hint_after(monitor(preset), lugging_view(preset, throttle_pct=throttle_pct), 2.0)
    assert (hint == "suggest_downshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("gap_mps", "fires"), [
    (0.0, False), (0.3, False), (0.5 - EPS, False), (0.5 + EPS, True), (2.0, True)])
def test_downshift_needs_the_target_ahead_by_half_a_metre_per_second(preset, gap_mps, fires):
    """Judged against the target, not the reference: the reference never leads by more than
    0.3 m/s (speed_control.max_ref_lead_mps), so a gap of 0.5 to it could never show."""
    view = lugging_view(preset)
    view = lugging_view(preset, target_mps=view.speed_mps + gap_mps)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_downshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("speed_mps", "fires"), [
    (0.0, True), (0.15 - EPS, True), (0.15 + EPS, False), (0.3, False)])
def test_downshift_when_stalled_short_of_a_slow_target(preset, speed_mps, fires):
    """Creeping to the end of a move (0.3 m/s): half the target behind is enough."""
    view = lugging_view(preset, speed_mps=speed_mps, wheel_mps=speed_mps, target_mps=0.3)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_downshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("accel_mps2", "fires"), [
    (-2.0, True), (0.0, True), (0.3 - EPS, True), (0.3, False), (0.3 + EPS, False),
    (1.0, False)])
def test_downshift_only_when_not_gaining(preset, accel_mps2, fires):
    """Accelerating at full throttle (a start, a hill the gear can climb) is not lugging."""
    view = lugging_view(preset, accel_mps2=accel_mps2)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_downshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("share", "fires"), [
    (0.0, True), (0.5, True), (1.0 - EPS, True), (1.0 + EPS, False), (1.5, False)])
def test_downshift_only_below_the_low_gears_cap(preset, share, fires):
    """"Speed and RPM low enough for downshift to LOW": after the shift the speed fits the gear."""
    p = PRESETS[preset]
    speed = share * CAP * p.gear(p.low_gear).max_speed_mps
    view = lugging_view(preset, speed_mps=speed, wheel_mps=speed, target_mps=speed + 1.0)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_downshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_downshift_after_a_second_of_lugging(preset):
    m = monitor(preset)
    view = lugging_view(preset)
    assert hint_after(m, view, 1.0 - 2 * PERIOD_S) == "none"
    assert m.update(1.0 - PERIOD_S, view) == "none"
    assert m.update(1.0, view) == "suggest_downshift"


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("speed_mps", [0.0, -0.05, -0.5])
def test_downshift_when_stalled_or_rolling_back_at_full_throttle(preset, speed_mps):
    """A grade the gear cannot hold: standing or rolling back with the throttle open."""
    view = lugging_view(preset, speed_mps=speed_mps, wheel_mps=speed_mps, target_mps=2.0,
                        accel_mps2=min(0.0, 2.0 * speed_mps))
    assert hint_after(monitor(preset), view, 2.0) == "suggest_downshift"


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_no_downshift_in_the_low_gear_in_reverse_or_outside_run(preset):
    p = PRESETS[preset]
    for gear in (p.low_gear, p.reverse_gear):
        assert hint_after(monitor(preset), lugging_view(preset, gear=p.gear(gear)), 3.0) == "none"
    m = monitor(preset)
    hint_after(m, lugging_view(preset), 0.9)
    assert hint_after(m, None, 0.5, start_s=1.0) == "none"        # leaving run resets the timing
    assert hint_after(m, lugging_view(preset), 0.9, start_s=2.0) == "none"


def test_downshift_from_the_rangers_middle_gear():
    """ranger-6x6 ``low`` pulls less than ``low6wd`` (the preset's low gear): lugging in it is a
    downshift too."""
    p = PRESETS["ranger-6x6"]
    view = lugging_view("ranger-6x6", gear=p.gear("low"))
    assert hint_after(monitor("ranger-6x6"), view, 2.0) == "suggest_downshift"


# --------------------------------------------------------------------------- upshift

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("rpm_fraction", "fires"), [
    (0.5, False), (0.85 - EPS, False), (0.85 + EPS, True), (0.9, True)])
def test_upshift_needs_high_rpm(preset, rpm_fraction, fires):
    view = upshift_view(preset, engine_rpm=rpm_at(PRESETS[preset], rpm_fraction))
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_upshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("speed_fraction", "fires"), [
    (0.0, False), (0.5, False), (0.85 - EPS, False), (0.85 + EPS, True), (0.9, True)])
def test_upshift_needs_high_ground_speed_not_just_rpm(preset, speed_fraction, fires):
    """Spinning wheels rev the engine at any ground speed: the rpm alone never upshifts."""
    p = PRESETS[preset]
    speed = speed_fraction * p.gear(p.low_gear).max_speed_mps
    view = upshift_view(preset, speed_mps=speed, engine_rpm=rpm_at(p, 0.95))
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_upshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("target_fraction", "fires"), [
    (0.0, False), (0.85 - EPS, False), (0.85 + EPS, True), (0.9, True)])
def test_upshift_only_when_asked_for_about_the_gears_top(preset, target_fraction, fires):
    """Overrunning the gear downhill while asked for less is not a reason to upshift."""
    p = PRESETS[preset]
    view = upshift_view(preset, target_mps=target_fraction * p.gear(p.low_gear).max_speed_mps)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_upshift") is fires


def drive_gain_mps2(p: VehicleParams, speed_mps: float, sin_pitch: float) -> float:
    """Full-throttle acceleration of the drive gear (the plant's powertrain, restated)."""
    gear = p.gear(p.drive_gear)
    force = min(gear.max_force_n, p.max_power_w / max(speed_mps, 0.5))
    if speed_mps > 0.9 * gear.max_speed_mps:
        force *= max(0.0, (gear.max_speed_mps - speed_mps) / (0.1 * gear.max_speed_mps))
    cos = math.sqrt(1.0 - sin_pitch ** 2)
    drag = 0.5 * 1.225 * p.drag_area_m2 * speed_mps ** 2
    return (force - drag) / p.mass_kg - p.rolling_resistance * G_MPS2 * cos - G_MPS2 * sin_pitch


def limit_sin_pitch(p: VehicleParams, speed_mps: float, gain_mps2: float) -> float:
    lo, hi = -0.5, 0.9
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if drive_gain_mps2(p, speed_mps, mid) > gain_mps2 else (lo, mid)
    return lo


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("offset", "fires"), [(-0.05, True), (-EPS, True), (EPS, False),
                                               (0.05, False)])
def test_upshift_only_where_the_drive_gear_gains_0_6_mps2(preset, offset, fires):
    """No upshift onto a grade the drive gear would lug on (hysteresis against the downshift):
    swept around the grade where its full-throttle gain is 0.6 m/s^2."""
    p = PRESETS[preset]
    view = upshift_view(preset)
    edge = limit_sin_pitch(p, view.speed_mps, CFG.upshift_accel_mps2)
    view = upshift_view(preset, sin_pitch=edge + offset)
    assert (hint_after(monitor(preset), view, 2.0) == "suggest_upshift") is fires


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_upshift_after_a_second_and_not_from_the_drive_gear_or_reverse(preset):
    p = PRESETS[preset]
    m = monitor(preset)
    view = upshift_view(preset)
    assert hint_after(m, view, 1.0 - 2 * PERIOD_S) == "none"
    assert m.update(1.0 - PERIOD_S, view) == "none"
    assert m.update(1.0, view) == "suggest_upshift"
    for gear in (p.drive_gear, p.reverse_gear):
        v = upshift_view(preset, gear=p.gear(gear))
        assert hint_after(monitor(preset), v, 3.0) == "none"


@settings(max_examples=300, deadline=None)
@given(preset=st.sampled_from(PRESET_NAMES), speed_share=st.floats(-1.0, 0.85 - EPS),
       rpm_fraction=st.floats(0.0, 1.2), target_share=st.floats(0.0, 5.0),
       sin_pitch=st.floats(-0.3, 0.3), slip_mps=st.floats(0.0, 5.0))
def test_no_upshift_below_85_percent_of_the_gears_speed(preset, speed_share, rpm_fraction,
                                                         target_share, sin_pitch, slip_mps):
    """In particular never at 0 m/s, whatever the rpm, the wheels or the request (issue 16)."""
    p = PRESETS[preset]
    top = p.gear(p.low_gear).max_speed_mps
    speed = speed_share * top
    view = upshift_view(preset, speed_mps=speed, wheel_mps=speed + slip_mps,
                        engine_rpm=rpm_at(p, rpm_fraction), target_mps=target_share * top,
                        sin_pitch=sin_pitch)
    assert hint_after(monitor(preset), view, 1.5) != "suggest_upshift"


# --------------------------------------------------------------------------- order and hold

def test_the_five_hints_are_the_whole_set():
    """Seed 001 "(others to be defined)": decided, none (docs/speed-server.md, Hints)."""
    assert set(typing.get_args(messages.Hint)) == set(HINTS)
    assert HINTS[0] == "none"


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_slipping_and_slowdown_come_before_a_downshift(preset):
    p = PRESETS[preset]
    assert hint_after(monitor(preset), lugging_view(preset, traction_control=True),
                      2.0) == "slipping"
    assert hint_after(monitor(preset), lugging_view(preset, engine_rpm=rpm_at(p, 0.98)),
                      2.0) == "suggest_slowdown"


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_downshift_hint_is_held_a_second_then_cleared(preset):
    m = monitor(preset)
    assert hint_after(m, lugging_view(preset), 1.5) == "suggest_downshift"   # since t = 1.0
    healthy = lugging_view(preset, accel_mps2=1.0)
    assert hint_after(m, healthy, 0.45, start_s=1.51) == "suggest_downshift"
    assert hint_after(m, healthy, 0.2, start_s=2.0) == "none"


# --------------------------------------------------------------------------- closed loop

def speed_run(vehicle, gear: str, speed_mps: float, grade_percent: float, duration_s: float = 20.0):
    """Start ready (drive gear, run); another gear: idle in it first (seed 001), then run
    (runwait 5 s)."""
    preset = vehicle if isinstance(vehicle, str) else vehicle["preset"]
    events = []
    run_s = 0.5
    if gear != PRESETS[preset].drive_gear:
        events.append({"at_s": 0.5, "set_speed": {"speed_mps": 0.0, "accel_mps2": 1.0,
                                                  "gear": gear, "state": "idle"}})
        run_s = 3.0
    events.append({"at_s": run_s, "set_speed": {"speed_mps": speed_mps, "accel_mps2": 1.0,
                                                "gear": gear, "state": "run"}})
    scenario = parse_scenario({
        "name": "hints", "vehicle": vehicle, "start": "ready", "duration_s": duration_s,
        "world": {"grade_percent": grade_percent}, "events": events}, source="<test>")
    return run_scenario(scenario, None)


def hints_of(result) -> list[tuple[float, str]]:
    return [(e["t_s"], e["hint"]) for e in result.summary["events"] if e["kind"] == "hint"]


def speed_at(result, t_s: float) -> float:
    return next(float(r["speed_mps"]) for r in result.trace if float(r["t_s"]) >= t_s - 1e-9)


@pytest.mark.parametrize(("vehicle", "grade_percent"), [
    ("ranger-6x6", 25.0), ("ranger-6x6", 30.0),                       # high cannot climb it
    ({"preset": "escape-hybrid", "mass_kg": 3400.0}, 16.0)])           # towing: drive cannot
def test_lugging_uphill_in_the_drive_gear_suggests_a_downshift(vehicle, grade_percent):
    """Issue 16 case 7: it could never fire (the reference is clamped 0.3 m/s ahead)."""
    p = PRESETS[vehicle if isinstance(vehicle, str) else vehicle["preset"]]
    result = speed_run(vehicle, p.drive_gear, 5.0, grade_percent)
    downs = [t for t, h in hints_of(result) if h == "suggest_downshift"]
    assert downs, hints_of(result)
    assert abs(speed_at(result, downs[0])) < CAP * p.gear(p.low_gear).max_speed_mps


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_percent", [-15.0, -5.0, 0.0, 5.0, 10.0, 15.0])
def test_no_hint_driving_healthy_in_the_drive_gear(preset, grade_percent):
    p = PRESETS[preset]
    result = speed_run(preset, p.drive_gear, 5.0, grade_percent)
    assert result.summary["violations"] == []
    assert [h for _, h in hints_of(result) if h != "none"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_upshift_at_the_low_gears_top_not_on_the_way_there(preset):
    p = PRESETS[preset]
    low = p.gear(p.low_gear)
    result = speed_run(preset, p.low_gear, 2.0 * low.max_speed_mps, 0.0, duration_s=30.0)
    ups = [t for t, h in hints_of(result) if h == "suggest_upshift"]
    assert ups, hints_of(result)
    assert all(speed_at(result, t) >= 0.85 * low.max_speed_mps for t in ups)


def test_no_upshift_onto_a_grade_high_cannot_carry():
    """ranger-6x6 in low6wd asked for more than its top on 20 %: high gains under 0.6 m/s^2."""
    result = speed_run("ranger-6x6", "low6wd", 8.0, 20.0, duration_s=30.0)
    top = PRESETS["ranger-6x6"].gear("low6wd").max_speed_mps
    assert max(float(r["speed_mps"]) for r in result.trace) >= 0.85 * top   # it got there
    assert "suggest_upshift" not in [h for _, h in hints_of(result)]
