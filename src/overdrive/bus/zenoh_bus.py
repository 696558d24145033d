"""Zenoh bus: the nodes' publish/subscribe interface across processes.

Key expressions are ``overdrive/<vehicle>/<topic>``, e.g. ``overdrive/ego/speed/set_speed``
(topics from ``overdrive.messages.Topic``; ``<vehicle>`` defaults to ``ego`` and lets several
vehicles share one network). Liveliness tokens ``overdrive/<vehicle>/_alive/<node>`` say which
nodes are up. Payloads are ``overdrive.bus.wire`` frames.

Delivery: Zenoh calls the subscriber callbacks on its own threads; each callback decodes the
frame, checks the sender against the publisher policy and appends ``(topic, msg)`` to a
``SafeInbox`` under a lock. The runtime drains the inbox (one swap under the lock) before each
step, so a node still sees the messages received since its last step, in arrival order. Taps
(recording, ``overdrive echo``) are queued the same way and delivered by ``pump()`` on the
runtime's thread, never on a Zenoh thread.

Publisher policy: ``PUBLISHERS[topic]`` is the set of node names allowed to publish on it.
A frame whose envelope ``sender`` is not in the set is dropped and counted, never delivered; for
actuator commands the message's own ``source`` must also equal the sender. This is a check
against mis-wiring and stray tools (``overdrive pub`` sends as ``cli`` unless told otherwise),
not authentication: the sender name is self-declared. Authentication is Zenoh's job (user and
password or mutual TLS, with access-control rules per key expression); see
``docs/multiprocess.md`` and ``config/zenoh-locked-down.json5``.

Network hygiene: ``session_config`` always disables multicast and gossip scouting, never
leaves Zenoh's default ``tcp/[::]:0`` listener in place, and refuses endpoints outside
127.0.0.0/8 unless ``allow_remote`` is given.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import threading
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import msgspec
import zenoh

from overdrive.bus.local import ChannelModel, Envelope, Tap
from overdrive.bus.wire import Registry, WireError
from overdrive.messages import Notice, Topic

KEY_ROOT = "overdrive"
DEFAULT_VEHICLE = "ego"
DEFAULT_PORT = 7447                       # Zenoh's registered port
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
LOOPBACK_NET = ipaddress.ip_network("127.0.0.0/8")  # the only network used by default
ALIVE = "_alive"                          # liveliness tokens: overdrive/<vehicle>/_alive/<node>
CONNECT_RETRY = {"period_init_ms": 50, "period_max_ms": 500, "period_increase_factor": 1.5}
"""A restarted peer is found again within 0.5 s (Zenoh's default backoff grows to 4 s)."""

SIM = frozenset({"scenario"})             # the scenario player stands in for planner and world
VEHICLE_SIDE = frozenset({"vehicle", "xgv"})
PUBLISHERS: dict[str, frozenset[str]] = {
    Topic.MOVE_COMMAND: SIM | {"planner"},
    Topic.MOVE_REPLY: frozenset({"move"}),
    Topic.MOVE_STATUS: frozenset({"move"}),
    Topic.STEERING: SIM | {"move", "planner"},
    Topic.MAX_SPEED: SIM | {"move", "planner"},
    Topic.ADVANCE: SIM | {"move", "planner"},
    Topic.DRIVE_MODE: frozenset({"move"}),
    Topic.DRIVING_STATUS: frozenset({"driving"}),
    Topic.SET_SPEED: SIM | {"driving"},
    Topic.SPEED_STATE: frozenset({"speed"}),
    Topic.PEDALS: SIM | {"speed"},
    Topic.STEER: SIM | {"driving"},
    Topic.POWERTRAIN: SIM | {"speed"},
    Topic.SAFETY: SIM | VEHICLE_SIDE,
    Topic.VEHICLE_STATUS: VEHICLE_SIDE,
    Topic.WHEEL_SPEED: VEHICLE_SIDE,
    Topic.GPS_INS: VEHICLE_SIDE,
    Topic.IMU: VEHICLE_SIDE,
    Topic.RADAR: VEHICLE_SIDE,
    Topic.TRUTH: VEHICLE_SIDE,
    "sim/world": SIM,
    "sim/faults": SIM,
}
"""Who may publish on each topic; topics not listed (``events``, extra topics) are open."""

SOURCE_MUST_MATCH = frozenset({Topic.PEDALS, Topic.STEER, Topic.POWERTRAIN})
"""Actuator commands carry ``source``; on the wire it must equal the envelope sender."""

_FORBIDDEN_TOPIC_CHARS = set("*$?#@ ")


def check_topic(topic: str) -> str:
    """Raise ValueError unless ``topic`` can be a chunk path of a key expression."""
    if not topic or topic.startswith("/") or topic.endswith("/") or "//" in topic \
            or _FORBIDDEN_TOPIC_CHARS & set(topic) or topic.split("/")[0] == ALIVE:
        raise ValueError(f"invalid topic {topic!r}: use chunks like 'speed/set_speed'")
    return topic


def key_for(vehicle: str, topic: str) -> str:
    return f"{KEY_ROOT}/{vehicle}/{topic}"


def _check_endpoint(endpoint: str, allow_remote: bool) -> str:
    proto, _, rest = endpoint.partition("/")
    if proto not in ("tcp", "tls", "udp", "quic") or not rest:
        raise ValueError(f"endpoint {endpoint!r}: expected PROTO/HOST:PORT, e.g. {DEFAULT_ENDPOINT}")
    host, _, port = rest.partition("#")[0].rpartition(":")
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"endpoint {endpoint!r}: bad port")
    if not allow_remote:
        try:
            loopback = ipaddress.ip_address(host) in LOOPBACK_NET
        except ValueError:
            loopback = False
        if not loopback:
            raise ValueError(f"endpoint {endpoint!r} is not on loopback (127.0.0.0/8); "
                             "pass --allow-remote to use other networks")
    return endpoint


