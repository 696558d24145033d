"""Client and kit double stepped together every 10 ms, in process (no bus, no clock)."""

from __future__ import annotations

from overdrive.dynamics.vehicle_params import with_overrides
from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.pacmod3_client import Pacmod3Client, Pacmod3ClientConfig
from tests.can.pacmod3_double import KitDouble

PERIOD_S = 0.01
CONSTANT = 16.0
VARIABLE = [[0.0, 16.0], [3.0, 14.0], [8.0, 13.0]]


def vehicle(ratio=None):
    return with_overrides(PRESETS["escape-hybrid"], {"steering_ratio": CONSTANT if ratio is None else ratio})


class Loop:
    def __init__(self, ratio=None, **config) -> None:
        self.params = vehicle(ratio)
        self.client = Pacmod3Client(self.params, Pacmod3ClientConfig(**config))
        self.kit = KitDouble(self.params)
        self.now_s = 0.0
        self.outputs: list[tuple[float, str, object]] = []
        self.sent: list[tuple[float, object]] = []
        self.pedals: PedalCommand | None = PedalCommand(throttle_pct=0.0, brake_pct=30.0,
                                                        source="speed")
        self.steer: SteerCommand | None = None
        self.powertrain: PowertrainCommand | None = None

    def step(self) -> None:
        self.now_s = round(self.now_s + PERIOD_S, 9)
        for frame in self.kit.step(self.now_s, PERIOD_S):
            self.client.receive(frame, self.now_s)
        for topic, msg in self.client.sensor_outputs(self.now_s):
            self.outputs.append((self.now_s, topic, msg))
        inbox = [(t, m) for t, m in ((Topic.PEDALS, self.pedals), (Topic.STEER, self.steer),
                                     (Topic.POWERTRAIN, self.powertrain)) if m is not None]
        self.client.take_inputs(inbox, self.now_s)
        for frame in self.client.command_frames(self.now_s):
            self.kit.take(frame, self.now_s)
            self.sent.append((self.now_s, self.kit.codec.decode(frame)))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / PERIOD_S)):
            self.step()

    def engage(self, within_s: float = 1.0) -> None:
        self.run(0.2)
        assert self.client.request_engage(self.now_s) is None
        for _ in range(round(within_s / PERIOD_S)):
            self.step()
            if self.client.state == "engaged":
                return
        raise AssertionError(f"not engaged: {self.client.state} {self.client.transitions}")

    def published(self, topic: str) -> list:
        return [m for _, t, m in self.outputs if t == topic]
