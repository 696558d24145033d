"""Hard braking (issue 17): when what is left of the authorization is shorter than a normal stop,
the driving module asks for a full-brake stop at once, without waiting for the SPSS period, and
the SPSS stream keeps its 100 ms cadence; an ordinary MOVE (a whole run uphill) never needs it."""

from __future__ import annotations

import itertools

import pytest

from overdrive.messages import AdvanceAuthorization, Notice, SetSpeed, Topic
from overdrive.servers.driving import DrivingModule
from tests.servers.driving_harness import DT_S, outputs, sensors
from tests.servers.move_harness import events_of, move
from tests.servers.move_harness import run_events as run


def drive(node: DrivingModule, t0: float, seconds: float, speed: float, odo: float,
          extra: list | None = None) -> tuple[list, float]:
    out: list = []
    n = round(seconds / DT_S)
    for i in range(n):
        inbox = sensors(node.params, speed_mps=speed, odometer_m=odo)
        if i == 0 and extra:
            inbox += extra
        out += [(t0 + i * DT_S, topic, msg) for topic, msg in node.step(t0 + i * DT_S, inbox)]
        odo += speed * DT_S
    return out, odo


def spss_times(out: list) -> list[float]:
    return [t for t, topic, _ in out if topic == Topic.SET_SPEED]


@pytest.mark.parametrize("speed", [3.0, 8.0, 12.0])
def test_a_cut_below_a_normal_stop_asks_for_full_brake_at_once(preset, speed: float) -> None:
    node = DrivingModule(preset)
    out, odo = drive(node, 0.0, 1.05, speed, 0.0,
                     [(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=500.0))])
    cut, odo = drive(node, 1.05, 0.5, speed, odo,
                     [(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=1.0))])
    first_t, _, first = next((t, topic, m) for t, topic, m in cut if topic == Topic.SET_SPEED)
    assert first_t == pytest.approx(1.05), "sent in the period the cut arrived, not at the next slot"
    assert (first.speed_mps, first.accel_mps2) == (0.0, preset.max_brake_decel_mps2)
    notices = [m for _, topic, m in cut if topic == Topic.NOTICE and m.kind == "hard_brake"]
    assert len(notices) == 1 and "braking with everything" in notices[0].reason
    times = spss_times(out + cut)
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert max(gaps) <= 0.1 + 1e-9, "an urgent SPSS never opens a gap in the stream"


def test_a_normal_approach_never_hard_brakes(preset) -> None:
    """Following its own braking curve the module never needs the hard path."""
    node = DrivingModule(preset)
    odo, speed = 0.0, 0.0
    events: list[Notice] = []
    t = 0.0
    for i in range(3000):
        inbox = sensors(preset, speed_mps=speed, odometer_m=odo)
        if i == 0:
            inbox.append((Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=40.0)))
        out = node.step(t, inbox)
        spss = outputs(out, Topic.SET_SPEED)
        if spss:
            goal: SetSpeed = spss[-1]
        events += [m for m in outputs(out, Topic.NOTICE) if m.kind == "hard_brake"]
        # an ideal vehicle: follows the SPSS at its rate
        if speed < goal.speed_mps:
            speed = min(goal.speed_mps, speed + goal.accel_mps2 * DT_S)
        else:
            speed = max(goal.speed_mps, speed - goal.accel_mps2 * DT_S)
        odo += speed * DT_S
        t += DT_S
    assert events == [] and 39.0 < odo <= 40.0


@pytest.mark.parametrize("noise", [0.05, 0.1, 0.14])
def test_no_hard_brake_for_a_standing_vehicles_speed_noise(preset, noise: float) -> None:
    node = DrivingModule(preset)
    out, _ = drive(node, 0.0, 1.0, noise, 0.0,
                   [(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=0.0))])
    assert not [m for _, topic, m in out if topic == Topic.NOTICE and m.kind == "hard_brake"]


# --------------------------------------------------------------------------- anchored in time

