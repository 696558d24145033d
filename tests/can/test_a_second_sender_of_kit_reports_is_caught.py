"""A second node sending a kit's report ids is caught by what it cannot hide: the id arrives more
often than the kit sends it, or the speed jumps faster than any vehicle can change it. Swept around
both limits; the kit's own reports, jittered as a loaded machine delivers them, never trip it."""

from __future__ import annotations

import random

import pytest

from overdrive.vehicle.kit_reports import (
    MAX_ACCEL_MPS2,
    RATE_WINDOW_S,
    SPEED_QUANTUM_MPS,
    ReportGuard,
)

PERIOD_S = 1.0 / 30.0
SPEED_ID = 0x400


def test_the_kits_own_reports_jittered_and_bunched_never_trip_the_rate():
    guard = ReportGuard(PERIOD_S)
    rng = random.Random(7)
    t = 0.0
    for i in range(3000):
        t += PERIOD_S + rng.uniform(-0.012, 0.012)
        stamp = t if i % 97 else t + 0.03      # now and then one late, the next on its heels
        assert guard.arrived(SPEED_ID, stamp), (i, guard.conflict)
    assert guard.conflict is None


@pytest.mark.parametrize(("extra_per_period", "caught"), [(0, False), (1, True), (2, True)])
def test_a_second_sender_at_the_kits_rate_or_faster_is_caught(extra_per_period, caught):
    guard = ReportGuard(PERIOD_S)
    for i in range(60):
        t = i * PERIOD_S
        ok = guard.arrived(SPEED_ID, t)
        for k in range(extra_per_period):
            ok = guard.arrived(SPEED_ID, t + (k + 1) * PERIOD_S / (extra_per_period + 1)) and ok
    assert (guard.conflict is not None) is caught
    if caught:
        assert "second sender" in guard.conflict and guard.too_fast > 0


def test_the_rate_counts_each_id_on_its_own():
    guard = ReportGuard(PERIOD_S)
    for i in range(60):
        for frame_id in (0x10, 0x200, 0x204, 0x228, 0x22C, 0x400, 0x40D):
            assert guard.arrived(frame_id, i * PERIOD_S + frame_id * 1e-6)
    assert guard.conflict is None


@pytest.mark.parametrize("dt_s", [PERIOD_S, 0.1, 0.0])
@pytest.mark.parametrize(("margin_mps", "plausible"), [(-0.01, True), (0.01, False)])
def test_a_speed_jump_beyond_the_physics_is_refused_at_its_limit(dt_s, margin_mps, plausible):
    guard = ReportGuard(PERIOD_S)
    assert guard.speed_plausible(5.0, 1.0)
    limit = MAX_ACCEL_MPS2 * max(dt_s, PERIOD_S) + SPEED_QUANTUM_MPS
    for sign in (1.0, -1.0):
        g = ReportGuard(PERIOD_S)
        g.speed_plausible(5.0, 1.0)
        assert g.speed_plausible(5.0 + sign * (limit + margin_mps), 1.0 + dt_s) is plausible
        assert (g.conflict is None) is plausible


def test_a_forged_zero_between_true_speeds_is_refused_and_the_true_ones_taken():
    guard = ReportGuard(PERIOD_S)
    taken = []
    for i in range(30):
        t = i * PERIOD_S
        if guard.speed_plausible(3.0 + 0.05 * i, t):
            taken.append(i)
        guard.speed_plausible(0.0, t + 0.01)      # the forger, between the kit's frames
    assert taken == list(range(30)) and guard.jumps == 30
    assert "not this vehicle's" in guard.conflict


def test_hard_braking_at_the_grip_limit_is_plausible():
    guard = ReportGuard(PERIOD_S)
    v, t = 20.0, 0.0
    while v > 0:
        assert guard.speed_plausible(v, t)
        v, t = max(0.0, v - 9.81 * PERIOD_S), t + PERIOD_S
    assert guard.conflict is None


def test_clear_forgets_a_conflict_and_the_counts_window():
    guard = ReportGuard(PERIOD_S)
    for k in range(20):
        guard.arrived(SPEED_ID, k * 0.001)
    assert guard.conflict is not None
    guard.clear()
    assert guard.conflict is None
    assert guard.arrived(SPEED_ID, RATE_WINDOW_S * 10)


@pytest.mark.parametrize("period_s", [0.0, -1.0, float("nan"), float("inf")])
def test_a_report_period_that_is_not_a_positive_number_is_refused(period_s):
    with pytest.raises(ValueError, match="report period"):
        ReportGuard(period_s)
