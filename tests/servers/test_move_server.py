"""The move server node stepped by hand: replies, driving-module inputs, e-stop, phases."""

from __future__ import annotations

import math
from typing import Any

import msgspec
import pytest

from overdrive.dynamics.vehicle_params import G_MPS2
from overdrive.messages import (
    AdvanceAuthorization,
    DriveMode,
    GpsIns,
    Imu,
    MaxSpeed,
    MoveCommand,
    MoveReply,
    MoveStatus,
    Notice,
    Radar,
    SpeedState,
    SteeringRequest,
    Topic,
    VehicleStatus,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.adaptive import ESTIMATES_TOPIC, ActuatorEstimates
from overdrive.servers.move import (
    EVENTS,
    PHASES,
    TRANSITIONS,
    MoveServer,
    mermaid_diagram,
    next_phase,
)
from tests.sensor_messages import gps_ins


def sensors(params, *, speed: float = 0.0, odo: float = 0.0, state: str = "run",
            gear: str | None = None, engine: str = "running", mode: str = "drive-by-wire",
            radar: float | None = None, pitch: float = 0.0, estop: bool = False) -> list:
    gear = gear or params.drive_gear
    return [
        (Topic.VEHICLE_STATUS, VehicleStatus(
            gear=gear, shifting=False, engine=engine, engine_rpm=1000.0,  # type: ignore[arg-type]
            start_failed=False, traction_control=False, steer_pct=0.0, throttle_pct=0.0,
            brake_pct=0.0, safety_mode=mode)),
        (Topic.GPS_INS, GpsIns(x_m=odo, y_m=0.0, heading_rad=0.0, speed_mps=speed,
                               pitch_rad=pitch, roll_rad=0.0, odometer_m=odo)),
        (Topic.IMU, Imu(accel_x_mps2=0.0, accel_y_mps2=0.0, accel_z_mps2=G_MPS2,
                        yaw_rate_rps=0.0)),
        (Topic.RADAR, Radar(target=radar is not None,
                            range_m=radar if radar is not None else params.radar_range_m)),
        (Topic.SPEED_STATE, SpeedState(speed_mps=speed, accel_mps2=0.0, gear=gear,
                                       state=state, estop=estop)),  # type: ignore[arg-type]
    ]


def last(out: list, topic: str) -> Any:
    found = [m for t, m in out if t == topic]
    return found[-1] if found else None


def all_of(out: list, topic: str) -> list:
    return [m for t, m in out if t == topic]


def run(node: MoveServer, t0: float, seconds: float, cmds: tuple = (), **kw) -> list:
    """Step ``node`` for ``seconds`` with steady sensors; ``cmds`` on the first step; all outputs."""
    out: list = []
    n = max(1, round(seconds / 0.01))
    for i in range(n):
        inbox = sensors(node.params, **kw)
        if i == 0:
            inbox += [(Topic.MOVE_COMMAND, c) for c in cmds]
        out += node.step(t0 + i * 0.01, inbox)
    return out


def cmd(kind: str = "move", d: float = 10.0, v: float = 3.0, k: float = 0.0, cid: int = 1):
    return MoveCommand(kind=kind, command_id=cid, distance_m=d, maxspeed_mps=v,  # type: ignore[arg-type]
                       curvature_1pm=k)


# ----------------------------------------------------------------------------- table

def test_transition_table_is_closed() -> None:
    for phase, row in TRANSITIONS.items():
        assert phase in PHASES
        for event, target in row.items():
            assert event in EVENTS and target in PHASES
    assert next_phase("moving", None) == "moving"
    assert next_phase("estopped", "stop_cmd") == "estopped"       # a STOP keeps the latch
    assert next_phase("moving", "estop") == "estopped"
    assert "estopped --> starting : command_start" in mermaid_diagram()


# ----------------------------------------------------------------------------- replies

def test_every_command_gets_one_reply(preset) -> None:
    node = MoveServer(preset)
    commands = [cmd(cid=1), cmd("stop", cid=2), cmd(d=math.nan, cid=3),
                cmd(k=1.0, cid=4), cmd("reverse", v=1.0, cid=5)]
    out = node.step(0.0, sensors(preset) + [(Topic.MOVE_COMMAND, c) for c in commands])
    replies = all_of(out, Topic.MOVE_REPLY)
    assert [r.command_id for r in replies] == [1, 2, 3, 4, 5]
    assert [r.code for r in replies] == ["ok", "ok", "invalid", "infeasible", "ok"]
    assert all(isinstance(r, MoveReply) for r in replies)


def test_garbage_on_the_command_topic_is_rejected_not_crashed(preset) -> None:
    node = MoveServer(preset)
    out = node.step(0.0, [*sensors(preset), (Topic.MOVE_COMMAND, "MOVE"), (Topic.MOVE_COMMAND, None)])
    assert [r.code for r in all_of(out, Topic.MOVE_REPLY)] == ["invalid", "invalid"]


def test_not_ready_without_position_or_in_pause(preset) -> None:
    node = MoveServer(preset)
    out = node.step(0.0, [(Topic.MOVE_COMMAND, cmd())])
    assert last(out, Topic.MOVE_REPLY).code == "not_ready"
    out = node.step(0.01, [*sensors(preset, mode="software-pause"), (Topic.MOVE_COMMAND, cmd(cid=2))])
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.code == "not_ready" and "software-pause" in reply.message
    out = node.step(0.02, [*sensors(preset, estop=True), (Topic.MOVE_COMMAND, cmd(cid=3))])
    assert last(out, Topic.MOVE_REPLY).code == "not_ready"


def test_infeasible_on_steep_ground(preset) -> None:
    node = MoveServer(preset)
    out = node.step(0.0, [*sensors(preset, pitch=preset.max_pitch_rad * 1.05), (Topic.MOVE_COMMAND, cmd())])
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.code == "infeasible" and "grade" in reply.message


@pytest.mark.parametrize("speed_mps", [0.2, 3.0, 15.0])
def test_reverse_while_rolling_forward_replaces_the_move_and_stops_first(preset,
                                                                        speed_mps) -> None:
    """Seed 004: the new command replaces the current one at once (issue 31 item 9: it was
    ``busy``). The forward authorization is void (a stop now), the REVERSE's own is published
    for the shift that follows the standstill, and the phase is ``shifting``."""
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0),), speed=speed_mps, odo=0.0)
    out = node.step(0.5, [*sensors(preset, speed=speed_mps, odo=1.0),
                          (Topic.MOVE_COMMAND, cmd("reverse", v=1.0, d=3.0, cid=2))])
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.accepted and reply.code == "ok"
    assert "stopping now" in reply.message and f"{speed_mps:.2f} m/s" in reply.message
    advances = all_of(out, Topic.ADVANCE)
    assert AdvanceAuthorization(source="move", distance_m=0.0, reverse=False,
                                issued_s=0.5) in advances            # the MOVE's end is void
    assert advances[-1].reverse and advances[-1].distance_m > 0.0
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="run", direction="reverse")
    assert last(out, Topic.MOVE_STATUS).phase == "shifting"
    assert last(out, Topic.MOVE_STATUS).command_id == 2