@pytest.mark.parametrize("delay_s", [0.0, 0.1, 0.5])
def test_an_authorization_counts_from_where_the_vehicle_was_when_issued(preset, delay_s: float) -> None:
    node = DrivingModule(preset)
    _, odo = drive(node, 0.0, 1.0, 5.0, 0.0)
    late = AdvanceAuthorization(source="lidar", distance_m=30.0, issued_s=1.0 - delay_s)
    out, _ = drive(node, 1.0, 0.01, 5.0, odo, [(Topic.ADVANCE, late)])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(30.0 - 5.0 * delay_s, abs=0.051)


@pytest.mark.parametrize(("issued_s", "why"), [(0.2, "stale"), (2.0, "in the future")])
def test_a_stale_or_future_dated_authorization_holds_its_source_at_zero(preset, issued_s: float,
                                                                        why: str) -> None:
    node = DrivingModule(preset)
    _, odo = drive(node, 0.0, 1.5, 0.0, 0.0,
                   [(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=30.0,
                                                         issued_s=0.0))])
    bad = AdvanceAuthorization(source="lidar", distance_m=50.0, issued_s=issued_s)
    out, _ = drive(node, 1.5, 0.01, 0.0, odo, [(Topic.ADVANCE, bad)])
    rejected = [m for _, topic, m in out if topic == Topic.NOTICE and m.kind == "rejected"]
    assert rejected and why in rejected[0].reason
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == 0.0, "fail-safe: the source's authorization is void"


# --------------------------------------------------------------------------- ordering per source

def test_an_older_or_repeated_authorization_from_a_source_is_refused(preset) -> None:
    node = DrivingModule(preset)
    newer = AdvanceAuthorization(source="lidar", distance_m=5.0, issued_s=0.5)
    older = AdvanceAuthorization(source="lidar", distance_m=50.0, issued_s=0.4)
    out, odo = drive(node, 0.5, 0.01, 0.0, 0.0, [(Topic.ADVANCE, newer)])
    out, _ = drive(node, 0.51, 0.05, 0.0, odo, [(Topic.ADVANCE, older), (Topic.ADVANCE, newer)])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(5.0), "the newer, shorter one stands"
    rejected = [m for _, topic, m in out if topic == Topic.NOTICE and m.kind == "rejected"]
    assert len(rejected) == 1 and "reordered" in rejected[0].reason
    other = AdvanceAuthorization(source="map", distance_m=3.0, issued_s=0.52)
    out, _ = drive(node, 0.6, 0.01, 0.0, odo, [(Topic.ADVANCE, other)])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(3.0), "ordering is per source"


def test_an_older_speed_limit_from_a_source_is_refused(preset) -> None:
    from overdrive.messages import MaxSpeed

    node = DrivingModule(preset)
    drive(node, 0.0, 0.01, 0.0, 0.0, [(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=2.0,
                                                                  issued_s=0.0))])
    out, _ = drive(node, 0.01, 0.01, 0.0, 0.0,
                   [(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=9.0, issued_s=-0.05))])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.speed_limit_mps == pytest.approx(2.0)



@pytest.mark.parametrize("older_m", [2.0, 4.9, 5.0, 50.0])
def test_an_older_authorization_still_brings_its_sources_end_closer(preset, older_m: float) -> None:
    """What slows or stops is always obeyed: a reordered authorization is not taken as the
    source's newest, but an end closer than the one in force applies."""
    node = DrivingModule(preset)
    _, odo = drive(node, 0.0, 0.5, 0.0, 0.0, [])    # odometer history from t=0
    newer = AdvanceAuthorization(source="lidar", distance_m=5.0, issued_s=0.5)
    older = AdvanceAuthorization(source="lidar", distance_m=older_m, issued_s=0.45)
    _, odo = drive(node, 0.5, 0.01, 0.0, odo, [(Topic.ADVANCE, newer)])
    out, _ = drive(node, 0.51, 0.02, 0.0, odo, [(Topic.ADVANCE, older)])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(min(older_m, 5.0))


