"""The speed server stepped directly, against a tiny fake vehicle (logic, not dynamics)."""

from __future__ import annotations

import math

import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from overdrive.dynamics.control import MAX_CONTROL_STEP_S
from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.messages import (
    GpsIns,
    Imu,
    Notice,
    PedalCommand,
    PowertrainCommand,
    SetSpeed,
    SpeedState,
    Topic,
    VehicleStatus,
    WheelSpeed,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.speed import SpeedServer, SpeedServerConfig
from overdrive.servers.speed_table import STATE_TABLE, STATES, FaultCode
from tests.sensor_messages import gps_ins

PERIOD_S = 0.01
PRESET_NAMES = sorted(PRESETS)


class FakeVehicle:
    """Just enough vehicle for the server's logic: engine, gearbox, a crude speed model."""

    def __init__(self, params: VehicleParams, *, engine: str = "off", gear: str | None = None,
                 start_failures: int = 0, refuse_shifts: bool = False, speed_mps: float = 0.0):
        self.params = params
        self.engine = engine
        self.gear = gear or params.park_gear
        self.shift_target: str | None = None
        self.shift_left_s = 0.0
        self.crank_left_s = 0.0
        self.start_failures = start_failures
        self.start_failed = False
        self.engine_request = engine == "running"
        self.refuse_shifts = refuse_shifts
        self.speed_mps = speed_mps
        self.accel_mps2 = 0.0
        self.throttle_pct = 0.0
        self.brake_pct = 100.0
        self.park_brake = True
        self.horn = False
        self.wheel_offset_mps = 0.0
        self.rpm_override: float | None = None
        self.traction_control = False
        self.pedal_log: list[PedalCommand] = []

    def command(self, outputs):
        for topic, msg in outputs:
            if topic == Topic.PEDALS:
                self.throttle_pct, self.brake_pct = msg.throttle_pct, msg.brake_pct
                self.pedal_log.append(msg)
            elif topic == Topic.POWERTRAIN:
                self._powertrain(msg)

    def _powertrain(self, cmd: PowertrainCommand):
        self.park_brake, self.horn = cmd.park_brake, cmd.horn
        if cmd.engine_on and not self.engine_request and self.engine == "off":
            self.engine, self.crank_left_s, self.start_failed = "cranking", self.params.crank_time_s, False
        if not cmd.engine_on:
            self.engine = "off"
        self.engine_request = cmd.engine_on
        if cmd.gear != self.gear and cmd.gear != self.shift_target and not self.refuse_shifts:
            self.shift_target, self.shift_left_s = cmd.gear, self.params.shift_time_s

    def advance(self, dt_s: float):
        if self.engine == "cranking":
            self.crank_left_s -= dt_s
            if self.crank_left_s <= 1e-9:
                failed = self.start_failures > 0
                self.start_failures -= failed
                self.engine, self.start_failed = ("off" if failed else "running"), failed
        if self.shift_target is not None:
            self.shift_left_s -= dt_s
            if self.shift_left_s <= 1e-9:
                self.gear, self.shift_target = self.shift_target, None
        direction = self.params.gear(self.gear).direction
        drive = 0.0
        if self.engine == "running" and self.shift_target is None:
            drive = direction * 3.0 * self.throttle_pct / 100.0
        brake = 8.0 * (100.0 if self.park_brake else self.brake_pct) / 100.0
        v = self.speed_mps + drive * dt_s
        v = math.copysign(max(abs(v) - brake * dt_s, 0.0), v)
        self.accel_mps2 = (v - self.speed_mps) / dt_s
        self.speed_mps = v

    def sensors(self):
        p = self.params
        gear = p.gear(self.gear)
        rpm = 0.0
        if self.engine == "running":
            frac = min(abs(self.speed_mps) / gear.max_speed_mps, 1.0) if gear.max_speed_mps else 0.0
            rpm = p.idle_rpm + (p.redline_rpm - p.idle_rpm) * frac
        if self.rpm_override is not None:
            rpm = self.rpm_override
        return [
            (Topic.VEHICLE_STATUS, VehicleStatus(
                gear=self.gear, shifting=self.shift_target is not None, engine=self.engine,
                engine_rpm=rpm, start_failed=self.start_failed,
                traction_control=self.traction_control, steer_pct=0.0,
                throttle_pct=self.throttle_pct, brake_pct=self.brake_pct,
                safety_mode="drive-by-wire")),
            (Topic.WHEEL_SPEED, WheelSpeed(speed_mps=self.speed_mps + self.wheel_offset_mps)),
            (Topic.GPS_INS, GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=self.speed_mps,
                                   pitch_rad=0.0, roll_rad=0.0, odometer_m=0.0)),
            (Topic.IMU, Imu(accel_x_mps2=self.accel_mps2, accel_y_mps2=0.0, accel_z_mps2=9.81,
                            yaw_rate_rps=0.0)),
        ]