# ----------------------------------------------------------------------------- execution

def test_before_any_command_a_parked_vehicle_stays_parked(preset) -> None:
    node = MoveServer(preset)
    out = node.step(0.0, sensors(preset, state="parked", engine="off", gear=preset.park_gear))
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="parked", direction="forward")
    assert last(out, Topic.ADVANCE).distance_m == 0.0
    assert last(out, Topic.MAX_SPEED).speed_mps == 0.0
    # a STOP does not start the engine either
    out = node.step(0.01, [*sensors(preset, state="parked", engine="off", gear=preset.park_gear), (Topic.MOVE_COMMAND, cmd("stop"))])
    assert last(out, Topic.DRIVE_MODE).state == "parked"


def test_move_from_parked_requests_run_and_authorizes_the_distance(preset) -> None:
    node = MoveServer(preset)
    node.step(0.0, sensors(preset, state="parked", engine="off", gear=preset.park_gear))
    out = node.step(0.01, [*sensors(preset, state="parked", engine="off", gear=preset.park_gear), (Topic.MOVE_COMMAND, cmd(d=30.0, v=8.0, k=-0.02))])
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="run", direction="forward")
    assert last(out, Topic.ADVANCE) == AdvanceAuthorization(source="move", distance_m=30.0,
                                                            issued_s=0.01)
    assert last(out, Topic.MAX_SPEED) == MaxSpeed(source="move", speed_mps=8.0, issued_s=0.01)
    assert last(out, Topic.STEERING) == SteeringRequest(curvature_1pm=-0.02)
    assert last(out, Topic.MOVE_STATUS).phase == "starting"
    # run reached: moving; the authorization is used up by the odometer
    out = run(node, 0.02, 0.1, speed=2.0, odo=12.5)
    assert last(out, Topic.MOVE_STATUS).phase == "moving"
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(17.5)
    assert last(out, Topic.MOVE_STATUS).remaining_m == pytest.approx(17.5)


