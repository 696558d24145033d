"""A CAN bus on loopback for machines without SocketCAN: a small socketcand-protocol hub.

python-can's ``socketcand`` interface connects to it unchanged (``interface="socketcand",
host="127.0.0.1", port=PORT, channel="can0"``). The handshake is socketcand's raw mode
(``< hi >``, ``< open CHANNEL >`` / ``< ok >``, ``< rawmode >`` / ``< ok >``); then a client's
``< send ID LEN B0 B1 .. >`` reaches every other client on the same channel as ``< frame ID
SECONDS.MICROS DATA >``, as a CAN bus delivers a frame to every node but its sender. Malformed
commands are counted and dropped, never relayed. Loopback only by default: it is a test bus,
not a gateway.

The hub is the runtime edge: it opens sockets and reads the wall clock for frame time stamps.
It runs in a thread of its own (``start``) or in the foreground (``serve_forever``:
``overdrive can-hub``).
"""

from __future__ import annotations

import contextlib
import re
import selectors
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Final

SOCKETCAND_PORT: Final = 29536
"""socketcand's default TCP port."""
MAX_BACKLOG_BYTES: Final = 256 * 1024
"""What the hub queues for a client that does not read (stopped, hung): beyond it, frames to that
client are dropped and counted, as a CAN node's full receive buffer drops them; the bus and the
other clients go on."""
MAX_LINE_CHARS: Final = 200
"""Longest command accepted (a classic frame is ~50 characters); longer input is dropped."""
_SEND = re.compile(r"< send ([0-9A-Fa-f]{1,8}) ([0-8]) *((?:[0-9A-Fa-f]{1,2} +)*)>")
_OPEN = re.compile(r"< open (\S{1,32}) >")


@dataclass
class _Client:
    sock: socket.socket
    buffer: str = ""
    channel: str | None = None
    raw: bool = False
    out: bytearray = field(default_factory=bytearray)


class CanHub:
    """A socketcand-protocol hub on ``host:port`` (port 0: any free port, see ``port``)."""

    def __init__(self, host: str = "127.0.0.1", port: int = SOCKETCAND_PORT) -> None:
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.host = host
        self.port: int = self._listener.getsockname()[1]
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ)
        self._clients: dict[socket.socket, _Client] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.relayed = 0
        self.malformed = 0
        self.overflowed = 0

    def start(self) -> CanHub:
        """Serve in a daemon thread; returns self."""
        self._thread = threading.Thread(target=self.serve_forever, name="can-hub", daemon=True)
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        while not self._stop.is_set():
            for key, events in self._selector.select(timeout=0.1):
                if key.fileobj is self._listener:
                    self._accept()
                    continue
                sock = key.fileobj
                if events & selectors.EVENT_WRITE and sock in self._clients:
                    self._flush(self._clients[sock])  # type: ignore[index]
                if events & selectors.EVENT_READ:
                    self._read(sock)  # type: ignore[arg-type]

    def stop(self) -> None:
        """Ask ``serve_forever`` to return (safe from a signal handler)."""
        self._stop.set()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        for sock in list(self._clients):
            self._drop(sock)
        self._selector.close()
        self._listener.close()

    def __enter__(self) -> CanHub:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def clients(self) -> int:
        return len(self._clients)

    def _accept(self) -> None:
        try:
            sock, _ = self._listener.accept()
        except OSError:
            return
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)
        self._clients[sock] = _Client(sock)
        self._selector.register(sock, selectors.EVENT_READ)
        self._write(self._clients[sock], "< hi >")

    def _drop(self, sock: socket.socket) -> None:
        self._clients.pop(sock, None)
        with contextlib.suppress(KeyError, ValueError):
            self._selector.unregister(sock)
        sock.close()

    def _read(self, sock: socket.socket) -> None:
        client = self._clients.get(sock)
        if client is None:
            return
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            self._drop(sock)
            return
        client.buffer += data.decode("ascii", errors="replace")
        while True:
            start = client.buffer.find("<")
            end = client.buffer.find(">", start + 1) if start >= 0 else -1
            if start < 0 or end < 0:
                if len(client.buffer) > MAX_LINE_CHARS or start < 0:
                    self.malformed += bool(client.buffer.strip())
                    client.buffer = "" if start < 0 else client.buffer[start:][-MAX_LINE_CHARS:]
                break
            line = client.buffer[start:end + 1]
            client.buffer = client.buffer[end + 1:]
            self._command(client, line)

    def _command(self, client: _Client, line: str) -> None:
        if client.channel is None:
            match = _OPEN.fullmatch(line)
            if match:
                client.channel = match.group(1)
                self._write(client, "< ok >")
            else:
                self.malformed += 1
            return
        if not client.raw:
            if line == "< rawmode >":
                client.raw = True
                self._write(client, "< ok >")
            else:
                self.malformed += 1
            return
        match = _SEND.fullmatch(line)
        if match is None:
            self.malformed += 1
            return
        ident, length, body = match.group(1), int(match.group(2)), match.group(3).split()
        if len(body) != length or int(ident, 16) > 0x1FFFFFFF or (
                len(ident) <= 3 and int(ident, 16) > 0x7FF):
            self.malformed += 1
            return
        data = "".join(f"{int(b, 16):02X}" for b in body)
        ident_text = f"{int(ident, 16):03X}" if len(ident) <= 3 else f"{int(ident, 16):08X}"
        now = time.time()
        text = f"< frame {ident_text} {now:.6f} {data} >"
        self.relayed += 1
        for other in list(self._clients.values()):
            if other is not client and other.raw and other.channel == client.channel:
                self._write(other, text)

    def _write(self, client: _Client, text: str) -> None:
        if len(client.out) > MAX_BACKLOG_BYTES:
            self.overflowed += 1
            return
        client.out += text.encode("ascii")
        self._flush(client)

    def _flush(self, client: _Client) -> None:
        try:
            sent = client.sock.send(client.out) if client.out else 0
        except BlockingIOError:
            sent = 0
        except OSError:
            self._drop(client.sock)
            return
        del client.out[:sent]
        events = selectors.EVENT_READ | (selectors.EVENT_WRITE if client.out else 0)
        with contextlib.suppress(KeyError, ValueError):
            self._selector.modify(client.sock, events)
