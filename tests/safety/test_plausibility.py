"""Unit tests of the motion-sensing plausibility checker (issue 16, case 1), swept around every
threshold: just inside it the source stays trusted, just outside it does not."""

from __future__ import annotations

import math
import random

import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import GpsIns, Imu, WheelSpeed
from overdrive.safety.plausibility import MotionPlausibility, PlausibilityConfig, PlausibilityFault

DT = 0.01
CFG = PlausibilityConfig()


def gps(speed: float = 0.0, odo: float = 0.0, x: float = 0.0, pitch: float = 0.0) -> GpsIns:
    return GpsIns(x_m=x, y_m=0.0, heading_rad=0.0, speed_mps=speed, pitch_rad=pitch,
                  roll_rad=0.0, odometer_m=odo)


def imu(accel: float = 0.0, pitch: float = 0.0) -> Imu:
    return Imu(accel_x_mps2=accel + G_MPS2 * math.sin(pitch), accel_y_mps2=0.0,
               accel_z_mps2=G_MPS2, yaw_rate_rps=0.0)


class Bench:
    """Feeds a checker one reading of each source per 10 ms period, like the simulator."""

    def __init__(self, seed: int = 1, noise: float = 0.02) -> None:
        self.node = MotionPlausibility("test")
        self.t = 0.0
        self.rng = random.Random(seed)
        self.noise = noise
        self.notices: list = []

    def n(self, sigma: float | None = None) -> float:
        return self.rng.gauss(0.0, self.noise if sigma is None else sigma)

    def step(self, g: GpsIns | None = None, w: WheelSpeed | None = None, i: Imu | None = None,
             direction: int = 1) -> list:
        if g is not None:
            self.node.gps(self.t, g)
        if w is not None:
            self.node.wheel(self.t, w)
        if i is not None:
            self.node.imu(self.t, i)
        out = self.node.step(self.t, direction)
        self.notices += out
        self.t = round(self.t + DT, 9)
        return out

    def codes(self) -> list[int]:
        return [int(n.code) for n in self.notices]


def frozen_gps_with_wheel(wheel_mps: float, periods: int) -> Bench:
    """GPS/INS repeats one reading; the wheel speed reads ``wheel_mps`` with noise."""
    bench = Bench()
    frozen = gps(speed=0.01, odo=0.0)
    for _ in range(periods):
        bench.step(frozen, WheelSpeed(speed_mps=wheel_mps + bench.n()), imu(bench.n(0.05)))
    return bench


@pytest.mark.parametrize(("periods", "flagged"), [(24, False), (25, False), (27, True), (40, True)])
def test_gps_repeating_is_frozen_after_freeze_s(periods: int, flagged: bool) -> None:
    # repeats counted from the first receipt: periods - 1 intervals of 10 ms
    bench = frozen_gps_with_wheel(2.0, periods)
    assert (not bench.node.gps_track.trusted) is flagged
    assert bench.codes() == ([PlausibilityFault.GPS_FROZEN] if flagged else [])


@pytest.mark.parametrize(("wheel_mps", "flagged"), [(0.0, False), (0.2, False), (0.24, False),
                                                    (0.36, True), (0.4, True), (-0.4, True)])
def test_gps_frozen_only_while_another_source_says_the_vehicle_moves(wheel_mps: float,
                                                                    flagged: bool) -> None:
    # moving_mps 0.3, the wheel's noise 0.02 (1 sigma) over 100 readings: 3 sigma either side
    bench = frozen_gps_with_wheel(wheel_mps, 100)
    assert (not bench.node.gps_track.trusted) is flagged
    assert bench.codes().count(PlausibilityFault.GPS_FROZEN) == (1 if flagged else 0), \
        "one notice per onset"