def test_new_command_replaces_from_where_the_vehicle_is(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.2, (cmd(d=30.0),), speed=3.0, odo=5.0)
    out = run(node, 0.2, 0.05, (cmd(d=12.0, v=4.0, cid=2),), speed=3.0, odo=9.0)
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(12.0)
    assert last(out, Topic.MAX_SPEED).speed_mps == pytest.approx(4.0)
    assert last(out, Topic.MOVE_STATUS).command_id == 2


def test_move_done_when_distance_used_and_standing(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.2, (cmd(d=10.0),), speed=3.0, odo=0.0)
    out = run(node, 0.2, 0.5, speed=0.0, odo=9.8)
    assert last(out, Topic.MOVE_STATUS).phase == "idle"
    assert last(out, Topic.ADVANCE).distance_m == 0.0
    assert last(out, Topic.DRIVE_MODE).state == "run"      # engine kept up for the next command


def test_stop_authorizes_nothing(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.2, (cmd(d=50.0),), speed=3.0, odo=0.0)
    out = run(node, 0.2, 0.05, (cmd("stop", cid=2),), speed=3.0, odo=1.0)
    assert last(out, Topic.ADVANCE).distance_m == 0.0
    assert last(out, Topic.MAX_SPEED).speed_mps == 0.0
    assert last(out, Topic.MOVE_STATUS).phase == "stopping"
    out = run(node, 0.3, 0.5, speed=0.0, odo=3.0)
    assert last(out, Topic.MOVE_STATUS).phase == "idle"


def test_reverse_after_standstill_shifts_and_voids_forward_authorization(preset) -> None:
    node = MoveServer(preset)
    for i in range(21):   # 10 m driven forward: a track the REVERSE may back over (move_radar;
        # 0.5 m a period is 50 m/s: a plausible odometer, so the track is recorded)
        node.step(i * 0.01, [*sensors(preset, speed=50.0 if i < 20 else 0.0, odo=0.5 * i),
                             *([(Topic.MOVE_COMMAND, cmd(d=10.0))] if i == 0 else [])])
    out = node.step(0.21, [*sensors(preset, odo=10.0), (Topic.MOVE_COMMAND, cmd("reverse", d=5.0, v=1.0, cid=2))])
    assert last(out, Topic.MOVE_REPLY).accepted
    advances = all_of(out, Topic.ADVANCE)
    assert AdvanceAuthorization(source="move", distance_m=0.0, reverse=False, issued_s=0.21) in advances
    assert advances[-1] == AdvanceAuthorization(source="move", distance_m=5.0, reverse=True,
                                                issued_s=0.21)
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="run", direction="reverse")
    assert last(out, Topic.MOVE_STATUS).phase == "shifting"
    out = run(node, 0.21, 0.05, speed=-0.5, odo=10.5, gear=preset.reverse_gear)
    assert last(out, Topic.MOVE_STATUS).phase == "moving"


# ----------------------------------------------------------------------------- e-stop

def test_radar_obstacle_inside_stopping_distance_is_an_emergency_stop(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.2, (cmd(d=60.0, v=8.0),), speed=8.0, odo=0.0)
    out = run(node, 0.2, 0.05, speed=8.0, odo=2.0, radar=40.0)
    assert last(out, Topic.DRIVE_MODE).fault == 0               # far away: nothing
    out = node.step(0.3, sensors(preset, speed=8.0, odo=3.0, radar=8.0))
    mode = last(out, Topic.DRIVE_MODE)
    assert mode.fault == node.config.estop_fault_code and mode.state == "run"
    assert last(out, Topic.ADVANCE).distance_m == 0.0
    assert last(out, Topic.MAX_SPEED).speed_mps == 0.0
    notice = last(out, Topic.NOTICE)
    assert isinstance(notice, Notice) and notice.kind == "estop" and notice.source == "move"
    assert notice.reason.startswith("radar: obstacle at 8.0 m inside stopping distance")
    status = last(out, Topic.MOVE_STATUS)
    assert status.phase == "estopped" and status.latched_estop
    # still braking: busy; once stopped the fault is released, the latch stays, idle is held
    out = node.step(0.31, [*sensors(preset, speed=4.0, odo=4.0, radar=7.0), (Topic.MOVE_COMMAND, cmd("reverse", v=1.0, cid=2))])
    assert last(out, Topic.MOVE_REPLY).code == "busy"
    out = run(node, 0.4, 0.5, speed=0.0, odo=5.0, radar=6.0)
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="idle", direction="forward",
                                                    reason="collision e-stop latched")
    assert last(out, Topic.MOVE_STATUS).latched_estop
    out = run(node, 0.9, 0.02, (cmd(d=20.0, cid=3),), speed=0.0, odo=5.0, radar=6.0)
    assert last(out, Topic.MOVE_REPLY).code == "not_ready"
    out = run(node, 1.0, 0.02, (cmd("stop", cid=4),), speed=0.0, odo=5.0, radar=6.0)
    assert last(out, Topic.MOVE_STATUS).latched_estop            # STOP keeps the latch
    # obstacle gone: a new MOVE clears the latch and resumes
    out = run(node, 1.1, 0.02, (cmd(d=20.0, cid=5),), speed=0.0, odo=5.0, state="idle")
    assert last(out, Topic.MOVE_REPLY).accepted
    status = last(out, Topic.MOVE_STATUS)
    assert not status.latched_estop and status.phase == "starting"
    assert last(out, Topic.DRIVE_MODE) == DriveMode(state="run", direction="forward")


