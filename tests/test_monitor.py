"""The independent invariant monitor: each invariant fires when violated and stays quiet otherwise."""

from __future__ import annotations

import pytest

from overdrive.messages import (
    AdvanceAuthorization,
    Notice,
    PedalCommand,
    SetSpeed,
    SteerCommand,
    Topic,
    Truth,
    VehicleStatus,
)
from overdrive.monitor import Monitor
from overdrive.scenario import parse_scenario
from overdrive.sim import run_scenario
from overdrive.vehicle.presets import ESCAPE_HYBRID
from tests.conftest import scenario_dict

DT = 0.01


def truth(odometer_m: float, speed_mps: float, accel: float = 0.0, lat: float = 0.0,
          contact: bool = False) -> Truth:
    return Truth(x_m=odometer_m, y_m=0.0, heading_rad=0.0, speed_mps=speed_mps, accel_mps2=accel,
                 lat_accel_mps2=lat, curvature_1pm=0.0, pitch_rad=0.0, roll_rad=0.0,
                 odometer_m=odometer_m, slip=False, contact=contact)


def status(mode: str = "drive-by-wire", brake_pct: float = 0.0) -> VehicleStatus:
    return VehicleStatus(gear="drive", shifting=False, engine="running", engine_rpm=900.0,
                         start_failed=False, traction_control=False, steer_pct=0.0,
                         throttle_pct=0.0, brake_pct=brake_pct, safety_mode=mode)


@pytest.fixture
def monitor() -> Monitor:
    return Monitor(ESCAPE_HYBRID, 0.8, DT)


def drive(monitor: Monitor, positions: list[float], speed: float = 1.0) -> None:
    for i, x in enumerate(positions):
        monitor.now_s = i * DT
        monitor.observe(Topic.TRUTH, truth(x, speed))
        monitor.tick(monitor.now_s)


def test_authorization_overrun_detected(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 0.0))
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=10.0))
    drive(monitor, [5.0, 9.99, 10.0])
    assert monitor.finish() == []
    drive(monitor, [10.001])
    assert any("authorization[lidar]" in v for v in monitor.finish())


def test_short_authorization_judged_from_shortest_possible_stop(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0))
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="move", distance_m=0.0))
    reaction = 2 * DT + ESCAPE_HYBRID.brake_lag_s
    shortest = 10.0 * reaction + 10.0**2 / (2 * min(ESCAPE_HYBRID.max_brake_decel_mps2, 0.8 * 9.80665))
    drive(monitor, [shortest - 0.01], speed=10.0)
    assert monitor.finish() == []
    drive(monitor, [shortest + 0.01], speed=10.0)
    assert monitor.finish()


def test_reverse_authorization(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 0.0))
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="move", distance_m=2.0, reverse=True))
    drive(monitor, [1.0, 2.0], speed=-1.0)
    assert monitor.finish() == []
    drive(monitor, [2.5], speed=-1.0)
    assert monitor.finish()


def test_throttle_while_braking(monitor: Monitor) -> None:
    monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=5.0, brake_pct=0.0, source="speed"))
    assert monitor.finish() == []
    monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=5.0, brake_pct=1.0, source="speed"))
    assert "throttle_while_braking" in monitor.finish()[0]


@pytest.mark.parametrize(("estop_after_s", "ok"), [(0.20, True), (0.21, True), (0.22, False), (None, False)])
def test_watchdog_deadline(monitor: Monitor, estop_after_s: float | None, ok: bool) -> None:
    monitor.observe(Topic.SET_SPEED, SetSpeed(speed_mps=1, accel_mps2=1, gear="drive", state="run"))
    for tick in range(1, 40):
        now = round(tick * DT, 6)
        monitor.now_s = now
        if estop_after_s is not None and now >= estop_after_s - 1e-9:
            monitor.observe(Topic.PEDALS, PedalCommand(throttle_pct=0, brake_pct=100, source="speed"))
        monitor.tick(now)
    assert (monitor.finish() == []) == ok


def test_commands_from_sources_without_control_must_be_rejected(monitor: Monitor) -> None:
    monitor.observe(Topic.STEER, SteerCommand(steer_pct=5.0, source="intruder"))
    assert monitor.finish()
    other = Monitor(ESCAPE_HYBRID, 0.8, DT)
    other.observe(Topic.STEER, SteerCommand(steer_pct=5.0, source="intruder"))
    other.observe(Topic.NOTICE, Notice(kind="rejected", source="vehicle", code="no_control"))
    assert other.finish() == []


