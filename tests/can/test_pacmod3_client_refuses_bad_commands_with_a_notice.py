"""Commands the client cannot act on as given (a non-finite steer, a gear the vehicle does not
have, pedals the gate clamps or overrides) are counted in ``rejected_commands`` with a
``rejected`` notice, said once while the same bad command repeats, and what goes to the kit is
the safe value (the last steer, the gear held, the gated pedals), judged from the emulated
kit's truth in lock step."""

from __future__ import annotations

import math

import pytest

from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import Pacmod3Client
from overdrive.vehicle.pacmod3_kit import Pacmod3Kit

STEP_S = 0.01
HOLD = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")


def run(client, kit, seconds, now_s, inbox, engage=False):
    notices = []
    for _ in range(round(seconds / STEP_S)):
        now_s = round(now_s + STEP_S, 9)
        kit.step(now_s)
        for frame in kit.report_frames(now_s):
            client.receive(frame, now_s)
        notices += [m for t, m in client.sensor_outputs(now_s) if t == Topic.NOTICE]
        notices += [m for t, m in client.take_inputs(inbox, now_s) if t == Topic.NOTICE]
        if engage:
            engage = False
            assert client.request_engage(now_s) is None
        for frame in client.command_frames(now_s):
            kit.receive(frame, now_s)
    return now_s, [n for n in notices if n.kind == "rejected"]


def engaged():
    params = KIT_VEHICLES["lexus-rx450h"]
    kit, client = Pacmod3Kit(params), Pacmod3Client(params)
    now, _ = run(client, kit, 1.0, 0.0, [(Topic.PEDALS, HOLD)], engage=True)
    assert client.state == "engaged"
    return client, kit, now


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_steer_is_refused_with_a_notice_and_the_last_one_held(bad) -> None:
    client, kit, now = engaged()
    good = [(Topic.PEDALS, HOLD), (Topic.STEER, SteerCommand(steer_pct=-30.0, source="driving"))]
    now, _ = run(client, kit, 2.0, now, good)
    wheel = kit.truth(now).steering_wheel_rad
    assert wheel > 0.1, "steered left"
    before = client.stats.rejected_commands
    bad_cmd = [(Topic.PEDALS, HOLD), (Topic.STEER, SteerCommand(steer_pct=bad, source="driving"))]
    now, rejected = run(client, kit, 1.0, now, bad_cmd)
    assert client.stats.rejected_commands - before == 100
    assert [n.code for n in rejected] == ["steer_not_finite"]
    assert kit.truth(now).steering_wheel_rad == pytest.approx(wheel, abs=1e-3)


@pytest.mark.parametrize("gear", ["warp", "", "DRIVE"])
def test_a_gear_the_vehicle_does_not_have_is_refused_with_a_notice(gear: str) -> None:
    client, kit, now = engaged()
    inbox = [(Topic.PEDALS, HOLD),
             (Topic.POWERTRAIN, PowertrainCommand(gear=gear, engine_on=True, source="speed"))]
    before_gear = kit.truth(now).gear
    now, rejected = run(client, kit, 1.5, now, inbox)
    assert [n.code for n in rejected] == ["unknown_gear"]
    assert client.stats.rejected_commands == 150
    assert kit.truth(now).gear == before_gear


@pytest.mark.parametrize(("throttle", "brake", "sent_brake"), [
    (math.nan, 0.0, 0.0), (0.0, math.nan, 1.0), (150.0, 0.0, 0.0), (0.0, 120.0, 1.0),
    (-5.0, 0.0, 0.0), (0.0, -1.0, 0.0)])
def test_pedals_the_gate_changes_are_refused_with_a_notice(throttle, brake, sent_brake) -> None:
    client, kit, now = engaged()
    bad = PedalCommand(throttle_pct=throttle, brake_pct=brake, source="speed")
    now, rejected = run(client, kit, 0.5, now, [(Topic.PEDALS, bad)])
    assert [n.code for n in rejected] == ["pedals_gated"]
    assert client.stats.rejected_commands == 50
    truth = kit.truth(now)   # what the gate sent, through the kit's pedal map and lag
    assert (truth.brake > 0.9) if sent_brake else (truth.brake < 0.05)
    assert (truth.throttle > 0.5) if throttle == 150.0 else (truth.throttle < 1e-3)

def test_a_pedal_command_braking_and_throttling_is_the_rule_not_a_refusal() -> None:
    client, kit, now = engaged()
    both = PedalCommand(throttle_pct=20.0, brake_pct=30.0, source="speed")
    now, rejected = run(client, kit, 0.5, now, [(Topic.PEDALS, both)])
    assert rejected == [] and client.stats.rejected_commands == 0
