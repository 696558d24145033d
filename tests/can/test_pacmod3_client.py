"""The PACMod 3 client (sans-IO) against a kit double, in process: the engage sequence judged
from the frames the kit took, overrides and timeouts latched, re-engage only by the operator,
report silence, garbage, steering through the ratio, gears, dead reckoning, a lost stack and
bring-up caps, each judged from the kit's own state."""

from __future__ import annotations

import itertools
import math

import pytest

from overdrive.dynamics.steering_ratio import road_wheel_rad
from overdrive.kits.frames import CanFrame
from overdrive.kits.pacmod3 import (
    AccelCmd,
    BrakeCmd,
    Gear,
    GlobalRpt,
    ShiftCmd,
    SteeringCmd,
    VehicleSpeedRpt,
    YawRateRpt,
)
from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.pacmod3_client import (
    BRING_UP_ACCEL_RATIO_MAX,
    BRING_UP_SPEED_MPS,
    BRING_UP_STEERING_RATE_RADPS,
    REPORT_TIMEOUT_S,
    Pacmod3Client,
    Pacmod3ClientConfig,
)
from overdrive.vehicle.pacmod3_engage import DISABLE_FRAMES, ENGAGE_BRAKE_RATIO
from tests.can.client_loop import CONSTANT, VARIABLE, Loop, vehicle

THROTTLE = PedalCommand(throttle_pct=40.0, brake_pct=0.0, source="speed")
BRAKE = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
SYSTEM_CMDS = (AccelCmd, BrakeCmd, SteeringCmd, ShiftCmd)


def kit_commands(loop: Loop, cls: type) -> list[tuple[float, object]]:
    return [(t, m) for t, m in loop.kit.log if isinstance(m, cls)]


def test_without_the_operator_nothing_enables_whatever_the_stack_commands() -> None:
    loop = Loop()
    loop.pedals = PedalCommand(throttle_pct=100.0, brake_pct=0.0, source="speed")
    loop.steer = SteerCommand(steer_pct=50.0, source="driving")
    loop.run(3.0)
    assert loop.client.state == "disengaged"
    assert not any(loop.kit.enabled.values())
    assert all(not m.enable for _, m in loop.kit.log)
    assert all(m.accel_ratio == 0.0 for _, m in kit_commands(loop, AccelCmd))
    assert loop.kit.speed_mps == 0.0
    status = loop.published(Topic.VEHICLE_STATUS)[-1]
    assert status.safety_mode == "software-pause" and not status.computer_speed


def test_the_engage_sequence_disables_then_enables_the_brake_held_first_then_the_rest() -> None:
    loop = Loop()
    loop.pedals = THROTTLE        # the stack asks for throttle all along: never before engaged
    loop.engage()
    log = [(t, m) for t, m in loop.kit.log if isinstance(m, SYSTEM_CMDS)]
    first_on = next(i for i, (_, m) in enumerate(log) if m.enable)
    assert isinstance(log[first_on][1], BrakeCmd)
    assert log[first_on][1].brake_ratio >= ENGAGE_BRAKE_RATIO
    # every system was sent enable=0 for DISABLE_FRAMES frames right before the first edge
    frames_before = {}
    for _, m in log[:first_on]:
        frames_before[type(m)] = frames_before.get(type(m), 0) + 1
    assert all(frames_before[c] >= DISABLE_FRAMES for c in SYSTEM_CMDS)
    brake_edge_s = log[first_on][0]
    for cls in (AccelCmd, SteeringCmd, ShiftCmd):
        edge_s = next(t for t, m in kit_commands(loop, cls) if m.enable)
        assert edge_s > brake_edge_s, cls   # after the kit reported the brake enabled
    # no throttle before the kit had every system enabled, and the brake held until then
    engaged_s = next(t for t, _, _, to in loop.client.transitions if to == "engaged")
    for t, m in kit_commands(loop, AccelCmd):   # the first engaged frame goes at engaged_s
        if t < engaged_s:
            assert m.accel_ratio == 0.0
    for t, m in kit_commands(loop, BrakeCmd):
        if brake_edge_s <= t < engaged_s:
            assert m.brake_ratio >= ENGAGE_BRAKE_RATIO
    assert all(loop.kit.enabled.values())
    loop.run(1.0)
    assert loop.kit.speed_mps > 0.5, "engaged: the stack's throttle drives"


