"""The XGV over JAUS/UDP: datagram links and the nodes at the runtime edge.

The XGV logic is sans-IO (``vehicle.xgv.XgvSimulator``, ``vehicle.xgv_client.XgvClient``);
this module carries their datagrams and puts them on the bus:

- ``LoopbackLink``: the two ends of one run in one process. ``transport="udp"`` (the default
  for ``interface: jaus``) uses two real UDP sockets on 127.0.0.1 with ephemeral ports;
  ``"memory"`` hands the same bytes over in memory (``interface: embedded`` with
  ``control: motion-profile``). Runs stay deterministic: each end drains exactly the datagrams
  the other sent (waiting for loopback delivery if needed), so nothing depends on timing, and
  takes datagrams only from the other end's address (others are dropped and counted). The
  scenario's faults on channel ``jaus`` (drop, loss, delay, duplicate, reorder) act on the
  datagrams, in both directions or one (``JausFault.direction``: ``to_vehicle``, the stack's
  datagrams to the XGV; ``from_vehicle``, the XGV's to the stack); loss drawn from the
  scenario's seed.
- ``UdpPort``: one non-blocking socket towards a remote XGV (``overdrive drive``).
- Nodes, in tick order: ``XgvSimNode`` ("xgv": the simulated XGV; it also publishes what an
  XGV does not report over JAUS: the simulator's ground truth and the forward radar, an
  external sensor in this setup), ``XgvSensorNode`` ("vehicle": the client's sensor side,
  first like the vehicle), the servers, ``XgvCommandNode`` ("xgv-client": the client's
  command side, last, so the XGV executes a command 10 ms after the speed server made it,
  as in the embedded run).

Sockets open on the first step and close with ``close()`` (``run_scenario`` closes every node).
"""

from __future__ import annotations

import contextlib
import select
import socket
import time
from collections.abc import Callable, Sequence
from typing import Any, Final, Literal, NamedTuple

from overdrive.bus.faults import ChannelFaults, Window
from overdrive.messages import SIM_FAULTS_TOPIC, SIM_WORLD_TOPIC, Topic
from overdrive.runtime.udp import Address, open_udp
from overdrive.vehicle.xgv import XgvSimulator
from overdrive.vehicle.xgv_client import XgvClient

LOOPBACK: Final = "127.0.0.1"
DELIVERY_TIMEOUT_S: Final = 1.0      # a loopback datagram not there after this is lost
RECEIVE_BUFFER: Final = 65535        # above the JUDP maximum, so oversized datagrams are seen
SOCKET_BUFFER_BYTES: Final = 1 << 20
STALL_BUFFER_BYTES: Final = 4 << 20  # as xgv-sim's: ~3 s of the XGV's reports (capped by
                                     # net.core.rmem_max)
_TO = {"xgv": "client", "client": "xgv"}
Side = Literal["xgv", "client"]
Direction = Literal["both", "to_vehicle", "from_vehicle"]
_RECEIVERS: Final[dict[str, tuple[str, ...]]] = {
    "both": ("xgv", "client"), "to_vehicle": ("xgv",), "from_vehicle": ("client",)}
"""The ends whose incoming datagrams a fault of each direction acts on."""


class JausFault(NamedTuple):
    """One fault window on the JAUS link (a scenario event on channel ``jaus``)."""

    kind: str
    start_s: float
    for_s: float
    delay_s: float = 0.0
    fraction: float = 1.0
    direction: Direction = "both"