def test_frozen_gps_hands_the_speed_to_the_wheels_and_the_progress_too() -> None:
    bench = frozen_gps_with_wheel(3.0, 200)
    assert bench.node.speed_mps == pytest.approx(3.0, abs=0.1)
    # 199 intervals of 10 ms at 3 m/s: the wheel's distance, though the GPS/INS says 0
    assert bench.node.progress_m(1) == pytest.approx(3.0 * 1.99, abs=0.05)


def test_frozen_wheel_speed_at_cruise_is_untrusted_by_the_gps() -> None:
    bench = Bench()
    odo = 0.0
    for _ in range(100):
        odo += 5.0 * DT
        bench.step(gps(5.0 + bench.n(), odo, x=odo), WheelSpeed(speed_mps=5.0), imu(bench.n(0.05)))
    assert not bench.node.wheel_track.trusted
    assert bench.codes() == [PlausibilityFault.WHEEL_SPEED_FROZEN]
    assert bench.node.speed_mps == pytest.approx(5.0, abs=0.1)


@pytest.mark.parametrize(("gps_mps", "flagged"), [(5.0, False), (5.01, True), (4.99, True)])
def test_one_quantised_speed_under_two_names_is_not_frozen_a_different_one_is(
        gps_mps: float, flagged: bool) -> None:
    """A CAN kit's single speed report (0.01 m/s steps) dead-reckoned into the pose and given
    as the wheel speed: at a steady cruise both repeat one value while the pose moves. The
    wheel speed agrees with the GPS/INS's speed exactly, so it is not frozen; one step of the
    quantum apart, the GPS/INS says otherwise and the repeating wheel is frozen (1102 was raised
    at a steady 3 m/s cruise across processes, 2026-11-26)."""
    bench = Bench()
    odo = 0.0
    for _ in range(100):
        odo += gps_mps * DT
        bench.step(gps(gps_mps, odo, x=odo), WheelSpeed(speed_mps=5.0), imu(bench.n(0.05)))
    assert (not bench.node.wheel_track.trusted) is flagged
    assert bench.codes() == ([PlausibilityFault.WHEEL_SPEED_FROZEN] if flagged else [])


def test_a_noise_free_bench_at_constant_speed_is_not_frozen() -> None:
    """Every source repeating: none disagrees, nothing is called frozen (synthetic benches)."""
    bench = Bench()
    for _ in range(300):
        bench.step(gps(5.0), WheelSpeed(speed_mps=5.0), imu(0.0))
    assert bench.codes() == []
    assert bench.node.speed_mps == 5.0


@pytest.mark.parametrize(("accel", "flagged"), [(0.0, False), (0.3, False), (0.5, True),
                                                (1.5, True), (-1.5, True)])
def test_both_speeds_frozen_are_caught_by_the_imu(accel: float, flagged: bool) -> None:
    """GPS/INS and wheel speed repeat 0 while the IMU integrates to motion: no trusted speed.
    At rest the IMU counts from SETTLE_S (0.5 s) after the repeats began: over the next 0.5 s
    0.3 m/s^2 integrates to 0.15 m/s (< imu_dv_mps 0.2), 0.5 to 0.25."""
    bench = Bench()
    frozen_g, frozen_w = gps(0.0), WheelSpeed(speed_mps=0.0)
    for _ in range(101):
        bench.step(frozen_g, frozen_w, imu(accel + bench.n(0.05)))
    assert (bench.node.speed_mps is None) is flagged
    if flagged:
        assert set(bench.codes()) == {PlausibilityFault.GPS_FROZEN,
                                      PlausibilityFault.WHEEL_SPEED_FROZEN,
                                      PlausibilityFault.NO_TRUSTED_SPEED}
        assert bench.codes().count(PlausibilityFault.NO_TRUSTED_SPEED) == 1
    else:
        assert bench.codes() == []


@pytest.mark.parametrize(("accel", "flagged"), [(0.0, False), (0.3, False), (0.5, True),
                                                (2.0, True)])
