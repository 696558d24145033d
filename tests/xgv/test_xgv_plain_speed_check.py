"""The plain JAUS profile's speed check (``vehicle.plain_jaus.SpeedCheck``, issue 19): Velocity
State is the plain vehicle's only speed, so it is checked against the Global Pose. Its bound
just inside / just outside (single pair, averaged blocks, the reports' skew), and lock-step
runs where the speed reads low or the fixes are noisy, judged from the simulated vehicle's
ground truth (the judge's violations, the trace's speed), never from the client's view."""

from __future__ import annotations

import math
from typing import Any

import msgspec
import pytest

from overdrive.jaus import (
    ReportGlobalPose,
    ReportVelocityState,
)
from overdrive.vehicle.plain_jaus import (
    MAX_POSITION_RMS_M,
    REPORT_SKEW_S,
    SPEED_CHECK_BLOCK_S,
    SPEED_CHECK_SIGMAS,
    SpeedCheck,
)
from tests.conftest import PRESET_NAMES
from tests.xgv.plain_runs import (
    MAX_SPEED_MPS,
    MOVE_M,
    OJ_RMS_M,
    faults,
    hooked_run,
    judged,
    noisy,
)

# ------------------------------------------------------------------------------------ the bound

@pytest.mark.parametrize(("margin_m", "caught"), [(-0.01, False), (0.01, True)])
@pytest.mark.parametrize("speed_mps", [0.0, 2.0])
def test_the_speed_check_bound(margin_m: float, caught: bool, speed_mps: float) -> None:
    """Just inside / just outside: the chord may exceed the odometer by the pair's position
    noise and the reports' skew at the reported speed, not more; a chord shorter than the
    odometer (a curve, a reversal) is never caught."""
    check = SpeedCheck()
    assert check.check(0.0, 0.0, 0.0, 100.0, 0.5, speed_mps) is None
    allowed_m = SPEED_CHECK_SIGMAS * math.sqrt(2.0) * 0.5 + speed_mps * REPORT_SKEW_S
    reason = check.check(1.0, 3.0 + allowed_m + margin_m, 0.0, 103.0, 0.5, speed_mps)
    assert (reason is not None) is caught
    assert SpeedCheck().check(0.0, 0.0, 0.0, 0.0, 0.0, 0.0) is None
    curve = SpeedCheck()
    curve.check(0.0, 0.0, 0.0, 0.0, 0.02, 2.0)
    assert curve.check(5.0, 6.0, 6.0, 10.0, 0.02, 2.0) is None   # an arc: chord 8.5 < 10 m


@pytest.mark.parametrize("rms_m", [0.02, 1.0, MAX_POSITION_RMS_M])
@pytest.mark.parametrize(("margin", "caught"), [(-0.001, False), (0.001, True)])
@pytest.mark.parametrize("n", [1, 10, 50])
def test_the_averaged_bound(rms_m: float, margin: float, caught: bool, n: int) -> None:
    """Just inside / just outside (0.1 %): a completed block of 50 still fixes, then ``n`` fixes
    ``d`` further on with an odometer that says 0 m: the block's mean is caught beyond
    SPEED_CHECK_SIGMAS x rms sqrt(1/50 + 1/n) (1.3 m at 1 m rms and n = 50, against 8.5 m
    for a single pair before), never inside it."""
    check = SpeedCheck()
    for i in range(50):
        assert check.check(i * 0.01, 0.0, 0.0, 0.0, rms_m, 0.0) is None
    allowed_m = SPEED_CHECK_SIGMAS * rms_m * math.sqrt(1.0 / 50 + 1.0 / n)
    reasons = [check.check(SPEED_CHECK_BLOCK_S + i * 0.01, allowed_m * (1.0 + margin), 0.0, 0.0,
                           rms_m, 0.0) for i in range(n)]
    assert (reasons[-1] is not None) is caught
    assert all(r is None for r in reasons[:-1])


@pytest.mark.parametrize("speed_mps", [0.0, 2.5])
def test_the_skew_allowance_is_at_the_later_speed(speed_mps: float) -> None:
    """The odometer integrates the velocity reports as they come, so it lags the pose by up
    to REPORT_SKEW_S: the later fix's speed times that is allowed (a block driven at 2.5 m/s
    then a fix reading 0 gets none: a speed reading low is not excused by the one before)."""
    check = SpeedCheck()
    for i in range(50):
        check.check(i * 0.01, 0.0, 0.0, 0.0, 0.02, 2.5 - speed_mps)
    base_m = SPEED_CHECK_SIGMAS * 0.02 * math.sqrt(1.0 / 50 + 1.0) + speed_mps * REPORT_SKEW_S
    assert check.check(0.5, base_m - 0.01, 0.0, 0.0, 0.02, speed_mps) is None
    assert check.check(0.51, base_m + 0.01, 0.0, 0.0, 0.02, speed_mps) is not None


# ------------------------------------------------------------------------------- lock-step runs

