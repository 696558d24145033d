"""The drive's CAN nodes (``runtime.can_link``) around the emulated kit, on a simulated clock:
a port that is the kit itself (frames sent reach ``Pacmod3Kit`` at once, its reports queue with
bus stamps until drained), so the nodes run as in a drive, deterministically. Judged from the
kit's own truth: the drive ending at speed brakes engaged to a standstill before letting go,
receive-side bus errors brake it too, and reports drained together count at their bus times."""

from __future__ import annotations

import pytest

from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.runtime.can_edge import CanErrors
from overdrive.runtime.can_link import STAMP_TRUST_S, CanCommandNode, CanSensorNode
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import Pacmod3Client
from overdrive.vehicle.pacmod3_engage import ENGAGE_STANDSTILL_MPS, stop_bound_s
from overdrive.vehicle.pacmod3_kit import Pacmod3Kit

TICK_S = 0.01
WALL0_S = 1.8e9   # the bus stamps' wall clock at the simulated clock's 0
HOLD = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
GO = PedalCommand(throttle_pct=40.0, brake_pct=0.0, source="speed")


class KitPort:
    """``CanPort``'s interface over a ``Pacmod3Kit``; ``sleep`` advances the clock and the kit."""

    def __init__(self, kit: Pacmod3Kit) -> None:
        self.kit = kit
        self.t_s = 0.0
        self.queue: list = []
        self.errors = CanErrors()
        self.sent = self.received = 0
        self.truths: list = []
        self.closed = False

    def clock(self) -> float:
        return self.t_s

    def wall(self) -> float:
        return WALL0_S + self.t_s

    def sleep(self, seconds: float) -> None:
        for _ in range(max(1, round(seconds / TICK_S))):
            self.t_s = round(self.t_s + TICK_S, 9)
            self.kit.step(self.t_s)
            self.queue += [(WALL0_S + self.t_s, f) for f in self.kit.report_frames(self.t_s)]
            self.truths.append(self.kit.truth(self.t_s))

    def send(self, frames, now_s):
        for frame in frames:
            self.kit.receive(frame, self.t_s)
        self.sent += len(frames)
        return []

    def receive(self, timeout_s=0.0, now_s=None):
        out, self.queue = self.queue, []
        self.received += len(out)
        return out

    def traffic(self):
        return None

    def close(self) -> None:
        self.closed = True


class Drive:
    def __init__(self) -> None:
        params = KIT_VEHICLES["lexus-rx450h"]
        self.kit = Pacmod3Kit(params)
        self.port = KitPort(self.kit)
        self.client = Pacmod3Client(params)
        self.sensor = CanSensorNode(self.client, self.port, wall_clock=self.port.wall)
        self.command = CanCommandNode(self.client, self.port, None, engage_at_start=True,
                                      sensor=self.sensor, clock=self.port.clock,
                                      sleep=self.port.sleep)

    def run(self, seconds, pedals, drain_every=1, until=None):
        for i in range(round(seconds / TICK_S)):
            self.port.sleep(TICK_S)
            now_s = self.port.t_s
            if i % drain_every == 0:
                self.sensor.step(now_s, [])
            self.command.step(now_s, [
                (Topic.PEDALS, pedals), (Topic.STEER, SteerCommand(steer_pct=0.0,
                                                                   source="driving")),
                (Topic.POWERTRAIN, PowertrainCommand(gear="drive", engine_on=True,
                                                     source="speed"))])
            if until is not None and until(self.kit.truth(now_s)):
                return

    def at_speed(self, speed_mps: float) -> float:
        self.run(2.5, HOLD)
        assert self.client.state == "engaged" and self.kit.truth(self.port.t_s).gear == "drive"
        self.run(20.0, GO, until=lambda t: t.speed_mps >= speed_mps)
        return self.kit.truth(self.port.t_s).speed_mps


def judge_braked_to_a_stop(d: Drive, from_s: float, speed_mps: float) -> None:
    after = [t for t in d.port.truths if t.t_s > from_s]
    for t in after:
        if abs(t.speed_mps) > ENGAGE_STANDSTILL_MPS:
            assert "brake" in t.enabled, f"let go at {t.speed_mps:.2f} m/s ({t.t_s:.2f} s)"
    stood = next(t.t_s for t in after if abs(t.speed_mps) < 1e-3)
    assert stood - from_s <= stop_bound_s(speed_mps)


@pytest.mark.parametrize("speed_mps", [0.5, 4.19, 8.0])
def test_ending_the_drive_at_speed_brakes_engaged_to_a_standstill_then_lets_go(speed_mps):
    d = Drive()
    v = d.at_speed(speed_mps)
    end_s = d.port.t_s
    d.command.close()
    judge_braked_to_a_stop(d, end_s, v)
    assert d.kit.truth(d.port.t_s).enabled == () and d.port.closed
    assert abs(d.kit.truth(d.port.t_s).speed_mps) < 1e-3


def test_ending_the_drive_disengaged_lets_go_at_once() -> None:
    d = Drive()
    d.command.engage_at_start = False
    d.run(1.0, HOLD)
    start_s = d.port.t_s
    d.command.close()
    assert d.port.t_s == start_s and d.kit.truth(start_s).enabled == ()


@pytest.mark.parametrize("kind", ["error_frames", "receive_failures"])
def test_bus_errors_seen_on_receive_brake_engaged_to_a_standstill(kind: str) -> None:
    d = Drive()
    v = d.at_speed(4.19)
    fault_s = d.port.t_s
    setattr(d.port.errors, kind, 1)
    d.run(6.0, GO)
    judge_braked_to_a_stop(d, fault_s, v)
    assert d.client.state == "faulted" and d.kit.truth(d.port.t_s).enabled == ()
    assert [t[2] for t in d.client.transitions][-2:] == ["client_fault", "stopped"]


@pytest.mark.parametrize("stall_s", [0.05, 0.15, 0.3, 0.6])
def test_reports_drained_together_after_a_stall_integrate_the_distance_at_their_bus_times(
        stall_s: float) -> None:
    """The drive's loop stalls (both nodes; the kit keeps driving and reporting): the reports
    queued meanwhile are drained together, and counted at their bus times the odometer covers
    the stall (read together at one time, the gaps were lost)."""
    d = Drive()
    d.at_speed(3.0)
    truth0, odo0 = d.kit.truth(d.port.t_s).odometer_m, d.client.odometer_m
    d.port.sleep(stall_s)
    d.run(0.5, GO)
    travelled = d.kit.truth(d.port.t_s).odometer_m - truth0
    assert travelled > 3.0 * (stall_s + 0.5)
    # the reports lag the plant by under one report period (1/30 s) at under 8 m/s
    assert d.client.odometer_m - odo0 == pytest.approx(travelled, abs=8.0 / 30.0)
    assert d.sensor.stale_frames == 0


def test_a_report_older_than_the_trust_window_is_dropped_and_counted() -> None:
    d = Drive()
    d.run(1.0, HOLD)
    seen = dict(d.client.seen_s)
    frame = d.kit.report_frames(d.port.t_s + 1.0)[0]
    d.port.queue.append((WALL0_S + d.port.t_s - STAMP_TRUST_S - 0.01, frame))
    d.sensor.drain(d.port.t_s)
    assert d.sensor.stale_frames == 1 and d.client.seen_s == seen
