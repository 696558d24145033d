"""Unit tests of the radar corridor (``servers/move_radar.py``): geometry, memory, health,
reverse limits. Thresholds swept just inside / just outside."""

from __future__ import annotations

import math

import pytest

from overdrive.messages import (
    AdvanceAuthorization,
    GpsIns,
    MoveCommand,
    Radar,
    SpeedState,
    Topic,
    VehicleStatus,
    WheelSpeed,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.move import MoveServer
from overdrive.servers.move_radar import (
    RadarConfig,
    RadarCorridor,
    RadarFault,
    in_corridor,
    path_offset,
)
from tests.conftest import PRESET_NAMES
from tests.sensor_messages import gps_ins, imu

CFG = RadarConfig()
DT = 0.01


def gps(x: float = 0.0, y: float = 0.0, h: float = 0.0, v: float = 0.0,
        odo: float | None = None) -> GpsIns:
    return GpsIns(x_m=x, y_m=y, heading_rad=h, speed_mps=v, pitch_rad=0.0, roll_rad=0.0,
                  odometer_m=x if odo is None else odo)


def radar(range_m: float | None = None, bearing: float | None = 0.0, seq: int | None = None,
          max_m: float = 100.0) -> Radar:
    return Radar(target=range_m is not None, range_m=max_m if range_m is None else range_m,
                 bearing_rad=bearing, seq=seq)


def corridor(preset: str = "escape-hybrid") -> RadarCorridor:
    return RadarCorridor(PRESETS[preset])


def drive(c: RadarCorridor, t0: float, x0: float, x1: float, v: float, target_xy=None,
          ks=(0.0,), seq0: int | None = None) -> float:
    """Drive straight from x0 to x1 (heading +x) with a static point target; returns the time."""
    p = c.params
    front = p.length_m - p.rear_overhang_m
    n = max(1, round(abs(x1 - x0) / (v * DT)))
    t = t0
    for i in range(n + 1):
        x = x0 + (x1 - x0) * i / n
        msg = radar(seq=None if seq0 is None else seq0 + i)
        if target_xy is not None:
            dx, dy = target_xy[0] - (x + front), target_xy[1]
            bearing = math.atan2(dy, dx)
            if dx > 0 and abs(bearing) <= p.radar_half_angle_rad:
                msg = radar(math.hypot(dx, dy), bearing, None if seq0 is None else seq0 + i)
        c.receive(t, msg)
        c.update(t, gps(x, v=v), ks, True)
        t += DT
    return t


# --------------------------------------------------------------------------- geometry

@pytest.mark.parametrize("k", [0.0, 0.02, -0.05, 0.15])
def test_points_on_the_arc_are_on_its_centre_line_at_their_path_distance(k: float) -> None:
    front = 3.5
    for s in (5.0, 10.0, 20.0):
        if k == 0.0:
            along, left = s, 0.0
        else:
            r = 1.0 / k
            along, left = abs(r) * math.sin(s / abs(r)), -r * (1.0 - math.cos(s / abs(r)))
        dist, offset, outer = path_offset(along, left, k, front, 0.9)
        assert offset == pytest.approx(0.0, abs=1e-9)
        assert dist <= s - front + 1e-9, "never later than the axle's arc length less the front"
        assert dist >= s - front - 0.5
        assert outer >= 0.9


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("k", [0.0, 0.03, -0.1])
def test_the_corridor_edge_is_half_width_plus_margin(preset: str, k: float) -> None:
    p = PRESETS[preset]
    hw = 0.5 * p.width_m
    edge = hw + CFG.corridor_margin_m
    assert in_corridor(-(edge - 0.01), hw, hw, CFG.corridor_margin_m, k)
    assert not in_corridor(-(edge + 0.01), hw, hw, CFG.corridor_margin_m, k)
    outer = path_offset(10.0, 0.0, k, p.length_m - p.rear_overhang_m, hw)[2]
    assert in_corridor(outer + CFG.corridor_margin_m - 0.01, outer, hw, CFG.corridor_margin_m, k)
    assert not in_corridor(outer + CFG.corridor_margin_m + 0.01, outer, hw, CFG.corridor_margin_m, k)


# --------------------------------------------------------------------------- memory

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("offset_m", [0.0, 0.85, -1.0, 1.5, -1.6])
def test_a_target_that_left_the_cone_is_remembered_until_passed(preset: str,
                                                                offset_m: float) -> None:
    p = PRESETS[preset]
    edge = 0.5 * p.width_m + CFG.corridor_margin_m
    inside = abs(offset_m) <= edge
    c = corridor(preset)
    front = p.length_m - p.rear_overhang_m
    target = (40.0, offset_m)
    drive(c, 0.0, 0.0, 30.0, 5.0, target)
    along = 40.0 - 30.0 - front          # leaves the cone near 0.85 / tan(6 deg) = 8 m
    assert c.nearest_m == (pytest.approx(along, abs=0.05) if inside else math.inf)
    drive(c, 7.0, 30.0, 40.0 - front + 0.5, 5.0, target)   # passed
    assert c.nearest_m == math.inf and not c.targets


def test_a_reading_without_a_bearing_is_placed_on_the_centre_line() -> None:
    c = corridor()
    c.receive(0.0, radar(20.0, bearing=None))
    c.update(0.0, gps(), (0.0,), True)
    assert c.nearest_m == pytest.approx(20.0)


def test_a_remembered_target_is_forgotten_when_the_radar_sees_through_its_place() -> None:
    c = corridor()
    c.receive(0.0, radar(20.0))
    c.update(0.0, gps(), (0.0,), True)
    c.receive(0.01, radar(20.0 + CFG.see_through_m - 0.05))   # not far enough beyond: kept
    c.update(0.01, gps(), (0.0,), True)
    assert len(c.targets) == 2 and c.nearest_m == pytest.approx(20.0)
    c.receive(0.02, radar(None))                              # nothing: it is gone
    c.update(0.02, gps(), (0.0,), True)
    assert c.targets == [] and c.nearest_m == math.inf


def test_a_target_beyond_the_nearest_one_is_not_forgotten() -> None:
    c = corridor()
    c.receive(0.0, radar(30.0))
    c.update(0.0, gps(), (0.0,), True)
    c.receive(0.01, radar(10.0))          # a nearer one hides it
    c.update(0.01, gps(), (0.0,), True)
    assert len(c.targets) == 2 and c.nearest_m == pytest.approx(10.0)


@pytest.mark.parametrize("k", [0.02, -0.02])
def test_the_corridor_follows_the_commanded_and_the_measured_arc(k: float) -> None:
    """A target straight ahead at 25 m is off an arc of 50 m radius but on the straight path the
    steering still has: judged in the union."""
    c = corridor()
    c.receive(0.0, radar(25.0))
    c.update(0.0, gps(), (k,), True)
    assert c.nearest_m == math.inf
    c.receive(0.01, radar(25.0))
    c.update(0.01, gps(), (k, 0.0), True)
    assert c.nearest_m == pytest.approx(25.0)


def test_memory_is_bounded() -> None:
    c = corridor()
    for i in range(3 * CFG.max_targets):
        c.receive(i * DT, radar(90.0 - i, bearing=0.05 * (-1) ** i))
        c.update(i * DT, gps(), (0.0,), True)
    assert len(c.targets) <= CFG.max_targets


# --------------------------------------------------------------------------- health

@pytest.mark.parametrize("gap_s", [CFG.timeout_s - 0.02, CFG.timeout_s + 0.02])
def test_silence_beyond_the_timeout_is_fault_1151_once(gap_s: float) -> None:
    c = corridor()
    c.receive(0.0, radar(seq=1))
    assert c.update(0.0, gps(), (0.0,), True) == []
    notices = []
    t = 0.0
    while t < gap_s - 1e-9:
        t += DT
        notices += c.update(t, gps(), (0.0,), True)
    late = gap_s > CFG.timeout_s
    assert [int(n.code) for n in notices] == ([RadarFault.SILENT] if late else [])
    assert (c.fault == RadarFault.SILENT) is late


def test_a_repeated_alive_counter_is_fault_1152() -> None:
    c = corridor()
    notices = []
    for i in range(40):
        c.receive(i * DT, radar(seq=7))
        notices += c.update(i * DT, gps(), (0.0,), True)
    assert [int(n.code) for n in notices] == [RadarFault.FROZEN]
    assert notices[0].kind == "fault" and notices[0].source == "move"


@pytest.mark.parametrize(("travel_m", "frozen"), [(CFG.frozen_travel_m - 0.05, False),
                                                  (CFG.frozen_travel_m + 0.05, True)])
def test_an_unchanged_target_range_while_travelling_is_frozen(travel_m: float, frozen: bool) -> None:
    """No alive counter: the same target range repeated while the vehicle travels."""
    c = corridor()
    n = 20
    for i in range(n + 1):
        c.receive(i * DT, radar(30.0))
        c.update(i * DT, gps(x=travel_m * i / n), (0.0,), True)
    assert (c.fault == RadarFault.FROZEN) is frozen


def test_an_unchanged_target_range_at_a_standstill_is_not_frozen() -> None:
    c = corridor()
    for i in range(300):
        c.receive(i * DT, radar(30.0))
        c.update(i * DT, gps(), (0.0,), True)
    assert c.fault is None


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_untrusted_radar_caps_the_authorization_to_the_range_last_seen_clear(preset: str) -> None:
    c = corridor(preset)
    c.receive(0.0, radar(40.0, seq=1))
    c.update(0.0, gps(odo=5.0), (0.0,), True)
    assert c.forward_cap_m(5.0, 2.0) == math.inf
    c.update(0.5, gps(x=3.0, odo=8.0), (0.0,), True)      # silent
    assert c.fault == RadarFault.SILENT
    assert c.forward_cap_m(8.0, 2.0) == pytest.approx(40.0 - 3.0 - 2.0 - CFG.hold_gap_m)
    assert c.forward_cap_m(50.0, 2.0) == 0.0
    fresh = corridor(preset)
    fresh.update(0.5, gps(), (0.0,), True)                 # never heard
    assert fresh.forward_cap_m(0.0, 2.0) == 0.0


# --------------------------------------------------------------------------- reverse limits

def reverse(distance_m: float, speed_mps: float = 1.0, k: float = 0.0) -> MoveCommand:
    return MoveCommand(kind="reverse", command_id=1, distance_m=distance_m,
                       maxspeed_mps=speed_mps, curvature_1pm=k)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_reverse_with_nothing_verified_is_clamped_to_the_blind_allowance(preset: str) -> None:
    c = corridor(preset)
    clamped, note = c.clamp_reverse(reverse(12.0, CFG.reverse_max_speed_mps + 1.0), gps())
    assert clamped.distance_m == pytest.approx(CFG.reverse_blind_m)
    assert clamped.maxspeed_mps == CFG.reverse_max_speed_mps
    assert "no rear sensor" in note
    same, note = c.clamp_reverse(reverse(CFG.reverse_blind_m - 0.01, 1.0), gps())
    assert same == reverse(CFG.reverse_blind_m - 0.01, 1.0) and note == ""
    move = MoveCommand(kind="move", command_id=1, distance_m=50.0, maxspeed_mps=10.0)
    assert c.clamp_reverse(move, gps()) == (move, "")


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("k", [0.0, 0.05])
def test_the_own_forward_track_is_verified_clear_for_a_reverse_that_retraces_it(preset: str,
                                                                              k: float) -> None:
    c = corridor(preset)
    x = y = h = 0.0
    odo = 0.0
    while odo < 20.0:      # forward along the arc of k
        c.record_trail(gps(x, y, h, v=2.0, odo=odo), 1)
        dh = -k * 0.02
        x += 0.02 * math.cos(h + 0.5 * dh)
        y += 0.02 * math.sin(h + 0.5 * dh)
        h += dh
        odo += 0.02
    here = gps(x, y, h, odo=odo)
    assert c.rear_clear_m(here, k) == pytest.approx(20.0, abs=0.6)
    other = c.rear_clear_m(here, -0.1 if k == 0.0 else 0.0)
    assert other < 6.0, "a REVERSE off the track is verified only while it stays on it"
    c.record_trail(gps(x, y, h, v=-1.0, odo=odo + 1.0), -1)        # reversing records nothing
    assert c.rear_clear_m(here, k) == pytest.approx(20.0, abs=0.6)


def test_a_new_reverse_continues_the_allowance_of_the_reverse_under_way() -> None:
    """The blind metre is granted once per reverse, not again by every REVERSE of a stream;
    forward travel of the blind allowance starts a new reverse."""
    c = corridor()
    first, _ = c.clamp_reverse(reverse(12.0), gps(odo=0.0))
    assert first.distance_m == pytest.approx(CFG.reverse_blind_m)
    c.record_trail(gps(x=-0.6, odo=0.6, v=-1.0), -1)
    again, _ = c.clamp_reverse(reverse(12.0), gps(x=-0.6, odo=0.6))
    assert again.distance_m == pytest.approx(CFG.reverse_blind_m - 0.6)
    for i in range(1, 12):   # forward 1.1 m: a new reverse (over that track, plus the blind metre)
        c.record_trail(gps(x=-0.6 + 0.1 * i, odo=0.6 + 0.1 * i, v=1.0), 1)
    fresh, _ = c.clamp_reverse(reverse(12.0), gps(x=0.5, odo=1.7))
    assert fresh.distance_m == pytest.approx(1.0 + CFG.reverse_blind_m, abs=0.3)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("noise_mps", [0.0, 0.06])
def test_a_second_reverse_of_a_stream_continues_along_the_track_after_a_standstill(
        preset: str, noise_mps: float) -> None:
    """Forward 20 m, REVERSE 4 m, stand, REVERSE 12 m: the second is granted along the track.
    Found by tests/safety/test_faults_rollback.py: GPS speed noise at the standstill (above the
    move server's 0.05 m/s) read as forward and put a trail point where the vehicle stood,
    cutting the track: the second REVERSE was clamped to 0 m."""
    c = corridor(preset)
    for i in range(0, 1001):
        c.record_trail(gps(x=0.02 * i, v=2.0), 1)
    first, _ = c.clamp_reverse(reverse(4.0), gps(x=20.0))
    assert first.distance_m == 4.0
    for i in range(1, 201):
        c.record_trail(gps(x=20.0 - 0.02 * i, odo=20.0 + 0.02 * i, v=-1.0), -1)
    for _ in range(100):     # standing after the reverse; noise may read as forward
        c.record_trail(gps(x=16.0, odo=24.0, v=noise_mps), 1 if noise_mps > 0.05 else 0)
    second, note = c.clamp_reverse(reverse(12.0), gps(x=16.0, odo=24.0))
    assert second.distance_m == 12.0, note
    over, _ = c.clamp_reverse(reverse(30.0), gps(x=16.0, odo=24.0))
    assert over.distance_m == pytest.approx(20.0 - 4.0 + CFG.reverse_blind_m, abs=0.6)


def test_forward_travel_after_a_reverse_is_tracked_from_where_it_began() -> None:
    """REVERSE 1 m (nothing verified), stand (noise reads as forward), MOVE 20 m, REVERSE 25 m:
    the track covers the 20 m from the start of the MOVE (scenario reverse-unreported-obstacle)."""
    c = corridor()
    c.record_trail(gps(x=0.0, odo=0.0, v=0.06), 1)           # noise at the ready start
    c.clamp_reverse(reverse(12.0), gps())
    for i in range(1, 51):
        c.record_trail(gps(x=-0.02 * i, odo=0.02 * i, v=-1.0), -1)
    for _ in range(50):
        c.record_trail(gps(x=-1.0, odo=1.0, v=0.06), 1)
    for i in range(1, 1001):
        c.record_trail(gps(x=-1.0 + 0.02 * i, odo=1.0 + 0.02 * i, v=2.0), 1)
    clamped, _ = c.clamp_reverse(reverse(25.0), gps(x=19.0, odo=21.0))
    assert clamped.distance_m == pytest.approx(20.0 + CFG.reverse_blind_m, abs=0.1)


# --------------------------------------------------------------------------- untrusted pose

def move_inbox(params, *, speed: float, odo: float, wheel_mps: float | None, radar: bool,
               i: int) -> list:
    gear = params.drive_gear
    inbox = [
        (Topic.VEHICLE_STATUS, VehicleStatus(
            gear=gear, shifting=False, engine="running", engine_rpm=1000.0, start_failed=False,
            traction_control=False, steer_pct=0.0, throttle_pct=0.0, brake_pct=0.0,
            safety_mode="drive-by-wire")),
        (Topic.GPS_INS, gps_ins(x_m=odo, speed_mps=speed, odometer_m=odo)),
        (Topic.IMU, imu(1e-4 * (i % 7))),
        (Topic.SPEED_STATE, SpeedState(speed_mps=speed, accel_mps2=0.0, gear=gear, state="run")),
    ]
    if wheel_mps is not None:
        inbox.append((Topic.WHEEL_SPEED, WheelSpeed(speed_mps=wheel_mps + 1e-4 * (i % 5))))
    if radar:
        inbox.append((Topic.RADAR, Radar(target=False, range_m=params.radar_range_m)))
    return inbox


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_untrusted_radar_cap_shrinks_with_progress_when_the_gps_freezes(preset: str) -> None:
    """Radar silent and GPS/INS frozen together while the wheels say 2 m/s: the forward
    authorization cap must shrink with the wheels' travel (it stood still on the raw odometer)."""
    params = PRESETS[preset]
    node = MoveServer(params)
    speed = 2.0
    odo = 0.0
    for i in range(50):                    # healthy: radar clear, GPS and wheels agree
        inbox = move_inbox(params, speed=speed, odo=odo, wheel_mps=speed, radar=True, i=i)
        if i == 0:
            inbox.append((Topic.MOVE_COMMAND, MoveCommand(kind="move", command_id=1,
                                                          distance_m=150.0, maxspeed_mps=3.0)))
        node.step(i * DT, inbox)
        odo += speed * DT
    caps = []
    for i in range(50, 350):               # radar silent, GPS frozen, the wheels go on
        out = node.step(i * DT, move_inbox(params, speed=speed, odo=odo, wheel_mps=speed,
                                           radar=False, i=i))
        adv = [m for t, m in out if t == Topic.ADVANCE and isinstance(m, AdvanceAuthorization)]
        caps.append(adv[-1].distance_m)
    travelled_m = speed * 300 * DT         # 6 m by the wheels
    assert caps[-1] <= caps[30] - (travelled_m - 0.6 - 1.0)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("outlier_m", [3.0, 20.0, 60.0, -60.0])
def test_a_remembered_target_survives_one_outlier_pose(preset: str, outlier_m: float) -> None:
    params = PRESETS[preset]
    c = RadarCorridor(params)
    front = params.length_m - params.rear_overhang_m
    target_x = 30.0
    x = 0.0
    for i in range(10):                    # the target dead ahead, seen
        c.receive(i * DT, Radar(target=True, range_m=target_x - x - front, bearing_rad=0.0))
        c.update(i * DT, gps_ins(x_m=x, speed_mps=1.0, odometer_m=x), (0.0,), True)
        x += 0.01
    seen = c.nearest_m
    # one period without a radar reading and a pose `outlier_m` off (odometer consistent)
    c.update(0.10, gps_ins(x_m=x + outlier_m, speed_mps=1.0, odometer_m=x), (0.0,), True)
    assert c.nearest_m == pytest.approx(seen, abs=0.05)
    x += 0.01
    c.update(0.11, gps_ins(x_m=x, speed_mps=1.0, odometer_m=x), (0.0,), True)
    assert c.nearest_m == pytest.approx(seen - 0.01, abs=0.05)
