"""Fault injection: channel faults on the bus, sensor faults, actuator faults, engine stall."""

from __future__ import annotations

import pytest

from overdrive.bus.faults import ChannelFaults
from overdrive.messages import Topic
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import scenario_dict


def make(kind: str, delay_s: float = 0.0) -> ChannelFaults:
    faults = ChannelFaults()
    faults.add("set_speed", kind, 1.0, 0.5, delay_s)
    return faults


def test_outside_the_window_messages_pass() -> None:
    faults = make("drop")
    faults.now_s = 0.99
    assert faults.route(Topic.SET_SPEED, "a") == ("a",)
    faults.now_s = 1.5
    assert faults.route(Topic.SET_SPEED, "b") == ("b",)
    assert faults.route(Topic.IMU, "c") == ("c",), "other channels untouched"


def test_drop() -> None:
    faults = make("drop")
    faults.now_s = 1.0
    assert faults.route(Topic.SET_SPEED, "a") == ()
    assert faults.counts["drop"] == 1


def test_duplicate() -> None:
    faults = make("duplicate")
    faults.now_s = 1.2
    assert faults.route(Topic.SET_SPEED, "a") == ("a", "a")


def test_delay_releases_in_order_after_delay() -> None:
    faults = make("delay", delay_s=0.3)
    faults.now_s = 1.0
    assert faults.route(Topic.SET_SPEED, "a") == ()
    faults.now_s = 1.1
    assert faults.route(Topic.SET_SPEED, "b") == ()
    faults.now_s = 1.29
    assert faults.due() == []
    faults.now_s = 1.3
    assert faults.due() == [(Topic.SET_SPEED, "a")]
    faults.now_s = 1.4
    assert faults.due() == [(Topic.SET_SPEED, "b")]
    assert faults.held == []


def test_reorder_swaps_consecutive_messages() -> None:
    faults = make("reorder")
    faults.now_s = 1.0
    assert faults.route(Topic.SET_SPEED, "a") == ()
    assert faults.route(Topic.SET_SPEED, "b") == ("b", "a")
    faults.now_s = 1.45
    assert faults.route(Topic.SET_SPEED, "c") == ()
    faults.now_s = 2.0
    assert faults.route(Topic.SET_SPEED, "d") == ("d", "c"), "a held message is never lost"


def open_loop(events, **kw):
    base = [{"at_s": 0.1, "engine": "on"}, {"at_s": 1.5, "gear": "drive"},
            {"at_s": 2.0, "actuators": {"throttle_pct": 30}}]
    return run_scenario(parse_scenario(scenario_dict(duration_s=8, events=base + events, **kw)), None)


@pytest.mark.parametrize("fault", ["dropout", "freeze", "noise"])
def test_sensor_faults(fault: str) -> None:
    result = open_loop([{"at_s": 3.0, "sensor": {"name": "gps", "fault": fault, "for_s": 2.0,
                                                  "sigma": 5.0}}])
    counts = result.nodes["vehicle"]
    assert counts is not None
    healthy = open_loop([])
    assert result.summary["final"] == healthy.summary["final"], "ground truth is untouched"


def test_sensor_dropout_silences_the_topic() -> None:
    from overdrive.bus.local import LocalBus
    from overdrive.run.compose import build_nodes
    from overdrive.runtime.lockstep import LockstepRuntime
    from overdrive.scenario.player import ScenarioPlayer, channel_faults

    scenario = parse_scenario(scenario_dict(duration_s=3, events=[
        {"at_s": 1.0, "sensor": {"name": "radar", "fault": "dropout", "for_s": 1.0}}]))
    nodes = build_nodes(scenario)
    assert isinstance(nodes[1], ScenarioPlayer)
    bus = LocalBus()
    bus.channel = channel_faults(scenario)
    times: list[float] = []
    runtime = LockstepRuntime(nodes, bus)
    bus.tap(lambda topic, msg: times.append(runtime.now_s) if topic == Topic.RADAR else None)
    runtime.run(3.0)
    gap = [t for t in times if 1.0 < t < 2.0]
    # the vehicle steps first in a tick, so the reading at t=1.0 was out before the fault arrived
    assert not gap and 1.0 in times and 2.0 in times and len(times) == 301 - 99


def test_stuck_brake_and_weak_throttle() -> None:
    weak = open_loop([{"at_s": 0.0, "actuator": {"throttle": {"effectiveness": 0.5}}}])
    healthy = open_loop([])
    assert weak.summary["odometer_m"] < 0.7 * healthy.summary["odometer_m"]
    stuck = open_loop([{"at_s": 1.0, "actuator": {"brake": {"stuck": True}}}])
    assert stuck.summary["odometer_m"] == 0.0, "brake stuck at 100 % (parked) holds the car"


def test_slow_brake_stops_longer() -> None:
    events = [{"at_s": 5.0, "actuators": {"brake_pct": 60}}]
    slow = open_loop([{"at_s": 4.0, "actuator": {"brake": {"lag_scale": 10}}}, *events])
    healthy = open_loop(events)
    assert slow.summary["odometer_m"] > healthy.summary["odometer_m"] + 0.5


def test_engine_stall_cuts_drive() -> None:
    stalled = open_loop([{"at_s": 3.0, "engine_stall": {}}])
    healthy = open_loop([])
    assert stalled.trace[-1]["engine"] == "off"
    assert stalled.summary["peaks"]["max_speed_mps"] < healthy.summary["peaks"]["max_speed_mps"]


def test_duplicate_and_reorder_on_a_run_are_counted() -> None:
    result = open_loop([{"at_s": 2.5, "duplicate": {"channel": "gps", "for_s": 1.0}},
                        {"at_s": 4.0, "reorder": {"channel": "imu", "for_s": 1.0}},
                        {"at_s": 5.5, "delay": {"channel": "wheel_speed", "for_s": 1.0, "delay_s": 0.2}}])
    assert result.summary["channel_faults"] == {"duplicate": 100, "reorder": 100, "delay": 100}


def test_delivered_taps_see_what_the_channel_delivers() -> None:
    """The judge's view of SPSS as delivered: drops, delays (released by ``pump``), duplicates
    and reordering as the subscribers get them; other topics are not tapped."""
    from overdrive.bus.local import LocalBus

    bus = LocalBus()
    faults = ChannelFaults()
    faults.add("set_speed", "drop", 1.0, 1.0)
    faults.add("set_speed", "delay", 3.0, 1.0, 0.5)
    faults.add("set_speed", "duplicate", 5.0, 1.0)
    faults.add("set_speed", "reorder", 7.0, 1.0)
    bus.channel = faults
    inbox = bus.subscribe([Topic.SET_SPEED])
    issued: list = []
    delivered: list = []
    bus.tap(lambda topic, msg: issued.append(msg))
    bus.tap_delivered(lambda topic, msg: delivered.append((faults.now_s, msg)), [Topic.SET_SPEED])
    for now_s, msg in ((0.5, "a"), (1.5, "dropped"), (3.2, "late"), (5.5, "twice"),
                       (7.2, "first"), (7.4, "second")):
        faults.now_s = now_s
        bus.publish(Topic.SET_SPEED, msg)
        bus.publish(Topic.PEDALS, "not tapped")
    faults.now_s = 3.7
    bus.pump()
    assert issued.count("dropped") == 1
    assert [m for _, m in delivered] == ["a", "twice", "twice", "second", "first", "late"]
    assert [m for _, m in inbox] == [m for _, m in delivered]
    assert delivered[-1][0] == 3.7, "a delayed message is delivered when it is released"