class Rig:
    """Server + fake vehicle on an integer-tick clock; records everything the server says."""

    def __init__(self, preset: str = "ranger-6x6", *, state: str = "parked",
                 gear: str | None = None, config: SpeedServerConfig | None = None, **vehicle):
        self.params = PRESETS[preset]
        engine = "running" if STATE_TABLE[state].engine_on and state != "starting" else "off"
        vehicle.setdefault("engine", engine)
        vehicle.setdefault("gear", gear if gear else (
            self.params.drive_gear if state == "run" else None))
        self.vehicle = FakeVehicle(self.params, **vehicle)
        self.server = SpeedServer(self.params, initial_state=state, initial_gear=gear,
                                  config=config)
        self.tick_count = 0
        self.states: list[tuple[float, str]] = [(0.0, state)]
        self.notices: list[tuple[float, Notice]] = []
        self.replies: list[SpeedState] = []
        self.last: list = []
        self.sensors_on = True
        self.last_request_s = math.nan

    @property
    def now_s(self) -> float:
        return self.tick_count * PERIOD_S

    def tick(self, *requests: SetSpeed):
        inbox = (self.vehicle.sensors() if self.sensors_on else []) + [
            (Topic.SET_SPEED, r) for r in requests]
        now = self.now_s
        if requests:
            self.last_request_s = now
        out = self.server.step(now, inbox)
        self.last = out
        self.vehicle.command(out)
        self.vehicle.advance(PERIOD_S)
        self.tick_count += 1
        for topic, msg in out:
            if topic == Topic.NOTICE:
                self.notices.append((now, msg))
            elif topic == Topic.SPEED_STATE:
                self.replies.append(msg)
        if self.server.state != self.states[-1][1]:
            self.states.append((now, self.server.state))
        return out

    def run(self, seconds: float, request: SetSpeed | None = None, every_s: float = 0.1,
            until=None):
        every = max(1, round(every_s / PERIOD_S))
        for i in range(round(seconds / PERIOD_S)):
            self.tick(*([request] if request is not None and i % every == 0 else []))
            if until is not None and until(self):
                return True
        return False

    def output(self, kind):
        return next(m for t, m in self.last if isinstance(m, kind))

    def state_names(self) -> list[str]:
        return [s for _, s in self.states]

    def faults(self) -> list[int]:
        return [int(n.code) for _, n in self.notices if n.kind == "fault"]


def spss(state="run", speed=0.0, accel=1.0, gear="high", fault=0) -> SetSpeed:
    return SetSpeed(speed_mps=speed, accel_mps2=accel, gear=gear, state=state, fault=fault)


def drive_gear(preset):
    return PRESETS[preset].drive_gear


# --------------------------------------------------------------------------- state table rows

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("state", STATES)
def test_state_does_what_its_table_row_says(preset, state):
    """One period in each state: engine, brakes, throttle and transmission as the seed's row."""
    params = PRESETS[preset]
    row = STATE_TABLE[state]
    gear = params.drive_gear if row.in_gear else None
    rig = Rig(preset, state=state, gear=gear)
    if state == "shifting":
        rig.vehicle.gear = params.low_gear   # the shift to the drive gear is still under way
    if state == "run":
        rig.run(0.3, spss("run", 3.0, 1.0, params.drive_gear))
    else:
        rig.tick()
    assert rig.server.state == state
    pedals, power = rig.output(PedalCommand), rig.output(PowertrainCommand)
    assert pedals.source == power.source == "speed"
    assert power.engine_on == row.engine_on
    assert power.horn == (state == "runwait")
    if row.brakes_locked:
        assert (pedals.throttle_pct, pedals.brake_pct, power.park_brake) == (0.0, 100.0, True)
    else:
        assert not power.park_brake and pedals.throttle_pct > 0.0 and pedals.brake_pct == 0.0
    if not row.throttle:
        assert pedals.throttle_pct == 0.0
    if row.in_gear:
        assert power.gear == params.drive_gear
    else:
        assert params.gear(power.gear).direction == 0
        assert power.gear == (params.park_gear if state in ("parked", "reset") else "neutral")


# --------------------------------------------------------------------------- sequences

@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_startup_parked_to_paused(preset):
    rig = Rig(preset)
    assert rig.run(10.0, spss("paused", gear=drive_gear(preset)),
                   until=lambda r: r.server.state == "paused")
    assert rig.state_names() == ["parked", "reset", "starting", "paused"]
    assert rig.vehicle.gear == "neutral" and rig.vehicle.engine == "running"
    assert rig.faults() == []