@pytest.mark.parametrize("speed", [2.0, 5.0, 8.0, 12.0])
def test_estop_threshold_swept_around_the_stopping_distance(preset, speed: float) -> None:
    probe = MoveServer(preset)
    run(probe, 0.0, 0.05, (cmd(d=100.0, v=speed),), speed=speed)
    from overdrive.dynamics.ellipse import stopping_distance_m
    reach = stopping_distance_m(probe._brake_ellipse(), speed, 0.0, 0.0, 0.0,
                                probe.config.estop_reaction_s) + probe.config.estop_margin_m
    for rng, expect in ((reach + 0.05, False), (reach - 0.05, True)):
        node = MoveServer(preset)
        run(node, 0.0, 0.05, (cmd(d=100.0, v=speed),), speed=speed)
        out = node.step(0.05, sensors(preset, speed=speed, radar=rng))
        assert (last(out, Topic.DRIVE_MODE).fault != 0) is expect


def test_no_estop_for_a_target_while_reversing(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.1, (cmd("reverse", d=5.0, v=1.0),), speed=-1.0,
        gear=preset.reverse_gear, radar=1.0)
    assert node.phase == "moving" and not node.latched


# ----------------------------------------------------------------------------- outputs

def test_estimates_published_at_10_hz(preset) -> None:
    node = MoveServer(preset)
    count = 0
    for i in range(100):
        out = node.step(i * 0.01, sensors(preset))
        count += len(all_of(out, ESTIMATES_TOPIC))
        assert all(isinstance(m, ActuatorEstimates) for m in all_of(out, ESTIMATES_TOPIC))
    assert count == 10


def test_non_finite_sensor_is_ignored_with_a_notice(preset) -> None:
    node = MoveServer(preset)
    node.step(0.0, sensors(preset, odo=3.0))
    bad = GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=math.nan, pitch_rad=0.0,
                 roll_rad=0.0, odometer_m=math.nan)
    out = node.step(0.01, [(Topic.GPS_INS, bad)])
    notices = [n for n in all_of(out, Topic.NOTICE) if n.kind == "rejected"]
    assert notices and notices[0].code == "sensor"
    assert node.odometer_m == 3.0
    assert isinstance(last(out, Topic.MOVE_STATUS), MoveStatus)


def test_speed_reduction_notice_when_it_starts(preset) -> None:
    node = MoveServer(preset)
    steep = preset.max_pitch_rad * 0.8
    run(node, 0.0, 0.3, (cmd(d=50.0, v=4.0),), speed=2.0, pitch=steep)
    out = node.step(0.3, sensors(preset, speed=2.0, pitch=steep))
    assert last(out, Topic.MAX_SPEED).speed_mps < 4.0
    assert all_of(out, Topic.NOTICE) == []   # only on the period it started
    node2 = MoveServer(preset)
    first = node2.step(0.0, [*sensors(preset, speed=2.0, pitch=steep), (Topic.MOVE_COMMAND, cmd(d=50.0, v=4.0))])
    codes = [m.code for m in all_of(first, Topic.NOTICE) if m.kind == "speed_reduction"]
    assert codes == ["steep"]


# ----------------------------------------------------------------------------- ordering

