"""Rollover (seed 003: "Whether we need to work actively to prevent rollover is an important
question. I don't know enough to answer that question."): the lateral acceleration is capped
by the static stability factor, SSF = track / (2 h_cg), derated like the ellipse, so the
ellipse's lateral semi-axis is min(grip, rollover).

Judged from ground truth: the simulated vehicle's lateral acceleration in a curve (its own
v^2 k) never reaches the planning limit g * SSF * (1 - derate), swept around the centre of
gravity height at which rollover starts to bind, on both presets; and the judge's rule
``rollover`` (no margin: g * SSF) flags a vehicle beyond it."""

from __future__ import annotations

import math

import msgspec
import pytest

from overdrive.dynamics.ellipse import DEFAULT_ENVELOPE, ellipse_for, rollover_lat_mps2
from overdrive.dynamics.vehicle_params import G_MPS2, VehicleSpecError, with_overrides
from overdrive.messages import Topic, Truth
from overdrive.observe.judge import Monitor
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS

FRICTION = 0.9            # dry: the preset's grip figures apply in full
CURVATURE_1PM = 0.1       # a 10 m radius, within both presets' steering
DERATE = 1.0 - DEFAULT_ENVELOPE.rollover_derate


def crossover_cg_m(preset: str) -> float:
    """The centre-of-gravity height above which rollover, not grip, bounds the lateral axis."""
    p = PRESETS[preset]
    grip = ellipse_for(p, FRICTION).lat_mps2
    return p.track_width_m * G_MPS2 * DERATE / (2.0 * grip)


def cg_heights_m(preset: str) -> list[float]:
    """Swept around the crossover: grip binds below it, rollover above."""
    h = crossover_cg_m(preset)
    return [round(h * f, 3) for f in (0.9, 0.99, 1.01, 1.1, 1.4)]


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_shipped_presets_are_bounded_by_grip_before_rollover(preset):
    p = PRESETS[preset]
    assert p.cg_height_m < crossover_cg_m(preset)
    assert ellipse_for(p, FRICTION).lat_mps2 < rollover_lat_mps2(p)
    assert rollover_lat_mps2(p) < G_MPS2 * p.static_stability_factor   # derated


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_the_lateral_axis_is_the_lower_of_grip_and_rollover(preset):
    for cg in cg_heights_m(preset):
        p = with_overrides(PRESETS[preset], {"cg_height_m": cg})
        ssf_limit = G_MPS2 * p.track_width_m / (2.0 * cg) * DERATE
        grip = ellipse_for(PRESETS[preset], FRICTION).lat_mps2
        assert ellipse_for(p, FRICTION).lat_mps2 == pytest.approx(min(grip, ssf_limit), rel=1e-12)
        # traction control and low friction shrink grip, never the rollover limit above it
        assert ellipse_for(p, FRICTION, shrink=0.5).lat_mps2 <= ssf_limit + 1e-12


def curve_run(preset: str, cg_height_m: float, seed: int = 1) -> dict:
    p = PRESETS[preset]
    top = p.gear(p.drive_gear).max_speed_mps * 0.9
    spec = {"name": f"rollover-{preset}", "vehicle": {"preset": preset, "cg_height_m": cg_height_m},
            "start": "ready", "seed": seed, "duration_s": 20,
            "world": {"friction": FRICTION},
            "events": [{"at_s": 0.5, "steer": {"curvature_1pm": CURVATURE_1PM}},
                       {"at_s": 1, "advance": {"source": "lidar", "distance_m": 60}},
                       {"at_s": 1, "max_speed": {"source": "map", "speed_mps": round(top, 2)}}]}
    return run_scenario(parse_scenario(spec, "rollover"), None, plot=False,
                        keep_trace=False).summary


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_lateral_acceleration_in_a_curve_stays_under_the_rollover_limit(preset):
    """Swept around the crossover: the peak lateral acceleration of the plant stays under the
    planning limit min(grip, rollover); where rollover binds, grip alone would have let the
    vehicle past the static rollover limit (the case is not one the limit cannot fail)."""
    for cg in cg_heights_m(preset):
        p = with_overrides(PRESETS[preset], {"cg_height_m": cg})
        limit = ellipse_for(p, FRICTION).lat_mps2
        summary = curve_run(preset, cg)
        peak = summary["peaks"]["max_lateral_accel_mps2"]
        assert peak <= limit, (cg, peak, limit)
        assert summary["odometer_m"] > 20.0, "it drove the curve"
        assert not [v for v in summary["violations"] if "rollover" in v], summary["violations"]
        if cg > crossover_cg_m(preset):
            grip_only = ellipse_for(PRESETS[preset], FRICTION).lat_mps2
            top = p.gear(p.drive_gear).max_speed_mps * 0.9
            reachable = min(grip_only, top * top * CURVATURE_1PM)
            assert reachable > limit, "grip alone would have gone beyond the rollover limit"
            assert peak >= 0.8 * limit, (cg, peak, limit)   # it drives near the limit