class LoopbackLink:
    """Both ends of the JAUS link of one lock-step run (see the module docstring)."""

    def __init__(self, transport: Literal["udp", "memory"] = "udp",
                 faults: Sequence[JausFault | tuple[Any, ...]] = (),
                 seed: int = 0) -> None:
        self.transport = transport
        self.faults = ChannelFaults(seed=seed)
        for fault in faults:
            f = JausFault(*fault)
            if f.direction not in _RECEIVERS:
                raise ValueError(f"JAUS fault direction: one of {tuple(_RECEIVERS)}, got "
                                 f"{f.direction!r}")
            for side in _RECEIVERS[f.direction]:
                self.faults.windows.setdefault(f"jaus>{side}", []).append(
                    Window(f.kind, f.start_s, f.start_s + f.for_s, f.delay_s, f.fraction))
        self.sockets: dict[str, socket.socket] = {}
        self.addresses: dict[str, Address] = {"xgv": ("memory", 1), "client": ("memory", 2)}
        self.queues: dict[str, list[tuple[bytes, Address]]] = {"xgv": [], "client": []}
        self.expected = {"xgv": 0, "client": 0}
        self.received = {"xgv": 0, "client": 0}
        self.lost = 0
        self.foreign = 0        # datagrams from any address but the other end: dropped
        self.closed = False

    def _open(self) -> None:
        if self.sockets or self.transport == "memory":
            return
        if self.closed:
            raise RuntimeError("the JAUS link is closed")
        try:
            for side in _TO:
                sock = open_udp((LOOPBACK, 0), receive_buffer_bytes=SOCKET_BUFFER_BYTES)
                self.sockets[side] = sock
                self.addresses[side] = sock.getsockname()[:2]
        except OSError:
            self.close()
            raise

    def address(self, side: Side) -> Address:
        self._open()
        return self.addresses[side]

    def send(self, side: Side, data: bytes, now_s: float, to: Address | None = None) -> None:
        """Send from ``side`` to the other end (or to ``to``, which may be elsewhere)."""
        self._open()
        dest = _TO[side]
        if to is not None and to != self.addresses[dest]:
            if self.transport == "udp":
                self.sockets[side].sendto(data, to)
            return
        self.faults.now_s = now_s
        for datagram in self.faults.route(f"jaus>{dest}", data):
            self._deliver(side, dest, datagram)

    def _deliver(self, side: str, dest: str, data: bytes) -> None:
        if self.transport == "memory":
            self.queues[dest].append((data, self.addresses[side]))
        else:
            self.sockets[side].sendto(data, self.addresses[dest])
        self.expected[dest] += 1

    def receive(self, side: Side, now_s: float) -> list[tuple[bytes, Address]]:
        """Every datagram sent to ``side`` so far (held ones once their delay is over)."""
        self._open()
        self.faults.now_s = now_s
        for topic, data in self.faults.due():
            dest = topic.split(">", 1)[1]
            self._deliver(_TO[dest], dest, data)
        if self.transport == "memory":
            got, self.queues[side] = self.queues[side], []
            self.received[side] += len(got)
            return got
        sock = self.sockets[side]
        peer = self.addresses[_TO[side]]
        got = []
        while True:
            try:
                data, sender = sock.recvfrom(RECEIVE_BUFFER)
            except BlockingIOError:
                if self.received[side] >= self.expected[side]:
                    return got
                ready, _, _ = select.select([sock], [], [], DELIVERY_TIMEOUT_S)
                if not ready:
                    self.lost += self.expected[side] - self.received[side]
                    self.received[side] = self.expected[side]
                continue
            if sender[:2] != peer:   # issue 18: only the other end of the run's link
                self.foreign += 1
                continue
            self.received[side] += 1
            got.append((data, sender[:2]))

    def close(self) -> None:
        self.closed = True
        for sock in self.sockets.values():
            sock.close()
        self.sockets.clear()


