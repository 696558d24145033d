"""The launcher's listening ports: distinct, free, and never where the kernel hands out ports
for outgoing connections (a node that could not bind its port failed a run under load)."""

from __future__ import annotations

import socket

import pytest

from overdrive.runtime import ports as ports_mod
from overdrive.runtime.ports import LISTEN_PORTS, endpoint_port, free_ports


def test_ports_are_distinct_free_and_outside_the_ephemeral_range() -> None:
    lo, hi = ports_mod.ephemeral_range()
    for _ in range(20):
        ports = free_ports(6)
        assert len(set(ports)) == 6
        assert all(LISTEN_PORTS[0] <= p < LISTEN_PORTS[1] and not lo <= p <= hi for p in ports)
        for port in ports:
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                s.bind(("127.0.0.1", port))


def test_a_port_in_use_or_reserved_is_never_picked(monkeypatch: pytest.MonkeyPatch) -> None:
    busy = 25000
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as held:
        try:
            held.bind(("127.0.0.1", busy))
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
                probe.bind(("127.0.0.1", busy + 2))
        except OSError:
            pytest.skip(f"port {busy} or {busy + 2} is in use on this host")
        held.listen()
        monkeypatch.setattr(ports_mod, "LISTEN_PORTS", (busy, busy + 3))
        assert free_ports(1, taken=frozenset({busy + 1})) == [busy + 2]
        first, second = free_ports(2, taken=frozenset({busy + 1}))   # the window has one
        assert first == busy + 2 and second not in (busy, busy + 1, busy + 2)   # then bind(0)


def test_a_host_whose_ephemeral_range_covers_the_window_gets_bind_zero_ports(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ports_mod, "ephemeral_range", lambda: (1024, 65535))
    ports = free_ports(6)
    assert len(set(ports)) == 6 and all(1024 <= p <= 65535 for p in ports)


def testendpoint_port() -> None:
    assert endpoint_port("tcp/127.0.0.1:7447") == 7447
    assert endpoint_port("") is None and endpoint_port("tcp/[::1]:x") is None