@pytest.mark.parametrize("older", [0, 1, 2])
def test_a_stale_command_never_extends_the_command_in_force(preset, older: int) -> None:
    node = MoveServer(preset)
    out = run(node, 0.0, 0.1, (cmd(d=50.0, v=3.0, cid=2),))
    assert last(out, Topic.MOVE_REPLY).accepted
    out = node.step(0.1, [*sensors(preset), (Topic.MOVE_COMMAND, cmd(d=80.0, v=6.0, cid=older))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.code, reply.command_id, reply.restricted) == \
        (False, "stale", older, False)
    assert "not newer than 2" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(50.0), "the newer command runs on"
    assert last(out, Topic.MAX_SPEED).speed_mps <= 3.0


@pytest.mark.parametrize("older", [0, 1, 2])
@pytest.mark.parametrize(("d", "v"), [(5.0, 3.0), (50.0, 1.0), (5.0, 1.0)])
def test_a_stale_command_that_slows_or_shortens_is_obeyed(preset, older: int, d: float,
                                                          v: float) -> None:
    """What slows or stops is always obeyed: a stale MOVE's closer end and lower max speed
    apply to the command in force (reordered, repeated, or from a restarted planner)."""
    node = MoveServer(preset)
    run(node, 0.0, 0.1, (cmd(d=50.0, v=3.0, cid=2),))
    out = node.step(0.1, [*sensors(preset), (Topic.MOVE_COMMAND, cmd(d=d, v=v, cid=older))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.code, reply.restricted) == (False, "stale", True)
    assert "restricted only" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(min(d, 50.0))
    assert last(out, Topic.MAX_SPEED).speed_mps <= v + 1e-9


def test_a_stale_command_in_the_other_direction_changes_nothing(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.1, (cmd(d=50.0, cid=2),))
    out = node.step(0.1, [*sensors(preset), (Topic.MOVE_COMMAND, cmd("reverse", d=1.0, cid=1))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.code, reply.restricted) == ("stale", False)
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(50.0)
    assert last(out, Topic.DRIVE_MODE).direction == "forward"


@pytest.mark.parametrize("older", [0, 1, 3])
def test_a_stale_stop_is_obeyed_at_once(preset, older: int) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=3),), speed=3.0)
    out = node.step(0.5, [*sensors(preset, speed=3.0), (Topic.MOVE_COMMAND, cmd("stop", cid=older))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.kind, reply.accepted) == ("stop", True)
    assert "a STOP is always obeyed" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == 0.0


def _session_cmd(kind: str = "move", d: float = 10.0, cid: int = 1, session: int = 1,
                 v: float = 3.0) -> MoveCommand:
    return MoveCommand(kind=kind, command_id=cid, session=session, distance_m=d,  # type: ignore[arg-type]
                       maxspeed_mps=v)


def test_a_restarted_planner_is_a_new_session_whose_first_command_goes_through(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (_session_cmd(d=80.0, cid=7, session=11),), speed=3.0)
    out = node.step(0.5, [*sensors(preset, speed=3.0),
                          (Topic.MOVE_COMMAND, _session_cmd(d=20.0, cid=1, session=42))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.session, reply.command_id) == (True, 42, 1)
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(20.0)
    # the new session may also extend: it is the planner now
    out = node.step(0.51, [*sensors(preset, speed=3.0),
                           (Topic.MOVE_COMMAND, _session_cmd(d=60.0, cid=2, session=42))])
    assert last(out, Topic.MOVE_REPLY).accepted
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(60.0)


def test_an_earlier_sessions_late_command_only_restricts(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.2, (_session_cmd(d=80.0, cid=9, session=11),), speed=3.0)
    node.step(0.2, [*sensors(preset, speed=3.0),
                    (Topic.MOVE_COMMAND, _session_cmd(d=30.0, cid=1, session=42))])
    out = node.step(0.21, [*sensors(preset, speed=3.0),   # session 11's MOVE, delayed
                           (Topic.MOVE_COMMAND, _session_cmd(d=90.0, cid=10, session=11))])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.code, reply.session) == (False, "stale", 11)
    assert "not the planner's current session 42" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(30.0)
    out = node.step(0.22, [*sensors(preset, speed=3.0),   # ... and its STOP: obeyed
                           (Topic.MOVE_COMMAND, _session_cmd("stop", cid=11, session=11))])
    assert last(out, Topic.MOVE_REPLY).accepted
    assert last(out, Topic.ADVANCE).distance_m == 0.0


def test_a_session_first_heard_of_late_is_stale_when_issued_before_the_current_newest(
        preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.3, (MoveCommand(kind="move", command_id=1, session=2, distance_m=10.0,
                                     maxspeed_mps=3.0, issued_s=0.0),), speed=2.0)
    late = MoveCommand(kind="move", command_id=5, session=1, distance_m=40.0, maxspeed_mps=3.0,
                       issued_s=-0.1)
    out = node.step(0.3, [*sensors(preset, speed=2.0), (Topic.MOVE_COMMAND, late)])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.code) == (False, "stale") and "before the current" in reply.message
    assert last(out, Topic.ADVANCE).distance_m < 10.0
    newer = MoveCommand(kind="move", command_id=1, session=3, distance_m=20.0, maxspeed_mps=3.0,
                        issued_s=0.29)
    out = node.step(0.31, [*sensors(preset, speed=2.0), (Topic.MOVE_COMMAND, newer)])
    assert last(out, Topic.MOVE_REPLY).accepted, "a later-issued new session is the planner now"


