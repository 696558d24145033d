"""The one place the stack opens a UDP socket: every JAUS/UDP edge (the lock-step loopback link,
the port to a remote XGV, the simulated XGV's server, the JUDP endpoint) binds through
``open_udp``, so how a socket is set up (buffer, blocking, clean-up on a failed bind) is decided
once."""

from __future__ import annotations

import socket

Address = tuple[str, int]
MAX_PORT = 65535                     # UDP ports are 16 bits; 0 asks the system for a free one


def parse_address(text: str, what: str, *, bind: bool, default_port: int | None = None) -> Address:
    """``HOST:PORT`` (or ``HOST`` when ``default_port`` is given) as an address, or
    ``ValueError`` with a one-line reason naming ``what``. The port is ASCII digits only
    (``str.isdigit`` also takes superscripts such as "²", which ``int`` refuses), 1..65535
    for a destination, 0..65535 for a ``bind`` (0: any free port)."""
    low = 0 if bind else 1
    form = "HOST or HOST:PORT" if default_port is not None else "HOST:PORT"
    reason = f"{what}: expected {form} with a port {low}..{MAX_PORT}, got {text!r}"
    host, sep, port = text.rpartition(":")
    if not sep:
        if default_port is None:
            raise ValueError(reason)
        host, port = text, str(default_port)
    if (not host or not host.isprintable() or not port.isascii() or not port.isdigit()
            or len(port) > 5 or not low <= int(port) <= MAX_PORT):
        raise ValueError(reason)
    return host, int(port)


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