def test_commands_go_out_every_thirtieth_of_a_second() -> None:
    loop = Loop()
    loop.engage()
    loop.run(2.0)
    times = [t for t, m in kit_commands(loop, BrakeCmd)]
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert max(gaps) <= 0.04 + 1e-9 and min(gaps) >= 0.03 - 1e-9
    assert len(times) == pytest.approx(30 * loop.now_s, abs=2)


def test_an_override_latches_and_no_planner_command_re_engages() -> None:
    loop = Loop()
    loop.engage()
    loop.pedals = THROTTLE
    loop.run(1.0)
    loop.kit.press("brake")
    loop.run(0.2)
    assert loop.client.state == "overridden"
    assert loop.published(Topic.VEHICLE_STATUS)[-1].safety_mode == "manual-override"
    loop.kit.press("brake", False)   # the operator lets go; the planner drives on
    override_s = loop.now_s
    loop.steer = SteerCommand(steer_pct=20.0, source="driving")
    loop.run(3.0)
    while loop.kit.speed_mps > 0.0:   # rolling out, the pedals handed back
        loop.step()
    assert loop.client.state == "overridden"
    assert not any(loop.kit.enabled.values())
    assert all(not m.enable for t, m in loop.kit.log if t > override_s and hasattr(m, "enable"))
    # the operator's act re-engages, clearing the released override
    assert loop.client.request_engage(loop.now_s) is None
    loop.pedals = BRAKE
    loop.run(1.0)
    assert loop.client.state == "engaged" and all(loop.kit.enabled.values())
    assert not any(loop.kit.override.values())


def test_an_override_still_held_when_re_engaging_falls_back_to_overridden() -> None:
    loop = Loop()
    loop.engage()
    loop.kit.press("accel")
    loop.run(0.2)
    assert loop.client.state == "overridden"
    assert loop.client.request_engage(loop.now_s) is None   # the operator still presses
    loop.run(1.0)
    assert loop.client.state == "overridden"
    assert not loop.kit.enabled["accel"]


def test_a_kit_timeout_latches_and_only_the_operator_re_engages() -> None:
    loop = Loop()
    loop.engage()
    loop.pedals = THROTTLE
    loop.run(0.5)
    stalled_s = loop.now_s
    while loop.now_s < stalled_s + 0.15:   # the client not stepped: no frames for 150 ms
        loop.now_s = round(loop.now_s + 0.01, 9)
        loop.kit.step(loop.now_s, 0.01)
    assert loop.kit.timed_out
    loop.run(1.0)
    assert loop.client.state == "timed_out"
    assert not any(loop.kit.enabled.values())
    assert any(m.kind == "fault" and m.code == "pacmod3_timed_out"
               for m in loop.published(Topic.NOTICE))


@pytest.mark.parametrize("silent_s", [0.02, 0.05, 0.07, 0.1, 0.13, 0.2])
def test_a_silent_report_is_a_fault_and_the_sensors_stop(silent_s: float) -> None:
    loop = Loop()
    loop.engage()
    loop.run(0.5)
    loop.kit.silent = {VehicleSpeedRpt}
    start = len(loop.outputs)
    loop.run(silent_s)
    loop.kit.silent = set()
    loop.run(0.3)
    sent = [t for t, cls in loop.kit.sent if cls is VehicleSpeedRpt]
    gap_s = max(b - a for a, b in itertools.pairwise(sent))
    assert not REPORT_TIMEOUT_S < gap_s < REPORT_TIMEOUT_S + 0.01, "a gap the 10 ms step blurs"
    faulted = gap_s > REPORT_TIMEOUT_S
    notices = [m for _, t, m in loop.outputs[start:] if t == Topic.NOTICE]
    assert any(m.code == "pacmod3_silent" for m in notices) == faulted
    assert (loop.client.state == "faulted") == faulted
    if faulted:
        assert not any(loop.kit.enabled.values())
        assert loop.client.request_engage(loop.now_s) is None   # the operator, reports back
        loop.run(1.0)
        assert loop.client.state == "engaged" and all(loop.kit.enabled.values())


