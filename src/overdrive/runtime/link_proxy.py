"""``overdrive link-proxy``: a UDP fault proxy between a JAUS client and its vehicle.

The client sends to ``listen`` instead of the vehicle; the proxy forwards each datagram from
its upstream socket (bound to ``upstream_bind``) to ``to``, and each datagram from ``to`` back
to the client, after ``bus.link_faults.LinkFaults`` decided to lose, cut or delay it. The
first address that sends to ``listen`` is the client; datagrams from any other address, and
upstream datagrams from anyone but ``to``, are dropped and counted (``foreign``). The link's
clock starts with the client's first datagram (as ``xgv-sim --scenario`` does), so
``--cut AT_S:FOR_S`` counts from when the client starts talking. The clock is passed in
(``serve(clock=...)``); the decisions never read it.
"""

from __future__ import annotations

import heapq
import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Final

from overdrive.bus.link_faults import LinkFaults, LinkFaultSpec
from overdrive.runtime.udp import Address, open_udp

RECEIVE_BUFFER: Final = 65535         # above the JUDP maximum (4101): nothing is truncated
SOCKET_BUFFER_BYTES: Final = 1 << 20
IDLE_WAIT_S: Final = 0.05             # longest select() with nothing held: stop() is seen
MAX_HELD: Final = 100_000             # datagrams held for delay at once; more are dropped
                                      # (counted ``overflow``): 100 Hz x 60 s x 2 directions
                                      # of the longest delay fit with room


class LinkProxy:
    """The sockets and the loop of ``overdrive link-proxy`` (see the module docstring)."""

    def __init__(self, listen: Address, to: Address, spec: LinkFaultSpec,
                 upstream_bind: Address = ("0.0.0.0", 0)) -> None:
        self.to = (socket.gethostbyname(to[0]), to[1])   # resolved once: replies are
        self.spec = spec                                  # matched against the address
        self.faults = {"to-vehicle": LinkFaults(spec, "to-vehicle"),
                       "from-vehicle": LinkFaults(spec, "from-vehicle")}
        self.listen_sock = open_udp(listen, receive_buffer_bytes=SOCKET_BUFFER_BYTES)
        try:
            self.upstream_sock = open_udp(upstream_bind, receive_buffer_bytes=SOCKET_BUFFER_BYTES)
        except OSError:
            self.listen_sock.close()
            raise
        self.client: Address | None = None
        self.origin_s: float | None = None
        self.held: list[tuple[float, int, str, bytes]] = []   # (release, order, direction, data)
        self.order = 0
        self.foreign = 0
        self.overflow = 0
        self.send_errors = 0
        self._stop = threading.Event()

    @property
    def address(self) -> Address:
        host, port = self.listen_sock.getsockname()[:2]
        return host, port

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.listen_sock.close()
        self.upstream_sock.close()

    def __enter__(self) -> LinkProxy:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def stats(self) -> str:
        parts = [f"{d}: " + ", ".join(f"{k} {v}" for k, v in f.counts.items())
                 for d, f in self.faults.items()]
        return "; ".join([*parts, f"foreign {self.foreign}", f"overflow {self.overflow}",
                          f"send errors {self.send_errors}"])

    def _take(self, direction: str, data: bytes, now_s: float) -> None:
        assert self.origin_s is not None
        release = self.faults[direction].decide(now_s - self.origin_s)
        if release is None:
            return
        if len(self.held) >= MAX_HELD:
            self.overflow += 1
            return
        self.order += 1
        heapq.heappush(self.held, (release + self.origin_s, self.order, direction, data))

    def _read(self, now_s: float) -> None:
        while True:
            try:
                data, sender = self.listen_sock.recvfrom(RECEIVE_BUFFER)
            except (BlockingIOError, ConnectionResetError):
                break
            sender = sender[:2]
            if self.client is None:
                self.client, self.origin_s = sender, now_s
            if sender != self.client:
                self.foreign += 1
                continue
            self._take("to-vehicle", data, now_s)
        while True:
            try:
                data, sender = self.upstream_sock.recvfrom(RECEIVE_BUFFER)
            except (BlockingIOError, ConnectionResetError):
                break
            if sender[:2] != self.to or self.client is None:
                self.foreign += 1
                continue
            self._take("from-vehicle", data, now_s)

    def _release(self, now_s: float) -> None:
        while self.held and self.held[0][0] <= now_s:
            _, _, direction, data = heapq.heappop(self.held)
            sock, dest = ((self.upstream_sock, self.to) if direction == "to-vehicle"
                          else (self.listen_sock, self.client))
            try:
                sock.sendto(data, dest)
            except OSError:
                self.send_errors += 1

    def serve(self, duration_s: float | None = None,
              clock: Callable[[], float] = time.monotonic) -> None:
        """Forward until ``stop()`` or ``duration_s`` (from the start)."""
        start = clock()
        socks = [self.listen_sock, self.upstream_sock]
        while not self._stop.is_set():
            now = clock()
            if duration_s is not None and now - start >= duration_s:
                return
            wait = IDLE_WAIT_S if not self.held else min(IDLE_WAIT_S,
                                                         max(0.0, self.held[0][0] - now))
            ready, _, _ = select.select(socks, [], [], wait)
            if ready:
                self._read(clock())
            self._release(clock())


__all__ = ["LinkProxy"]