def session_config(*, mode: str = "peer", listen: Iterable[str] = (), connect: Iterable[str] = (),
                   base_file: str | Path | None = None, user: str | None = None,
                   password: str | None = None, allow_remote: bool = False) -> zenoh.Config:
    """A Zenoh config with explicit endpoints and scouting off.

    ``base_file`` (JSON5: TLS, access control, authentication) is loaded first; endpoints, mode,
    scouting and the connect retry are then set here and override it. ``user``/``password``
    fill the user-password authentication (its ``dictionary_file`` comes from ``base_file``).
    """
    if mode not in ("peer", "client"):
        raise ValueError(f"mode must be peer or client, got {mode!r}")
    listen = [_check_endpoint(e, allow_remote) for e in listen]
    connect = [_check_endpoint(e, allow_remote) for e in connect]
    if mode == "client" and (listen or not connect):
        raise ValueError("a client needs --connect and cannot --listen")
    config = zenoh.Config.from_file(str(base_file)) if base_file is not None else zenoh.Config()
    config.insert_json5("mode", json.dumps(mode))
    config.insert_json5("listen/endpoints", json.dumps(listen))
    config.insert_json5("connect/endpoints", json.dumps(connect))
    config.insert_json5("connect/retry", json.dumps(CONNECT_RETRY))
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("scouting/gossip/enabled", "false")
    if user is not None:
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password or ""))
    return config


class SafeInbox:
    """A node's inbox filled from other threads: ``append`` and ``drain`` under one lock."""

    __slots__ = ("_items", "_lock")

    def __init__(self) -> None:
        self._items: deque[Envelope] = deque()
        self._lock = threading.Lock()

    def append(self, envelope: Envelope) -> None:
        with self._lock:
            self._items.append(envelope)

    def drain(self) -> list[Envelope]:
        """Everything received since the last drain, in arrival order."""
        with self._lock:
            items, self._items = self._items, deque()
        return list(items)

    def __len__(self) -> int:
        return len(self._items)


