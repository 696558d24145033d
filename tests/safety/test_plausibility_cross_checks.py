"""Unit tests of the issue-30 cross-checks in ``safety.plausibility``: GPS/INS speed against the
wheels (the IMU tells slip from drift), position and heading steps, the receiver's solution.
Each threshold swept just inside / just outside."""

from __future__ import annotations

import math
import random

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import GpsIns, Imu, Topic, WheelSpeed
from overdrive.safety.plausibility import (
    MotionPlausibility,
    PlausibilityConfig,
    PlausibilityFault,
    plausibility_config,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingModule
from overdrive.servers.move import MoveServer
from overdrive.servers.speed import SpeedServer
from tests.conftest import PRESET_NAMES

DT = 0.01
CFG = PlausibilityConfig()


class Drive:
    """A vehicle at ``speed`` m/s along +x, one reading of each source per 10 ms, with noise;
    ``gps_error``/``wheel_error`` are added to the speeds, ``pose_error`` to the position."""

    def __init__(self, config: PlausibilityConfig = CFG, seed: int = 3,
                 noise_mps: float = 0.02) -> None:
        self.node = MotionPlausibility("test", config)
        self.rng = random.Random(seed)
        self.noise_mps = noise_mps
        self.t = 0.0
        self.x = 0.0
        self.heading = 0.0
        self.notices: list = []

    def step(self, speed: float, accel: float = 0.0, gps_error: float = 0.0,
             wheel_error: float = 0.0, dx: float = 0.0, dy: float = 0.0, dh: float = 0.0,
             yaw_rate: float = 0.0, solution: str = "rtk_fixed",
             sigma: float | None = 0.02) -> None:
        n = self.rng.gauss
        self.x += speed * DT
        self.heading += yaw_rate * DT
        g = GpsIns(x_m=self.x + dx + n(0.0, 0.02), y_m=dy + n(0.0, 0.02),
                   heading_rad=self.heading + dh,
                   speed_mps=speed + gps_error + n(0.0, self.noise_mps), pitch_rad=0.0,
                   roll_rad=0.0, odometer_m=self.x, solution=solution,  # type: ignore[arg-type]
                   position_sigma_m=sigma)
        self.node.gps(self.t, g)
        self.node.wheel(self.t, WheelSpeed(speed_mps=speed + wheel_error + n(0.0, self.noise_mps)))
        self.node.imu(self.t, Imu(accel_x_mps2=accel + n(0.0, 0.05), accel_y_mps2=0.0,
                                  accel_z_mps2=G_MPS2, yaw_rate_rps=yaw_rate))
        self.notices += self.node.step(self.t, 1)
        self.t = round(self.t + DT, 9)

    def cruise(self, seconds: float, speed: float = 8.0, **kw: float) -> None:
        for _ in range(round(seconds / DT)):
            self.step(speed, **kw)

    def codes(self) -> list[int]:
        return [int(n.code) for n in self.notices if n.kind == "fault"]


def test_the_thresholds_come_from_the_vehicle_file() -> None:
    for preset in PRESET_NAMES:
        p = PRESETS[preset]
        cfg = plausibility_config(p)
        for name in ("speed_agree_mps", "speed_disagree_fault_mps", "speed_disagree_fault_frac",
                     "speed_disagree_confirm_s", "position_step_m", "position_step_sigmas",
                     "heading_step_rad"):
            assert getattr(cfg, name) == getattr(p, name)


# --------------------------------------------------------------------------- speed

@pytest.mark.parametrize(("error_mps", "higher"), [(-0.05, False), (-0.2, True), (-0.5, True),
                                                   (0.2, True)])
def test_a_gps_speed_off_the_wheels_is_outvoted_by_the_higher_reading(error_mps: float,
                                                                      higher: bool) -> None:
    """A GPS/INS bias that grew slowly (the wheels and the IMU agree with each other): beyond
    the agreement band the higher of the two readings is the speed."""
    d = Drive()
    d.cruise(1.0)
    steps = 200
    for k in range(steps + 1):
        d.step(8.0, gps_error=error_mps * k / steps)
    v = d.node.speed_mps
    assert v is not None
    if higher:
        assert v == pytest.approx(8.0 + max(error_mps, 0.0), abs=0.08)
    assert d.node.gps_reads_low is (error_mps < -CFG.speed_agree_mps)


FILTER_DELAY_S = 0.04   # the filtered difference crosses the bound 0.04 s after the raw step
                        # (0.2 s x ln(0.06 / 0.05) from bound - 0.01 to bound + 0.05)


@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize(("margin_mps", "seconds", "fault"), [
    (-0.05, 3.0, False),                                                 # under the bound
    (0.05, CFG.speed_disagree_confirm_s - 0.05, False),                  # not for long enough
    (0.05, CFG.speed_disagree_confirm_s + FILTER_DELAY_S + 0.05, True)])
def test_a_disagreement_beyond_the_bound_for_the_confirm_time_is_fault_1107_once(
        sign: int, margin_mps: float, seconds: float, fault: bool) -> None:
    d = Drive(noise_mps=0.002)   # small noise: an exact repeat is a frozen source
    d.cruise(1.0)
    # the bound's fraction is of the higher reading: 8 m/s + the bias when the GPS/INS reads high
    bound = CFG.speed_disagree_fault_mps + CFG.speed_disagree_fault_frac * 8.0
    if sign > 0:
        bound /= 1.0 - CFG.speed_disagree_fault_frac
    for k in range(100):   # the bias grows to just under the bound over 1 s, settles 1.5 s
        d.step(8.0, gps_error=sign * (bound - 0.01) * (k + 1) / 100)
    d.cruise(1.5, gps_error=sign * (bound - 0.01))
    assert d.codes() == []
    error = sign * (bound + margin_mps)
    d.cruise(seconds, gps_error=error)
    assert d.codes() == ([PlausibilityFault.SPEED_DISAGREE] if fault else [])
    d.cruise(2.0, gps_error=error)
    assert d.codes().count(PlausibilityFault.SPEED_DISAGREE) == (1 if margin_mps > 0 else 0)
    assert d.node.trusted("gps_ins") and d.node.trusted("wheel_speed"), "no source dropped"


@pytest.mark.parametrize("spin_mps", [0.3, 1.0, 4.0])
def test_a_wheel_spin_is_slip_not_a_gps_fault(spin_mps: float) -> None:
    """The wheels jump ahead of the ground while the IMU says the vehicle did not: slip. The
    GPS/INS speed is kept (as before issue 30), and nothing is a fault."""
    d = Drive()
    d.cruise(1.0, speed=2.0)
    for k in range(300):
        d.step(2.0, wheel_error=min(spin_mps, spin_mps * (k + 1) / 20))
    assert d.node.wheel_slipping and not d.node.gps_reads_low
    assert d.node.speed_mps == pytest.approx(2.0, abs=0.08)
    assert d.codes() == []


def test_abs_braking_wheels_under_the_ground_are_slip_not_a_fault() -> None:
    """ABS: the wheels read 15 % under the ground while braking at 3 m/s^2 (the plant's
    model); the IMU follows the GPS/INS: it is the wheels' own departure."""
    d = Drive()
    v = 10.0
    d.cruise(1.0, speed=v)
    while v > 0.5:
        v -= 3.0 * DT
        d.step(v, accel=-3.0, wheel_error=-0.15 * v)
    assert d.codes() == []


# --------------------------------------------------------------------------- pose

SLACK_M = 8.0 * CFG.step_timing_s   # the pose's time stamp jitter at the drives' 8 m/s


def step_bound_m(sigma: float | None) -> float:
    return max(CFG.position_step_m, CFG.position_step_sigmas * math.sqrt(2.0) * (sigma or 0.0)) \
        + SLACK_M


@pytest.mark.parametrize("sigma", [0.02, 0.3, None])
@pytest.mark.parametrize(("margin_m", "fault"), [(-0.12, False), (0.12, True)])
def test_a_position_step_beyond_the_bound_is_fault_1105(sigma: float | None, margin_m: float,
                                                        fault: bool) -> None:
    """The bound is ``position_step_m`` or the receiver's own sigma x 6 x sqrt 2, whichever is
    wider, plus speed x 20 ms of time-stamp slack (0.16 m at 8 m/s); both sides swept (the
    margin is 4 sigma of two RTK readings' difference)."""
    step_m = step_bound_m(sigma) + margin_m
    d = Drive()
    d.cruise(1.0, sigma=sigma)
    d.cruise(1.0, dy=step_m, sigma=sigma)
    expected = [PlausibilityFault.GPS_POSITION_STEP] if fault else []
    assert d.codes() == expected
    assert d.node.trusted("gps_ins"), "a step is reported; the pose is not used for safety"


@pytest.mark.parametrize(("step_rad", "fault"), [(CFG.heading_step_rad - 0.01, False),
                                                 (CFG.heading_step_rad + 0.01, True),
                                                 (-CFG.heading_step_rad - 0.01, True)])
def test_a_heading_step_beyond_the_gyro_is_fault_1106(step_rad: float, fault: bool) -> None:
    d = Drive()
    d.cruise(1.0, yaw_rate=0.3)           # a turn the gyro explains is no step
    d.cruise(1.0, yaw_rate=0.3, dh=step_rad)
    assert d.codes() == ([PlausibilityFault.GPS_HEADING_STEP] if fault else [])


def test_a_receiver_without_a_solution_is_untrusted_until_it_has_one() -> None:
    d = Drive()
    d.cruise(1.0)
    d.cruise(0.5, solution="rtk_float", sigma=0.3)
    changes = [n for n in d.notices if n.code == "gps_solution"]
    assert len(changes) == 1 and "rtk_fixed -> rtk_float" in changes[0].reason
    d.cruise(0.5, solution="none", sigma=None)
    assert not d.node.trusted("gps_ins")
    assert PlausibilityFault.GPS_NO_SOLUTION in d.codes()
    assert d.node.speed_mps == pytest.approx(8.0, abs=0.08), "the wheels carry the speed"
    d.cruise(CFG.recover_s - 0.05, solution="rtk_fixed")
    assert not d.node.trusted("gps_ins")
    d.cruise(0.1, solution="rtk_fixed")
    assert d.node.trusted("gps_ins")


# --------------------------------------------------------------------------- input validation

@pytest.mark.parametrize("sigma", [math.nan, math.inf, -math.inf, -0.1])
@pytest.mark.parametrize("server", ["move", "driving", "speed"])
def test_a_gps_ins_with_a_bad_position_sigma_is_rejected_by_every_server(sigma: float,
                                                                         server: str) -> None:
    """A reported sigma that is no finite number >= 0 rejects the reading with a notice (it
    would widen or disable the position-step bound)."""
    params = PRESETS["escape-hybrid"]
    node = {"move": MoveServer, "driving": DrivingModule, "speed": SpeedServer}[server](params)
    bad = GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=0.0, pitch_rad=0.0, roll_rad=0.0,
                 odometer_m=0.0, position_sigma_m=sigma)
    out = node.step(0.0, [(Topic.GPS_INS, bad)])
    rejected = [m for t, m in out if t == Topic.NOTICE and m.kind == "rejected"]
    assert rejected and "gps_ins" in rejected[0].reason
    assert node.motion.gps_track.last is None, "never handed to the cross-checks"


@pytest.mark.parametrize("bad", [{"x_m": math.nan}, {"y_m": math.inf}, {"heading_rad": math.nan},
                                 {"position_sigma_m": -1.0}, {"position_sigma_m": math.nan}])
def test_a_pose_the_servers_would_reject_is_not_checked_for_steps(bad: dict[str, float]) -> None:
    """A non-finite pose or a bad sigma handed straight to the checks (the servers reject such
    a reading first) raises no step, heading or solution notice and never crashes; the next
    good fix is judged against the last good one."""
    node = MotionPlausibility("test", CFG)
    fix = {"x_m": 0.0, "y_m": 0.0, "heading_rad": 0.0, "speed_mps": 0.0, "pitch_rad": 0.0,
           "roll_rad": 0.0, "odometer_m": 0.0}
    node.gps(0.0, GpsIns(**fix))
    node.gps(0.1, GpsIns(**{**fix, **bad}))
    node.gps(0.2, GpsIns(**fix))
    assert node._pending == []
