"""Red-team attacks on the plain JAUS profile (``vehicle.plain_jaus``, issue 19): what a faulty
or hostile plain JAUS vehicle, or the network, can send. Judged from what the client commands on
the wire (Set Wrench Effort), the mode it gives the stack, and in lock-step runs from the
simulated vehicle's ground truth (the judge's violations, the trace's speed), never from the
client's own view of itself. Attacks that found nothing are kept only as a few representatives.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec
import pytest

from overdrive.jaus import (
    ComponentStatus,
    ConfirmComponentControl,
    JausId,
    RejectComponentControl,
    ReportComponentControl,
    ReportComponentStatus,
    ReportGlobalPose,
    ReportHeartbeatPulse,
    ReportVelocityState,
    RequestComponentControl,
    SetWrenchEffort,
    encode_datagram,
)
from overdrive.messages import GpsIns, PedalCommand, Topic, VehicleStatus
from overdrive.vehicle.plain_jaus import (
    REPORT_SKEW_S,
    SPEED_CHECK_SIGMAS,
    LocalFrame,
    PoseRefused,
    SpeedCheck,
)
from overdrive.vehicle.xgv_client import REGISTRATION_GRACE_S, XgvClient
from tests.conftest import PRESET_NAMES
from tests.xgv.test_xgv_plain_profile import (
    GPOS,
    ME,
    PD,
    VSS,
    XGV_NM,
    controlling,
    deliver,
    fix,
    report,
    sent,
)
from tests.xgv.test_xgv_plain_review import hooked_run

LATER_S = REGISTRATION_GRACE_S + 1.0   # past OpenJAUS's registration grace: a Reject is real
MOVE_M = 12.0                          # openjaus-wrench-drive.yaml's move
MAX_SPEED_MPS = 2.5                    # and its speed limit


def wrench(client: XgvClient, now_s: float) -> list[SetWrenchEffort]:
    return [m for m in sent(client, now_s) if isinstance(m, SetWrenchEffort)]


def throttling(client: XgvClient) -> XgvClient:
    """The stack asks for throttle (as the speed server does when driving)."""
    client.take_inputs([(Topic.PEDALS, PedalCommand(source="speed", throttle_pct=40.0,
                                              brake_pct=0.0))])
    return client


def mode(out: dict[str, Any]) -> str:
    status = out[Topic.VEHICLE_STATUS]
    assert isinstance(status, VehicleStatus)
    return status.safety_mode


# ---------------------------------------------------------------- lock-step harness


def judged(summary: dict) -> list[str]:
    return [v for v in summary["violations"] if not v.startswith("expect")]


# ---------------------------------------------------------------- DEFECT: speed vs pose

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
        if isinstance(m, ReportVelocityState) and now_s >= 2.0:
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


# ---------------------------------------------------------------- DEFECT: report sources

@pytest.mark.parametrize(("message", "wrong_source"), [
    (ReportVelocityState(velocity_x_mps=0.0, yaw_rate_radps=0.0), PD),     # not the VSS
    (ReportVelocityState(velocity_x_mps=0.0, yaw_rate_radps=0.0), GPOS),
    (ReportVelocityState(velocity_x_mps=0.0, yaw_rate_radps=0.0), JausId(1, 1, 99, 1)),
])
def test_velocity_state_from_another_component_is_not_the_speed(message: Any,
                                                                wrong_source: JausId) -> None:
    """Found: any component of the vehicle's node could set the speed (and so the odometer
    the move stops on). A second sensor, or a spoofed source, reporting 0 while the VSS says
    2 m/s made the stack's speed flip to 0 (an under-counted odometer overshoots)."""
    client = controlling()
    report(client, 0.1, pose=fix(), speed_mps=2.0)
    deliver(client, message, wrong_source, 0.15)
    out = report(client, 0.2, pose=fix(0.2), speed_mps=2.0)
    deliver(client, message, wrong_source, 0.25)     # last before the stack's sensors
    deliver(client, ReportHeartbeatPulse(), XGV_NM, 0.25)
    out2 = dict(client.sensor_outputs(0.25))
    gps = out[Topic.GPS_INS]
    assert isinstance(gps, GpsIns) and gps.speed_mps == pytest.approx(2.0)
    assert Topic.WHEEL_SPEED not in out2            # nothing new from the VSS: nothing published
    assert client.speed_mps == pytest.approx(2.0)


def test_global_pose_from_another_component_is_not_the_pose() -> None:
    """Found: a Global Pose from any component of the node was projected, so a second (or
    spoofed) pose source set the run's origin or interleaved its fixes with the sensor's."""
    client = controlling()
    deliver(client, fix(40.0), PD, 0.05)                  # not the Global Pose Sensor: ignored
    out = report(client, 0.1, pose=fix())                 # the real sensor's first fix
    gps = out[Topic.GPS_INS]
    assert isinstance(gps, GpsIns) and (gps.x_m, gps.y_m) == (0.0, 0.0)
    deliver(client, fix(5.0), JausId(1, 1, 99, 1), 0.15)
    gps = report(client, 0.2, pose=fix(0.4))[Topic.GPS_INS]
    assert isinstance(gps, GpsIns) and gps.x_m == pytest.approx(0.4, abs=0.01)
    assert client.stats.rejected_reports == 0