def test_failed_start_waits_30_s_in_startwait_then_retries():
    rig = Rig("ranger-6x6", start_failures=1)
    assert rig.run(45.0, spss("paused"), until=lambda r: r.server.state == "paused")
    assert rig.state_names() == ["parked", "reset", "starting", "startwait", "starting", "paused"]
    t_wait = next(t for t, s in rig.states if s == "startwait")
    t_retry = rig.states[4][0]
    assert t_retry - t_wait == pytest.approx(30.0, abs=0.011)


def test_no_start_at_all_gives_up_after_the_crank_timeout():
    rig = Rig("ranger-6x6")
    rig.vehicle.crank_left_s = math.inf
    rig.vehicle.advance = lambda dt_s: None   # a dead starter: never leaves "off"
    rig.run(8.0, spss("paused"))
    assert "startwait" in rig.state_names()


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_gear_change_goes_idle_shifting_idle(preset):
    params = PRESETS[preset]
    rig = Rig(preset, state="idle", gear=params.drive_gear)
    rig.run(5.0, spss("idle", gear=params.low_gear))
    assert rig.state_names() == ["idle", "shifting", "idle"]
    shift_s = rig.states[2][0] - rig.states[1][0]
    assert params.shift_time_s <= shift_s <= params.shift_time_s + 0.05
    assert rig.vehicle.gear == params.low_gear
    assert rig.output(PowertrainCommand).gear == params.low_gear


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_run_request_waits_5_s_in_runwait_with_the_horn(preset):
    params = PRESETS[preset]
    rig = Rig(preset, state="idle", gear=params.low_gear)
    horn_during_wait = []
    request = spss("run", 3.0, 1.0, params.drive_gear)
    for i in range(1000):
        rig.tick(*([request] if i % 10 == 0 else []))
        if rig.server.state == "runwait":
            horn_during_wait.append(rig.output(PowertrainCommand).horn)
            assert rig.output(PedalCommand).brake_pct == 100.0
    assert rig.state_names() == ["idle", "runwait", "shifting", "run"]
    t = dict((s, t) for t, s in rig.states)
    assert t["shifting"] - t["runwait"] == pytest.approx(5.0, abs=0.011)
    assert all(horn_during_wait) and len(horn_during_wait) >= 499
    assert t["run"] - t["shifting"] >= params.shift_time_s   # the gear changed after the wait
    assert rig.vehicle.speed_mps > 0.5


def test_run_in_the_current_gear_passes_shifting_for_one_period():
    rig = Rig("ranger-6x6", state="idle", gear="high")
    rig.run(6.0, spss("run", 3.0, 1.0, "high"))
    assert rig.state_names() == ["idle", "runwait", "shifting", "run"]
    t = dict((s, t) for t, s in rig.states)
    assert t["run"] - t["shifting"] == pytest.approx(PERIOD_S)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_from_parked_a_run_request_walks_the_whole_sequence(preset):
    params = PRESETS[preset]
    rig = Rig(preset)
    rig.run(15.0, spss("run", 2.0, 1.0, params.drive_gear))
    assert rig.state_names() == ["parked", "reset", "starting", "paused", "runwait", "shifting",
                                 "run"]
    assert rig.vehicle.speed_mps > 1.0


def test_out_of_pause_idle_goes_through_runwait():
    rig = Rig("ranger-6x6", state="paused")
    rig.run(6.0, spss("idle", gear="neutral"))
    assert rig.state_names() == ["paused", "runwait", "idle"]
    assert rig.states[2][0] - rig.states[1][0] == pytest.approx(5.0, abs=0.011)


def test_pause_from_run_stops_first():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(4.0, spss("run", 4.0, 2.0))
    assert rig.vehicle.speed_mps > 3.0
    speeds = []
    for i in range(500):
        rig.tick(*([spss("paused", 0.0, 2.0)] if i % 10 == 0 else []))
        speeds.append((rig.server.state, abs(rig.vehicle.speed_mps)))
        if rig.server.state == "paused":
            break
    assert rig.server.state == "paused"
    first_paused = next(i for i, (s, _) in enumerate(speeds) if s == "paused")
    assert speeds[first_paused - 1][1] < 0.1          # it entered paused only at a standstill
    assert all(s == "run" for s, _ in speeds[:first_paused])