def test_an_older_authorization_that_cannot_be_placed_holds_its_source(preset) -> None:
    """Issued before the module's first odometer reading: where its end lies is unknown."""
    node = DrivingModule(preset)
    newer = AdvanceAuthorization(source="lidar", distance_m=5.0, issued_s=0.5)
    older = AdvanceAuthorization(source="lidar", distance_m=50.0, issued_s=0.45)
    _, odo = drive(node, 0.5, 0.01, 0.0, 0.0, [(Topic.ADVANCE, newer)])
    out, _ = drive(node, 0.51, 0.02, 0.0, odo, [(Topic.ADVANCE, older)])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == 0.0


@pytest.mark.parametrize("older_mps", [1.0, 2.0, 5.0])
def test_an_older_lower_speed_limit_still_applies(preset, older_mps: float) -> None:
    from overdrive.messages import MaxSpeed

    node = DrivingModule(preset)
    drive(node, 0.0, 0.01, 0.0, 0.0, [(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=2.0,
                                                                  issued_s=0.0))])
    out, _ = drive(node, 0.01, 0.01, 0.0, 0.0,
                   [(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=older_mps,
                                               issued_s=-0.05))])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.speed_limit_mps == pytest.approx(min(older_mps, 2.0))


def test_the_last_of_equal_stamps_wins(preset) -> None:
    """Two messages from one source with the same stamp (two events at the same at_s): the
    later one stands, as before ordering existed; a shorter one is never refused for it."""
    node = DrivingModule(preset)
    out, _ = drive(node, 0.5, 0.02, 0.0, 0.0, [
        (Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=60.0, issued_s=0.5)),
        (Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=3.0, issued_s=0.5))])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(3.0)


def test_a_future_dated_message_does_not_block_its_source(preset) -> None:
    from overdrive.messages import MaxSpeed

    node = DrivingModule(preset)
    future = [(Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=50.0, issued_s=1e6)),
              (Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=30.0, issued_s=1e6))]
    out, odo = drive(node, 1.0, 0.02, 0.0, 0.0, future)
    reasons = [m.reason for _, topic, m in out if topic == Topic.NOTICE and m.kind == "rejected"]
    assert any("future" in r for r in reasons) and len(reasons) == 2
    out, _ = drive(node, 1.02, 0.02, 0.0, odo, [
        (Topic.ADVANCE, AdvanceAuthorization(source="lidar", distance_m=7.0, issued_s=1.02)),
        (Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=3.0, issued_s=1.02))])
    status = [m for _, topic, m in out if topic == Topic.DRIVING_STATUS][-1]
    assert status.authorized_m == pytest.approx(7.0) and status.speed_limit_mps == pytest.approx(3.0)


# --------------------------------------------------------------------------- whole runs

def test_an_ordinary_uphill_move_ends_without_hard_braking() -> None:
    """Attack: spurious hard braking in normal driving (one MOVE, no cut, on a hill).

    MOVE 12 m at 5 m/s on a +5 % grade. The terminal approach arrives at 0.35 m/s with 0.21 m
    left and ``_hard_brake`` fires at 7.73 s: "0.21 m authorized at 0.35 m/s, a normal stop needs
    0.21 m: braking with everything" (the tail allowance ``stop_tail_m(v, 0.0, ...)`` ignores the
    slope that helps the stop). It fires at the end of every uphill MOVE tried: +5/10/15/20 %,
    escape-hybrid and ranger-6x6 (e.g. +15 % escape: 0.21 m at 0.38 m/s vs 0.23 m), and in a
    plain MOVE stream on +15 %. On the flat and downhill it does not. Nothing in the command
    asked for a stop shorter than the normal one.
    """
    result = run([move(0.5, 12, 5)], duration_s=15, world={"grade_percent": 5})
    assert result.exit_code == 0
    assert events_of(result, "hard_brake") == []