def test_a_stale_command_that_cannot_be_placed_stops(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 1.5, (cmd(d=60.0, cid=5),), speed=3.0)
    old = MoveCommand(kind="move", command_id=2, distance_m=8.0, maxspeed_mps=3.0, issued_s=0.1)
    out = node.step(1.5, [*sensors(preset, speed=3.0), (Topic.MOVE_COMMAND, old)])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.code, reply.restricted) == ("stale", True) and "stopping" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == 0.0


def test_an_invalid_stop_is_still_a_stop(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    bad = MoveCommand(kind="stop", command_id=2, issued_s=float("nan"))
    out = node.step(0.5, [*sensors(preset, speed=3.0), (Topic.MOVE_COMMAND, bad)])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.kind, reply.accepted) == ("stop", True) and "issued_s" in reply.message
    assert last(out, Topic.ADVANCE).distance_m == 0.0


def test_a_stop_outranks_an_earlier_move_delivered_after_it(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    out = node.step(0.5, [*sensors(preset, speed=3.0), (Topic.MOVE_COMMAND, cmd("stop", cid=3)),
                          (Topic.MOVE_COMMAND, cmd(d=80.0, cid=2))])
    replies = all_of(out, Topic.MOVE_REPLY)
    assert [(r.kind, r.accepted, r.code) for r in replies] == [("stop", True, "ok"),
                                                               ("move", False, "stale")]
    assert last(out, Topic.ADVANCE).distance_m == 0.0 and node.phase == "stopping"


def test_a_rejected_command_raises_the_bar_but_a_malformed_one_does_not(preset) -> None:
    node = MoveServer(preset)
    out = node.step(0.0, [*sensors(preset, mode="software-pause"), (Topic.MOVE_COMMAND, cmd(cid=5))])
    assert last(out, Topic.MOVE_REPLY).code == "not_ready"
    out = node.step(0.01, [*sensors(preset), (Topic.MOVE_COMMAND, cmd(cid=5))])
    assert last(out, Topic.MOVE_REPLY).code == "stale", "a repeat of a rejected command"
    bad = MoveCommand(kind="move", command_id=99, distance_m=math.nan, maxspeed_mps=3.0)
    out = node.step(0.02, [*sensors(preset), (Topic.MOVE_COMMAND, bad)])
    assert last(out, Topic.MOVE_REPLY).code == "invalid"
    out = node.step(0.03, [*sensors(preset), (Topic.MOVE_COMMAND, cmd(cid=6))])
    assert last(out, Topic.MOVE_REPLY).accepted, "a malformed id 99 must not lock out id 6"


# ----------------------------------------------------------------------------- interruptions

@pytest.mark.parametrize(("mode", "engine", "hold"), [
    ("estop-pause", "running", "paused"), ("software-pause", "running", "paused"),
    ("manual-override", "running", "paused"), ("manual-override", "off", "parked"),
    ("emergency-manual-override", "running", "paused"), ("estop-disable", "running", "parked"),
    ("estop-disable", "off", "parked")])
def test_an_interruption_discards_the_command_and_holds(preset, mode: str, engine: str,
                                                        hold: str) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    out = node.step(0.5, sensors(preset, speed=3.0, mode=mode, engine=engine))
    notice = last(out, Topic.NOTICE)
    assert (notice.kind, notice.code) == ("interrupted", mode) and "command 1 discarded" in notice.reason
    assert node.phase == "interrupted" and node.active is None
    out = run(node, 0.51, 1.0, mode=mode, engine=engine)
    assert last(out, Topic.DRIVE_MODE).state == hold
    out = run(node, 1.51, 1.0)              # the interruption is over: nothing moves
    assert {m.distance_m for m in all_of(out, Topic.ADVANCE)} == {0.0}
    assert {m.speed_mps for m in all_of(out, Topic.MAX_SPEED)} == {0.0}
    assert last(out, Topic.DRIVE_MODE).state == hold and node.phase == "interrupted"
    out = run(node, 2.51, 0.1, (cmd(d=20.0, cid=2),))
    assert last(out, Topic.MOVE_REPLY).accepted and last(out, Topic.DRIVE_MODE).state == "run"
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(20.0)


def test_commands_during_an_interruption_say_why(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    out = run(node, 0.5, 0.2, (cmd(d=20.0, cid=2),), mode="estop-pause")
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.code == "not_ready" and "estop-pause" in reply.message


def test_losing_computer_speed_control_is_an_interruption(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    inbox = sensors(preset, speed=3.0)
    status = inbox[0][1]
    inbox[0] = (Topic.VEHICLE_STATUS, VehicleStatus(**{
        **{f: getattr(status, f) for f in status.__struct_fields__}, "computer_speed": False}))
    out = node.step(0.5, inbox)
    assert last(out, Topic.NOTICE).kind == "interrupted" and node.phase == "interrupted"


def test_no_interruption_before_any_command(preset) -> None:
    """A vehicle found in a pause at start-up (an XGV before control is taken) is not 'interrupted'."""
    node = MoveServer(preset)
    out = run(node, 0.0, 0.5, mode="software-pause")
    assert node.phase == "idle" and not [n for n in all_of(out, Topic.NOTICE) if n.kind == "interrupted"]


def test_a_radar_estop_is_not_overridden_by_an_interruption(preset) -> None:
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=80.0, v=8.0, cid=1),), speed=8.0)
    run(node, 0.5, 0.05, speed=8.0, radar=3.0)
    assert node.phase == "estopped"
    run(node, 0.55, 0.2, speed=4.0, mode="estop-pause", radar=3.0)
    assert node.phase == "estopped" and node.latched



