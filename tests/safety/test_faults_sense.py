"""Issue 16, case 1 on whole runs: frozen motion sensing (GPS/INS, wheel speed, IMU) swept over
both presets, grades, speeds and fault times, judged from the summary's violations (ground
truth) and its events; and healthy vehicles (noise, ice, grades, curves) that must not trip."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.messages import GpsIns, Imu, Topic, WheelSpeed
from overdrive.run.sim import run_scenario
from overdrive.safety.plausibility import PlausibilityFault
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.move import MoveServer
from tests.conftest import PRESET_NAMES, reachable_mps

pytestmark = pytest.mark.variants

SENSE_CODES = {str(int(c)) for c in PlausibilityFault}


def run(vehicle: str = "escape-hybrid", duration_s: float = 30.0, world: dict | None = None,
        events: list[dict] = ()) -> Any:
    events = [{**e, "move": {**e["move"], "maxspeed_mps": reachable_mps(
        vehicle, e["move"]["maxspeed_mps"])}} if "move" in e else e for e in events]
    data = {"name": "sense", "vehicle": vehicle, "start": "ready", "duration_s": duration_s,
            "world": world or {}, "events": events}
    return run_scenario(parse_scenario(data), None, keep_trace=False, plot=False,
                        record_mcap=False)


def move(distance_m: float, speed_mps: float, curvature_1pm: float = 0.0) -> dict:
    return {"at_s": 0.5, "move": {"distance_m": distance_m, "maxspeed_mps": speed_mps,
                                  "curvature_1pm": curvature_1pm}}


def freeze(name: str, at_s: float, for_s: float = 40.0) -> dict:
    return {"at_s": at_s, "sensor": {"name": name, "fault": "freeze", "for_s": for_s}}


def faults(result: Any, source: str | None = None) -> set[str]:
    return {e["code"] for e in result.summary["events"]
            if e["kind"] == "fault" and (source is None or e["source"] == source)}


def moved(result: Any) -> bool:
    return result.summary["odometer_m"] > 1.0


# --------------------------------------------------------------------------- frozen at standstill

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade", [-10, 0, 10])
@pytest.mark.parametrize("speed_mps", [1, 5, 12])
def test_gps_frozen_at_standstill_during_a_move_ends_at_its_end(preset: str, grade: float,
                                                                speed_mps: float) -> None:
    result = run(preset, duration_s=15 + 30 / speed_mps, world={"grade_percent": grade},
                 events=[freeze("gps", 0.2), move(30, speed_mps)])
    assert result.summary["violations"] == []
    assert abs(result.summary["final"]["speed_mps"]) < 0.05
    if moved(result):
        assert str(int(PlausibilityFault.GPS_FROZEN)) in faults(result, "speed")
        assert result.summary["odometer_m"] <= 30.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("name", ["wheel_speed", "imu"])
def test_other_sources_frozen_at_standstill_during_a_move(preset: str, name: str) -> None:
    result = run(preset, events=[freeze(name, 0.2), move(30, 5)])
    assert result.summary["violations"] == []
    assert abs(result.summary["final"]["speed_mps"]) < 0.05


# --------------------------------------------------------------------------- frozen at cruise

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("name", ["gps", "wheel_speed", "imu"])
@pytest.mark.parametrize("at_s", [3.0, 6.0])
@pytest.mark.parametrize("grade", [-10, 0, 10])
def test_one_source_frozen_at_cruise(preset: str, name: str, at_s: float, grade: float) -> None:
    result = run(preset, duration_s=40, world={"grade_percent": grade},
                 events=[move(60, 8), freeze(name, at_s)])
    assert result.summary["violations"] == []
    assert abs(result.summary["final"]["speed_mps"]) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("speed_mps", [1, 4, 8])
@pytest.mark.parametrize("at_s", [0.2, 3.0, 6.0])
def test_both_speeds_frozen_stop_under_the_speed_servers_emergency_braking(
        preset: str, speed_mps: float, at_s: float) -> None:
    """GPS/INS and wheel speed frozen together (two faults): the IMU sees the speed change, no
    trusted speed is left, the speed server's e-stop stops the vehicle and it stays stopped."""
    result = run(preset, duration_s=15 + 60 / speed_mps,
                 events=[move(60, speed_mps), freeze("gps", at_s, 100.0),
                         freeze("wheel_speed", at_s, 100.0)])
    assert result.summary["violations"] == []
    assert abs(result.summary["final"]["speed_mps"]) < 0.05
    if moved(result):
        assert str(int(PlausibilityFault.NO_TRUSTED_SPEED)) in faults(result, "speed")
        assert any(e["kind"] == "estop" and e["source"] == "speed"
                   for e in result.summary["events"])


