"""Plant physics against closed-form answers, for every preset."""

from __future__ import annotations

import math
import random

import msgspec
import pytest

from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.vehicle.plant import Plant, World

DT_S = 0.01


def ideal(params: VehicleParams) -> VehicleParams:
    """No drag, no rolling resistance, no engine braking, instant brakes: the closed-form
    braking assumptions."""
    gears = tuple(msgspec.structs.replace(g, engine_brake_decel_mps2=0.0) for g in params.gears)
    return msgspec.structs.replace(params, rolling_resistance=0.0, drag_area_m2=0.0,
                                   brake_lag_s=1e-6, gears=gears)


def moving_plant(params: VehicleParams, speed_mps: float, world: World | None = None) -> Plant:
    plant = Plant(params, world or World(friction=1.0), random.Random(0), engine_running=True,
                  gear=params.drive_gear)
    plant.speed_mps = speed_mps
    return plant


def brake_to_stop(plant: Plant, brake_pct: float, limit_s: float = 60.0) -> float:
    x0, t = plant.odometer_m, 0.0
    while plant.speed_mps > 0.0 and t < limit_s:
        plant.step(DT_S, 0.0, brake_pct, 0.0, plant.gear, True)
        t += DT_S
    return plant.odometer_m - x0


def test_braking_at_0_8_g_stops_in_v2_over_2a(preset: VehicleParams) -> None:
    params = ideal(preset)
    decel = 0.8 * G_MPS2
    if decel > params.max_brake_decel_mps2:
        params = msgspec.structs.replace(params, max_brake_decel_mps2=decel / 0.9)
    plant = moving_plant(params, 20.0)
    distance = brake_to_stop(plant, 100.0 * decel / params.max_brake_decel_mps2)
    expected = 20.0**2 / (2.0 * decel)
    assert distance == pytest.approx(expected, rel=0.02)
    assert plant.speed_mps == 0.0


@pytest.mark.parametrize("grade_percent", [-10.0, 10.0])
def test_grade_changes_stopping_distance(preset: VehicleParams, grade_percent: float) -> None:
    flat = brake_to_stop(moving_plant(preset, 15.0), 40.0)
    sloped = brake_to_stop(moving_plant(preset, 15.0, World(
        grade_segments=((-1e9, grade_percent),), friction=1.0)), 40.0)
    if grade_percent < 0:
        assert sloped > flat * 1.05, "downhill must stop measurably longer"
    else:
        assert sloped < flat * 0.95, "uphill must stop measurably shorter"


def test_downhill_braking_matches_gravity_term(preset: VehicleParams) -> None:
    params = ideal(preset)
    grade = -10.0
    plant = moving_plant(params, 15.0, World(grade_segments=((-1e9, grade),), friction=1.0))
    brake_pct = 40.0
    distance = brake_to_stop(plant, brake_pct)
    pitch = math.atan(grade / 100.0)
    decel = brake_pct / 100.0 * params.max_brake_decel_mps2 + G_MPS2 * math.sin(pitch)
    assert distance == pytest.approx(15.0**2 / (2.0 * decel), rel=0.02)


def test_throttle_beyond_friction_slips_and_signals_traction_control(preset: VehicleParams) -> None:
    plant = Plant(preset, World(friction=0.05), random.Random(0), engine_running=True,
                  gear=preset.low_gear)
    plant.step(DT_S, 0.0, 0.0, 0.0, plant.gear, True)
    slipped = False
    for _ in range(100):
        plant.step(DT_S, 100.0, 0.0, 0.0, plant.gear, True)
        slipped |= plant.slip
    assert slipped
    assert plant.wheel_speed_mps > plant.speed_mps + 0.1, "spinning wheels outrun the ground"
    assert plant.accel_mps2 <= 0.05 * G_MPS2 + 1e-6, "traction limits the acceleration"


def test_no_slip_within_friction(preset: VehicleParams) -> None:
    plant = moving_plant(preset, 5.0, World(friction=0.9))
    for _ in range(200):
        plant.step(DT_S, 20.0, 0.0, 0.0, plant.gear, True)
        assert not plant.slip