def test_garbage_frames_are_counted_and_change_no_command() -> None:
    clean, dirty = Loop(), Loop()
    for loop in (clean, dirty):
        loop.engage()
    garbage = [CanFrame(arbitration_id=dirty.client.codec.frame_id(GlobalRpt), data=b"\x01"),
               CanFrame(arbitration_id=0x7FF, data=bytes(8)),              # unknown id
               CanFrame(arbitration_id=0x1234567, data=bytes(8), is_extended=True)]
    for _ in range(100):
        for loop in (clean, dirty):
            loop.step()
        for frame in garbage:
            dirty.client.receive(frame, dirty.now_s)
    stats = dirty.client.stats
    assert stats.malformed >= 100 and stats.unknown >= 200 and stats.foreign_commands == 0
    assert [m for _, m in clean.sent] == [m for _, m in dirty.sent]
    assert dirty.client.state == "engaged"


@pytest.mark.parametrize("ratio", [CONSTANT, VARIABLE], ids=["constant", "variable"])
@pytest.mark.parametrize("steer_pct", [-100.0, -60.0, -10.0, 0.0, 10.0, 60.0, 100.0])
def test_steering_reaches_the_road_wheel_angle_on_the_side_asked(ratio, steer_pct) -> None:
    loop = Loop(ratio)
    loop.engage()
    loop.steer = SteerCommand(steer_pct=steer_pct, source="driving")
    loop.pedals = PedalCommand(throttle_pct=10.0, brake_pct=0.0, source="speed")
    loop.run(3.0)
    road_left = road_wheel_rad(loop.params.steering_ratio, loop.kit.wheel_rad)
    assert road_left == pytest.approx(-steer_pct / 100.0 * loop.params.max_steer_rad, abs=1e-3)
    if steer_pct:
        assert math.copysign(1.0, loop.kit.yaw_radps) == -math.copysign(1.0, steer_pct), \
            "positive steer_pct turns right (clockwise)"
    status = loop.published(Topic.VEHICLE_STATUS)[-1]
    assert status.steer_pct == pytest.approx(steer_pct, abs=0.2)


def test_steering_is_rate_limited_to_the_vehicle_rate() -> None:
    loop = Loop(VARIABLE)
    loop.engage()
    loop.steer = SteerCommand(steer_pct=100.0, source="driving")
    loop.run(2.0)
    p = loop.params
    road = [(t, m.position_rad) for t, m in kit_commands(loop, SteeringCmd) if m.enable]
    for (t0, a), (t1, b) in itertools.pairwise(road):
        step = abs(road_wheel_rad(p.steering_ratio, b) - road_wheel_rad(p.steering_ratio, a))
        # and the frame's 0.001 rad resolution of the wheel angle, through the ratio
        assert step <= p.steer_rate_rps * (t1 - t0) + 2 * 0.0005 / 13.0


def reports_client(speed_mps: float, brake_ratio: float, gear: Gear = Gear.PARK):
    """A client fed one round of reports directly (no plant): engaged, at ``speed_mps``."""
    loop = Loop()
    loop.engage()
    client = loop.client
    kit = loop.kit
    kit.brake_ratio, kit.gear = brake_ratio, gear
    # to the speed at a physical rate (0.3 m/s per report, 9 m/s^2): a report jumping beyond
    # any vehicle's acceleration is refused as a second sender's (vehicle.kit_reports)
    steps = max(1, math.ceil(abs(speed_mps) / 0.3))
    for k in range(1, steps + 1):
        kit.speed_mps = speed_mps * k / steps
        loop.now_s += 1.0 / 30.0
        for frame in kit.reports():
            client.receive(frame, loop.now_s)
    return loop


@pytest.mark.parametrize("speed", [0.0, 0.05, 0.1, 0.11, -0.11, 0.5, 3.0])   # 0.01 m/s steps
@pytest.mark.parametrize("brake", [0.0, ENGAGE_BRAKE_RATIO - 0.01, ENGAGE_BRAKE_RATIO, 1.0])
def test_a_shift_goes_out_only_at_a_standstill_with_the_brake_held(speed, brake) -> None:
    loop = reports_client(speed, brake)
    client = loop.client
    client.take_inputs([(Topic.PEDALS, PedalCommand(throttle_pct=0.0, brake_pct=brake * 100,
                                                    source="speed")),
                        (Topic.POWERTRAIN, PowertrainCommand(gear="drive", engine_on=True,
                                                             source="speed"))], loop.now_s)
    client.next_send_s = -math.inf
    shifts = [client.codec.decode(f) for f in client.command_frames(loop.now_s)]
    shift = next(m for m in shifts if isinstance(m, ShiftCmd))
    allowed = abs(speed) <= 0.1 and brake >= ENGAGE_BRAKE_RATIO   # the double's output
                                                                    # follows the command
    assert shift.gear == (Gear.FORWARD if allowed else Gear.PARK)
    assert (client.stats.shifts_refused == 0) == allowed


