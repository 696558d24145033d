"""Property: over random authorizations, limits, curves, grades and friction, against an ideal
speed server and vehicle (speed follows the SPSS ramp 0.3 s late), the commanded acceleration
never leaves the ellipse and the vehicle never passes the end of its authorization."""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from overdrive.dynamics.ellipse import braking_distance_m, ellipse_for, load_axes_mps2
from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import AdvanceAuthorization, MaxSpeed, SteeringRequest, Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingConfig
from tests.servers.driving_harness import DT_S, IdealLoop, outputs

DELAY_S = 0.3          # ideal plant's response delay, below the module's reaction allowance
TICKS = 1500           # 15 s per example
CFG = DrivingConfig()

event = st.tuples(st.integers(0, TICKS - 1), st.sampled_from(["advance", "max_speed", "steer"]),
                  st.sampled_from(["lidar", "radar", "map"]), st.floats(0.0, 1.0))


def stopping_need_m(e, v, k, grade):
    """Distance the ideal loop may still need: pipeline delay at a raised speed, then braking
    at the full ellipse, with 10 % + 0.2 m for the 100 ms updates of the braking rate."""
    lag = DELAY_S + 0.1 + DT_S
    v_hi = v + CFG.accel_mps2 * lag
    return 1.1 * (v_hi * lag + braking_distance_m(e, v_hi, k, grade)) + 0.2


@pytest.mark.parametrize("name", tuple(PRESETS))
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(friction=st.floats(0.3, 1.0), grade_frac=st.floats(-0.8, 0.8),
       events=st.lists(event, max_size=30))
def test_never_leaves_ellipse_never_overruns(name, friction, grade_frac, events):
    p = PRESETS[name]
    grade = grade_frac * p.max_pitch_rad
    e = ellipse_for(p, friction)
    a_axis, b_axis = load_axes_mps2(e, grade)
    g_along = G_MPS2 * math.sin(grade)
    assume(a_axis - abs(g_along) >= 0.8)      # the vehicle can hold and stop on this slope
    loop = IdealLoop(p, friction=friction, pitch_rad=grade, delay_s=DELAY_S, config=CFG)
    by_tick: dict[int, list] = {}
    for tick, kind, source, x in sorted(events):
        by_tick.setdefault(tick, []).append((kind, source, x))
    ends: dict[str, float] = {}
    k_req = 0.0
    for tick in range(TICKS):
        v, odo = loop.speed_mps, loop.odometer_m
        k_worst = max(abs(k_req), abs(loop.curvature_1pm))
        extra = []
        for kind, source, x in by_tick.get(tick, []):
            if kind == "advance":
                distance = 60.0 * x
                end = min([*ends.values(), odo + distance] if source not in ends else
                          [*(v_ for s, v_ in ends.items() if s != source), odo + distance])
                if end - odo < stopping_need_m(e, v, k_worst, grade):
                    continue       # infeasible when issued: not a fair test input
                ends[source] = odo + distance
                extra.append((Topic.ADVANCE, AdvanceAuthorization(source=source,
                                                                  distance_m=distance)))
            elif kind == "max_speed":
                extra.append((Topic.MAX_SPEED, MaxSpeed(source=source, speed_mps=15.0 * x)))
            else:
                k_new = (2.0 * x - 1.0) * p.max_curvature_1pm
                left = min(ends.values(), default=odo) - odo
                if left < stopping_need_m(e, v, max(k_worst, abs(k_new)), grade):
                    continue
                k_req = k_new
                extra.append((Topic.STEERING, SteeringRequest(curvature_1pm=k_new)))
        out = loop.step(extra)
        end = min(ends.values(), default=0.0)
        assert loop.odometer_m <= end + 1e-6, f"overran by {loop.odometer_m - end:.4f} m"
        for spss in outputs(out, Topic.SET_SPEED):
            if spss.state != "run" or (spss.speed_mps == 0.0 and v == 0.0):
                continue
            if spss.speed_mps > v + CFG.accel_band_mps:
                lon = spss.accel_mps2 + g_along
            elif spss.speed_mps < v - CFG.accel_band_mps:
                lon = -spss.accel_mps2 + g_along
            else:
                lon = g_along
            lat = v * v * loop.curvature_1pm
            use = (lon / a_axis) ** 2 + (lat / b_axis) ** 2
            assert use <= 1.0 + 1e-6, f"ellipse use {use:.4f} at v={v:.2f}"
