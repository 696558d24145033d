"""Zenoh bus: the nodes' publish/subscribe interface across processes.

Key expressions are ``overdrive/<vehicle>/<topic>``, e.g. ``overdrive/ego/speed/set_speed``
(topics from ``overdrive.messages.Topic``; ``<vehicle>`` defaults to ``ego`` and lets several
vehicles share one network). Liveliness tokens ``overdrive/<vehicle>/_alive/<node>`` say which
nodes are up. Payloads are ``overdrive.bus.wire`` frames.

Delivery by kind of message (``DELIVERY``, documented per topic in docs/architecture.md):
commands and events are published reliable, in order, with blocking congestion control at a
high priority (a full Zenoh transmit queue holds the publisher back instead of dropping; a link
that stays blocked for ``BLOCK_CLOSE_US`` is closed, which the liveliness tokens report);
periodic state is published best-effort with congestion control ``DROP``, so a stale sample
may be lost under load and the next one replaces it. On the receiving side each node's inbox is
bounded (``INBOX_CAPACITY``): when it is full a state sample makes room by dropping the oldest
state sample (counted as ``stale_dropped``); a command that finds no room is an explicit fault:
counted as ``overflow`` and reported once per topic as ``Notice(kind="fault", code="bus_overflow")``.

Zenoh calls the subscriber callbacks on its own threads; each callback decodes the
frame, checks the sender against the publisher policy and appends a ``Stamped`` ``(topic,
msg)`` (with the frame's send time) to a ``SafeInbox`` under a lock. The runtime drains the inbox (one swap under the lock) before each
step, so a node still sees the messages received since its last step, in arrival order. Taps
(recording, ``overdrive echo``) are queued the same way and delivered by ``pump()`` on the
runtime's thread, never on a Zenoh thread.

Pull mode (``pull=True``, the launcher's bus): a Python callback needs the GIL. In a process
whose own thread is busy (the launcher records and judges every message of the run), Zenoh's
receiving thread waits for it, and on a loaded host the GIL holder may itself be descheduled;
that link is then not read, and since commands are published with blocking congestion control,
every node publishing to this process stalls on it, SPSS to the speed server included (issue 20).
In pull mode one subscriber on ``**`` queues samples in Zenoh's own FIFO channel, with no Python
on Zenoh's threads for data (liveliness changes, rare, still use a callback); ``pump()`` decodes
them on the runtime's thread into the inboxes and taps (``PULL_BATCH``). It is
meant for a process that taps everything anyway: its links carry every topic. Pull mode has no
wake-ups of its own: a trigger is seen when the runtime pumps (at its nodes' steps). This
process's own publications reach its inboxes at once, decoded and policed like a received
sample; a remote sample received earlier but not yet pumped then comes after them.

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
import heapq
import ipaddress
import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from operator import itemgetter
from pathlib import Path
from typing import Any

import msgspec
import zenoh

from overdrive.bus.delivery import COMMAND, STATE, STATE_TOPICS, delivery
from overdrive.bus.local import ChannelModel, Envelope, Stamped, Tap
from overdrive.bus.wire import Registry, WireError
from overdrive.messages import Notice, Topic
from overdrive.servers.clock_offset import (
    CLOCK_REPORT_TOPIC,
    MAX_CLOCK_UNCERTAINTY_S,
    ClockReport,
    OffsetEstimate,
    PeerClocks,
)

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
RUN_PROCESSES = VEHICLE_SIDE | {"speed", "driving", "move"}   # run.launch.NODE_CLASSES' senders
PUBLISHERS: dict[str, frozenset[str]] = {
    Topic.MOVE_COMMAND: SIM | {"planner"},
    Topic.MOVE_REPLY: frozenset({"move"}),
    Topic.MOVE_STATUS: frozenset({"move"}),
    Topic.PLANNER_CLOCK: frozenset({"move"}),
    Topic.STEERING: SIM | {"move", "planner"},
    Topic.MAX_SPEED: SIM | {"move", "planner"},
    Topic.ADVANCE: SIM | {"move", "planner"},
    Topic.DRIVE_MODE: frozenset({"move"}),
    Topic.DRIVING_STATUS: frozenset({"driving"}),
    Topic.SET_SPEED: SIM | {"driving"},
    Topic.SPEED_STATE: frozenset({"speed"}),
    Topic.DISPLAY: frozenset({"speed"}),
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
    Topic.TICK: RUN_PROCESSES | {"gate"},
    CLOCK_REPORT_TOPIC: RUN_PROCESSES | SIM,
}
"""Who may publish on each topic; topics not listed (``events``, extra topics) are open.
Liveness ticks (``NodeTick``): each run process in its own name (``runtime.supervision.TickNode``,
sender = node name) and the tool gate (``bus.access.GATE_USER``, not imported: access imports
this module); the launcher also requires ``NodeTick.process`` to equal the sender. Clock
reports: the run processes and the launcher (``bus.access.LAUNCHER_USER`` = ``scenario``),
whose ``ClockReport.source`` must equal the sender (``_admit``)."""

INBOX_CAPACITY = 1024
"""Envelopes a node's inbox holds: ~1 s of everything the busiest node (the recorder) receives
(~900 messages/s in a whole-stack run), 100 periods of a 10 ms node; beyond it a node is stalled."""
PULL_CAPACITY = 16_384
"""Samples Zenoh queues for a pull-mode bus between two pumps: ~10 s of a whole-stack run. A full
FIFO channel blocks Zenoh's receiving thread: the publishers' links back up (commands wait, state
samples are dropped) and a link blocked for ``BLOCK_CLOSE_US`` closes. Bounded for memory: a
queued sample holds its receive buffer (measured ~9 kB resident per 100-byte sample)."""
PULL_BATCH = INBOX_CAPACITY // 2
"""Samples one ``pump()`` takes from the channel when the bus has inboxes: half an inbox, so a
backlog is worked off over a few steps (each step drains its inbox) instead of overflowing an
inbox in one pump. A bus with taps only (the launcher's) takes everything queued: its judge must
see all evidence of a stall before it judges it (``launch.JUDGE_LAG_S``)."""
TAP_CAPACITY = 65_536
"""Envelopes queued for taps (the recorder sees every message): ~60 s of a whole-stack run, so a
launcher stalled for seconds on a loaded host loses nothing (~100 B each: ~7 MB at most)."""
OFFSETS_REFRESH_S = 0.05
"""The peers' clock bounds handed to the runtime are recomputed this often (each holds up to 128
samples per peer), and computed for the end of that window, so they hold throughout it."""
BLOCK_CLOSE_US = 5_000_000
"""A command publisher blocked this long closes the link (Zenoh's default, stated explicitly):
long enough for a loaded 2-core host, and the vehicle's 200 ms command timeout stops it first."""

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
    config.insert_json5("transport/link/tx/queue/congestion_control/block/wait_before_close",
                        str(BLOCK_CLOSE_US))
    if user is not None:
        config.insert_json5("transport/auth/usrpwd/user", json.dumps(user))
        config.insert_json5("transport/auth/usrpwd/password", json.dumps(password or ""))
    return config


class SafeInbox:
    """A node's inbox filled from other threads: ``append`` and ``drain`` under one lock.

    Bounded by ``capacity`` (see the module doc). ``triggers``: topics whose arrival sets
    ``wake`` and ``triggered`` so an event-driven runtime steps the node at once.
    """

    __slots__ = ("_commands", "_lock", "_seq", "_states", "capacity", "triggered", "triggers",
                 "wake")

    def __init__(self, capacity: int = INBOX_CAPACITY) -> None:
        # commands and state samples queue apart, numbered in arrival order: a full inbox drops
        # its oldest state sample in O(1) instead of scanning past every queued command
        self._commands: deque[tuple[int, Envelope]] = deque()
        self._states: deque[tuple[int, Envelope]] = deque()
        self._seq = 0
        self._lock = threading.Lock()
        self.capacity = capacity
        self.triggers: frozenset[str] = frozenset()
        self.wake: threading.Event | None = None
        self.triggered = False

    def append(self, envelope: Envelope) -> str:
        """Queue ``envelope``; returns ``""``, ``"stale_dropped"`` or ``"overflow"`` (refused)."""
        outcome = ""
        state = envelope[0] in STATE_TOPICS
        with self._lock:
            if len(self._commands) + len(self._states) >= self.capacity:
                if not self._states:
                    return "stale_dropped" if state else "overflow"   # nothing older can go
                self._states.popleft()
                outcome = "stale_dropped"
            self._seq += 1
            (self._states if state else self._commands).append((self._seq, envelope))
            if envelope[0] in self.triggers:
                self.triggered = True
                if self.wake is not None:
                    self.wake.set()
        return outcome

    def drain(self) -> list[Envelope]:
        """Everything received since the last drain, in arrival order."""
        with self._lock:
            commands, states = self._commands, self._states
            self._commands, self._states = deque(), deque()
            self.triggered = False
        if not states or not commands:
            return [envelope for _seq, envelope in commands or states]
        return [envelope for _seq, envelope in heapq.merge(commands, states, key=itemgetter(0))]

    def __len__(self) -> int:
        return len(self._commands) + len(self._states)


class BusStats:
    """Counters of one bus; updated under the bus lock (from Zenoh threads, or pulling, the
    runtime's). ``received`` counts admitted samples: per subscription with callbacks (a sample
    both tapped and subscribed counts twice), per sample in pull mode."""

    def __init__(self) -> None:
        self.published = 0
        self.received = 0
        self.decode_errors: dict[str, int] = {}         # reason -> count
        self.rejected: dict[str, int] = {}              # "topic from sender" -> count
        self.unencodable: dict[str, int] = {}           # type name -> publications dropped
        self.overflow: dict[str, int] = {}              # topic -> commands refused, inbox full
        self.stale_dropped: dict[str, int] = {}         # topic -> state samples dropped, inbox full

    def as_dict(self) -> dict[str, Any]:
        return {"published": self.published, "received": self.received,
                "decode_errors": dict(sorted(self.decode_errors.items())),
                "rejected": dict(sorted(self.rejected.items())),
                "unencodable": dict(sorted(self.unencodable.items())),
                "overflow": dict(sorted(self.overflow.items())),
                "stale_dropped": dict(sorted(self.stale_dropped.items()))}


class ZenohBus:
    """``LocalBus``'s interface (subscribe, publish, tap, filter) over a Zenoh session."""

    def __init__(self, session: zenoh.Session, *, sender: str, vehicle: str = DEFAULT_VEHICLE,
                 registry: Registry | None = None,
                 publishers: Mapping[str, frozenset[str]] | None = PUBLISHERS,
                 own_session: bool = False, express: bool = True, pull: bool = False,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.session = session
        self.sender = sender
        self.vehicle = vehicle
        self.registry = registry or Registry()
        self.publishers = publishers
        self.express = express
        self.pull = pull
        """Receive through one FIFO-channel subscriber drained by ``pump()`` (see module doc)."""
        self.clock = clock
        """Stamps each frame's ``sent_s``: CLOCK_MONOTONIC, shared by the processes of a host."""
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
        self._overflow_once: set[str] = set()
        self._stamped_taps: list[tuple[Callable[..., None], bool]] = []   # (observer, with sender)
        self._tokens: list[Any] = []
        self._pulled: Any = None            # pull mode: the FIFO-channel subscriber on **
        self.clocks = PeerClocks(sender)
        """Bounds on every peer's clock offset: each received frame's stamp, each peer's
        ``ClockReport`` (docs/multiprocess.md, "Clocks across machines"); under ``_lock``."""
        self._offsets: dict[str, OffsetEstimate | None] = {}
        self._offsets_until = -math.inf
        self._clock_inbox: SafeInbox | None = None
        self._tap_offsets: dict[str, float] = {}      # sender -> the last narrow midpoint
        self.closed = False

    # ------------------------------------------------------------------ receiving

    def _admit(self, key: str, payload: bytes) -> Envelope | None:
        """Decode and police one sample; None (counted) when it must not be delivered."""
        received_s = self.clock()
        topic = key[len(self._prefix):] if key.startswith(self._prefix) else key
        try:
            sender, msg, sent_s = self.registry.decode_stamped(payload, topic)
        except WireError as exc:
            with self._lock:
                self.stats.decode_errors[exc.reason] = self.stats.decode_errors.get(exc.reason, 0) + 1
            return None
        if self._refused(topic, sender, msg):
            return None
        with self._lock:
            self.stats.received += 1
            self.clocks.received(sender, received_s, sent_s)
            if type(msg) is ClockReport and msg.source == sender:
                self.clocks.report(msg)
        return Stamped(topic, msg, sent_s, sender)

    def _refused(self, topic: str, sender: str, msg: Any) -> bool:
        """True (counted, reported once) when the publisher policy refuses ``msg`` from ``sender``."""
        allowed = self.publishers.get(topic) if self.publishers is not None else None
        if allowed is None or (sender in allowed and (
                topic not in SOURCE_MUST_MATCH or getattr(msg, "source", sender) == sender)):
            return False
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
        return True

    def _deliver(self, sample: zenoh.Sample, inboxes: Iterable[SafeInbox]) -> None:
        try:
            envelope = self._admit(str(sample.key_expr), sample.payload.to_bytes())
        except Exception:  # never let a frame kill a Zenoh thread (or the runtime's, pulling)
            with self._lock:
                self.stats.decode_errors["internal"] = self.stats.decode_errors.get("internal", 0) + 1
            return
        if envelope is not None:
            self._append(envelope, inboxes)

    def _append(self, envelope: Envelope, inboxes: Iterable[SafeInbox]) -> None:
        for inbox in inboxes:
            outcome = inbox.append(envelope)
            if outcome:
                self._count_full(outcome, envelope[0])

    def _callback(self, inboxes: list[SafeInbox]) -> Callable[[zenoh.Sample], None]:
        def deliver(sample: zenoh.Sample) -> None:
            self._deliver(sample, inboxes)
        return deliver

    def _pull_subscriber(self) -> None:
        if self._pulled is None:
            self._pulled = self.session.declare_subscriber(
                self._prefix + "**", zenoh.handlers.FifoChannel(PULL_CAPACITY),
                allowed_origin=zenoh.Locality.REMOTE)
            self._subscribers.append(self._pulled)

    def _pull(self) -> None:
        """Pull mode: decode what Zenoh queued into the inboxes and the tap queue, in order."""
        pulled, prefix = self._pulled, self._prefix
        if pulled is None:
            return
        alive = prefix + ALIVE + "/"
        tap_queue = [self._tap_queue] if self._tap_queue is not None else []
        # the clock reports' inbox is read on arrival (``_admit``): it does not make a bus of taps
        # (the launcher's) a bus of inboxes
        nodes_read = any(topic != CLOCK_REPORT_TOPIC for topic in self._inboxes)
        for _ in range(PULL_BATCH if nodes_read else PULL_CAPACITY):
            sample = pulled.try_recv()
            if sample is None:
                break
            key = str(sample.key_expr)
            if key.startswith(alive):
                continue
            inboxes = self._inboxes.get(key[len(prefix):], [])
            if inboxes or tap_queue:       # decode only what someone reads
                self._deliver(sample, [*inboxes, *tap_queue])

    def _count_full(self, outcome: str, topic: str) -> None:
        with self._lock:
            counts = self.stats.overflow if outcome == "overflow" else self.stats.stale_dropped
            counts[topic] = counts.get(topic, 0) + 1
            first = outcome == "overflow" and topic not in self._overflow_once
            self._overflow_once.add(topic)
        if first:
            self._notices.append(Notice(
                kind="fault", source=self.sender, code="bus_overflow",
                reason=f"{topic}: inbox full ({INBOX_CAPACITY} messages), command refused"))

    def subscribe(self, topics: tuple[str, ...] | list[str]) -> SafeInbox:
        """Return a new inbox that receives every message published on ``topics``."""
        inbox = SafeInbox()
        for topic in topics:
            check_topic(topic)
            inboxes = self._inboxes.get(topic)
            if inboxes is None:
                inboxes = self._inboxes[topic] = []
                if self.pull:
                    self._pull_subscriber()
                else:
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
            self._tap_queue = SafeInbox(TAP_CAPACITY)
            if self.pull:
                self._pull_subscriber()
            else:
                callback = self._callback([self._tap_queue])
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
        self._pull()
        while self._notices:
            self.publish(Topic.NOTICE, self._notices.popleft())
        if self._tap_queue is None:
            return 0
        items = self._tap_queue.drain()
        offsets = self.clock_offsets() if self._stamped_taps else {}
        for envelope in items:
            topic, msg = envelope
            for tap in self._taps:
                tap(topic, msg)
            if self._stamped_taps:
                sent_s = getattr(envelope, "sent_s", math.nan)
                sender = getattr(envelope, "sender", "")
                estimate = offsets.get(sender)
                # an observer's best guess, the midpoint, while the bounds are narrow: a stalled
                # pull-mode bus takes frames in late, which widens its upper bounds for a while
                if estimate is not None and estimate.uncertainty_s <= MAX_CLOCK_UNCERTAINTY_S:
                    self._tap_offsets[sender] = estimate.offset_s
                sent_s += self._tap_offsets.get(sender, 0.0)
                for stamped, with_sender in self._stamped_taps:
                    if with_sender:
                        stamped(topic, msg, sent_s, sender)
                    else:
                        stamped(topic, msg, sent_s)
        return len(items)

    def tap_stamped(self, observer: Callable[..., None], *, sender: bool = False) -> None:
        """Like ``tap``, with the frame's send time as a third argument: on this process's clock
        (``clock``), converted from the sender's with the midpoint of its offset bounds when
        they are known (as they are when the launcher judges: it engages only then). With
        ``sender``, the envelope's sender (admitted by ``publishers``) as a fourth: what a
        message claims about who wrote it is checked against it (liveness ticks)."""
        if self._tap_queue is None:
            self.tap(lambda _topic, _msg: None)
        self._stamped_taps.append((observer, sender))

    # ------------------------------------------------------------------ clocks

    def clock_offsets(self) -> dict[str, OffsetEstimate | None]:
        """Each peer's bounds on ``this clock - the peer's`` (None: unknown), recomputed every
        ``OFFSETS_REFRESH_S`` for the end of that window: valid throughout it."""
        now = self.clock()
        if now >= self._offsets_until:
            self._offsets_until = now + OFFSETS_REFRESH_S
            with self._lock:
                self._offsets = self.clocks.estimates(self._offsets_until)
        return self._offsets

    def clock_reports(self) -> dict[str, ClockReport]:
        """The newest ``ClockReport`` of each peer."""
        with self._lock:
            return dict(self.clocks.latest)

    def exchange_clocks(self) -> None:
        """Publish this process's ``ClockReport`` (its peers' lower bounds); the peers' reports
        are taken in as they arrive (the first call subscribes)."""
        if self._clock_inbox is None:
            self._clock_inbox = self.subscribe([CLOCK_REPORT_TOPIC])
        self._clock_inbox.drain()               # read on arrival (``_admit``)
        now = self.clock()
        with self._lock:
            report = self.clocks.make_report(now)
        self.publish(CLOCK_REPORT_TOPIC, report)

    # ------------------------------------------------------------------ sending

    def publish(self, topic: str, msg: Any) -> None:
        if self._tap_queue is not None:
            self._tap_queue.append(Stamped(topic, msg, self.clock()))
        if self.channel is None:
            self._send(topic, msg)
            return
        for routed in self.channel.route(topic, msg):
            self._send(topic, routed)

    def _send(self, topic: str, msg: Any) -> None:
        publisher = self._publishers.get(topic)
        if publisher is None:
            key = self._prefix + check_topic(topic)
            if delivery(topic) == COMMAND:
                publisher = self.session.declare_publisher(
                    key, express=self.express, congestion_control=zenoh.CongestionControl.BLOCK,
                    reliability=zenoh.Reliability.RELIABLE, priority=zenoh.Priority.INTERACTIVE_HIGH)
            else:
                publisher = self.session.declare_publisher(
                    key, express=self.express, congestion_control=zenoh.CongestionControl.DROP,
                    reliability=zenoh.Reliability.BEST_EFFORT, priority=zenoh.Priority.DATA)
            self._publishers[topic] = publisher
        sent_s = self.clock()
        with self._lock:
            self.clocks.sent(sent_s)      # a peer's report may name this stamp (and no other)
        try:
            frame = self.registry.encode(msg, self.sender, sent_s)
        except (TypeError, ValueError, OverflowError, msgspec.EncodeError):   # never crash the node
            name = type(msg).__name__
            self.stats.unencodable[name] = self.stats.unencodable.get(name, 0) + 1
            return
        publisher.put(frame)
        self.stats.published += 1
        inboxes = self._inboxes.get(topic) if self.pull else None
        if inboxes:                   # the pulled subscriber takes remote samples only
            envelope = self._admit(self._prefix + topic, frame)   # checked as a receiver would
            if envelope is not None:
                self._append(envelope, inboxes)

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
        self._pulled = None
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
             publishers: Mapping[str, frozenset[str]] | None = PUBLISHERS,
             pull: bool = False, clock: Callable[[], float] = time.monotonic) -> ZenohBus:
    """Open a session with ``session_config`` and wrap it in a bus that owns it."""
    config = session_config(mode=mode, listen=listen, connect=connect, base_file=base_file,
                            user=user, password=password, allow_remote=allow_remote)
    return ZenohBus(zenoh.open(config), sender=sender, vehicle=vehicle, registry=registry,
                    publishers=publishers, own_session=True, pull=pull, clock=clock)


__all__ = [
    "COMMAND",
    "DEFAULT_ENDPOINT",
    "INBOX_CAPACITY",
    "PUBLISHERS",
    "PULL_CAPACITY",
    "STATE",
    "STATE_TOPICS",
    "BusStats",
    "SafeInbox",
    "ZenohBus",
    "check_topic",
    "delivery",
    "key_for",
    "open_bus",
    "session_config",
]
