"""The acceleration ellipse (overdrive.dynamics.ellipse): closed forms, inverses, properties."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from overdrive.dynamics.ellipse import (
    Braking,
    BrakingCache,
    EnvelopeConfig,
    TractionMonitor,
    braking_distance_m,
    braking_speed_cap_mps,
    ellipse_for,
    lateral_speed_limit_mps,
    load_axes_mps2,
    longitudinal_limits,
    max_safe_speed_mps,
    stopping_distance_m,
)
from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.scenario.vehicles import PRESETS

PRESET_NAMES = tuple(PRESETS)
FRICTIONS = (0.3, 0.8, 0.9)


def numeric_braking_m(e, v, k, grade, roll, n=4000):
    """Midpoint-rule integral of w / b(w) dw, independent of the closed form."""
    a, b = e.lon_mps2 * math.cos(grade) * math.cos(roll), e.lat_mps2 * math.cos(grade) * math.cos(roll)
    g_along, c = G_MPS2 * math.sin(grade), G_MPS2 * math.sin(roll)
    h = v / n
    total = 0.0
    for i in range(n):
        w = (i + 0.5) * h
        s = (w * w * k - c) / b
        decel = a * math.sqrt(max(0.0, 1.0 - s * s)) + g_along
        if abs(s) > 1.0 or decel <= 0.0:
            return math.inf
        total += w / decel * h
    return total


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("friction", FRICTIONS)
def test_ellipse_is_derated_published_figures_scaled_by_friction(name, friction):
    p = PRESETS[name]
    e = ellipse_for(p, friction)
    scale = 0.75 * friction / 0.9
    assert e.lon_mps2 == pytest.approx(26.8224**2 / (2 * p.stopping_distance_60mph_m) * scale)
    assert e.lat_mps2 == pytest.approx(p.skidpad_lat_g * G_MPS2 * scale)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_friction_above_dry_pavement_never_exceeds_published_figures(name):
    p = PRESETS[name]
    assert ellipse_for(p, 1.2) == ellipse_for(p, 0.9)
    assert ellipse_for(p, 0.9).lon_mps2 == pytest.approx(0.75 * p.max_decel_mps2)
    wide = ellipse_for(p, 0.9, EnvelopeConfig(derate=0.0))
    assert wide.lon_mps2 == pytest.approx(p.max_decel_mps2)


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("friction", FRICTIONS)
@pytest.mark.parametrize("speed", [0.5, 3.0, 8.0, 20.0])
def test_flat_straight_stopping_distance_is_v2_over_2a(name, friction, speed):
    p = PRESETS[name]
    e = ellipse_for(p, friction)
    a = p.max_decel_mps2 * 0.75 * friction / 0.9
    assert braking_distance_m(e, speed) == pytest.approx(speed**2 / (2 * a), rel=1e-12)
    assert stopping_distance_m(e, speed, reaction_s=0.4) == pytest.approx(
        0.4 * speed + speed**2 / (2 * a), rel=1e-12)
    assert braking_distance_m(e, -speed) == braking_distance_m(e, speed)   # reversing


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_downhill_longer_uphill_shorter_monotonic_in_grade(name):
    e = ellipse_for(PRESETS[name], 0.8)
    grades = [math.atan(g / 100) for g in (-25, -10, -5, 0, 5, 10, 25)]
    dists = [braking_distance_m(e, 10.0, 0.0, g) for g in grades]
    assert all(d1 > d2 for d1, d2 in itertools.pairwise(dists))
    # closed form on a slope: b = A cos(grade) + g sin(grade)
    grade = math.atan(-0.10)
    b = e.lon_mps2 * math.cos(grade) + G_MPS2 * math.sin(grade)
    assert braking_distance_m(e, 10.0, 0.0, grade) == pytest.approx(100.0 / (2 * b), rel=1e-12)


def test_downhill_steeper_than_friction_cannot_stop():
    e = ellipse_for(PRESETS["ranger-6x6"], 0.2)
    steep = math.atan(0.30)
    assert longitudinal_limits(e, 0.0, 0.0, -steep).decel_mps2 < 0.0
    assert braking_distance_m(e, 1.0, 0.0, -steep) == math.inf
    assert max_safe_speed_mps(e, 100.0, 0.0, -steep) == 0.0


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("k", [0.01, 0.05, -0.05, 0.1])
def test_curve_closed_form_and_longer_than_straight(name, k):
    e = ellipse_for(PRESETS[name], 0.8)
    v = 0.9 * lateral_speed_limit_mps(e, k)
    a, b = e.lon_mps2, e.lat_mps2
    expected = b / (2 * a * abs(k)) * math.asin(v * v * abs(k) / b)
    assert braking_distance_m(e, v, k) == pytest.approx(expected, rel=1e-10)
    assert braking_distance_m(e, v, k) > braking_distance_m(e, v, 0.0)
    assert max_safe_speed_mps(e, 20.0, k, reaction_s=0.5) < max_safe_speed_mps(e, 20.0, 0.0,
                                                                                reaction_s=0.5)


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(PRESET_NAMES), friction=st.floats(0.2, 1.0),
       frac=st.floats(0.01, 0.99), k=st.floats(-0.2, 0.2),
       grade_pct=st.floats(-30, 30), roll=st.floats(-0.1, 0.1))
def test_closed_form_matches_numerical_integral(name, friction, frac, k, grade_pct, roll):
    e = ellipse_for(PRESETS[name], friction)
    grade = math.atan(grade_pct / 100)
    cap = braking_speed_cap_mps(e, k, grade, roll)
    assume(cap > 0.0)
    v = frac * min(cap, 25.0)
    closed = braking_distance_m(e, v, k, grade, roll)
    numeric = numeric_braking_m(e, v, k, grade, roll)
    assume(math.isfinite(numeric) and numeric < 1e4)
    assert closed == pytest.approx(numeric, rel=2e-4)


@settings(max_examples=150, deadline=None)
@given(name=st.sampled_from(PRESET_NAMES), friction=st.floats(0.2, 1.0),
       v=st.floats(0.0, 30.0), k=st.floats(-0.2, 0.2) | st.just(0.0),
       grade_pct=st.floats(-30, 30), roll=st.floats(-0.1, 0.1), reaction=st.floats(0.0, 1.5))
def test_max_safe_speed_inverts_stopping_distance(name, friction, v, k, grade_pct, roll,
                                                  reaction):
    e = ellipse_for(PRESETS[name], friction)
    grade = math.atan(grade_pct / 100)
    d = stopping_distance_m(e, v, k, grade, roll, reaction)
    assume(math.isfinite(d) and d > 1e-6)
    back = max_safe_speed_mps(e, d, k, grade, roll, reaction)
    assert back == pytest.approx(v, rel=1e-7, abs=1e-9)
    # and the other way: the speed found stops within the distance (to 1e-9 m)
    assert stopping_distance_m(e, back, k, grade, roll, reaction) <= d * (1 + 1e-9) + 1e-9


@pytest.mark.parametrize("name", PRESET_NAMES)
@pytest.mark.parametrize("distance", [-1.0, 0.0, math.nan])
def test_no_distance_no_speed(name, distance):
    assert max_safe_speed_mps(ellipse_for(PRESETS[name], 0.8), distance, 0.0, reaction_s=0.5) == 0.0


def test_max_safe_speed_capped_where_the_curve_leaves_the_ellipse():
    e = ellipse_for(PRESETS["escape-hybrid"], 0.8)
    k = 0.1
    cap = braking_speed_cap_mps(e, k)
    assert cap == pytest.approx(math.sqrt(e.lat_mps2 / k))
    assert max_safe_speed_mps(e, 1e6, k) == pytest.approx(cap)
    assert braking_distance_m(e, cap * 1.0001, k) == math.inf


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_lateral_limit_uses_whole_ellipse_on_the_flat(name):
    e = ellipse_for(PRESETS[name], 0.8)
    for k in (0.02, -0.02, 0.15):
        v = lateral_speed_limit_mps(e, k)
        assert v * v * abs(k) == pytest.approx(e.lat_mps2)
    assert lateral_speed_limit_mps(e, 0.0) == math.inf


def test_roll_shifts_the_lateral_limit():
    e = ellipse_for(PRESETS["escape-hybrid"], 0.8)
    bank = 0.05   # right side down: a right turn is banked, a left turn off-camber
    right = lateral_speed_limit_mps(e, 0.05, 0.0, bank)
    left = lateral_speed_limit_mps(e, -0.05, 0.0, bank)
    flat = lateral_speed_limit_mps(e, 0.05)
    assert left < flat < right
    b = e.lat_mps2 * math.cos(bank)
    assert right**2 * 0.05 == pytest.approx(b + G_MPS2 * math.sin(bank))
    # left side down: mirror image
    assert lateral_speed_limit_mps(e, -0.05, 0.0, -bank) == pytest.approx(right)
    assert lateral_speed_limit_mps(e, 0.05, 0.0, -bank) == pytest.approx(left)
    assert braking_speed_cap_mps(e, -0.05, 0.0, -bank) == pytest.approx(
        braking_speed_cap_mps(e, 0.05, 0.0, bank))


def test_grade_takes_ellipse_for_holding_speed_in_a_curve():
    e = ellipse_for(PRESETS["escape-hybrid"], 0.8)
    grade = math.atan(0.15)
    v = lateral_speed_limit_mps(e, 0.05, grade)
    assert v < lateral_speed_limit_mps(e, 0.05)
    a, b = load_axes_mps2(e, grade)
    lat = v * v * 0.05
    hold = G_MPS2 * math.sin(grade)
    assert (lat / b) ** 2 + (hold / a) ** 2 == pytest.approx(1.0)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_longitudinal_limits_share_the_ellipse_and_add_gravity(name):
    e = ellipse_for(PRESETS[name], 0.8)
    flat = longitudinal_limits(e, 5.0, 0.0)
    assert flat.accel_mps2 == pytest.approx(e.lon_mps2)
    assert flat.decel_mps2 == pytest.approx(e.lon_mps2)
    k = 0.5 * e.lat_mps2 / 25.0     # half the lateral axis at 5 m/s
    curve = longitudinal_limits(e, 5.0, k)
    assert curve.decel_mps2 == pytest.approx(e.lon_mps2 * math.sqrt(0.75))
    up = longitudinal_limits(e, 5.0, 0.0, math.atan(0.1))
    a, _ = load_axes_mps2(e, math.atan(0.1))
    assert up.decel_mps2 == pytest.approx(a + G_MPS2 * math.sin(math.atan(0.1)))
    assert up.accel_mps2 == pytest.approx(a - G_MPS2 * math.sin(math.atan(0.1)))
    out = longitudinal_limits(e, 5.0, 2 * e.lat_mps2 / 25.0)
    assert out.accel_mps2 == out.decel_mps2 == 0.0


def test_traction_control_shrinks_for_the_hold_time():
    cfg = EnvelopeConfig(traction_shrink=0.5, traction_hold_s=2.0)
    tc = TractionMonitor(cfg)
    assert tc.shrink(0.0) == 1.0
    tc.update(1.0, True)
    tc.update(1.5, False)
    assert tc.shrink(1.0) == 0.5
    assert tc.shrink(2.99) == 0.5
    assert tc.shrink(3.0) == 1.0
    p = PRESETS["ranger-6x6"]
    assert ellipse_for(p, 0.8, cfg, tc.shrink(2.0)).lon_mps2 == pytest.approx(
        0.5 * ellipse_for(p, 0.8, cfg).lon_mps2)


# --------------------------------------------------------------------------- braking cache

def test_the_braking_cache_gives_what_braking_gives_and_rebuilds_for_a_new_ellipse() -> None:
    params = PRESETS["escape-hybrid"]
    one, two = ellipse_for(params, 0.8), ellipse_for(params, 0.5)
    cache = BrakingCache(size=3)
    first = cache.get(one, 0.01, 0.02, 0.0)
    assert cache.get(one, 0.01, 0.02, 0.0) is first, "the same curve and slope: built once"
    assert cache.get(one, 0.01, 0.02, -0.0) is first, "+0.0 and -0.0 share an entry"
    for k, grade in ((0.0, 0.0), (0.01, 0.02), (-0.02, 0.1)):
        got = cache.get(one, k, grade, 0.0)
        ref = Braking(one, k, grade, 0.0)
        assert got.stopping_distance_m(10.0, 0.3) == ref.stopping_distance_m(10.0, 0.3)
        assert got.max_safe_speed_mps(30.0, 0.7) == ref.max_safe_speed_mps(30.0, 0.7)
    other = cache.get(two, 0.01, 0.02, 0.0)
    assert other is not first, "another ellipse: nothing kept from the first"
    assert other.stopping_distance_m(10.0, 0.3) > first.stopping_distance_m(10.0, 0.3)
    for i in range(5):                                   # bounded: at most ``size`` kept
        cache.get(two, 0.01 * i, 0.0, 0.0)
    assert len(cache._by_key) <= 3