@pytest.mark.parametrize("steer_pct", [-20.0, 10.0, 25.0])
def test_steady_steering_lateral_acceleration_is_v2_k(preset: VehicleParams, steer_pct: float) -> None:
    params = msgspec.structs.replace(preset, rolling_resistance=0.0, drag_area_m2=0.0)
    plant = moving_plant(params, 6.0, World(friction=1.0))
    for _ in range(500):  # let the steering actuator settle; coast at (nearly) constant speed
        plant.step(DT_S, 0.0, 0.0, steer_pct, plant.gear, True)
    k = math.tan(steer_pct / 100.0 * params.max_steer_rad) / params.wheelbase_m
    assert plant.curvature_1pm == pytest.approx(k, rel=1e-3)
    assert plant.lat_accel_mps2 == pytest.approx(plant.speed_mps**2 * k, rel=1e-6)
    heading_before = plant.heading_rad
    plant.step(DT_S, 0.0, 0.0, steer_pct, plant.gear, True)
    turned = math.remainder(plant.heading_rad - heading_before, math.tau)
    assert math.copysign(1.0, turned) == -math.copysign(1.0, steer_pct), "right steer lowers heading"


def test_lateral_acceleration_capped_by_friction(preset: VehicleParams) -> None:
    plant = moving_plant(preset, 15.0, World(friction=0.3))
    for _ in range(300):
        plant.step(DT_S, 0.0, 0.0, 100.0, plant.gear, True)
        assert abs(plant.lat_accel_mps2) <= 0.3 * G_MPS2 * (1 + 1e-9)
    assert plant.slip


def test_steering_actuator_is_rate_limited(preset: VehicleParams) -> None:
    plant = moving_plant(preset, 0.0)
    plant.step(0.1, 0.0, 0.0, 100.0, plant.gear, True)
    assert plant.road_wheel_rad <= preset.steer_rate_rps * 0.1 + 1e-12


def test_parked_vehicle_holds_on_a_grade(preset: VehicleParams) -> None:
    plant = Plant(preset, World(grade_segments=((-1e9, 20.0),)), random.Random(0))
    for _ in range(300):
        plant.step(DT_S, 0.0, 0.0, 0.0, preset.park_gear, False, park_brake=True)
    assert plant.speed_mps == 0.0 and plant.x_m == 0.0


def test_released_vehicle_rolls_downhill(preset: VehicleParams) -> None:
    plant = Plant(preset, World(grade_segments=((-1e9, 20.0),)), random.Random(0),
                  engine_running=True, gear="neutral")
    for _ in range(300):
        plant.step(DT_S, 0.0, 0.0, 0.0, "neutral", True)
    assert plant.speed_mps < -0.5


def test_engine_crank_can_fail_then_start(preset: VehicleParams) -> None:
    params = msgspec.structs.replace(preset, start_failures=1)
    plant = Plant(params, World(), random.Random(0))
    steps = round(params.crank_time_s / DT_S) + 2
    for _ in range(steps):
        plant.step(DT_S, 0.0, 100.0, 0.0, params.park_gear, True, park_brake=True)
    assert plant.engine == "off" and plant.start_failed
    plant.step(DT_S, 0.0, 100.0, 0.0, params.park_gear, False, park_brake=True)
    for _ in range(steps):
        plant.step(DT_S, 0.0, 100.0, 0.0, params.park_gear, True, park_brake=True)
    assert plant.engine == "running" and not plant.start_failed


def test_gear_shift_takes_time_and_no_drive_meanwhile(preset: VehicleParams) -> None:
    plant = Plant(preset, World(), random.Random(0), engine_running=True, gear="neutral")
    plant.step(DT_S, 50.0, 0.0, 0.0, preset.drive_gear, True)
    assert plant.shift_target == preset.drive_gear and plant.gear == "neutral"
    assert plant.speed_mps == 0.0
    for _ in range(round(preset.shift_time_s / DT_S) + 1):
        plant.step(DT_S, 50.0, 0.0, 0.0, preset.drive_gear, True)
    assert plant.gear == preset.drive_gear


