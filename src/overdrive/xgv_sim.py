"""``overdrive xgv-sim``: the simulated ByWire XGV on a real UDP socket, in wall-clock time.

The runtime edge of ``vehicle.xgv.XgvSimulator``: one UDP socket (default 127.0.0.1:3794,
reference §2), every datagram handed to the simulator as it arrives and its replies sent back
to the sender's address and port, the vehicle stepped every 10 ms of wall-clock time. With a
scenario, its vehicle, start, seed and world are used and its ``world`` and safety-device
events (SafeStop, overrides, door, e-stop, errors, partial mode) and vehicle faults are played
at their times; the scenario clock starts with the first datagram received, so a client
started a little later (``overdrive drive``) sees the events when the scenario says.
"""

from __future__ import annotations

import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Final

from overdrive.jaus.judp import JUDP_PORT
from overdrive.messages import Topic
from overdrive.player import ScenarioPlayer, world_from_spec
from overdrive.scenario import Scenario
from overdrive.vehicle.presets import PRESETS
from overdrive.vehicle.sim_node import FAULTS_TOPIC, WORLD_TOPIC
from overdrive.vehicle.xgv import XgvSimulator

PERIOD_S: Final = 0.01          # the vehicle's step, as in the lock-step runs
RECEIVE_BUFFER: Final = 65535


class XgvServer:
    """The simulator behind a socket; ``serve()`` runs until ``stop()`` or ``duration_s``."""

    def __init__(self, host: str = "127.0.0.1", port: int = JUDP_PORT,
                 scenario: Scenario | None = None) -> None:
        params = scenario.vehicle if scenario is not None else PRESETS["escape-hybrid"]
        spec = scenario.spec if scenario is not None else None
        self.simulator = XgvSimulator(
            params, world_from_spec(spec.world) if spec is not None else None,
            spec.seed if spec is not None else 1, ready=spec is not None and spec.start == "ready")
        self.player = ScenarioPlayer(scenario) if scenario is not None else None
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
            self.sock.setblocking(False)
        except OSError:
            self.sock.close()
            raise
        self._stop = threading.Event()
        self.send_errors = 0

    @property
    def address(self) -> tuple[str, int]:
        host, port = self.sock.getsockname()[:2]
        return host, port

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> XgvServer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _send(self, outgoing: list[tuple[bytes, tuple[str, int]]]) -> None:
        for data, address in outgoing:
            try:
                self.sock.sendto(data, address)
            except OSError:
                self.send_errors += 1

    def serve(self, duration_s: float | None = None,
              clock: Callable[[], float] = time.monotonic) -> None:
        """Step every ``PERIOD_S`` and answer datagrams as they come, until stopped."""
        sim = self.simulator
        start = clock()
        scenario_start: float | None = None
        tick = 0
        while not self._stop.is_set():
            now = clock() - start
            if duration_s is not None and now >= duration_s:
                return
            next_tick_s = tick * PERIOD_S
            ready, _, _ = select.select([self.sock], [], [], max(0.0, next_tick_s - now))
            if ready:
                while True:
                    try:
                        data, sender = self.sock.recvfrom(RECEIVE_BUFFER)
                    except (BlockingIOError, ConnectionResetError):
                        break
                    if scenario_start is None:
                        scenario_start = clock() - start
                    self._send(sim.receive(data, sender[:2], clock() - start))
            now = clock() - start
            if now < next_tick_s:
                continue
            if self.player is not None and scenario_start is not None:
                self._play(now - scenario_start)
            self._send(sim.step(now))
            tick = max(tick + 1, int(now / PERIOD_S))

    def _play(self, scenario_s: float) -> None:
        assert self.player is not None
        if scenario_s > self.player.scenario.spec.duration_s:
            return
        for topic, msg in self.player.step(scenario_s, ()):
            if topic == Topic.SAFETY:
                self.simulator.set_devices(msg)
            elif topic == WORLD_TOPIC:
                self.simulator.set_world(msg)
            elif topic == FAULTS_TOPIC:
                self.simulator.apply_fault(msg)


__all__ = ["XgvServer"]