# ----------------------------------------------------------------------------- anchored in time

@pytest.mark.parametrize("delay_s", [0.0, 0.2, 0.5])
def test_a_command_counts_from_where_the_vehicle_was_when_it_was_issued(preset, delay_s: float) -> None:
    node = MoveServer(preset)
    odo = 0.0
    for i in range(100):                               # driving at 5 m/s for 1 s
        node.step(i * 0.01, sensors(preset, speed=5.0, odo=odo))
        odo += 0.05
    issued_s = 1.0 - delay_s
    late = MoveCommand(kind="move", command_id=1, distance_m=20.0, maxspeed_mps=5.0,
                       issued_s=issued_s)
    out = node.step(1.0, [*sensors(preset, speed=5.0, odo=odo), (Topic.MOVE_COMMAND, late)])
    assert last(out, Topic.MOVE_REPLY).accepted
    travelled = 5.0 * delay_s
    assert last(out, Topic.ADVANCE).distance_m == pytest.approx(20.0 - travelled, abs=0.051)


@pytest.mark.parametrize(("age_s", "code", "why"), [(1.2, "stale", "stale"),
                                             (-0.5, "clock", "ahead of this server's")])
def test_a_stale_or_future_dated_command_is_refused(preset, age_s: float, code: str,
                                                    why: str) -> None:
    """Too old: stale. Dated ahead of this clock by more than the step phase, from a planner
    that echoes no MoveStatus (so its offset is not measured): a time refusal, saying so."""
    node = MoveServer(preset)
    run(node, 0.0, 1.5)
    bad = MoveCommand(kind="move", command_id=1, distance_m=20.0, maxspeed_mps=5.0,
                      issued_s=1.5 - age_s)
    out = node.step(1.5, [*sensors(preset), (Topic.MOVE_COMMAND, bad)])
    reply = last(out, Topic.MOVE_REPLY)
    assert (reply.accepted, reply.code) == (False, code) and why in reply.message


@pytest.mark.parametrize(("speed", "distance", "short"), [(9.9, 2.0, True), (9.9, 12.0, False),
                                                          (3.0, 0.5, True), (3.0, 2.0, False)])
def test_a_command_shorter_than_the_shortest_stop_is_accepted_with_a_warning(
        preset, speed: float, distance: float, short: bool) -> None:
    """Seed 004's "vehicle not in the expected position": executed (hard braking), and the
    reply and a notice say how far past its end the vehicle will stop."""
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=100.0, v=10.0, cid=1),), speed=speed)
    out = node.step(0.5, [*sensors(preset, speed=speed), (Topic.MOVE_COMMAND, cmd(d=distance, v=10.0, cid=2))])
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.accepted
    notices = [n for n in all_of(out, Topic.NOTICE) if n.kind == "short_command"]
    assert bool(notices) == short and ("vehicle not in the expected position" in reply.message) == short
    if short:
        assert "expect an overrun" in notices[0].reason