def test_ranger_refuses_to_shift_while_moving() -> None:
    from overdrive.scenario.vehicles import PRESETS

    plant = moving_plant(PRESETS["ranger-6x6"], 3.0)
    plant.step(DT_S, 0.0, 0.0, 0.0, "low", True)
    assert plant.shift_refused and plant.gear == PRESETS["ranger-6x6"].drive_gear


def test_gear_top_speed_caps_speed() -> None:
    from overdrive.scenario.vehicles import PRESETS

    plant = moving_plant(PRESETS["ranger-6x6"], 0.0, World(friction=1.0))
    plant.gear = "low6wd"
    for _ in range(6000):
        plant.step(DT_S, 100.0, 0.0, 0.0, "low6wd", True)
    assert plant.speed_mps <= PRESETS["ranger-6x6"].gear("low6wd").max_speed_mps


def test_radar_sees_obstacle_ahead_not_behind(preset: VehicleParams) -> None:
    plant = moving_plant(preset, 0.0, World(obstacles=((30.0, 0.0), (-10.0, 0.0))))
    target, range_m, _ = plant.radar()
    front = preset.length_m - preset.rear_overhang_m
    assert target and range_m == pytest.approx(30.0 - front)
    plant.world = World(obstacles=((30.0, 10.0),))   # outside the cone
    assert not plant.radar()[0]


def test_contact_when_obstacle_inside_footprint(preset: VehicleParams) -> None:
    front = preset.length_m - preset.rear_overhang_m
    plant = moving_plant(preset, 0.0, World(obstacles=((front - 0.01, 0.0),)))
    assert plant.contact()
    plant.world = World(obstacles=((front + 0.01, 0.0),))
    assert not plant.contact()


@pytest.mark.parametrize("friction", [0.1, 0.25, 0.5, 0.8])
@pytest.mark.parametrize("brake_pct", [20.0, 60.0, 100.0])
@pytest.mark.parametrize("steer_pct", [-60.0, 30.0, 80.0])
def test_combined_slip_saturates_along_the_demand(preset: VehicleParams, friction: float,
                                                  brake_pct: float, steer_pct: float) -> None:
    """Braking in a curve beyond grip (issue 30): the tyre force lies on the friction ellipse
    (X = mu N, Y = N skid-pad mu / 0.9) in the direction of the demand (brush model at full
    sliding), so braking still slows the vehicle; inside the ellipse nothing is scaled."""
    params = ideal(preset)
    speed = 12.0
    plant = moving_plant(params, speed, World(friction=friction))
    plant.brake = brake_pct / 100.0
    road_wheel = steer_pct / 100.0 * params.max_steer_rad
    plant.road_wheel_rad = plant._steer_rate_limited_rad = road_wheel
    geom_k = math.tan(road_wheel) / params.wheelbase_m
    dt = 1e-4
    plant.step(dt, 0.0, brake_pct, steer_pct, plant.gear, True)
    lon_demand = brake_pct / 100.0 * params.max_brake_decel_mps2       # per unit mass
    lat_demand = speed * speed * geom_k
    x_axis = friction * G_MPS2
    y_axis = params.skidpad_lat_g * G_MPS2 * min(friction / 0.9, 1.0)
    usage = math.hypot(lon_demand / x_axis, lat_demand / y_axis)
    scale = min(1.0, 1.0 / usage)
    assert plant.curvature_1pm == pytest.approx(geom_k * scale, rel=1e-9)
    assert -plant.accel_mps2 == pytest.approx(lon_demand * scale, rel=1e-3)
    assert plant.slip == (usage > 1.0)
    if usage > 1.0:
        got = math.hypot(-plant.accel_mps2 / x_axis, speed * speed * plant.curvature_1pm / y_axis)
        assert got == pytest.approx(1.0, rel=1e-3), "on the ellipse, not inside nor beyond"
