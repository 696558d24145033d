"""The driving module's rule for acting on gear hints (servers.gear_hints): change at once only
when stopping, shifting and restarting reaches the end of the authorization sooner."""

from __future__ import annotations

import math

import msgspec
import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingConfig
from overdrive.servers.gear_hints import (
    GearHintConfig,
    GearHints,
    change_time_s,
    time_to_cover_s,
    worth_changing_now,
)
from tests.conftest import PRESET_NAMES

CFG = DrivingConfig()
ACCEL = CFG.accel_mps2          # comfort acceleration, also the stop's assumed deceleration
EPS = 1e-3


def hints(preset: str) -> GearHints:
    return GearHints(PRESETS[preset], gear_speed_fraction=CFG.gear_speed_fraction,
                     accel_mps2=ACCEL)


def cap(preset: str, gear: str) -> float:
    return PRESETS[preset].gear(gear).max_speed_mps * CFG.gear_speed_fraction


# --------------------------------------------------------------------------- pure timing

@pytest.mark.parametrize(("d", "v", "a", "top", "expected"), [
    (10.0, 2.0, 0.0, 5.0, 5.0),                       # cruising
    (0.0, 0.0, 0.0, 5.0, 0.0),
    (4.0, 0.0, 2.0, 10.0, 2.0),                       # d = a t^2 / 2
    (20.0, 0.0, 2.0, 4.0, 2.0 + 16.0 / 4.0),          # ramp 4 m in 2 s, then 16 m at 4 m/s
    (1.5, 2.0, -1.0, 5.0, 1.0),                       # coasts in: 2 m/s to 1 m/s over 1.5 m
    (2.002, 2.0, -1.0, 5.0, math.inf),                # stops 2 mm short: never there
    (5.0, 0.0, 0.0, 5.0, math.inf),                   # stalled
])
def test_time_to_cover(d, v, a, top, expected):
    assert time_to_cover_s(d, v, a, top) == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_gear_change_costs_the_shift_the_runwait_and_the_ramps(preset):
    p = PRESETS[preset]
    hint_cfg = GearHintConfig()
    assert hint_cfg.runwait_s == 5.0                                  # seed 001
    fixed = p.shift_time_s + hint_cfg.runwait_s + hint_cfg.sequencing_s
    assert change_time_s(p, 0.0, 0.0, ACCEL, ACCEL, 4.0, hint_cfg) == pytest.approx(fixed)
    # from 3 m/s: 2 s of braking over 3 m, then 30 m from rest up to 4 m/s at 1.5 m/s^2
    expected = 2.0 + fixed + 4.0 / 1.5 + (30.0 - 16.0 / 3.0) / 4.0
    assert change_time_s(p, 33.0, 3.0, ACCEL, ACCEL, 4.0, hint_cfg) == pytest.approx(expected)


def test_never_worth_without_a_finite_authorization():
    for remaining in (math.nan, 0.0, -1.0, math.inf):
        assert not worth_changing_now(remaining, math.inf, 1.0)
    assert worth_changing_now(1.0, math.inf, 1e9)
    assert not worth_changing_now(1.0, 5.0, 5.0)


# --------------------------------------------------------------------------- the rule, swept

LIMIT_MPS = {"ranger-6x6": 8.0, "escape-hybrid": 30.0}   # above each low gear's cap


def upshift_break_even_m(preset: str) -> float:
    """Remaining distance beyond which an upshift at the low gear's cap pays (``LIMIT_MPS``
    allowed, flat): ``d / v_low = stop + fixed + ramp to the limit + rest / limit``, the plant's
    physics restated."""
    p = PRESETS[preset]
    hint_cfg = GearHintConfig()
    v_low = cap(preset, p.low_gear)
    top = min(LIMIT_MPS[preset], cap(preset, p.drive_gear))
    drive = p.gear(p.drive_gear)
    v_mid = 0.5 * top
    force = min(drive.max_force_n, p.max_power_w / max(v_mid, 0.5))
    gain = ((force - 0.5 * 1.225 * p.drag_area_m2 * v_mid ** 2) / p.mass_kg
            - p.rolling_resistance * G_MPS2)
    a = min(ACCEL, gain)
    stop_s, stop_m = v_low / ACCEL, v_low ** 2 / (2.0 * ACCEL)
    ramp_s, ramp_m = top / a, top ** 2 / (2.0 * a)
    fixed = stop_s + p.shift_time_s + hint_cfg.runwait_s + hint_cfg.sequencing_s + ramp_s
    # d / v_low = fixed + (d - stop_m - ramp_m) / top
    return (fixed - (stop_m + ramp_m) / top) / (1.0 / v_low - 1.0 / top)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("share", "now"), [(0.5, False), (0.98, False), (1.02, True), (2.0, True)])
def test_an_upshift_stops_the_move_only_when_the_rest_is_long_enough(preset, share, now):
    p = PRESETS[preset]
    d_star = upshift_break_even_m(preset)
    h = hints(preset)
    h.prefer_low = True
    v = cap(preset, p.low_gear)
    h.update("suggest_upshift", "run", p.low_gear, v, 0.0, share * d_star, LIMIT_MPS[preset],
             0.0, v)
    assert h.prefer_low is False                       # the hint lifts the preference either way
    assert h.now_gear == (p.drive_gear if now else None)