class UdpPort:
    """A non-blocking UDP socket talking to one remote XGV (wall-clock runs)."""

    def __init__(self, remote: Address, bind: Address = ("0.0.0.0", 0),
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.remote = remote
        self.bind = bind
        self.sock: socket.socket | None = None
        self.foreign = 0
        self.clock = clock

    def _open(self) -> socket.socket:
        if self.sock is None:
            # a host name resolved once, so replies can be matched against the address
            self.remote = (socket.gethostbyname(self.remote[0]), self.remote[1])
            # a queue deep enough to hold seconds of 100 Hz reports while the stack is stalled
            # (they are counted by their stamps when read; dropped ones would be a gap)
            self.sock = open_udp(self.bind, receive_buffer_bytes=STALL_BUFFER_BYTES)
        return self.sock

    def send(self, data: bytes) -> None:
        with contextlib.suppress(BlockingIOError):
            self._open().sendto(data, self.remote)

    def receive(self) -> list[bytes]:
        return [data for data, _ in self.receive_timed()]

    def receive_timed(self) -> list[tuple[bytes, float]]:
        """What is waiting, each with when it was read (``clock``: any steady clock; the
        reports' age is measured against their stamps, so its origin does not matter)."""
        sock = self._open()
        got = []
        while True:
            try:
                data, sender = sock.recvfrom(RECEIVE_BUFFER)
            except (BlockingIOError, ConnectionRefusedError):
                return got
            if sender[:2] != self.remote:   # issue 18: the XGV's address and port only
                self.foreign += 1
                continue
            got.append((data, self.clock()))

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None


# --------------------------------------------------------------------------- nodes

class XgvSimNode:
    """The simulated XGV as the first node of a lock-step run."""

    name = "xgv"
    period_s = 0.01
    subscriptions = (Topic.SAFETY, SIM_WORLD_TOPIC, SIM_FAULTS_TOPIC)

    def __init__(self, simulator: XgvSimulator, link: LoopbackLink) -> None:
        self.simulator = simulator
        self.link = link

    @property
    def gate_interventions(self) -> dict[str, int]:
        return self.simulator.gate_interventions

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        sim, link = self.simulator, self.link
        for topic, msg in inbox:
            if topic == Topic.SAFETY:
                sim.set_devices(msg)
            elif topic == SIM_WORLD_TOPIC:
                sim.set_world(msg)
            elif topic == SIM_FAULTS_TOPIC:
                sim.apply_fault(msg)
        for data, sender in link.receive("xgv", now_s):
            for reply, address in sim.receive(data, sender, now_s):
                link.send("xgv", reply, now_s, to=address)
        for datagram, address in sim.step(now_s):
            link.send("xgv", datagram, now_s, to=address)
        latest = sim.latest
        return [(topic, latest[topic]) for topic in (Topic.RADAR, Topic.TRUTH) if topic in latest]

    def close(self) -> None:
        self.link.close()


class ClientPort:
    """What the client nodes need from a link: receive and send the client's datagrams."""

    def __init__(self, link: LoopbackLink | UdpPort) -> None:
        self.link = link

    def receive(self, now_s: float) -> list[tuple[bytes, float]]:
        """The client's datagrams, each with when it was read: the lock-step clock on the
        loopback link, the wall clock on a real one (a stalled stack reads its queue late)."""
        if isinstance(self.link, LoopbackLink):
            return [(data, now_s) for data, _ in self.link.receive("client", now_s)]
        return self.link.receive_timed()

    def send(self, data: bytes, now_s: float) -> None:
        if isinstance(self.link, LoopbackLink):
            self.link.send("client", data, now_s)
        else:
            self.link.send(data)

    def close(self) -> None:
        self.link.close()


class XgvSensorNode:
    """The client's sensor side: the XGV's reports in, the stack's sensor messages out."""

    name = "vehicle"
    period_s = 0.01
    subscriptions: tuple[str, ...] = ()

    def __init__(self, client: XgvClient, port: ClientPort) -> None:
        self.client = client
        self.port = port

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        for data, read_s in self.port.receive(now_s):
            self.client.receive(data, now_s, read_s)
        return self.client.sensor_outputs(now_s)

    def link_report(self) -> dict[str, Any]:
        """``summary.json`` ``link``: the reports' age, the round trips and the loss measured."""
        return {**self.client.link_time.report(), "probes": self.client.round_trips.report()}

    def close(self) -> None:
        self.port.close()


class XgvCommandNode:
    """The client's command side: the stack's commands in, JAUS commands out."""

    name = "xgv-client"
    period_s = 0.01
    subscriptions = (Topic.PEDALS, Topic.STEER, Topic.POWERTRAIN, Topic.SET_SPEED,
                     Topic.SPEED_STATE)

    def __init__(self, client: XgvClient, port: ClientPort) -> None:
        self.client = client
        self.port = port
        self.last_now_s = 0.0

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.last_now_s = now_s
        out = self.client.take_inputs(inbox)
        for datagram in self.client.command_datagrams(now_s):
            self.port.send(datagram, now_s)
        return out

    def close(self) -> None:
        """Give control back (the XGV pauses), then close the socket."""
        with contextlib.suppress(OSError, RuntimeError):
            for datagram in self.client.release():
                self.port.send(datagram, self.last_now_s)
        self.port.close()


__all__ = ["ClientPort", "JausFault", "LoopbackLink", "UdpPort", "XgvCommandNode", "XgvSensorNode", "XgvSimNode"]
