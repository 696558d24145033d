"""Issue 18: the runtime edge's per-tick input bounds (pure bookkeeping) and the lock-step
link's and ``UdpPort``'s refusal of datagrams from anyone but their peer."""

from __future__ import annotations

import select
import socket

from overdrive.jaus import QueryHeartbeatPulse, encode_datagram
from overdrive.run.xgv_sim import MAX_PER_ADDRESS_PER_TICK, MAX_UNTRUSTED_PER_TICK, Admission
from overdrive.runtime.xgv_link import LoopbackLink, UdpPort

CONTROLLER = ("127.0.0.1", 40000)


def test_trusted_senders_first_and_the_rest_bounded_per_tick() -> None:
    admission = Admission()
    flood = [(b"x", ("127.0.0.1", 50000 + i % 5000)) for i in range(10_000)]
    mine = [(b"q", CONTROLLER)] * 3
    admitted = admission.admit(flood[:5000] + mine + flood[5000:], {CONTROLLER})
    assert admitted[:3] == mine                       # served first, wherever it queued
    assert len(admitted) == 3 + MAX_UNTRUSTED_PER_TICK
    assert admission.dropped == len(flood) - MAX_UNTRUSTED_PER_TICK
    assert admission.admit(flood[:100], {CONTROLLER}) == []   # the tick's budget is spent
    admission.new_tick()
    assert len(admission.admit(flood[:100], set())) == MAX_UNTRUSTED_PER_TICK


def test_even_a_trusted_address_is_bounded_per_tick() -> None:
    admission = Admission()
    admitted = admission.admit([(b"q", CONTROLLER)] * 100, {CONTROLLER})
    assert len(admitted) == MAX_PER_ADDRESS_PER_TICK


def test_lockstep_link_takes_datagrams_only_from_the_other_end() -> None:
    link = LoopbackLink("udp")
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        hello = encode_datagram(QueryHeartbeatPulse())
        for side in ("xgv", "client"):
            stranger.sendto(b"\x01spoof", link.address(side))   # type: ignore[arg-type]
        link.send("client", hello, 0.0)
        link.send("xgv", hello, 0.0)
        assert link.receive("xgv", 0.0) == [(hello, link.address("client"))]
        assert [d for d, _ in link.receive("client", 0.0)] == [hello]
        assert link.foreign == 2 and link.lost == 0
    finally:
        stranger.close()
        link.close()


def test_udp_port_takes_datagrams_only_from_the_xgv_port() -> None:
    xgv = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    xgv.bind(("127.0.0.1", 0))
    other.bind(("127.0.0.1", 0))
    port = UdpPort(xgv.getsockname(), bind=("127.0.0.1", 0))
    try:
        port.send(b"hello")
        _, client = xgv.recvfrom(100)
        other.sendto(b"spoof", client)          # same IP, another port
        xgv.sendto(b"report", client)
        assert port.sock is not None
        select.select([port.sock], [], [], 1.0)   # loopback delivers both at once, in order
        assert port.receive() == [b"report"] and port.foreign == 1
    finally:
        port.close()
        xgv.close()
        other.close()