def test_break_even_figures():
    """The figures docs/driving-module.md quotes."""
    assert upshift_break_even_m("ranger-6x6") == pytest.approx(94.3, abs=0.5)
    assert upshift_break_even_m("escape-hybrid") == pytest.approx(1098.0, abs=5.0)   # 18 -> 30 m/s


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("remaining_m", [0.2, 1.0, 10.0, 100.0, 1000.0])
def test_a_stall_downshifts_at_once_whatever_is_left(preset, remaining_m):
    p = PRESETS[preset]
    h = hints(preset)
    h.update("suggest_downshift", "run", p.drive_gear, 0.0, 0.0, remaining_m, 5.0, 0.1, 5.0)
    assert h.prefer_low and h.now_gear == p.low_gear


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_losing_speed_at_full_throttle_downshifts_unless_the_end_comes_first(preset):
    p = PRESETS[preset]
    v, a = 2.0, -0.2                                  # stalls after v^2 / 2|a| = 10 m
    for remaining_m, now in ((9.5, False), (10.5, True), (40.0, True)):
        h = hints(preset)
        h.update("suggest_downshift", "run", p.drive_gear, v, a, remaining_m, 5.0, 0.1, 5.0)
        assert h.prefer_low
        assert (h.now_gear == p.low_gear) is now, remaining_m


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_no_stop_while_the_module_itself_slows_the_vehicle(preset):
    """Braking for the end of a move is not lugging, even under a hint still held."""
    p = PRESETS[preset]
    h = hints(preset)
    h.update("suggest_downshift", "run", p.drive_gear, 2.0, -0.7, 2.9, 5.0, 0.1, 1.5)
    assert h.prefer_low and h.now_gear is None


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("goal_mps", "speed_mps", "now"), [
    (2.5, 2.0 - EPS, True), (2.5, 2.0 + EPS, False),      # the goal leads by 0.5 m/s ...
    (0.3, 0.15 - EPS, True), (0.3, 0.15 + EPS, False)])   # ... or half a slower goal
def test_a_downshift_stops_the_move_only_while_the_goal_still_leads(preset, goal_mps, speed_mps,
                                                                    now):
    p = PRESETS[preset]
    h = hints(preset)
    h.update("suggest_downshift", "run", p.drive_gear, speed_mps, -1.0, 40.0, 5.0, 0.1, goal_mps)
    assert h.prefer_low
    assert (h.now_gear == p.low_gear) is now


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("goal_below_mps", "considered"), [(0.3 - EPS, True), (0.3 + EPS, False)])
def test_an_upshift_stops_the_move_only_while_the_goal_is_near_the_speed(preset, goal_below_mps,
                                                                         considered):
    p = PRESETS[preset]
    h = hints(preset)
    v = cap(preset, p.low_gear)
    h.update("suggest_upshift", "run", p.low_gear, v, 0.0, 1e5, LIMIT_MPS[preset], 0.0,
             v - goal_below_mps)
    assert (h.now_gear == p.drive_gear) is considered


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("limit_over_cap_mps", "lifted", "now"), [
    (-1.0, False, False), (0.0, False, False), (EPS, True, False), (2.0, True, True)])
def test_an_upshift_is_ignored_when_the_limit_gains_nothing(preset, limit_over_cap_mps, lifted,
                                                            now):
    p = PRESETS[preset]
    h = hints(preset)
    h.prefer_low = True
    v = cap(preset, p.low_gear)
    h.update("suggest_upshift", "run", p.low_gear, v, 0.0, 1e5, v + limit_over_cap_mps, 0.0, v)
    assert h.prefer_low is not lifted
    assert (h.now_gear == p.drive_gear) is now


def test_a_slow_climb_that_low_gear_barely_improves_is_finished_in_drive():
    """escape-hybrid towing (3,400 kg) on 14 %: drive gains 0.1 m/s^2, low only 0.3 more; the
    stop and the 5 s runwait would lose more than low gains over 46 m."""
    heavy = GearHints(msgspec.structs.replace(PRESETS["escape-hybrid"], mass_kg=3400.0),
                      gear_speed_fraction=CFG.gear_speed_fraction, accel_mps2=ACCEL)
    heavy.update("suggest_downshift", "run", "drive", 2.3, 0.1, 46.0, 5.0,
                 math.sin(math.atan(0.14)), 5.0)
    assert heavy.prefer_low and heavy.now_gear is None


def test_no_change_into_a_gear_that_cannot_climb_either():
    h = hints("ranger-6x6")   # sin 0.65 (86 % grade): beyond low6wd's 6,500 N at 1,050 kg
    h.update("suggest_downshift", "run", "high", 0.0, 0.0, 50.0, 5.0, 0.65, 5.0)
    assert h.now_gear is None


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_hints_count_only_in_run_in_a_forward_gear(preset):
    p = PRESETS[preset]
    for state, gear in (("idle", p.drive_gear), ("runwait", p.drive_gear),
                        ("run", p.reverse_gear)):
        h = hints(preset)
        h.update("suggest_downshift", state, gear, 0.0, 0.0, 50.0, 5.0, 0.1, 5.0)
        assert not h.prefer_low and h.now_gear is None
    h = hints(preset)
    h.update("suggest_downshift", "run", p.low_gear, 0.0, 0.0, 50.0, 5.0, 0.1, 5.0)
    assert not h.prefer_low                       # already in the low gear
    h.update("suggest_upshift", "run", p.drive_gear, 5.0, 0.0, 50.0, 5.0, 0.0, 5.0)
    assert h.now_gear is None                     # already in the drive gear