class BusStats:
    """Counters of one bus; updated from Zenoh threads under the bus lock."""

    def __init__(self) -> None:
        self.published = 0
        self.received = 0
        self.decode_errors: dict[str, int] = {}         # reason -> count
        self.rejected: dict[str, int] = {}              # "topic from sender" -> count
        self.unencodable: dict[str, int] = {}           # type name -> publications dropped

    def as_dict(self) -> dict[str, Any]:
        return {"published": self.published, "received": self.received,
                "decode_errors": dict(sorted(self.decode_errors.items())),
                "rejected": dict(sorted(self.rejected.items())),
                "unencodable": dict(sorted(self.unencodable.items()))}


class ZenohBus:
    """``LocalBus``'s interface (subscribe, publish, tap, filter) over a Zenoh session."""

    def __init__(self, session: zenoh.Session, *, sender: str, vehicle: str = DEFAULT_VEHICLE,
                 registry: Registry | None = None,
                 publishers: Mapping[str, frozenset[str]] | None = PUBLISHERS,
                 own_session: bool = False, express: bool = True) -> None:
        self.session = session
        self.sender = sender
        self.vehicle = vehicle
        self.registry = registry or Registry()
        self.publishers = publishers
        self.express = express
        self.channel: ChannelModel | None = None
        """Channel faults between this process's publishers and the network (like LocalBus)."""
        self.stats = BusStats()
        self._own_session = own_session
        self._prefix = f"{KEY_ROOT}/{vehicle}/"
        self._lock = threading.Lock()
        self._inboxes: dict[str, list[SafeInbox]] = {}
        self._subscribers: list[Any] = []
        self._publishers: dict[str, Any] = {}
        self._taps: list[Tap] = []
        self._tap_queue: SafeInbox | None = None
        self._notices: deque[Notice] = deque()
        self._rejected_once: set[str] = set()
        self._tokens: list[Any] = []
        self.closed = False

    # ------------------------------------------------------------------ receiving

    def _admit(self, key: str, payload: bytes) -> Envelope | None:
        """Decode and police one sample; None (counted) when it must not be delivered."""
        topic = key[len(self._prefix):] if key.startswith(self._prefix) else key
        try:
            sender, msg = self.registry.decode(payload, topic)
        except WireError as exc:
            with self._lock:
                self.stats.decode_errors[exc.reason] = self.stats.decode_errors.get(exc.reason, 0) + 1
            return None
        allowed = self.publishers.get(topic) if self.publishers is not None else None
        if allowed is not None and (sender not in allowed or (
                topic in SOURCE_MUST_MATCH and getattr(msg, "source", sender) != sender)):
            label = f"{topic} from {sender[:40]!r}"
            with self._lock:
                self.stats.rejected[label] = self.stats.rejected.get(label, 0) + 1
                first = label not in self._rejected_once
                self._rejected_once.add(label)
            if first:
                self._notices.append(Notice(
                    kind="rejected", source=self.sender, code="publisher",
                    reason=f"{type(msg).__name__} on {topic} from {sender[:40]!r}, "
                           f"allowed: {', '.join(sorted(allowed))}"))
            return None
        with self._lock:
            self.stats.received += 1
        return topic, msg

    def _callback(self, inboxes: list[SafeInbox]) -> Callable[[zenoh.Sample], None]:
        def deliver(sample: zenoh.Sample) -> None:
            try:
                envelope = self._admit(str(sample.key_expr), sample.payload.to_bytes())
            except Exception:  # never let a frame kill a Zenoh thread
                with self._lock:
                    self.stats.decode_errors["internal"] = self.stats.decode_errors.get("internal", 0) + 1
                return
            if envelope is not None:
                for inbox in inboxes:
                    inbox.append(envelope)
        return deliver

    def subscribe(self, topics: tuple[str, ...] | list[str]) -> SafeInbox:
        """Return a new inbox that receives every message published on ``topics``."""
        inbox = SafeInbox()
        for topic in topics:
            check_topic(topic)
            inboxes = self._inboxes.get(topic)
            if inboxes is None:
                inboxes = self._inboxes[topic] = []
                self._subscribers.append(self.session.declare_subscriber(
                    self._prefix + topic, self._callback(inboxes)))
            inboxes.append(inbox)
        return inbox

    def tap(self, observer: Tap) -> None:
        """Observe every message on this vehicle's keys; delivered by ``pump()``.

        As with ``LocalBus``, this process's own publications are tapped as published (before
        channel faults); other processes' as received (after the publisher's faults and this
        bus's decode and policy checks).
        """
        if self._tap_queue is None:
            self._tap_queue = SafeInbox()
            queue = [self._tap_queue]
            callback = self._callback(queue)
            alive = self._prefix + ALIVE + "/"

            def tap_sample(sample: zenoh.Sample) -> None:
                if not str(sample.key_expr).startswith(alive):
                    callback(sample)
            self._subscribers.append(self.session.declare_subscriber(
                self._prefix + "**", tap_sample, allowed_origin=zenoh.Locality.REMOTE))
        self._taps.append(observer)

    def pump(self) -> int:
        """Send held (delayed) messages and queued notices, deliver taps; on the runtime thread."""
        if self.channel is not None:
            for topic, msg in self.channel.due():
                self._send(topic, msg)
        while self._notices:
            self.publish(Topic.NOTICE, self._notices.popleft())
        if self._tap_queue is None:
            return 0
        items = self._tap_queue.drain()
        for topic, msg in items:
            for tap in self._taps:
                tap(topic, msg)
        return len(items)

    # ------------------------------------------------------------------ sending

    def publish(self, topic: str, msg: Any) -> None:
        if self._tap_queue is not None:
            self._tap_queue.append((topic, msg))
        if self.channel is None:
            self._send(topic, msg)
            return
        for routed in self.channel.route(topic, msg):
            self._send(topic, routed)

    def _send(self, topic: str, msg: Any) -> None:
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = self._publishers[topic] = self.session.declare_publisher(
                self._prefix + check_topic(topic), express=self.express,
                congestion_control=zenoh.CongestionControl.DROP)
        try:
            frame = self.registry.encode(msg, self.sender)
        except (TypeError, ValueError, OverflowError, msgspec.EncodeError):   # never crash the node
            name = type(msg).__name__
            self.stats.unencodable[name] = self.stats.unencodable.get(name, 0) + 1
            return
        publisher.put(frame)
        self.stats.published += 1

    # ------------------------------------------------------------------ liveliness

    def announce(self, name: str) -> None:
        """Declare this node alive (token dropped when the session closes or the link dies)."""
        self._tokens.append(self.session.liveliness().declare_token(self._prefix + f"{ALIVE}/{name}"))

    def watch_alive(self, on_change: Callable[[str, bool], None]) -> None:
        """``on_change(node, alive)`` for every token now and later (called on a Zenoh thread)."""
        alive = self._prefix + ALIVE + "/"

        def changed(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            if key.startswith(alive):
                on_change(key[len(alive):], sample.kind == zenoh.SampleKind.PUT)
        self._subscribers.append(self.session.liveliness().declare_subscriber(
            alive + "*", changed, history=True))

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        for entity in (*self._tokens, *self._subscribers, *self._publishers.values()):
            with contextlib.suppress(Exception):   # the session may already be gone
                entity.undeclare()
        if self._own_session:
            self.session.close()

    def __enter__(self) -> ZenohBus:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def open_bus(*, sender: str, mode: str = "peer", listen: Iterable[str] = (),
             connect: Iterable[str] = (), vehicle: str = DEFAULT_VEHICLE,
             registry: Registry | None = None, base_file: str | Path | None = None,
             user: str | None = None, password: str | None = None, allow_remote: bool = False,
             publishers: Mapping[str, frozenset[str]] | None = PUBLISHERS) -> ZenohBus:
    """Open a session with ``session_config`` and wrap it in a bus that owns it."""
    config = session_config(mode=mode, listen=listen, connect=connect, base_file=base_file,
                            user=user, password=password, allow_remote=allow_remote)
    return ZenohBus(zenoh.open(config), sender=sender, vehicle=vehicle, registry=registry,
                    publishers=publishers, own_session=True)


__all__ = ["DEFAULT_ENDPOINT", "PUBLISHERS", "BusStats", "SafeInbox", "ZenohBus", "check_topic",
           "key_for", "open_bus", "session_config"]