# ----------------------------------------------------------------------------- sensor input

DT_S = 0.01
BAD_NUMBERS = (math.nan, math.inf, -math.inf)
GPS_FIELDS = ("x_m", "y_m", "heading_rad", "speed_mps", "pitch_rad", "roll_rad", "odometer_m")


@pytest.mark.parametrize("field", GPS_FIELDS)
@pytest.mark.parametrize("bad", BAD_NUMBERS)
def test_move_server_refuses_a_gps_ins_with_any_non_finite_field(field: str, bad: float) -> None:
    node = MoveServer(PRESETS["escape-hybrid"])
    good = gps_ins(x_m=1.0, odometer_m=1.0)
    node.step(0.0, [(Topic.GPS_INS, good)])
    out = node.step(DT_S, [(Topic.GPS_INS, gps_ins(**{"x_m": 1.0, "odometer_m": 1.0,
                                                      field: bad}))])
    rejected = [n for t, n in out if t == Topic.NOTICE and n.kind == "rejected"]
    assert rejected and rejected[0].code == "sensor"
    assert node.gps == good


def _with_speed_state(inbox: list, **fields: Any) -> list:
    return [(t, msgspec.structs.replace(m, **fields) if t == Topic.SPEED_STATE else m)
            for t, m in inbox]


@pytest.mark.parametrize(("fields", "code"), [
    ({"unasked_stops": 2}, "unasked_stop"),
    ({"unasked_stops": 1, "fault": 1001}, "watchdog"),
    ({"started_s": 0.4}, "restart"),
    ({"started_s": -5.0}, "restart")], ids=["jump-of-2", "cause-still-shown", "later-start",
                                            "start-on-a-clock-behind"])
def test_a_stop_seen_only_in_the_count_or_the_start_interrupts(preset, fields: dict,
                                                              code: str) -> None:
    """Every report of a speed server's stop lost (``SpeedState`` is droppable): the count
    rose, by one or more, or the server restarted (its ``started_s`` changed). The command
    is discarded all the same; nothing moves until a new command."""
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    out = node.step(0.5, _with_speed_state(sensors(preset, speed=3.0), **fields))
    notice = last(out, Topic.NOTICE)
    assert (notice.kind, notice.code) == ("interrupted", code) and node.active is None
    out = run(node, 0.51, 1.0)
    assert {m.distance_m for m in all_of(out, Topic.ADVANCE)} == {0.0}


def test_an_old_speed_state_arriving_late_is_no_stop(preset) -> None:
    """A report with a lower count from the same start is an old one, reordered: no news."""
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    node.step(0.5, _with_speed_state(sensors(preset, speed=3.0), unasked_stops=1))
    out = run(node, 0.51, 0.5, (cmd(d=50.0, cid=2),), speed=3.0)
    assert last(out, Topic.MOVE_REPLY).accepted
    out = node.step(1.01, _with_speed_state(sensors(preset, speed=3.0), unasked_stops=0))
    assert not [n for n in all_of(out, Topic.NOTICE) if n.kind == "interrupted"]
    assert node.active is not None


def test_an_old_speed_state_arriving_late_still_stops_when_it_reports_an_estop(preset) -> None:
    """A reordered report (lower count, same start) is not the state now, but the e-stop it
    reports is obeyed: what stops is never stale."""
    node = MoveServer(preset)
    run(node, 0.0, 0.5, (cmd(d=50.0, cid=1),), speed=3.0)
    node.step(0.5, _with_speed_state(sensors(preset, speed=3.0), unasked_stops=2))
    out = run(node, 0.51, 0.5, (cmd(d=50.0, cid=2),), speed=3.0)
    assert last(out, Topic.MOVE_REPLY).accepted
    out = node.step(1.01, _with_speed_state(sensors(preset, speed=3.0), unasked_stops=1,
                                            estop=True, estop_code=1001))
    notice = last(out, Topic.NOTICE)
    assert (notice.kind, notice.code) == ("interrupted", "watchdog") and node.active is None


def test_a_reverse_with_no_track_behind_is_clamped_to_the_blind_allowance_and_says_so(
        preset) -> None:
    """No rear sensor: a REVERSE from where the vehicle has not driven forward is accepted,
    clamped to ``reverse_blind_m``, and the reply says so (the planner is told)."""
    node = MoveServer(preset)
    out = run(node, 0.0, 0.5, (cmd(kind="reverse", d=5.0, v=1.0),))
    reply = last(out, Topic.MOVE_REPLY)
    assert reply.accepted and "distance clamped to 1.00 m" in reply.message