# --------------------------------------------------------------------------- healthy vehicles

HEALTHY = [
    pytest.param({"grade_percent": -15}, [move(40, 8)], id="downhill-15"),
    pytest.param({"grade_percent": 15}, [move(40, 8)], id="uphill-15"),
    pytest.param({"friction": 0.2}, [move(40, 6)], id="ice"),
    pytest.param({"friction": 0.15, "grade_percent": 8}, [move(30, 4)], id="ice-uphill-spin"),
    pytest.param({}, [move(40, 6, 0.05)], id="curve"),
    pytest.param({}, [move(60, 12)], id="fast"),
    pytest.param({}, [move(40, 8), {"at_s": 3, "sensor": {"name": "gps", "fault": "noise",
                                                          "sigma": 0.5, "for_s": 5}}],
                 id="gps-noise"),
    pytest.param({}, [move(40, 8), {"at_s": 3, "sensor": {"name": "wheel_speed", "fault": "noise",
                                                          "sigma": 0.5, "for_s": 5}}],
                 id="wheel-noise"),
    pytest.param({}, [move(40, 8), {"at_s": 3, "sensor": {"name": "imu", "fault": "noise",
                                                          "sigma": 1.0, "for_s": 5}}],
                 id="imu-noise"),
    pytest.param({}, [move(40, 8), {"at_s": 3, "drop": {"channel": "gps", "for_s": 0.4}}],
                 id="gps-channel-drop"),
    pytest.param({}, [move(10, 3), {"at_s": 12, "reverse": {"distance_m": 8, "maxspeed_mps": 2,
                                                            "curvature_1pm": 0}}], id="reverse"),
]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("world", "events"), HEALTHY)
def test_healthy_vehicle_raises_no_plausibility_fault(preset: str, world: dict,
                                                      events: list[dict]) -> None:
    result = run(preset, duration_s=30, world=world, events=events)
    assert not faults(result) & SENSE_CODES, result.summary["events"]
    assert result.summary["violations"] == []


# --------------------------------------------------------------------------- signed progress

def _sensors(speed: float, odo: float, params: Any) -> list:
    from overdrive.messages import SpeedState, VehicleStatus
    return [
        (Topic.VEHICLE_STATUS, VehicleStatus(
            gear=params.drive_gear, shifting=False, engine="running", engine_rpm=1000.0,
            start_failed=False, traction_control=False, steer_pct=0.0, throttle_pct=0.0,
            brake_pct=0.0, safety_mode="drive-by-wire")),
        (Topic.GPS_INS, GpsIns(x_m=odo, y_m=0.0, heading_rad=0.0, speed_mps=speed, pitch_rad=0.0,
                               roll_rad=0.0, odometer_m=odo)),
        (Topic.WHEEL_SPEED, WheelSpeed(speed_mps=speed)),
        (Topic.IMU, Imu(accel_x_mps2=0.0, accel_y_mps2=0.0, accel_z_mps2=9.81, yaw_rate_rps=0.0)),
        (Topic.SPEED_STATE, SpeedState(speed_mps=speed, accel_mps2=0.0, gear=params.drive_gear,
                                       state="run")),
    ]


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_move_server_counts_a_rollback_back_not_as_progress(preset: str) -> None:
    """Forward MOVE of 20 m: 4 m forward, then 3 m backwards (the GPS/INS odometer, a path
    length, grows by 7 m): the move server reports 19 m left, not 13 m."""
    from overdrive.messages import MoveCommand

    params = PRESETS[preset]
    node = MoveServer(params)
    t, odo = 0.0, 0.0
    node.step(t, [*_sensors(0.0, 0.0, params), (Topic.MOVE_COMMAND, MoveCommand(
        kind="move", command_id=1, distance_m=20.0, maxspeed_mps=4.0))])
    for v, seconds in ((2.0, 2.0), (-1.5, 2.0)):
        for _ in range(round(seconds / 0.01)):
            t = round(t + 0.01, 9)
            odo += abs(v) * 0.01
            node.step(t, _sensors(v, odo, params))
    assert odo == pytest.approx(7.0)
    assert node.remaining_m == pytest.approx(19.0, abs=0.05)
