"""The one place the stack opens a UDP socket: every JAUS/UDP edge (the lock-step loopback link,
the port to a remote XGV, the simulated XGV's server, the JUDP endpoint) binds through
``open_udp``, so how a socket is set up (buffer, blocking, clean-up on a failed bind) is decided
once."""

from __future__ import annotations

import socket

Address = tuple[str, int]


def open_udp(bind: Address, *, receive_buffer_bytes: int | None = None,
             timeout_s: float | None = 0.0) -> socket.socket:
    """A UDP/IPv4 socket bound to ``bind``: non-blocking (``timeout_s=0``), blocking with a
    timeout, or blocking (``None``); ``SO_RCVBUF`` raised to ``receive_buffer_bytes`` when given
    (before the bind). Closed again if any step fails (``OSError`` propagates)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        if receive_buffer_bytes is not None:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
        sock.bind(bind)
        sock.settimeout(timeout_s)
    except OSError:
        sock.close()
        raise
    return sock