def test_automatic_park_after_ten_minutes_in_paused():
    assert SpeedServerConfig().pause_park_s == 600.0
    rig = Rig("ranger-6x6", state="paused", config=SpeedServerConfig(pause_park_s=3.0))
    rig.run(10.0, spss("paused"))
    assert rig.state_names() == ["paused", "parked"]
    assert rig.states[1][0] == pytest.approx(3.0, abs=0.011)
    assert rig.output(PowertrainCommand).engine_on is False
    rig.run(1.0, spss("parked"))                     # a new request re-arms the engine start
    rig.run(6.0, spss("paused"), until=lambda r: r.server.state == "paused")
    assert rig.state_names() == ["paused", "parked", "reset", "starting", "paused"]


def test_speed_is_capped_by_the_gear():
    params = PRESETS["ranger-6x6"]
    rig = Rig("ranger-6x6", state="run", gear="low6wd")
    rig.run(20.0, spss("run", 15.0, 2.0, "low6wd"))
    cap = params.gear("low6wd").max_speed_mps * SpeedServerConfig().gear_cap_fraction
    assert rig.server.controller.v_ref_mps <= cap + 1e-9
    assert rig.vehicle.speed_mps <= cap + 0.3   # the fake vehicle is not the preset's model
    assert rig.replies[-1].hint == "suggest_upshift"


def test_reverse_gear_drives_backwards():
    rig = Rig("escape-hybrid", state="run", gear="reverse")
    rig.run(5.0, spss("run", 1.5, 1.0, "reverse"))
    assert rig.vehicle.speed_mps == pytest.approx(-1.5, abs=0.2)
    assert rig.replies[-1].speed_mps < 0


# --------------------------------------------------------------------------- faults

def test_client_fault_in_run_goes_idle_with_brakes_slammed():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(3.0, spss("run", 4.0, 2.0))
    rig.tick(spss("run", 4.0, 2.0, fault=42))
    assert rig.server.state == "idle"
    assert rig.output(PedalCommand).throttle_pct == 0.0
    assert rig.output(PedalCommand).brake_pct == 100.0
    kinds = [(n.kind, n.code) for _, n in rig.notices]
    assert ("fault", "42") in kinds and any(k == "estop" for k, _ in kinds)
    assert rig.replies[-1].fault == 42 and rig.replies[-1].estop
    rig.run(2.0, spss("run", 4.0, 2.0, fault=42))     # held while the client keeps the code
    assert rig.server.state == "idle" and rig.faults() == [42]
    rig.run(3.0, spss("run", 4.0, 2.0))               # cleared: stopped, valid, fault 0
    assert rig.server.state == "runwait" and not rig.replies[-1].estop


@pytest.mark.parametrize("state", ["paused", "idle", "runwait", "starting", "startwait"])
def test_client_fault_outside_run_resets(state):
    rig = Rig("ranger-6x6", state=state, gear="high" if STATE_TABLE[state].in_gear else None)
    rig.tick(spss("paused", fault=3))
    assert rig.server.state == "reset"
    assert rig.output(PowertrainCommand).engine_on is False
    rig.run(2.0, spss("paused", fault=3))
    assert rig.server.state == "reset"                # held in reset while the fault is active
    rig.run(8.0, spss("paused"), until=lambda r: r.server.state == "paused")
    assert rig.server.state == "paused"


INVALID = [
    (dict(speed=math.nan), FaultCode.NOT_FINITE),
    (dict(speed=math.inf), FaultCode.NOT_FINITE),
    (dict(accel=math.nan), FaultCode.NOT_FINITE),
    (dict(accel=-math.inf), FaultCode.NOT_FINITE),
    (dict(speed=-0.01), FaultCode.OUT_OF_RANGE),
    (dict(speed=70.01), FaultCode.OUT_OF_RANGE),
    (dict(accel=0.0), FaultCode.OUT_OF_RANGE),
    (dict(accel=-1.0), FaultCode.OUT_OF_RANGE),
    (dict(accel=10.01), FaultCode.OUT_OF_RANGE),
    (dict(state="runwait"), FaultCode.BAD_STATE),
    (dict(state="shifting"), FaultCode.BAD_STATE),
    (dict(state="reset"), FaultCode.BAD_STATE),
    (dict(state="drive"), FaultCode.BAD_STATE),
    (dict(gear="overdrive"), FaultCode.UNKNOWN_GEAR),
    (dict(gear="drive"), FaultCode.UNKNOWN_GEAR),      # an Escape gear, not a Ranger one
    (dict(gear="low"), FaultCode.GEAR_CHANGE_OUTSIDE_IDLE),
    (dict(gear="neutral"), FaultCode.NO_DRIVE_GEAR),
]