def test_the_driving_module_uses_the_rollover_limit_not_the_grip():
    """Grip-only planning reaches beyond the static rollover limit where the CG is high: the
    judge flags that as ``rollover``; the stack's run of the same vehicle does not."""
    preset = "escape-hybrid"
    cg = round(crossover_cg_m(preset) * 2.0, 3)
    p = with_overrides(PRESETS[preset], {"cg_height_m": cg})
    grip_only = ellipse_for(PRESETS[preset], FRICTION).lat_mps2
    assert grip_only > G_MPS2 * p.static_stability_factor   # grip alone would tip it
    summary = curve_run(preset, cg)
    assert summary["peaks"]["max_lateral_accel_mps2"] <= rollover_lat_mps2(p)
    assert summary["violations"] == []


# --------------------------------------------------------------------------- the judge's rule

def lateral_truth(lat_mps2: float, roll_rad: float = 0.0, pitch_rad: float = 0.0) -> Truth:
    return Truth(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=5.0, accel_mps2=0.0,
                 lat_accel_mps2=lat_mps2, curvature_1pm=lat_mps2 / 25.0, pitch_rad=pitch_rad,
                 roll_rad=roll_rad, odometer_m=0.0, slip=False, contact=False)


@pytest.mark.parametrize("preset", sorted(PRESETS))
@pytest.mark.parametrize("roll_rad", [0.0, 0.1, -0.1])
@pytest.mark.parametrize("offset", [-0.01, -0.001, 0.001, 0.01])
def test_the_judge_flags_lateral_force_beyond_the_static_limit(preset, roll_rad, offset):
    # a raised CG so that the limit lies inside the plant's grip (otherwise unreachable)
    p = with_overrides(PRESETS[preset], {"cg_height_m": 1.5})
    limit = G_MPS2 * p.static_stability_factor * math.cos(roll_rad)
    for sign in (1.0, -1.0):
        monitor = Monitor(p, FRICTION, 0.01)
        lat = sign * limit * (1.0 + offset) + G_MPS2 * math.sin(roll_rad)
        monitor.observe(Topic.TRUTH, lateral_truth(lat, roll_rad))
        flagged = any("rollover" in v for v in monitor.finish())
        assert flagged == (offset > 0), (sign, offset)


@pytest.mark.parametrize("field", ["track_width_m", "cg_height_m"])
@pytest.mark.parametrize("value", [float("nan"), float("inf"), -1.0, 0.0, 50.0, "1.2"])
def test_rollover_parameters_are_validated(field, value):
    with pytest.raises(VehicleSpecError) as err:
        with_overrides(PRESETS["ranger-6x6"], {field: value})
    assert err.value.field == field


def test_a_track_wider_than_the_vehicle_is_refused():
    p = PRESETS["ranger-6x6"]
    with pytest.raises(VehicleSpecError, match="wider than width_m"):
        with_overrides(p, {"track_width_m": p.width_m + 0.01})
    assert with_overrides(p, {"track_width_m": p.width_m}).track_width_m == p.width_m
    assert msgspec.structs.replace(p).static_stability_factor == pytest.approx(
        p.track_width_m / (2.0 * p.cg_height_m))