RESIDUAL = pytest.mark.xfail(strict=True, reason=(
    "DEFECT (mitigated, not solved): with ojVehicleSim's claimed 1 m position rms the "
    "pose-vs-speed check (plain_jaus.SpeedCheck) averages fixes over 0.5 s blocks (bound "
    "1.3 m between two full blocks, was 8.5 m for a pair): a Velocity State reading 0 or half "
    "from t=2 s is caught 0.7-1.7 s later and the vehicle e-stops 3.2-8.7 m into the 12 m move, "
    "but it briefly reaches 3.5-5.0 m/s at a 2.5 m/s limit (before: caught at 4.1-6.4 s, "
    "5.0-7.7 m/s, 13.9-20.6 m). 1 m of noise cannot be told from motion faster while the "
    "stack accelerates on a speed reading 0; needs an independent speed (wheel speeds)"))


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("scale", [0.0, 0.5])
@pytest.mark.parametrize("rms_m", [None, pytest.param(1.0, marks=RESIDUAL)])
def test_velocity_state_reading_low_while_the_pose_moves_stops_the_vehicle(
        preset: str, scale: float, rms_m: float | None) -> None:
    """Found: Velocity State is the plain profile's only speed (wheel speed, GPS speed and the
    odometer the move stops on); reading 0 or half the truth from t=2 s (a stuck or
    mis-scaled sensor) ran the vehicle away (28 m/s, 154 m for a 12 m move, no fault). Now
    checked against the Global Pose: a fault, no more sensors, the watchdog's e-stop. With
    the simulated vehicle's rms (0.02 m) it is caught in 0.1-0.5 s, with no violation."""
    def low_speed(simulator: Any, m: Any, now_s: float) -> Any:
        if isinstance(m, ReportGlobalPose) and rms_m is not None:
            m = msgspec.structs.replace(m, position_rms_m=rms_m)
        if (isinstance(m, ReportVelocityState) and m.velocity_x_mps is not None
                and now_s >= 2.0):
            return msgspec.structs.replace(m, velocity_x_mps=scale * m.velocity_x_mps)
        return m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, low_speed)
    top_mps = max(float(r["speed_mps"]) for r in result.trace)
    assert top_mps <= MAX_SPEED_MPS + 0.3, top_mps           # ground truth, not the stack's
    assert result.summary["odometer_m"] <= MOVE_M + 1.0, result.summary["odometer_m"]
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert judged(result.summary) == []
    codes = [e.get("code") for e in result.summary["events"] if e["kind"] == "fault"]
    assert codes[0] == "xgv_speed" and codes.count("xgv_speed") == 1, codes
    assert any(e["kind"] == "estop" for e in result.summary["events"])


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("name", ["openjaus-wrench-drive.yaml", "move-curve.yaml"])
@pytest.mark.parametrize("seed", range(3))
def test_healthy_drives_with_1m_noise_raise_no_speed_fault(preset: str, name: str,
                                                          seed: int) -> None:
    """No false alarm: ojVehicleSim's 1 m rms as white noise on each axis (harder than its
    claim). Offline, 150 such runs (seeds 0-24, both presets, straight, long straight and
    curve) peaked at 5.2 sigma against the bound's 6.5."""
    result = hooked_run(name, preset, noisy(OJ_RMS_M, seed))
    assert faults(result.summary) == []
    assert judged(result.summary) == []
    assert result.summary["odometer_m"] > 10.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("scale", [0.0, 0.5])
@pytest.mark.parametrize("seed", range(2))
def test_a_low_speed_at_1m_rms_is_caught_before_the_move_is_driven(preset: str, scale: float,
                                                                  seed: int) -> None:
    """Found: at ojVehicleSim's 1 m rms the single-pair bound (8.5 m) caught a Velocity State
    reading 0 or half the truth from t=2 s only at 4.1-6.4 s, after 13.9-20.6 m of the 12 m
    move at up to 7.7 m/s. Averaged blocks catch it 0.7-1.7 s after the fault with 1 m of
    real noise: 3.2-8.7 m driven (ground truth), up to 5.0 m/s. Still over the speed limit
    for a moment (the strict xfail of
    test_velocity_state_reading_low_while_the_pose_moves_stops_the_vehicle)."""
    base = noisy(OJ_RMS_M, seed)

    def low(simulator: Any, m: Any, now_s: float) -> Any:
        m = base(simulator, m, now_s)
        if (isinstance(m, ReportVelocityState) and m.velocity_x_mps is not None
                and now_s >= 2.0):
            return msgspec.structs.replace(m, velocity_x_mps=scale * m.velocity_x_mps)
        return m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, low)
    caught = faults(result.summary)
    # the client's speed check, or first the stack's own plausibility check (issue 16: a
    # Velocity State of 0 while the pose moves is a frozen wheel speed, fault 1102)
    assert caught[0][0] in ("xgv_speed", "1102") and caught[0][1] <= 2.0 + 2.0, caught
    assert result.summary["odometer_m"] <= MOVE_M - 2.0, result.summary["odometer_m"]
    assert max(float(r["speed_mps"]) for r in result.trace) <= 5.5
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert any(e["kind"] == "estop" for e in result.summary["events"])