def test_frozen_imu_is_untrusted_when_the_speed_changes_more_than_it_says(accel: float,
                                                                         flagged: bool) -> None:
    bench = Bench()
    frozen = imu(0.0)
    v = odo = 0.0
    for _ in range(51):
        v += accel * DT
        odo += v * DT
        bench.step(gps(v + bench.n(), odo, x=odo), WheelSpeed(speed_mps=v + bench.n()), frozen)
    assert (not bench.node.imu_track.trusted) is flagged
    assert bench.codes() == ([PlausibilityFault.IMU_FROZEN] if flagged else [])


@pytest.mark.parametrize(("extra_m", "flagged"), [(0.0, False), (0.19, False), (0.21, True),
                                                  (5.0, True), (-0.21, False), (-0.23, True)])
def test_odometer_jump(extra_m: float, flagged: bool) -> None:
    """The GPS/INS odometer may advance speed x dt (+ 12 m/s^2 x dt^2) + jump_m 0.2 per reading,
    and go back by no more than jump_m (the reading adds 2 m/s x 10 ms = 0.02 m to ``extra_m``)."""
    bench = Bench()
    odo = 0.0
    for k in range(20):
        odo += 2.0 * DT + (extra_m if k == 10 else 0.0)
        bench.step(gps(2.0 + bench.n(), odo, x=odo), WheelSpeed(speed_mps=2.0 + bench.n()),
                   imu(bench.n(0.05)))
    assert (not bench.node.gps_track.trusted) is flagged
    # the position jumps with the odometer: a step too (issue 30), reported, not distrusted
    odometer_codes = [c for c in bench.codes() if c != PlausibilityFault.GPS_POSITION_STEP]
    assert odometer_codes == ([PlausibilityFault.GPS_ODOMETER_JUMP] if flagged else [])


def test_an_untrusted_source_is_trusted_again_after_recover_s_of_plausible_readings() -> None:
    bench = frozen_gps_with_wheel(2.0, 40)
    assert not bench.node.gps_track.trusted
    odo = 0.0
    periods = round(CFG.recover_s / DT)
    for k in range(periods + 1):
        odo += 2.0 * DT
        bench.step(gps(2.0 + bench.n(), odo, x=odo), WheelSpeed(speed_mps=2.0 + bench.n()),
                   imu(bench.n(0.05)))
        if k == periods - 2:
            assert not bench.node.gps_track.trusted, "not before recover_s"
    assert bench.node.gps_track.trusted


def test_progress_is_signed_a_rollback_gives_the_distance_back() -> None:
    """5 m forward, then 2 m backwards (the gear still forward, GPS speed negative)."""
    bench = Bench()
    odo = 0.0
    for v, seconds in ((2.5, 2.0), (-1.0, 2.0)):
        for _ in range(round(seconds / DT)):
            odo += abs(v) * DT
            bench.step(gps(v + bench.n(), odo, x=odo), WheelSpeed(speed_mps=v + bench.n()),
                       imu(bench.n(0.05)), direction=1)
    assert bench.node.progress_m(1) == pytest.approx(3.0, abs=0.05)
    assert bench.node.progress_m(-1) == pytest.approx(-3.0, abs=0.05)


def test_no_phantom_progress_from_noise_at_standstill() -> None:
    """60 s standing with the presets' noise: less than 1 cm of progress either way."""
    bench = Bench(seed=7)
    for _ in range(6000):
        bench.step(gps(bench.n(), 0.0, x=bench.n()), WheelSpeed(speed_mps=bench.n()),
                   imu(bench.n(0.05)))
    assert abs(bench.node.progress_m(1)) < 0.01
    assert abs(bench.node.progress_m(-1)) < 0.01
    assert bench.codes() == []


