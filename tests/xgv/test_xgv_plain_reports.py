"""The plain JAUS profile's reports (issue 19): speed, pose and status are taken only from the
component that owns them (Velocity State Sensor, Global Pose Sensor, Primitive Driver), packed
datagrams are read whole or not at all, and a status that stops coming or goes stale stops the
vehicle and is never resumed; lock-step runs judged from the simulated vehicle's ground truth."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.jaus import (
    ComponentStatus,
    JausId,
    ReportComponentStatus,
    ReportHeartbeatPulse,
    ReportVelocityState,
    Resume,
    encode_datagram,
)
from overdrive.messages import GpsIns, Topic
from overdrive.vehicle.plain_jaus import STATUS_TIMEOUT_S
from tests.conftest import PRESET_NAMES
from tests.xgv.plain_runs import (
    hooked_run,
    judged,
    mode_of,
    throttling,
)
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

# ------------------------------------------------------------------------------- report sources

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


def test_status_from_a_spoofed_component_is_not_the_pds() -> None:
    """Held: a READY from another component of the node does not lift the PD's emergency."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix(), status=ComponentStatus.EMERGENCY)
    deliver(client, ReportComponentStatus(primary_status=ComponentStatus.READY), GPOS, 0.15)
    deliver(client, ReportVelocityState(velocity_x_mps=0.0), VSS, 0.15)
    assert mode_of(dict(client.sensor_outputs(0.15))) == "estop-pause"


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
    assert mode_of(out) == "estop-pause"
    gps = out[Topic.GPS_INS]
    assert isinstance(gps, GpsIns) and gps.x_m == pytest.approx(0.3, abs=0.01)


# ------------------------------------------------------------------------------- a stale status

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("silent_s", [3.0, 4.0])
def test_a_status_that_stops_coming_stops_the_vehicle_soon(preset: str, silent_s: float) -> None:
    """Found: the PD's last READY stayed drive-by-wire for 1.5 s (the heartbeat timeout), so a
    PD whose status stream stopped mid-move was driven 4.1-4.2 m further. Now STATUS_TIMEOUT_S
    (0.5 s): 1.7-1.8 m from the last status to standstill (ground truth), no violation."""
    def silent(simulator: Any, m: Any, now_s: float) -> Any:
        return None if isinstance(m, ReportComponentStatus) and now_s >= silent_s else m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, silent)
    at = next(r for r in result.trace if float(r["t_s"]) >= silent_s)
    assert result.summary["odometer_m"] - float(at["odometer_m"]) <= 2.5
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert judged(result.summary) == []


@pytest.mark.parametrize(("age_s", "resumes"), [(STATUS_TIMEOUT_S - 0.05, True),
                                                (STATUS_TIMEOUT_S + 0.05, False)])
def test_no_resume_on_a_stale_standby(age_s: float, resumes: bool) -> None:
    """Found: a STANDBY last heard 1.5 s ago still drew a Resume every 0.5 s; a PD whose
    state is unknown is not resumed."""
    client = controlling()
    report(client, 0.1, pose=fix(), status=ComponentStatus.STANDBY)
    assert any(isinstance(m, Resume) for m in sent(client, 0.1))      # the first Resume
    deliver(client, ReportComponentStatus(primary_status=ComponentStatus.STANDBY), PD, 0.2)
    # the next is due 0.5 s after the first (retry_s): asked at 0.65 / 0.75
    assert any(isinstance(m, Resume) for m in sent(client, 0.2 + age_s)) is resumes