@pytest.mark.parametrize(("change", "code"), INVALID)
def test_invalid_request_in_run_is_a_fault_and_not_executed(change, code):
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(3.0, spss("run", 3.0, 1.0))
    before = (rig.server.goal, rig.server.goal_gear, rig.server.target_mps, rig.server.rate_mps2)
    fields = dict(state="run", speed=8.0, accel=5.0, gear="high")
    fields.update(change)
    bad = spss(**fields)
    for _ in range(5):
        rig.tick(bad)
        assert rig.replies[-1].fault == code and rig.replies[-1].fault_message
    assert rig.faults() == [code]                     # one Notice for a run of identical requests
    assert (rig.server.goal, rig.server.goal_gear) == before[:2], "the request is not executed"
    # ... and the vehicle is brought to a controlled stop (issue 17): never faster than allowed
    assert rig.server.target_mps == 0.0
    too_hard = change.get("accel", 0.0) > 10.0 and math.isfinite(change["accel"])
    assert rig.server.rate_mps2 == (10.0 if too_hard else max(before[3], 2.5))
    assert rig.server.state == "run" and rig.vehicle.gear == "high"
    rig.run(3.0, spss("run", 3.0, 1.0))
    assert rig.replies[-1].fault == 0                 # cleared by valid requests after the hold


@pytest.mark.parametrize("state", ["parked", "paused", "idle"])
@pytest.mark.parametrize(("change", "code"), INVALID[:14])
def test_invalid_request_outside_run_is_a_fault_and_not_executed(state, change, code):
    rig = Rig("ranger-6x6", state=state, gear="high" if state == "idle" else None)
    fields = dict(state="run", speed=3.0, accel=1.0, gear="high")
    fields.update(change)
    rig.run(1.0, spss(**fields))
    assert rig.faults() == [code]
    assert rig.state_names() == [state]
    assert rig.server.goal == state


def test_shifting_while_moving_is_refused():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(3.0, spss("run", 4.0, 2.0))
    rig.tick(spss("run", 4.0, 2.0, fault=1))          # client fault: idle at speed
    rig.tick(spss("idle", 0.0, 2.0, gear="low"))
    assert rig.server.state == "idle" and abs(rig.vehicle.speed_mps) > 0.5
    assert FaultCode.SHIFT_WHILE_MOVING in rig.faults()
    assert rig.server.goal_gear == "high"


def test_nonzero_fault_code_outside_the_client_range_still_stops():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(2.0, spss("run", 3.0, 1.0))
    rig.tick(spss("run", 3.0, 1.0, fault=5000))
    assert rig.server.state == "idle"
    assert FaultCode.OUT_OF_RANGE in rig.faults()


def test_engine_stall_restarts_through_reset():
    rig = Rig("ranger-6x6", state="idle", gear="high")
    rig.run(0.5, spss("idle", gear="high"))
    rig.vehicle.engine = "off"
    rig.vehicle.engine_request = False
    rig.run(8.0, spss("idle", gear="high"))
    assert rig.state_names()[:4] == ["idle", "reset", "starting", "paused"]
    assert rig.faults()[0] == FaultCode.ENGINE_STALLED


def test_shift_that_never_completes_is_a_fault_back_to_idle():
    rig = Rig("ranger-6x6", state="idle", gear="high", refuse_shifts=True)
    rig.run(6.0, spss("idle", gear="low"))
    timeout_s = rig.params.shift_time_s + SpeedServerConfig().shift_timeout_margin_s
    assert rig.state_names()[:3] == ["idle", "shifting", "idle"]
    assert rig.states[2][0] - rig.states[1][0] == pytest.approx(timeout_s, abs=0.011)
    assert rig.faults() == [FaultCode.SHIFT_FAILED]
    rig.run(6.0, spss("idle", gear="low"))          # the client insists: another attempt
    assert rig.state_names()[3:5] == ["shifting", "idle"]


def test_non_finite_sensor_values_are_rejected_with_a_notice():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(1.0, spss("run", 2.0, 1.0))
    bad = GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=math.nan, pitch_rad=0.0,
                 roll_rad=0.0, odometer_m=0.0)
    rejected = []
    for _ in range(3):
        out = rig.server.step(rig.now_s, [(Topic.GPS_INS, bad)])
        rig.tick_count += 1
        rejected += [m for t, m in out if t == Topic.NOTICE and m.kind == "rejected"]
    assert len(rejected) == 1 and rejected[0].reason.startswith("gps_ins")
    assert math.isfinite(rig.server.speed_mps)


# --------------------------------------------------------------------------- replies and pedals

def test_every_spss_gets_exactly_one_reply_and_a_status_otherwise():
    rig = Rig("ranger-6x6", state="paused")
    out = rig.tick(spss("paused"), spss("paused"), spss("idle"))
    assert sum(1 for t, _ in out if t == Topic.SPEED_STATE) == 3
    out = rig.tick()
    assert sum(1 for t, _ in out if t == Topic.SPEED_STATE) == 1
    assert sum(1 for t, _ in out if t == Topic.PEDALS) == 1
    assert sum(1 for t, _ in out if t == Topic.POWERTRAIN) == 1