@pytest.mark.parametrize("spin_mps", [0.5, 2.0, 6.0])
def test_wheel_spin_on_ice_is_not_a_fault_and_only_adds_progress(spin_mps: float) -> None:
    """Slip: the wheels read more than the ground. Not a sensor fault; the progress counts the
    larger (the vehicle stops short, never long)."""
    bench = Bench()
    odo = 0.0
    for _ in range(300):
        odo += 1.0 * DT
        bench.step(gps(1.0 + bench.n(), odo, x=odo), WheelSpeed(speed_mps=1.0 + spin_mps + bench.n()),
                   imu(bench.n(0.05)))
    assert bench.codes() == []
    assert bench.node.speed_mps == pytest.approx(1.0, abs=0.1), "the loop closes on the ground"
    assert bench.node.progress_m(1) >= odo - 0.01


@pytest.mark.parametrize("gap_s", [0.1, 0.4, 2.0])
def test_a_gps_dropout_while_moving_is_not_a_freeze(gap_s: float) -> None:
    """Silence is not repetition (red team: the move sweep's 0.4 s GPS channel drop was called
    frozen): after the gap the odometer catches up by speed x gap, which is no jump either."""
    bench = Bench()
    odo = 0.0
    gap = range(100, 100 + round(gap_s / DT))
    for k in range(300):
        odo += 5.0 * DT
        g = None if k in gap else gps(5.0 + bench.n(), odo, x=odo)
        bench.step(g, WheelSpeed(speed_mps=5.0 + bench.n()), imu(bench.n(0.05)))
    assert bench.codes() == []
    assert bench.node.progress_m(1) == pytest.approx(odo, abs=0.05)


def test_a_silent_source_is_not_live_and_gives_no_speed() -> None:
    bench = Bench()
    bench.step(gps(1.0), WheelSpeed(speed_mps=1.0))
    for _ in range(round(CFG.timeout_s / DT)):
        bench.step()
    assert bench.node.speed_mps is None
    assert bench.codes() == [], "silence is the speed server's sensor timeout, not a plausibility fault"


# --------------------------------------------------------------------------- which source is trusted, a step with no direction

@pytest.mark.parametrize(("frozen", "untrusted"), [
    ("gps_ins", "gps_ins"), ("wheel_speed", "wheel_speed"), ("imu", "imu"), (None, None)])
def test_trusted_names_the_source_found_implausible(frozen: str | None,
                                                    untrusted: str | None) -> None:
    """One source repeats while the others show the vehicle accelerating: only it is untrusted."""
    bench = Bench()
    v = odo = 0.0
    for _ in range(60):
        v += 2.0 * DT
        odo += v * DT
        bench.step(gps(0.5, 0.0) if frozen == "gps_ins" else gps(v + bench.n(), odo, x=odo),
                   WheelSpeed(speed_mps=0.5) if frozen == "wheel_speed"
                   else WheelSpeed(speed_mps=v + bench.n()),
                   imu(0.0) if frozen == "imu" else imu(2.0 + bench.n(0.05)))
    for name in ("gps_ins", "wheel_speed", "imu"):
        assert bench.node.trusted(name) is (name != untrusted)


@pytest.mark.parametrize("engaged", [1, -1])
@pytest.mark.parametrize(("gps_mps", "signed_by_speed"), [(CFG.sign_mps - 0.001, False),
                                                          (CFG.sign_mps, True),
                                                          (CFG.sign_mps + 0.001, True)])
def test_a_step_without_a_direction_keeps_the_engaged_one(engaged: int, gps_mps: float,
                                                          signed_by_speed: bool) -> None:
    """Below sign_mps the GPS/INS speed's sign is noise: its path length is signed by the
    direction last engaged, which a step with direction 0 does not change."""
    bench = Bench()
    odo = 0.0
    bench.step(gps(gps_mps, odo), direction=-engaged)
    bench.step(gps(gps_mps, odo, x=1e-4), direction=engaged)
    for _ in range(200):
        odo += gps_mps * DT
        bench.step(gps(gps_mps, odo, x=odo), direction=0)
    sign = 1 if signed_by_speed else engaged
    assert bench.node.progress_m(1) == pytest.approx(sign * odo, abs=1e-6)
    assert bench.node.progress_m(-1) == pytest.approx(-sign * odo, abs=1e-6)
    assert bench.codes() == []