def test_acceleration_outside_ellipse(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-3.0, lat=3.0))
    assert monitor.finish() == []
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-9.0, lat=6.0))
    assert "acceleration_ellipse" in monitor.finish()[0]


def test_estop_disable_needs_full_brake(monitor: Monitor) -> None:
    for i in range(100):
        monitor.now_s = i * DT
        monitor.observe(Topic.VEHICLE_STATUS, status("estop-disable", brake_pct=min(100.0, i * 10.0)))
    assert monitor.finish() == []
    bad = Monitor(ESCAPE_HYBRID, 0.8, DT)
    for i in range(100):
        bad.now_s = i * DT
        bad.observe(Topic.VEHICLE_STATUS, status("estop-disable", brake_pct=40.0))
    assert "estop_precedence" in bad.finish()[0]


def test_open_loop_throttle_with_brake_is_a_violation_exit_1() -> None:
    data = scenario_dict(duration_s=4, events=[{"at_s": 1, "actuators": {"throttle_pct": 10, "brake_pct": 10}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.exit_code == 1
    assert any("throttle_while_braking" in v for v in result.summary["violations"])


def test_contact_is_a_violation() -> None:
    data = scenario_dict(duration_s=10, world={"obstacles": [{"x_m": 12, "y_m": 0}]}, events=[
        {"at_s": 0.1, "engine": "on"}, {"at_s": 1.5, "gear": "drive"},
        {"at_s": 2, "actuators": {"throttle_pct": 40}}])
    result = run_scenario(parse_scenario(data), None)
    assert result.exit_code == 1 and any("contact" in v for v in result.summary["violations"])


def test_estop_button_stops_the_vehicle_with_full_brake() -> None:
    data = scenario_dict(duration_s=10, events=[
        {"at_s": 0.1, "engine": "on"}, {"at_s": 1.5, "gear": "drive"},
        {"at_s": 2, "actuators": {"throttle_pct": 40}}, {"at_s": 5, "estop_button": True}],
        expect=[{"final_speed_below_mps": 0.01}, {"final_safety_mode": "estop-disable"}])
    result = run_scenario(parse_scenario(data), None)
    assert result.summary["violations"] == []
    assert float(result.trace[-1]["brake_pct"]) > 99.0 and result.trace[-1]["engine"] == "off"


def test_pedal_and_powertrain_commands_from_intruders_must_be_rejected() -> None:
    from overdrive.messages import PowertrainCommand

    for msg, topic in ((PedalCommand(throttle_pct=50.0, brake_pct=0.0, source="intruder"), Topic.PEDALS),
                       (PowertrainCommand(gear="drive", engine_on=True, source="intruder"),
                        Topic.POWERTRAIN)):
        monitor = Monitor(ESCAPE_HYBRID, 0.8, DT)
        monitor.observe(topic, msg)
        assert "control" in monitor.finish()[0]
        fine = Monitor(ESCAPE_HYBRID, 0.8, DT)
        fine.observe(topic, msg)
        fine.observe(Topic.NOTICE, Notice(kind="fault", source="speed", code="1"))   # not a rejection
        fine.observe(Topic.NOTICE, Notice(kind="rejected", source="vehicle", code="no_control"))
        assert fine.finish() == []


def test_invalid_authorization_is_not_held_against_the_vehicle(monitor: Monitor) -> None:
    monitor.observe(Topic.TRUTH, truth(0.0, 0.0))
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="bad", distance_m=float("nan")))
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="neg", distance_m=-1.0))
    drive(monitor, [5.0])
    assert monitor.finish() == [] and monitor.authorization_margin_m() is None


def test_world_friction_change_tightens_the_ellipse(monitor: Monitor) -> None:
    from overdrive.vehicle.plant import World
    from overdrive.vehicle.sim_node import WORLD_TOPIC

    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-5.0))
    assert monitor.finish() == []
    monitor.observe(WORLD_TOPIC, World(friction=0.2))
    monitor.observe(Topic.TRUTH, truth(0.0, 10.0, accel=-5.0))
    assert "acceleration_ellipse" in monitor.finish()[0]


def test_stop_margins_recorded_per_stop(monitor: Monitor) -> None:
    drive(monitor, [0.0, 1.0], speed=1.0)
    monitor.observe(Topic.TRUTH, truth(1.0, 0.0))
    assert monitor.stop_margins_m == [], "a stop without any authorization has no margin"
    monitor.observe(Topic.ADVANCE, AdvanceAuthorization(source="a", distance_m=4.0))
    drive(monitor, [2.0, 3.0], speed=1.0)
    monitor.observe(Topic.TRUTH, truth(3.0, 0.0))
    assert monitor.stop_margins_m == [pytest.approx(2.0)]