requests = st.builds(
    spss,
    state=st.sampled_from(["run", "run", "run", "idle", "paused", "parked", "bogus"]),
    speed=st.one_of(st.floats(0.0, 15.0), st.sampled_from([math.nan, -1.0, 80.0])),
    accel=st.one_of(st.floats(0.1, 6.0), st.sampled_from([0.0, math.inf])),
    gear=st.sampled_from(["high", "high", "low", "neutral", "reverse", "bogus"]),
    fault=st.sampled_from([0] * 12 + [7]),
)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(requests, st.integers(1, 60)), min_size=1, max_size=12))
def test_never_throttle_and_brake_together_and_never_move_outside_run(plan):
    rig = Rig("ranger-6x6", state="run", gear="high")
    for request, hold_ticks in plan:
        for i in range(hold_ticks):
            rig.tick(*([request] if i % 10 == 0 else []))
            pedals = rig.output(PedalCommand)
            assert 0.0 <= pedals.throttle_pct <= 100.0 and 0.0 <= pedals.brake_pct <= 100.0
            assert pedals.throttle_pct == 0.0 or pedals.brake_pct == 0.0
            if rig.server.state != "run":
                assert pedals.throttle_pct == 0.0 and pedals.brake_pct == 100.0
            if rig.server.latched:
                assert pedals.throttle_pct == 0.0 and pedals.brake_pct == 100.0
            assert rig.server.state in STATES


# --------------------------------------------------------------------------- watchdog

def test_watchdog_estop_at_200_ms_and_latched_until_stopped_and_valid():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(4.0, spss("run", 5.0, 2.0))
    last_spss_s = rig.last_request_s
    estop_at = None
    for _ in range(30):
        rig.tick()
        if rig.server.latched and estop_at is None:
            estop_at = rig.now_s - PERIOD_S
            assert rig.output(PedalCommand) == PedalCommand(throttle_pct=0.0, brake_pct=100.0,
                                                            source="speed")
    assert estop_at is not None
    assert 0.2 - 1e-9 <= estop_at - last_spss_s <= 0.2 + PERIOD_S + 1e-9
    assert rig.server.state == "idle"
    kinds = [n.kind for _, n in rig.notices]
    assert kinds.count("estop") == 1 and FaultCode.SPSS_TIMEOUT in rig.faults()
    # SPSS resume while still rolling: still latched; an invalid one does not clear it either
    rig.tick(spss("run", 5.0, 2.0, gear="bogus"))
    assert rig.server.latched
    # stopped, the old "run" keeps coming: the client has not seen the stop, nothing clears
    # (issue 38: the old command never drives on by itself)
    rig.run(4.0, spss("run", 5.0, 2.0))
    assert rig.server.latched and rig.server.state == "idle"
    # a request for a state that does not move clears it; run again only after the 5 s wait
    rig.tick(spss("idle", 0.0, 2.0))
    assert not rig.server.latched
    rig.run(0.5, spss("run", 5.0, 2.0))
    assert rig.server.state == "runwait"


def test_watchdog_not_armed_before_the_first_spss():
    rig = Rig("ranger-6x6", state="parked")
    rig.run(2.0)
    assert rig.notices == []


def test_sensor_silence_is_an_emergency_stop():
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(2.0, spss("run", 3.0, 1.0))
    rig.sensors_on = False
    rig.run(0.3, spss("run", 3.0, 1.0))
    assert FaultCode.SENSOR_TIMEOUT in rig.faults()
    assert rig.server.latched and rig.server.state == "idle"


gaps = st.lists(st.integers(min_value=1, max_value=45), min_size=1, max_size=25)


@settings(max_examples=60, deadline=None)
@given(gaps, st.sampled_from(PRESET_NAMES))
def test_watchdog_property(gap_ticks, preset):
    """E-stop starts within 200 ms + one period after the last SPSS, never with gaps <= 190 ms."""
    params = PRESETS[preset]
    rig = Rig(preset, state="run", gear=params.drive_gear)
    request = spss("run", 2.0, 1.0, params.drive_gear)
    sent: list[float] = []
    estops: list[float] = []
    schedule = [0]
    for g in gap_ticks:
        schedule.append(schedule[-1] + g)
    end_tick = schedule[-1] + 40
    sends = set(schedule)
    for tick in range(end_tick):
        now = rig.now_s
        if tick in sends:
            sent.append(now)
        rig.tick(*([request] if tick in sends else []))
        estops += [now for t, n in rig.notices if t == now and n.kind == "estop"]
    for t_e in estops:
        last = max(t for t in sent if t <= t_e)
        assert 0.2 - 1e-9 <= t_e - last <= 0.2 + PERIOD_S + 1e-9
    for a, b in zip(sent, [*sent[1:], math.inf], strict=True):
        if b - a > 0.2 + 1e-9:
            assert any(a + 0.2 - 1e-9 <= t <= a + 0.2 + PERIOD_S + 1e-9 for t in estops)
    if all(g <= 19 for g in gap_ticks):
        assert [t for t in estops if t < sent[-1]] == []


