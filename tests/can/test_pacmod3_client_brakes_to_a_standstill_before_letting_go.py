"""A fault the CLIENT detects at speed (reports silent, a bus error, another node's command
frames) and the drive ending: the client keeps the kit enabled with the brake full on until the
vehicle stands, then lets go and latches. Judged from the emulated kit's own truth
(``Pacmod3Kit`` stepped in lock step with the client every 10 ms): the vehicle never rolls with
the kit let go, it stops within the bound, and nothing re-engages without the operator."""

from __future__ import annotations

import itertools

import pytest

from overdrive.kits.frames import CanFrame
from overdrive.kits.pacmod3 import AccelCmd
from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import Pacmod3Client, Pacmod3ClientConfig
from overdrive.vehicle.pacmod3_engage import (
    ENGAGE_STANDSTILL_MPS,
    STANDSTILL_HOLD_S,
    stop_bound_s,
)
from overdrive.vehicle.pacmod3_kit import KitFault, Pacmod3Kit

STEP_S = 0.01
HOLD = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
GO = PedalCommand(throttle_pct=40.0, brake_pct=0.0, source="speed")
STEER = SteerCommand(steer_pct=5.0, source="driving")


class LockStep:
    """Client and kit stepped together; ``hook(now_s)`` runs before the client's commands."""

    def __init__(self, dialect: str = "v3") -> None:
        params = KIT_VEHICLES["lexus-rx450h"]
        self.kit = Pacmod3Kit(params, dialect=dialect)
        self.client = Pacmod3Client(params, Pacmod3ClientConfig(dialect=dialect))
        self.now_s = 0.0
        self.truths = []

    def run(self, seconds, pedals, hook=None, until=None, engage=False):
        for _ in range(round(seconds / STEP_S)):
            self.now_s = now_s = round(self.now_s + STEP_S, 9)
            self.kit.step(now_s)
            for frame in self.kit.report_frames(now_s):
                self.client.receive(frame, now_s)
            self.client.sensor_outputs(now_s)
            self.client.take_inputs([(Topic.PEDALS, pedals), (Topic.STEER, STEER),
                                     (Topic.POWERTRAIN, PowertrainCommand(
                                         gear="drive", engine_on=True, source="speed"))], now_s)
            if engage:
                engage = False
                assert self.client.request_engage(now_s) is None
            if hook is not None:
                hook(now_s)
            for frame in self.client.command_frames(now_s):
                self.kit.receive(frame, now_s)
            self.truths.append(self.kit.truth(now_s))
            if until is not None and until(self.truths[-1]):
                return

    def at_speed(self, speed_mps: float) -> float:
        """Engaged, in drive, at ``speed_mps`` or more (returns the truth's speed)."""
        self.run(1.0, HOLD, engage=True)
        self.run(1.5, HOLD)
        assert self.client.state == "engaged" and self.kit.truth(self.now_s).gear == "drive"
        self.run(20.0, GO, until=lambda t: t.speed_mps >= speed_mps)
        return self.kit.truth(self.now_s).speed_mps


def judge_the_stop(ls: LockStep, fault_s: float, speed_mps: float) -> None:
    after = [t for t in ls.truths if t.t_s > fault_s]
    for before, t in itertools.pairwise(after):
        if abs(t.speed_mps) > ENGAGE_STANDSTILL_MPS:
            assert "brake" in t.enabled, f"let go at {t.speed_mps:.2f} m/s ({t.t_s:.2f} s)"
        if t.t_s > fault_s + 0.2:   # detected (3.5 report periods at most): throttle off
            assert t.throttle <= before.throttle + 1e-12, f"throttle rising at {t.t_s:.2f} s"
            assert t.brake >= min(before.brake, 0.9) - 1e-12 or "brake" not in t.enabled
    stopped = next(t.t_s for t in after if abs(t.speed_mps) < 1e-3)
    assert stopped - fault_s <= stop_bound_s(speed_mps)
    ending = ls.client.ending
    assert ls.client.state == ("disengaged" if ending else "faulted"), ls.client.transitions
    assert ls.kit.truth(ls.now_s).enabled == (), "stood: then let go"
    assert [t[2] for t in ls.client.transitions][-2:] == (
        ["drive_end", "released"] if ending else ["client_fault", "stopped"])