# ---------------------------------------------------------------- DEFECT: control

def test_a_duplicated_confirm_after_control_was_taken_away_is_not_control() -> None:
    """Found: a Confirm Component Control arriving with no request outstanding (a UDP
    duplicate or a late copy of the first one, after another controller took the PD and it
    sent us a Reject) put the client back in control: drive-by-wire and throttle sent to a
    PD that someone else controls."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, RejectComponentControl(), PD, LATER_S)
    deliver(client, ConfirmComponentControl(response=0), PD, LATER_S + 0.001)   # the duplicate
    out = report(client, LATER_S + 0.01, pose=fix())
    assert mode(out) == "software-pause"
    commands = sent(client, LATER_S + 0.01)
    assert not [m for m in commands if isinstance(m, SetWrenchEffort)]
    assert [m for m in commands if isinstance(m, RequestComponentControl)]     # asks again
    # the answer to that request is control again
    deliver(client, ConfirmComponentControl(response=0), PD, LATER_S + 0.02)
    assert mode(report(client, LATER_S + 0.03, pose=fix())) == "drive-by-wire"


@pytest.mark.parametrize("controller", [JausId(1, 3, 1, 1), JausId(0, 0, 0, 0)])
def test_report_component_control_naming_another_controller_takes_control_away(
        controller: JausId) -> None:
    """Found: a Report Component Control from the PD naming someone else (or nobody) was
    ignored; the client went on sending throttle and telling the stack drive-by-wire."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, ReportComponentControl(controller=controller, authority=7), PD, 0.2)
    out = report(client, 0.21, pose=fix())
    assert mode(out) == "software-pause"
    assert not wrench(client, 0.21)
    assert any(n.code == "xgv_control" for t, n in out.items() if t == Topic.NOTICE)


def test_report_component_control_naming_us_keeps_control() -> None:
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, ReportComponentControl(controller=ME, authority=6), PD, 0.2)
    assert mode(report(client, 0.21, pose=fix())) == "drive-by-wire"
    assert [w.propulsive_linear_x_pct for w in wrench(client, 0.21)] == [pytest.approx(40.0, abs=0.01)]


# ---------------------------------------------------------------- held (representatives)

def test_status_from_a_spoofed_component_is_not_the_pds() -> None:
    """Held: a READY from another component of the node does not lift the PD's emergency."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix(), status=ComponentStatus.EMERGENCY)
    deliver(client, ReportComponentStatus(primary_status=ComponentStatus.READY), GPOS, 0.15)
    deliver(client, ReportVelocityState(velocity_x_mps=0.0), VSS, 0.15)
    assert mode(dict(client.sensor_outputs(0.15))) == "estop-pause"


def test_a_frozen_pose_never_moves_and_a_first_bad_fix_never_becomes_a_far_pose() -> None:
    """Held: a first fix 100 m off becomes the origin, and the true fixes after it are refused
    as a jump until the time since it allows 100 m at 65 m/s; the stack gets no position in
    between (it cannot drive) rather than a wrong one."""
    frame = LocalFrame()
    frame.project(fix(100.0), 0.0)
    for i in range(1, 10):
        with pytest.raises(PoseRefused, match="jumped"):
            frame.project(fix(0.1 * i), 0.1 * i)


def test_packed_and_truncated_datagrams() -> None:
    """Held: a packed datagram's messages are all read; a packed datagram cut inside its last
    message is dropped whole (nothing of it used)."""
    client = controlling()
    report(client, 0.1, pose=fix())
    packed = encode_datagram([
        ReportComponentStatus(primary_status=ComponentStatus.EMERGENCY).with_header(
            source=PD, destination=ME),
        fix(0.3).with_header(source=GPOS, destination=ME),
        ReportVelocityState(velocity_x_mps=0.5).with_header(source=VSS, destination=ME)])
    client.receive(packed[:-3], 0.2)
    assert client.stats.malformed == 1 and client.pd_status == ComponentStatus.READY
    client.receive(packed, 0.21)
    out = dict(client.sensor_outputs(0.21))
    assert mode(out) == "estop-pause"
    gps = out[Topic.GPS_INS]
    assert isinstance(gps, GpsIns) and gps.x_m == pytest.approx(0.3, abs=0.01)


@pytest.mark.parametrize("yaw_rad", [math.pi, -math.pi])
def test_heading_across_plus_minus_pi_is_continuous(yaw_rad: float) -> None:
    """Held: a vehicle heading south reports +pi or -pi (the same heading): both are 0 in
    the run's frame, never a half turn."""
    frame = LocalFrame()
    frame.project(fix(yaw_rad=math.pi), 0.0)
    assert abs(frame.project(fix(yaw_rad=yaw_rad), 0.1).yaw_rad) < 1e-6


def test_a_fix_claiming_a_huge_rms_cannot_jump_half_a_kilometre() -> None:
    """Found: the jump bound grew with the rms each fix claims (up to the wire's 100 m: 849 m
    at dt 0), so a fix 500 m away 20 ms later was accepted. Now a fix claiming more than
    MAX_POSITION_RMS_M is refused, whatever its position."""
    frame = LocalFrame()
    frame.project(fix(), 0.0)
    with pytest.raises(PoseRefused):
        frame.project(fix(500.0, position_rms_m=100.0), 0.02)