def test_config_is_a_frozen_msgspec_struct_with_the_seed_defaults():
    cfg = SpeedServerConfig()
    assert (cfg.spss_timeout_s, cfg.runwait_s, cfg.start_retry_s, cfg.pause_park_s) == (
        0.2, 5.0, 30.0, 600.0)
    with pytest.raises(AttributeError):
        cfg.runwait_s = 1.0  # type: ignore[misc]
    assert msgspec.json.decode(msgspec.json.encode(cfg), type=SpeedServerConfig) == cfg


# ----------------------------------------------------------------------------- invalid requests fail safe

@pytest.mark.parametrize("speed", [3.0, 8.0])
def test_a_stop_harder_than_allowed_stops_at_the_allowed_maximum(speed: float):
    rig = Rig("escape-hybrid", state="run", gear="drive")
    rig.run(8.0, spss("run", speed, 2.0, gear="drive"))
    assert rig.vehicle.speed_mps > speed - 0.5
    rig.run(3.0, spss("run", 0.0, 12.0, gear="drive"))
    assert FaultCode.OUT_OF_RANGE in rig.faults()
    assert rig.vehicle.speed_mps < 0.05, "the vehicle stopped although the request was invalid"


def test_a_stream_of_only_invalid_requests_trips_the_watchdog():
    rig = Rig("escape-hybrid", state="run", gear="drive")
    rig.run(3.0, spss("run", 3.0, 1.0, gear="drive"))
    t_last_valid = rig.last_request_s
    rig.run(1.0, spss("run", 3.0, math.nan, gear="drive"))
    estops = [t for t, n in rig.notices if n.kind == "estop"]
    assert estops, "invalid requests do not feed the watchdog"
    assert estops[0] - t_last_valid <= 0.2 + PERIOD_S + 1e-9
    assert FaultCode.SPSS_TIMEOUT in rig.faults()


@pytest.mark.parametrize("speed", [2.0, 5.0])
def test_idle_with_a_new_gear_from_run_stops_then_shifts(speed: float):
    """Seed 001: "go to idle and specify a new gear" is the way to change gear from run."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(6.0, spss("run", speed, 2.0, gear="high"))
    assert rig.vehicle.speed_mps > speed - 0.5
    done = rig.run(15.0, spss("idle", 0.0, 2.0, gear="low"),
                   until=lambda r: r.vehicle.gear == "low" and r.server.state == "idle")
    assert done and rig.faults() == []
    names = rig.state_names()
    assert names[-3:] == ["idle", "shifting", "idle"] and "run" in names


# --------------------------------------------------------------------------- sensor input

BAD_NUMBERS = (math.nan, math.inf, -math.inf)


@pytest.mark.parametrize("field", ("speed_mps", "pitch_rad", "odometer_m"))
@pytest.mark.parametrize("bad", BAD_NUMBERS)
def test_speed_server_refuses_a_gps_ins_with_a_non_finite_field_it_uses(field: str,
                                                                         bad: float) -> None:
    node = SpeedServer(PRESETS["ranger-6x6"])
    good = gps_ins(odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(PERIOD_S, [(Topic.GPS_INS, gps_ins(**{"odometer_m": 1.0, field: bad}))])
    rejected = [n for t, n in out if t == Topic.NOTICE and n.kind == "rejected"]
    assert rejected and rejected[0].reason.startswith("gps_ins")
    assert node.gps == good


def test_an_untrusted_gps_is_not_a_source_of_the_slow_creep_rule() -> None:
    """A frozen GPS reading 0 (untrusted by the plausibility checks) must not hide a rollback the
    wheels see: the direction hold gets only trusted sources."""
    server = SpeedServer(PRESETS["escape-hybrid"], initial_state="run")
    server.last_now_s = 1.0
    server.gps, server.last_gps_s = gps_ins(speed_mps=0.0), 1.0
    server.wheel_mps, server.last_wheel_s = -0.08, 1.0
    assert sorted(server._source_speeds_mps(1)) == [-0.08, 0.0]
    server.motion.gps_track.trusted = False
    assert server._source_speeds_mps(1) == [-0.08]


# --------------------------------------------------------------------------- unasked stops

@pytest.mark.parametrize("code", [5000, 1001, -7])
def test_a_client_fault_code_out_of_range_is_still_the_clients_own_stop(code: int) -> None:
    """The client sent a fault: it asked for the stop, whatever the code. Was: a code above
    999 named the e-stop as one of the server's own (1001: a watchdog stop to the move server
    and the judge). Now the e-stop's code stays in the clients' 1..999, nothing is counted."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(1.0, spss("run", 3.0, 1.0))
    rig.tick(spss("run", 3.0, 1.0, fault=code))
    reply = rig.replies[-1]
    assert reply.estop and 1 <= reply.estop_code <= 999
    assert reply.unasked_stops == 0
    assert [n.code for _, n in rig.notices if n.kind == "estop"] == [str(reply.estop_code)]


