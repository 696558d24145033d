"""Choosing TCP ports for a multi-process run's listeners on loopback."""

from __future__ import annotations

import random
import socket
from pathlib import Path
from typing import Final

LISTEN_PORTS: Final = (20000, 32768)
"""Where listening ports are picked: below Linux's default ephemeral range (32768-60999), from
which the kernel takes both ``bind(port 0)`` answers and the source ports of outgoing
connections. A port picked there could be handed out twice, or taken by a peer's dial before
the node binds it (seen under load: the speed node could not listen and the run failed)."""


def ephemeral_range() -> tuple[int, int]:
    try:
        lo, hi = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
        return int(lo), int(hi)
    except (OSError, ValueError):
        return 32768, 60999


WINDOW_TRIES: Final = 500   # random picks in LISTEN_PORTS before falling back to bind(0)


def free_ports(count: int, taken: frozenset[int] = frozenset()) -> list[int]:
    """``count`` distinct TCP ports free on 127.0.0.1 now: in ``LISTEN_PORTS`` outside the
    ephemeral range, and where too few of those are free (a host whose ephemeral range covers
    the window), distinct ports from ``bind(port 0)``."""
    eph_lo, eph_hi = ephemeral_range()
    pick = random.SystemRandom()   # not the scenario's seeded RNG: ports never reach a trace
    ports: list[int] = []
    for attempt in range(WINDOW_TRIES + 2000):
        in_window = attempt < WINDOW_TRIES
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", pick.randrange(*LISTEN_PORTS) if in_window else 0))
            except OSError:
                continue
            port = s.getsockname()[1]
        if port in ports or port in taken or (in_window and eph_lo <= port <= eph_hi):
            continue
        ports.append(port)
        if len(ports) == count:
            return ports
    raise RuntimeError(f"could not find {count} free TCP ports on 127.0.0.1")


def endpoint_port(endpoint: str) -> int | None:
    """The port of a ``tcp/HOST:PORT`` endpoint, else None."""
    _, _, port = (endpoint or "").rpartition(":")
    return int(port) if port.isdigit() else None


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now, outside the ephemeral range (``free_ports``)."""
    return free_ports(1)[0]
