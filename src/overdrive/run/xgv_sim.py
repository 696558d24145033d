"""``overdrive xgv-sim``: the simulated ByWire XGV on a real UDP socket, in wall-clock time.

The runtime edge of ``vehicle.xgv.XgvSimulator``: one UDP socket (default 127.0.0.1:3794,
reference §2), every datagram handed to the simulator as it arrives and its replies sent back
to the sender's address and port, the vehicle stepped every 10 ms of wall-clock time. With a
scenario, its vehicle, start, seed and world are used and its ``world`` and safety-device
events (SafeStop, overrides, door, e-stop, errors, partial mode) and vehicle faults are played
at their times; the scenario clock starts with the first datagram received, so a client
started a little later (``overdrive drive``) sees the events when the scenario says.

Bounded input (issue 18): each 10 ms tick reads at most ``MAX_READ_PER_TICK`` datagrams (for
at most ``READ_BUDGET_S``), then hands the simulator first every datagram from an address that
holds a session (control or a service connection: ``XgvSimulator.trusted_addresses``), then the others,
at most ``MAX_PER_ADDRESS_PER_TICK`` per address and ``MAX_UNTRUSTED_PER_TICK`` in all; the rest
is dropped unread by the simulator and counted (``dropped``). A flood from other addresses
therefore costs the controller at most one tick.
"""

from __future__ import annotations

import select
import threading
import time
from collections.abc import Callable
from typing import Final, TextIO

from overdrive.jaus.judp import JUDP_PORT
from overdrive.messages import SIM_FAULTS_TOPIC, SIM_WORLD_TOPIC, Topic
from overdrive.runtime.udp import open_udp
from overdrive.scenario.player import ScenarioPlayer, world_from_spec
from overdrive.scenario.schema import Scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv import XgvSimulator

PERIOD_S: Final = 0.01          # the vehicle's step, as in the lock-step runs
RECEIVE_BUFFER: Final = 65535
RECEIVE_QUEUE_BYTES: Final = 4 << 20    # kernel queue: a burst waits to be read (and dropped by
                                        # the bounds below) instead of the kernel dropping the
                                        # controller's datagrams; capped by net.core.rmem_max
MAX_READ_PER_TICK: Final = 2000         # datagrams read per tick; reading and dropping is
READ_BUDGET_S: Final = 0.004            # cheap, decoding is not (~20 us each): under 40 % of a tick
MAX_PER_ADDRESS_PER_TICK: Final = 32    # a client sends ~3 per tick (command, devices, a query)
MAX_UNTRUSTED_PER_TICK: Final = 20      # ~0.5 ms of decoding per tick for everyone else
                                        # (2,000/s: discovery and new clients need a few)
READ_CHUNK: Final = 64

Datagram = tuple[bytes, tuple[str, int]]
TRUTH_HEADER: Final = "t_s,scenario_s,x_m,y_m,speed_mps"   # scenario_s empty before the first datagram


class Admission:
    """Which datagrams of one tick the simulator gets (module docstring); pure bookkeeping.

    ``admit(batch, trusted)`` (a set of addresses) may be called several times per tick; ``new_tick()`` resets the
    per-tick counts. Trusted senders are capped per address only; the others also share
    ``MAX_UNTRUSTED_PER_TICK``. Order is kept within each group.
    """

    def __init__(self) -> None:
        self.per_address: dict[tuple[str, int], int] = {}
        self.untrusted = 0
        self.dropped = 0

    def new_tick(self) -> None:
        self.per_address.clear()
        self.untrusted = 0

    def admit(self, batch: list[Datagram], trusted: set[tuple[str, int]]) -> list[Datagram]:
        first: list[Datagram] = []
        rest: list[Datagram] = []
        for datagram in batch:
            sender = datagram[1]
            count = self.per_address.get(sender, 0)
            if count >= MAX_PER_ADDRESS_PER_TICK:
                continue
            known = sender in trusted
            if not known:
                if self.untrusted >= MAX_UNTRUSTED_PER_TICK:
                    continue
                self.untrusted += 1
            self.per_address[sender] = count + 1
            (first if known else rest).append(datagram)
        self.dropped += len(batch) - len(first) - len(rest)
        return first + rest


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
        self.sock = open_udp((host, port), receive_buffer_bytes=RECEIVE_QUEUE_BYTES)
        self._stop = threading.Event()
        self.send_errors = 0
        self.admission = Admission()   # per-tick input bounds; .dropped counts the excess

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

    def _read(self, clock: Callable[[], float]) -> list[Datagram]:
        """What is waiting, up to ``MAX_READ_PER_TICK`` datagrams or ``READ_BUDGET_S``."""
        batch: list[Datagram] = []
        append, recvfrom = batch.append, self.sock.recvfrom
        deadline = clock() + READ_BUDGET_S
        while len(batch) < MAX_READ_PER_TICK:
            for _ in range(READ_CHUNK):   # the clock is read once per chunk: reads are ~1 us
                try:
                    append(recvfrom(RECEIVE_BUFFER))
                except (BlockingIOError, ConnectionResetError):
                    return batch
            if clock() >= deadline:
                break
        return batch

    def serve(self, duration_s: float | None = None,
              clock: Callable[[], float] = time.monotonic, truth: TextIO | None = None) -> None:
        """Step every ``PERIOD_S`` and answer datagrams as they come, until stopped. ``truth``:
        the simulated vehicle's own state after every step, as CSV (``TRUTH_HEADER``), so a
        run over a real link can be judged from ground truth (``xgv-sim --truth``)."""
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
                batch = self._read(clock)
                if batch and scenario_start is None:
                    scenario_start = clock() - start
                for data, sender in self.admission.admit(batch, sim.trusted_addresses()):
                    self._send(sim.receive(data, sender, clock() - start))
            now = clock() - start
            if now < next_tick_s:
                continue
            if self.player is not None and scenario_start is not None:
                self._play(now - scenario_start)
            self._send(sim.step(now))
            if truth is not None:
                self._write_truth(truth, now, scenario_start)
            self.admission.new_tick()
            tick = max(tick + 1, int(now / PERIOD_S))

    def _write_truth(self, out: TextIO, now_s: float, scenario_start: float | None) -> None:
        state = self.simulator.latest.get(Topic.TRUTH)
        if state is None:
            return
        scenario_s = "" if scenario_start is None else f"{now_s - scenario_start:.4f}"
        out.write(f"{now_s:.4f},{scenario_s},{state.x_m:.4f},{state.y_m:.4f},"
                  f"{state.speed_mps:.4f}\n")

    def _play(self, scenario_s: float) -> None:
        assert self.player is not None
        if scenario_s > self.player.scenario.spec.duration_s:
            return
        for topic, msg in self.player.step(scenario_s, ()):
            if topic == Topic.SAFETY:
                self.simulator.set_devices(msg)
            elif topic == SIM_WORLD_TOPIC:
                self.simulator.set_world(msg)
            elif topic == SIM_FAULTS_TOPIC:
                self.simulator.apply_fault(msg)


__all__ = ["TRUTH_HEADER", "XgvServer"]