def test_dead_reckoning_follows_the_kit_round_a_curve() -> None:
    loop = Loop()
    loop.engage()
    loop.steer = SteerCommand(steer_pct=-40.0, source="driving")
    loop.pedals = PedalCommand(throttle_pct=15.0, brake_pct=0.0, source="speed")
    loop.run(8.0)
    gps = loop.published(Topic.GPS_INS)[-1]
    kit = loop.kit
    assert kit.y_m > 2.0, "a left turn (steer_pct negative) goes to the left (+y)"
    assert gps.solution == "dead_reckoning"
    assert math.hypot(gps.x_m - kit.x_m, gps.y_m - kit.y_m) < 0.05 * kit.odometer_m
    assert gps.odometer_m == pytest.approx(kit.odometer_m, rel=0.02)
    imu = loop.published(Topic.IMU)[-1]
    assert imu.yaw_rate_rps > 0.0


def test_a_lost_stack_brakes_to_a_stop_while_the_kit_stays_engaged() -> None:
    loop = Loop()
    loop.engage()
    loop.pedals = THROTTLE
    loop.run(2.0)
    assert loop.kit.speed_mps > 1.0
    loop.pedals = None            # no more pedal commands
    loop.run(2.0)
    assert loop.kit.speed_mps == 0.0
    assert all(loop.kit.enabled.values()) and loop.client.state == "engaged"


@pytest.mark.parametrize("axis", ["throttle", "brake", "steering"])
def test_bring_up_enables_one_axis_with_low_caps(axis: str) -> None:
    loop = Loop(bring_up=axis)
    loop.engage()
    loop.pedals = PedalCommand(throttle_pct=100.0, brake_pct=0.0, source="speed")
    loop.steer = SteerCommand(steer_pct=100.0, source="driving")
    loop.run(6.0)
    expected = {"throttle": {"brake", "accel", "shift"}, "brake": {"brake"},
                "steering": {"brake", "steering"}}[axis]
    assert {s for s, on in loop.kit.enabled.items() if on} == expected
    assert all(m.accel_ratio <= BRING_UP_ACCEL_RATIO_MAX for _, m in kit_commands(loop, AccelCmd))
    assert all(m.rotation_rate_radps <= BRING_UP_STEERING_RATE_RADPS
               for _, m in kit_commands(loop, SteeringCmd))
    assert loop.kit.speed_mps <= BRING_UP_SPEED_MPS + 0.1
    if axis != "throttle":
        assert loop.kit.speed_mps == 0.0


def test_a_vehicle_without_a_steering_ratio_is_refused() -> None:
    with pytest.raises(ValueError, match="steering_ratio"):
        Pacmod3Client(PRESETS["escape-hybrid"])
    Pacmod3Client(vehicle())


def test_yaw_reports_that_are_not_finite_are_not_taken() -> None:
    loop = Loop()
    loop.engage()
    codec = loop.client.codec
    loop.client.receive(codec.encode(YawRateRpt(yaw_rate_radps=0.5)), loop.now_s)
    assert loop.client.yaw_radps == 0.5


@pytest.mark.parametrize("bad", [{"command_period_s": 0.05}, {"command_period_s": math.nan},
                                 {"report_timeout_s": 0.0}, {"bring_up": "gear"}])
def test_bad_client_configurations_are_refused(bad) -> None:
    with pytest.raises(ValueError):
        Pacmod3ClientConfig(**bad)


def test_a_global_override_alone_disengages() -> None:
    loop = Loop()
    loop.engage()
    codec = loop.client.codec
    g = GlobalRpt(enabled=True, override_active=True, usr_can_timeout=False,
                  str_can_timeout=False, brk_can_timeout=False, subsystem_timeout=False,
                  veh_can_timeout=False, fault_active=False, config_fault_active=False,
                  usr_can_read_errors=0)
    loop.client.receive(codec.encode(g), loop.now_s)
    loop.client.next_send_s = -math.inf
    loop.client.command_frames(loop.now_s)
    assert loop.client.state == "overridden"
