"""The tool gate: where ``overdrive pub`` / ``echo`` meet a locked-down run (issue 18).

Two Zenoh sessions in one process. The *tool side* listens on the run's public endpoint, accepts
only the run's tool user (``access.TOOL_USER``, per-run password) and is an island: nothing
routes through it. The *mesh side* is an authenticated peer of the run (user ``gate``; the
mesh's rules let it put only ``TOOL_TOPICS``). Everything a tool publishes is decoded and
policed here (``ToolPolicy``): a valid message on a tool topic is re-sent on the mesh as
sender ``tool``; anything else (a command topic, a claimed node name, a malformed frame, a key
outside the run) is dropped and counted by reason. Mesh traffic is forwarded, byte for byte,
to the tool side for the keys a tool subscribes to (and only then: the gate subscribes on the
mesh to a topic only while a tool listens to it, so an idle gate costs the run nothing). The gate
runs at normal priority: it is not part of the control loop. Like every process of a launch it
publishes a ``NodeTick`` every ``NODE_TICK_PERIOD_S`` from its loop, so the launcher sees it hang.

A tool can never hold the run back: the mesh-side relays queue samples in Zenoh ring channels
(``RELAY_CAPACITY``; no Python on Zenoh's threads) and the gate's loop forwards them. When a
tool or the gate falls behind, the oldest samples for the tool are dropped; a Python callback
there would make the mesh link wait for the gate's GIL, and every node's blocking command
publisher with it (issue 20). Each key has its own channel: a tool sees each key's samples in
order, but samples of different keys published within one forwarding period (2 ms) may reach it
in another order than they were sent.
"""

from __future__ import annotations

import json
import signal
import threading
import time
from pathlib import Path
from typing import Any

import zenoh

from overdrive.bus.access import GATE_USER, LOG_FILTER, TOOL_TOPICS, RunAccess
from overdrive.bus.delivery import COMMAND, delivery
from overdrive.bus.wire import Registry, WireError
from overdrive.bus.zenoh_bus import KEY_ROOT, session_config
from overdrive.messages import NODE_TICK_PERIOD_S, NodeTick, Topic

TOOL_SENDER = "tool"       # the sender a tool's admitted messages carry on the mesh
INTEREST_POLL_S = 0.2      # how often the gate looks for tool subscribers (echo's first wait)
RELAY_POLL_S = 0.002       # how often the gate forwards queued mesh samples to tools (2 ms late at most)
RELAY_CAPACITY = 1024
"""Samples queued per relayed key between two forwards: ~10 s of a 100 Hz topic."""
EXTRA_TOPICS = ("move/estimates", "launch/clock", "sim/world", "sim/faults")
"""Topics without a fixed type in ``wire.TOPIC_TYPES`` that a tool may still want to read."""


def forwarded_topics(registry: Registry) -> list[str]:
    """The topics the gate forwards to tools that subscribe to them (``echo``)."""
    return sorted(set(registry.topic_types) | set(EXTRA_TOPICS))


class ToolPolicy:
    """Decide what of a tool's publications enters the run; count the rest. No I/O."""

    def __init__(self, registry: Registry, vehicle: str) -> None:
        self.registry = registry
        self.prefix = f"{KEY_ROOT}/{vehicle}/"
        self.admitted = 0
        self.denied: dict[str, int] = {}      # "topic as 'sender'" or "reason on key" -> count
        self._lock = threading.Lock()

    def _deny(self, label: str) -> None:
        with self._lock:
            self.denied[label] = self.denied.get(label, 0) + 1

    def admit(self, key: str, payload: bytes, now_s: float) -> tuple[str, bytes] | None:
        """``(key, frame)`` to put on the mesh for a tool's sample, or None (counted)."""
        if not key.startswith(self.prefix):
            self._deny(f"outside the run: {key[:80]}")
            return None
        topic = key[len(self.prefix):]
        try:
            sender, msg, _sent_s = self.registry.decode_stamped(payload, topic)
        except WireError as exc:
            self._deny(f"{topic[:60]}: {exc.reason}")
            return None
        if topic not in TOOL_TOPICS:
            self._deny(f"{topic[:60]} as {sender[:40]!r}")
            return None
        with self._lock:
            self.admitted += 1
        return key, self.registry.encode(msg, TOOL_SENDER, now_s)

    def report(self) -> dict[str, Any]:
        with self._lock:
            return {"admitted": self.admitted, "denied": dict(sorted(self.denied.items())),
                    "denied_total": sum(self.denied.values())}


def stop_on_signals() -> list[int]:
    """Handle SIGTERM/SIGINT by appending the signal to the returned list: lock-free, as every
    node's stop flag (``runtime.processes.StopFlag``). The launcher sends the gate SIGTERM twice
    (to every process group, then to the gate alone); a ``threading.Event`` set here deadlocked
    when the second arrived inside the first handler's ``set()`` (its lock held, the GIL with
    Zenoh's callback threads): the gate hung until SIGKILL and wrote no report, so the run's
    ``access["tool_denied"]`` came out empty."""
    stopping: list[int] = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    return stopping