def test_a_watchdog_stop_after_a_client_fault_is_named_by_the_watchdog() -> None:
    """A client fault, then the client falls silent: the watchdog's stop is one the stack did
    not ask for. Was: the client's code kept naming it, so the old run cleared it at rest.
    Now the latest unasked cause names it and only a non-moving request clears it."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(2.0, spss("run", 3.0, 1.0))
    rig.run(1.0, spss("run", 3.0, 1.0, fault=40))
    rig.run(3.0)                                   # silent: the watchdog fires, it stops
    assert rig.replies[-1].estop_code == FaultCode.SPSS_TIMEOUT
    rig.run(2.0, spss("run", 3.0, 1.0))             # the old run at rest: still latched
    assert rig.server.latched and rig.replies[-1].estop_code == FaultCode.SPSS_TIMEOUT
    rig.tick(spss("idle", 0.0, 1.0))
    assert not rig.server.latched


def test_every_unasked_stop_is_counted_and_the_count_survives_clearing() -> None:
    """``SpeedState.unasked_stops`` rises at each stop of the server's own and is never reset,
    so a client that lost every report of a stop still sees that one happened."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    for stops in (1, 2):
        rig.run(1.0, spss("run", 3.0, 1.0))
        rig.run(3.0)                               # silent: watchdog, at rest
        rig.tick(spss("idle", 0.0, 1.0))           # cleared
        assert not rig.server.latched
        assert rig.replies[-1].unasked_stops == stops
    assert rig.replies[-1].started_s == 0.0


def test_a_rollback_during_a_stall_of_the_server_is_measured_in_full() -> None:
    """The server stalls 0.3 s while the vehicle rolls back at 0.4 m/s. Was: the direction
    hold got the controllers' bounded step (0.02 s) and counted 8 mm of the 0.12 m rolled
    back. Now it measures with the real elapsed time: 0.124 m, past the 0.10 m limit."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(1.0, spss("run", 3.0, 1.0))
    last_s = rig.now_s - PERIOD_S
    rig.vehicle.speed_mps = -0.4
    rig.server.step(last_s + 0.31, [*rig.vehicle.sensors(), (Topic.SET_SPEED, spss("run", 3.0))])
    assert rig.server.direction_hold.back_m == pytest.approx(0.4 * 0.31, abs=0.01)


def _accelerating_then_stalled(gap_s: float) -> tuple[Rig, float, float]:
    """A server accelerating towards 3 m/s that is then not stepped for ``gap_s``: the rig,
    the throttle and the speed reference before the gap."""
    rig = Rig("ranger-6x6", state="run", gear="high")
    rig.run(1.0, spss("run", 3.0, 1.0))
    before = (rig.output(PedalCommand).throttle_pct, rig.server.controller.v_ref_mps)
    last_s = rig.now_s - PERIOD_S
    rig.server.step(last_s + gap_s, [*rig.vehicle.sensors(), (Topic.SET_SPEED, spss("run", 3.0))])
    return rig, *before


def test_after_a_stall_the_throttle_is_no_harder_than_before_it() -> None:
    """The first throttle after a 0.3 s gap, while the loop was raising it, is capped at the
    one before the gap (without the cap the loop would go on raising it at once)."""
    rig, throttle_before, _ = _accelerating_then_stalled(0.31)
    assert throttle_before > 0.0 and rig.server.stalls == 1
    assert rig.server.pedals.throttle_pct <= throttle_before + 1e-9


def test_a_stall_advances_the_speed_ramp_by_no_more_than_two_periods() -> None:
    """The controllers integrate at most MAX_CONTROL_STEP_S per step: after a 0.3 s gap the
    speed reference has moved by at most 2 periods at the requested 1 m/s^2, not 0.3 s."""
    rig, _, ref_before = _accelerating_then_stalled(0.31)
    assert rig.server.controller.v_ref_mps - ref_before <= 1.0 * MAX_CONTROL_STEP_S + 1e-9
