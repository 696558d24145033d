"""A JUDP/UDP endpoint: the only JAUS module that touches sockets and threads.

One UDP socket, bound to ``host:port`` (default port 3794, reference §2; tests pass 0 for an
ephemeral port), sends datagrams and receives them on a background thread. Each received
message goes to every handler whose registered JAUS ID it reaches (255 in either ID matches
any part, reference §1). The endpoint fills headers when sending: source, destination and the
sequence number, counted per (source, destination) and, for messages flagged
service-connection, per (source, destination, command code) from 0 (reference §4).

Replies: the reference (§2) says a JAUS node answers on the sender's IP at port 3794. The
endpoint learns each source ID's address from its datagrams and, by default, answers on the
port the datagram came from (which is 3794 when the peer is bound there); set ``reply_port``
to 3794 to follow the reference literally.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable, Iterable
from typing import Any, Final, NamedTuple

import msgspec

from overdrive.jaus.addresses import JausId
from overdrive.jaus.codec import Header, JausDecodeError, Message
from overdrive.jaus.judp import JUDP_PORT, datagrams, decode_datagram
from overdrive.runtime.udp import open_udp

_log = logging.getLogger(__name__)

Address = tuple[str, int]
_RECV_BUFFER: Final = 65535  # larger than MAX_DATAGRAM_SIZE so oversized datagrams are seen
_SEQUENCE_MODULUS: Final = 0x10000  # reference §1: uint16 sequence number


class Received(NamedTuple):
    """A message taken off the wire, with the address it came from."""

    message: Message
    sender: Address


Handler = Callable[[Received], Any]


class EndpointStats:
    """Counters, for diagnostics and tests."""

    __slots__ = (
        "datagrams_received",
        "datagrams_sent",
        "decode_errors",
        "handler_errors",
        "messages_received",
        "unroutable",
    )

    def __init__(self) -> None:
        self.datagrams_received = 0
        self.datagrams_sent = 0
        self.decode_errors = 0
        self.handler_errors = 0
        self.messages_received = 0
        self.unroutable = 0

    def __repr__(self) -> str:
        return "EndpointStats(" + ", ".join(f"{k}={getattr(self, k)}" for k in self.__slots__) + ")"


class JudpEndpoint:
    """Sends and receives JAUS messages over JUDP; use as a context manager.

    >>> with JudpEndpoint(port=0) as client:               # doctest: +SKIP
    ...     inbox = client.subscribe(DEFAULT_CLIENT_ID)
    ...     client.send(RequestComponentControl(), to=("127.0.0.1", 3794))
    ...     reply = inbox.get(timeout=1.0).message
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = JUDP_PORT,
        *,
        default_peer: Address | None = None,
        reply_port: int | None = None,
        poll_interval_s: float = 0.05,
    ) -> None:
        """Bind now; start receiving with :meth:`start` or by entering the context.

        ``default_peer`` receives messages whose destination has no learned or added address.
        ``poll_interval_s`` bounds how long :meth:`close` waits for the receive thread.
        """
        self._sock = open_udp((host, port), timeout_s=poll_interval_s)
        self._default_peer = default_peer
        self._reply_port = reply_port
        self._lock = threading.Lock()
        self._handlers: list[tuple[JausId, Handler]] = []
        self._peers: dict[JausId, Address] = {}
        self._sequences: dict[tuple[Any, ...], int] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.stats = EndpointStats()

    # ------------------------------------------------------------------ lifecycle

    @property
    def address(self) -> Address:
        """The bound (host, port); the port is the real one when 0 was asked for."""
        host, port = self._sock.getsockname()[:2]
        return host, port

    def start(self) -> JudpEndpoint:
        """Start the receive thread (idempotent)."""
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._receive_loop, name=f"judp-{self.address[1]}", daemon=True
            )
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the receive thread and close the socket (idempotent)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()
        self._sock.close()

    def __enter__(self) -> JudpEndpoint:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # ------------------------------------------------------------------ routing

    def register(self, jaus_id: JausId, handler: Handler) -> None:
        """Call ``handler(received)`` on the receive thread for messages reaching ``jaus_id``."""
        with self._lock:
            self._handlers.append((jaus_id, handler))

    def unregister(self, jaus_id: JausId) -> None:
        """Drop every handler registered for ``jaus_id``."""
        with self._lock:
            self._handlers = [(i, h) for i, h in self._handlers if i != jaus_id]

    def subscribe(self, jaus_id: JausId, maxsize: int = 0) -> queue.Queue[Received]:
        """A queue receiving the messages that reach ``jaus_id``."""
        inbox: queue.Queue[Received] = queue.Queue(maxsize)

        def put(received: Received) -> None:
            try:
                inbox.put_nowait(received)
            except queue.Full:
                _log.warning("inbox of %s full, dropping %s", jaus_id, received.message.name)

        self.register(jaus_id, put)
        return inbox

    def add_peer(self, jaus_id: JausId, address: Address) -> None:
        """Send messages for ``jaus_id`` to ``address``."""
        with self._lock:
            self._peers[jaus_id] = address

    def peer(self, jaus_id: JausId) -> Address | None:
        """Where messages for ``jaus_id`` go: added or learned address, else the default peer."""
        with self._lock:
            return self._peers.get(jaus_id, self._default_peer)

    # ------------------------------------------------------------------ sending

    def next_sequence(
        self, source: JausId, destination: JausId, code: int, service_connection: bool
    ) -> int:
        """The sequence number for the next message on that stream (wraps at 65536)."""
        key: tuple[Any, ...] = (source, destination)
        if service_connection:
            key = (source, destination, code)
        with self._lock:
            sequence = self._sequences.get(key, 0)
            self._sequences[key] = (sequence + 1) % _SEQUENCE_MODULUS
        return sequence

    def address_message(
        self,
        message: Message,
        *,
        destination: JausId | None = None,
        source: JausId | None = None,
        **header_changes: Any,
    ) -> Message:
        """``message`` with its header completed for sending.

        The sequence number is the stream's next one unless ``sequence=`` is given.
        """
        changes = dict(header_changes)
        if destination is not None:
            changes["destination"] = destination
        if source is not None:
            changes["source"] = source
        header: Header = message.header.replace(**changes) if changes else message.header
        if "sequence" not in changes:
            header = header.replace(
                sequence=self.next_sequence(
                    header.source, header.destination, message.code, header.service_connection
                )
            )
        return msgspec.structs.replace(message, header=header)

    def send(
        self,
        message: Message,
        to: Address | None = None,
        *,
        destination: JausId | None = None,
        source: JausId | None = None,
        **header_changes: Any,
    ) -> Message:
        """Send one message in its own datagram; returns it as sent (header filled in).

        ``to`` defaults to the destination's peer address. Other keywords change header
        fields (``priority``, ``ack_nak``, ``service_connection``).
        """
        return self.send_many(
            [message], to, destination=destination, source=source, **header_changes
        )[0]

    def send_many(
        self,
        messages: Iterable[Message],
        to: Address | None = None,
        *,
        destination: JausId | None = None,
        source: JausId | None = None,
        packed: bool = False,
        **header_changes: Any,
    ) -> list[Message]:
        """Send several messages, one per datagram, or as few datagrams as they fit in when
        ``packed`` (reference §2; only for peers known to read past the first message)."""
        sent = [
            self.address_message(m, destination=destination, source=source, **header_changes)
            for m in messages
        ]
        if not sent:
            return sent
        target = to if to is not None else self.peer(sent[0].header.destination)
        if target is None:
            raise LookupError(
                f"no address for {sent[0].header.destination}; pass to= or add_peer()"
            )
        for datagram in datagrams(sent, packed):
            self._sock.sendto(datagram, target)
            self.stats.datagrams_sent += 1
        return sent

    def reply(
        self,
        received: Received,
        message: Message,
        *,
        source: JausId | None = None,
        **header_changes: Any,
    ) -> Message:
        """Answer ``received``: to its source ID, at the address replies for it go, from the ID
        it was sent to (pass ``source`` when that was a broadcast ID)."""
        asked = received.message.header
        if source is None:
            if asked.destination.is_broadcast:
                raise ValueError(f"{asked.destination} is a broadcast ID: pass source=")
            source = asked.destination
        to = (received.sender[0], self._reply_port or received.sender[1])
        return self.send(message, to, destination=asked.source, source=source, **header_changes)

    # ------------------------------------------------------------------ receiving

    def _receive_loop(self) -> None:
        while not self._stop.is_set():
            try:
                data, sender = self._sock.recvfrom(_RECV_BUFFER)
            except TimeoutError:
                continue
            except OSError:
                if not self._stop.is_set():
                    _log.exception("JUDP receive failed")
                return
            self.dispatch(data, sender[:2])

    def dispatch(self, data: bytes, sender: Address) -> None:
        """Decode one datagram and hand its messages to the handlers they reach."""
        self.stats.datagrams_received += 1
        try:
            messages = decode_datagram(data)
        except JausDecodeError as exc:
            self.stats.decode_errors += 1
            _log.warning("dropping datagram from %s:%s: %s", sender[0], sender[1], exc)
            return
        with self._lock:
            handlers = list(self._handlers)
        for message in messages:
            self.stats.messages_received += 1
            header = message.header
            if header.source.is_valid and not header.source.is_broadcast:
                with self._lock:
                    self._peers[header.source] = (sender[0], self._reply_port or sender[1])
            targets = [h for jaus_id, h in handlers if header.destination.matches(jaus_id)]
            if not targets:
                self.stats.unroutable += 1
                continue
            received = Received(message, sender)
            for handler in targets:
                try:
                    handler(received)
                except Exception:
                    self.stats.handler_errors += 1
                    _log.exception("JAUS handler failed on %s", message.name)
