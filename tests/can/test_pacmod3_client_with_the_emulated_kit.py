"""The client against the emulated kit (``Pacmod3Kit``, sans-IO) stepped together every 10 ms
in lock step, both dialects: the engage sequence is the one the kit accepts, and the kit's
own state judges it (its enable edges, its override latch, its truth)."""

from __future__ import annotations

import pytest

from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import Pacmod3Client, Pacmod3ClientConfig
from overdrive.vehicle.pacmod3_kit import KitFault, Pacmod3Kit

STEP_S = 0.01
ALL = {"accel", "brake", "steering", "shift"}


def lock_step(client, kit, seconds, start_s, pedals, steer=None, engage_at=None, gear=None):
    now_s = start_s
    for _ in range(round(seconds / STEP_S)):
        now_s = round(now_s + STEP_S, 9)
        kit.step(now_s)
        for frame in kit.report_frames(now_s):
            client.receive(frame, now_s)
        client.sensor_outputs(now_s)
        inbox = [(Topic.PEDALS, pedals)] + ([(Topic.STEER, steer)] if steer else [])
        if gear is not None:
            inbox.append((Topic.POWERTRAIN, PowertrainCommand(gear=gear, engine_on=True,
                                                              source="speed")))
        client.take_inputs(inbox, now_s)
        if engage_at is not None and now_s >= engage_at:
            engage_at = None
            assert client.request_engage(now_s) is None
        for frame in client.command_frames(now_s):
            kit.receive(frame, now_s)
    return now_s


@pytest.mark.parametrize("dialect", ["v3", "v14"])
def test_the_emulated_kit_accepts_the_engage_sequence_and_drives(dialect: str) -> None:
    params = KIT_VEHICLES["lexus-rx450h"]
    kit = Pacmod3Kit(params, dialect=dialect)
    client = Pacmod3Client(params, Pacmod3ClientConfig(dialect=dialect))
    hold = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
    now = lock_step(client, kit, 1.0, 0.0, hold, engage_at=0.3)
    assert client.state == "engaged", client.transitions
    assert set(kit.truth(now).enabled) == ALL
    edges = kit.summary(now)["enable_edges"]
    assert edges[0]["system"] == "brake"
    assert all(e["t_s"] > edges[0]["t_s"] for e in edges[1:])
    assert kit.summary(now)["refused_edges"] == []
    now = lock_step(client, kit, 1.5, now, hold, gear="drive")   # stopped, brake held: shifts
    assert kit.truth(now).gear == "drive"
    go = PedalCommand(throttle_pct=30.0, brake_pct=0.0, source="speed")
    now = lock_step(client, kit, 3.0, now, go, SteerCommand(steer_pct=0.0, source="driving"),
                    gear="drive")
    assert kit.truth(now).speed_mps > 0.5, "engaged: the throttle drives the kit's plant"


def test_an_emulated_override_latches_until_the_operator_re_engages() -> None:
    params = KIT_VEHICLES["lexus-rx450h"]
    kit = Pacmod3Kit(params, faults=(KitFault(kind="override", system="steering", value=20.0,
                                              start_s=2.0, end_s=2.5),))
    client = Pacmod3Client(params)
    hold = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
    now = lock_step(client, kit, 4.0, 0.0, hold, engage_at=0.3)
    assert client.state == "overridden" and kit.truth(now).enabled == ()
    now = lock_step(client, kit, 3.0, now, hold)          # the planner's commands go on
    assert client.state == "overridden" and kit.truth(now).enabled == ()
    now = lock_step(client, kit, 1.0, now, hold, engage_at=now + 0.1)
    assert client.state == "engaged" and set(kit.truth(now).enabled) == ALL


@pytest.mark.parametrize("dialect", ["v3", "v14"])
def test_a_kit_fault_latches_and_the_operator_re_engages_once_the_actuator_works(dialect) -> None:
    params = KIT_VEHICLES["lexus-rx450h"]
    kit = Pacmod3Kit(params, dialect=dialect, faults=(
        KitFault(kind="stuck", system="brake", start_s=2.0, end_s=3.0),))
    client = Pacmod3Client(params, Pacmod3ClientConfig(dialect=dialect))
    hold = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
    now = lock_step(client, kit, 2.5, 0.0, hold, engage_at=0.3)
    assert client.state == "faulted" and "brake" not in kit.truth(now).enabled
    now = lock_step(client, kit, 1.0, now, hold)            # nothing re-engages by itself
    assert client.state == "faulted"
    now = lock_step(client, kit, 1.0, now, hold, engage_at=now + 0.1)   # the stuck ended at 3 s
    assert client.state == "engaged" and set(kit.truth(now).enabled) == ALL


def test_an_engage_while_the_actuator_is_still_stuck_falls_back_to_faulted() -> None:
    params = KIT_VEHICLES["lexus-rx450h"]
    kit = Pacmod3Kit(params, faults=(KitFault(kind="stuck", system="brake", start_s=2.0,
                                              end_s=30.0),))
    client = Pacmod3Client(params)
    hold = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
    now = lock_step(client, kit, 2.5, 0.0, hold, engage_at=0.3)
    now = lock_step(client, kit, 1.5, now, hold, engage_at=now + 0.1)
    assert client.state == "faulted" and "brake" not in kit.truth(now).enabled
    assert [t[2] for t in client.transitions][-2:] == ["engage_request", "fault"]