@pytest.mark.parametrize("dialect", ["v3", "v14"])
@pytest.mark.parametrize("speed_mps", [1.0, 4.19, 8.0])
def test_reports_silent_at_speed_brake_engaged_to_a_standstill_then_latch(speed_mps,
                                                                          dialect) -> None:
    ls = LockStep(dialect)
    v = ls.at_speed(speed_mps)
    fault_s = ls.now_s
    ls.kit.inject(KitFault(kind="silence", start_s=fault_s, end_s=fault_s + 0.2))
    ls.run(6.0, GO)   # the planner still asks for throttle: nothing of it goes out
    judge_the_stop(ls, fault_s, v)
    ls.run(2.0, GO)
    assert ls.client.state == "faulted" and abs(ls.kit.truth(ls.now_s).speed_mps) < 1e-3


def test_reports_silent_for_good_let_go_at_the_bound_with_the_vehicle_stood() -> None:
    ls = LockStep()
    v = ls.at_speed(4.19)
    fault_s = ls.now_s
    ls.kit.inject(KitFault(kind="silence", start_s=fault_s, end_s=None))
    ls.run(stop_bound_s(v) - 0.2, GO)
    assert ls.client.state == "stopping" and "brake" in ls.kit.truth(ls.now_s).enabled
    ls.run(0.5, GO)
    judge_the_stop(ls, fault_s, v)


@pytest.mark.parametrize("speed_mps", [1.0, 4.19, 8.0])
def test_a_transient_bus_error_at_speed_brakes_engaged_to_a_standstill(speed_mps) -> None:
    ls = LockStep()
    v = ls.at_speed(speed_mps)
    fault_s = ls.now_s
    ls.run(STEP_S, GO, hook=lambda now: ls.client.bus_error("no acknowledgement"))
    ls.run(6.0, GO)
    judge_the_stop(ls, fault_s, v)
    # the standstill was held before the kit was let go
    let_go = next(t.t_s for t in ls.truths if t.t_s > fault_s and "brake" not in t.enabled)
    stood = [t for t in ls.truths if fault_s < t.t_s < let_go and abs(t.speed_mps) < 1e-3]
    assert stood and let_go - stood[0].t_s >= STANDSTILL_HOLD_S - 0.05


def test_another_nodes_command_frames_at_speed_brake_to_a_standstill() -> None:
    ls = LockStep()
    v = ls.at_speed(4.19)
    fault_s = ls.now_s
    foreign = ls.client.codec.encode(AccelCmd(enable=True, accel_ratio=0.5))
    seen = []

    def second_controller(now_s: float) -> None:
        if now_s < fault_s + 0.3:
            seen.append(now_s)
            ls.client.receive(CanFrame(arbitration_id=foreign.arbitration_id,
                                       data=foreign.data), now_s)

    ls.run(6.0, GO, hook=second_controller)
    judge_the_stop(ls, fault_s, v)
    assert ls.client.stats.foreign_commands == len(seen) > 0


def test_an_engage_is_refused_while_another_node_commands_the_kit() -> None:
    ls = LockStep()
    ls.run(0.5, HOLD)
    foreign = ls.client.codec.encode(AccelCmd(enable=False, accel_ratio=0.0))
    ls.client.receive(foreign, ls.now_s)
    why = ls.client.request_engage(ls.now_s)
    assert why is not None and "another node" in why
    ls.run(0.5, HOLD)   # not seen for longer than the hold: accepted
    assert ls.client.request_engage(ls.now_s) is None
    ls.run(1.0, HOLD)
    assert ls.client.state == "engaged"


@pytest.mark.parametrize("speed_mps", [0.0, 4.19])
def test_the_drive_ending_brakes_engaged_to_a_standstill_then_lets_go(speed_mps) -> None:
    ls = LockStep()
    v = ls.at_speed(speed_mps) if speed_mps else 0.0
    if not speed_mps:
        ls.run(1.0, HOLD, engage=True)
    end_s = ls.now_s
    ls.client.end_drive(end_s)
    assert ls.client.releasing
    ls.run(6.0, GO, until=lambda t: not ls.client.releasing)
    assert not ls.client.releasing
    judge_the_stop(ls, end_s, v)