def run_tool_gate(*, public: str, listen: str, connect: list[str], vehicle: str, access_dir: Path,
                  registry: Registry, report_path: Path | None, password: str,
                  ready: threading.Event | None = None, ready_path: Path | None = None) -> int:
    """Run the gate until SIGTERM/SIGINT; write its counts to ``report_path``. Returns 0.
    ``ready`` is set, and ``ready_path`` written, once both sessions listen."""
    zenoh.init_log_from_env_or(LOG_FILTER)
    access = RunAccess(access_dir, {})
    stopping = stop_on_signals()
    tool_conf = session_config(listen=[public])
    tool_conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(str(access.tool_users)))
    mesh_conf = session_config(listen=[listen], connect=connect, base_file=access.mesh_config,
                               user=GATE_USER, password=password)
    mesh = zenoh.open(mesh_conf)
    tools = zenoh.open(tool_conf)
    policy = ToolPolicy(registry, vehicle)
    prefix = f"{KEY_ROOT}/{vehicle}/"
    outward: dict[str, Any] = {}
    inward: dict[str, Any] = {}
    lock = threading.Lock()

    def publisher(session: zenoh.Session, cache: dict[str, Any], key: str) -> Any:
        with lock:
            pub = cache.get(key)
            if pub is None:
                reliable = delivery(key[len(prefix):]) == COMMAND
                pub = cache[key] = session.declare_publisher(   # never to our own subscribers
                    key, express=True, allowed_destination=zenoh.Locality.REMOTE,
                    congestion_control=zenoh.CongestionControl.BLOCK if reliable
                    else zenoh.CongestionControl.DROP)
        return pub

    def from_tool(sample: zenoh.Sample) -> None:
        try:
            admitted = policy.admit(str(sample.key_expr), sample.payload.to_bytes(), time.monotonic())
        except Exception:      # never let a tool's frame kill a Zenoh thread
            policy._deny("internal")
            return
        if admitted is not None:
            publisher(mesh, inward, admitted[0]).put(admitted[1])

    for topic in forwarded_topics(registry):      # a tool can see that a key is subscribed
        publisher(tools, outward, prefix + topic)
    subs = [tools.declare_subscriber("**", from_tool, allowed_origin=zenoh.Locality.REMOTE)]
    relays: dict[str, Any] = {}                    # mesh subscriptions, only while a tool listens
    ticks = mesh.declare_publisher(prefix + Topic.TICK, express=True,
                                   congestion_control=zenoh.CongestionControl.DROP)
    seq = 0
    if ready is not None:
        ready.set()
    if ready_path is not None:
        ready_path.write_text("listening\n", encoding="utf-8")
    started = time.monotonic()
    next_interest_s = started
    try:
        next_tick_s = started
        while not stopping:
            time.sleep(min(RELAY_POLL_S if relays else INTEREST_POLL_S,       # idle: 10 wakes/s
                           max(0.0, next_tick_s - time.monotonic())))
            if stopping:
                break
            now_s = time.monotonic()
            if now_s >= next_tick_s:          # liveness: the launcher reports a silent gate
                ticks.put(registry.encode(NodeTick(process=GATE_USER, seq=seq), GATE_USER, now_s))
                seq += 1
                next_tick_s += NODE_TICK_PERIOD_S
                if next_tick_s <= now_s:      # behind (not run): re-anchor, no burst
                    next_tick_s = now_s + NODE_TICK_PERIOD_S
            for key, relay in relays.items():
                pub = outward[key]
                while (sample := relay.try_recv()) is not None:
                    pub.put(sample.payload)
            if time.monotonic() < next_interest_s:
                continue
            next_interest_s = time.monotonic() + INTEREST_POLL_S
            for key, pub in list(outward.items()):
                wanted = pub.matching_status
                if wanted and key not in relays:
                    relays[key] = mesh.declare_subscriber(
                        key, zenoh.handlers.RingChannel(RELAY_CAPACITY),
                        allowed_origin=zenoh.Locality.REMOTE)
                elif not wanted and key in relays:
                    relays.pop(key).undeclare()
    finally:
        subs.extend(relays.values())
        ticks.undeclare()
        report = {"node": "gate", "uptime_s": round(time.monotonic() - started, 3),
                  **policy.report()}
        if report_path is not None:
            report_path.parent.mkdir(parents=True, exist_ok=True)
            tmp = report_path.with_suffix(".tmp")
            tmp.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
            tmp.replace(report_path)
        for sub in subs:
            sub.undeclare()
        tools.close()
        mesh.close()
    return 0


__all__ = ["TOOL_SENDER", "ToolPolicy", "run_tool_gate", "stop_on_signals"]
