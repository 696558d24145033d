"""Loss of command traffic (issue 38): a streaming source (the move server) silent beyond
``command_silence_s`` stops the vehicle, is counted and reported, and stays held at 0 until it
sends 0; a source that authorizes once is never timed out; the module's own stall is not the
source's silence; queued sensor samples count at their own time."""

from __future__ import annotations

import math
from typing import Any

from overdrive.messages import AdvanceAuthorization, DrivingStatus, MaxSpeed, Notice, Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingModule
from overdrive.servers.move_arrivals import sample_times
from tests.servers.driving_harness import DT_S, outputs, sensors

PARAMS = PRESETS["escape-hybrid"]
SPEED_MPS = 5.0


def _step(node: DrivingModule, tick: int, extra: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    t = round(tick * DT_S, 6)
    return node.step(t, [*sensors(PARAMS, speed_mps=SPEED_MPS, odometer_m=SPEED_MPS * t), *extra])


def _from(source: str, tick: int, distance_m: float) -> list[tuple[str, Any]]:
    t = round(tick * DT_S, 6)
    return [(Topic.ADVANCE, AdvanceAuthorization(source=source, distance_m=distance_m,
                                                 issued_s=t)),
            (Topic.MAX_SPEED, MaxSpeed(source=source, speed_mps=8.0, issued_s=t))]


def _status(out: list[tuple[str, Any]]) -> DrivingStatus:
    return outputs(out, Topic.DRIVING_STATUS)[-1]


def _faults(out: list[tuple[str, Any]]) -> list[Notice]:
    return [n for n in outputs(out, Topic.NOTICE) if n.kind == "fault"]


def test_a_silent_streaming_source_stops_the_vehicle_counts_it_and_holds_until_it_sends_zero(
) -> None:
    node = DrivingModule(PARAMS)
    tick = 0
    for tick in range(1, 51):                      # the move server streams 50 m
        out = _step(node, tick, _from("move", tick, 50.0))
    assert _status(out).authorized_m > 40.0 and _status(out).unasked_stops == 0
    last_heard = tick
    faults: list[Notice] = []
    while not faults:
        tick += 1
        out = _step(node, tick, [])
        faults = _faults(out)
    silent_s = (tick - last_heard) * DT_S
    assert 0.2 < silent_s <= 0.2 + DT_S + 1e-9     # within one period of the bound
    assert faults[0].code == "command_silence" and "'move'" in faults[0].reason
    assert _status(out).authorized_m == 0.0 and _status(out).goal_speed_mps == 0.0
    assert _status(out).unasked_stops == 1
    assert any(n.kind == "hard_brake" for n in outputs(out, Topic.NOTICE))
    assert outputs(out, Topic.SET_SPEED)            # the stop is sent in this very period
    for _ in range(20):                             # it resumes with the old command: held
        tick += 1
        out = _step(node, tick, _from("move", tick, 40.0))
        assert _status(out).authorized_m == 0.0
    tick += 1                                       # it says it knows: 0 releases it
    out = _step(node, tick, _from("move", tick, 0.0))
    tick += 1
    out = _step(node, tick, _from("move", tick, 30.0))   # a new command drives
    assert _status(out).authorized_m > 25.0
    assert _status(out).unasked_stops == 1          # counted once, never reset


def test_a_source_that_authorizes_once_is_never_timed_out() -> None:
    """Seed 003 allows it (scenarios/driving-single-stop.yaml): only streaming sources are
    watched."""
    node = DrivingModule(PARAMS)
    out = _step(node, 1, _from("lidar", 1, 500.0))
    for tick in range(2, 300):
        out = _step(node, tick, [])
        assert not _faults(out)
    assert _status(out).authorized_m > 400.0 and _status(out).unasked_stops == 0


def test_the_modules_own_stall_is_not_the_sources_silence() -> None:
    """Stalled 1 s itself (the speed server's watchdog covers that), the module resumes with the
    source's queued messages, or with none yet: the source gets its full bound from the resume."""
    node = DrivingModule(PARAMS)
    for tick in range(1, 51):
        _step(node, tick, _from("move", tick, 100.0))
    tick = 150                                       # 1 s later, nothing queued yet
    for tick in range(150, 165):                     # 0.15 s after the resume: not yet silent
        out = _step(node, tick, [])
        assert not _faults(out), _faults(out)
    out = _step(node, tick + 1, _from("move", tick + 1, 100.0))
    assert not _faults(out) and _status(out).authorized_m > 90.0


def test_queued_samples_are_spread_over_the_gap_and_single_ones_keep_their_arrival() -> None:
    inbox = [("gps", 1), ("imu", 1), ("gps", 2), ("other", 0), ("gps", 3), ("imu", 2)]
    times = sample_times(inbox, {"gps", "imu"}, 1.0, 4.0)
    assert times == [2.0, 2.5, 3.0, 4.0, 4.0, 4.0]
    assert sample_times([("gps", 1), ("imu", 1)], {"gps", "imu"}, 1.0, 1.01) == [1.01, 1.01]
    assert sample_times(inbox, {"gps"}, None, 4.0) == [4.0] * len(inbox)
    assert all(math.isfinite(t) for t in times)
