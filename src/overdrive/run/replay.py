"""Replaying a recorded run through the control stack: a regression check for control code.

``overdrive replay run.mcap`` rebuilds the servers the run used (move server, driving module,
speed server: whichever ``overdrive.run.compose.build_nodes`` makes for the recorded scenario, so with
the same vehicle parameters), replaces the vehicle and the scenario player by playback of the
messages they published, steps everything on the lock-step runtime in the recorded tick order
(with the scenario's channel faults, drop/loss/delay/duplicate/reorder, re-applied on the bus), and compares each server's
outputs, tick by tick and message by message, with the recorded ones.

The closed loop is open during replay: the vehicle does not react to the replayed commands.
So the first difference is the meaningful one (the decision the changed code made
differently); later ones are mostly its consequences, and are only counted.

The recording must say who published what: ``McapRecorder.wrap`` writes that per tick. For a
recording made without it, publishers are inferred from the topic and the message's ``source``
(``infer_publisher``), which is exact for the vehicle and the scenario player.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from overdrive.bus.local import LocalBus
from overdrive.messages import Topic
from overdrive.observe.mcap_log import RunInfo, decode_lenient, iter_ticks, read_info, resolve_type
from overdrive.run.compose import build_nodes
from overdrive.runtime.lockstep import LockstepRuntime
from overdrive.scenario.player import channel_faults
from overdrive.scenario.schema import load_scenario_text

PLAYED_BACK = ("vehicle", "scenario")
"""Nodes played back when the recording does not list its nodes; otherwise every recorded node
that is not one of the rebuilt servers (e.g. a fake planner) is played back."""

VEHICLE_TOPICS = frozenset({Topic.VEHICLE_STATUS, Topic.WHEEL_SPEED, Topic.GPS_INS, Topic.IMU,
                            Topic.RADAR, Topic.TRUTH})
SCENARIO_TOPICS = frozenset({Topic.SAFETY, Topic.MOVE_COMMAND, "sim/world", "sim/faults"})
SERVER_TOPICS = {Topic.SPEED_STATE: "speed", Topic.DISPLAY: "speed", Topic.DRIVING_STATUS: "driving",
                 Topic.DRIVE_MODE: "move", Topic.MOVE_REPLY: "move", Topic.MOVE_STATUS: "move",
                 Topic.PLANNER_CLOCK: "move"}
"""Topics with a single publisher among the servers (the others carry a ``source``)."""
REL_TOL = 0.0
"""Replay is bit-for-bit: floats must match exactly (the runtime is deterministic)."""


class ReplayError(Exception):
    """The recording cannot be replayed (no scenario, unknown server, unattributable message)."""


@dataclass
class Difference:
    """One server output that differs from the recording (``None``: absent on that side)."""

    t_s: float
    tick: int
    node: str
    index: int                                 # position among the node's outputs of that tick
    topic: str
    recorded: dict[str, Any] | None
    replayed: dict[str, Any] | None
    recorded_topic: str | None = None

    @property
    def fields(self) -> dict[str, tuple[Any, Any]]:
        """``{field: (recorded, replayed)}`` of the fields that differ."""
        rec, rep = self.recorded or {}, self.replayed or {}
        if not isinstance(rec, dict) or not isinstance(rep, dict):
            return {"(message)": (self.recorded, self.replayed)}
        return {k: (rec.get(k), rep.get(k)) for k in sorted(set(rec) | set(rep))
                if rec.get(k) != rep.get(k)}

    def describe(self) -> str:
        if self.recorded is None:
            what = f"extra output {self.topic} {_short(self.replayed)} (not in the recording)"
        elif self.replayed is None:
            what = f"missing output {self.recorded_topic} {_short(self.recorded)}"
        elif self.recorded_topic is not None and self.recorded_topic != self.topic:
            what = (f"output #{self.index} is {self.topic} {_short(self.replayed)}, "
                    f"recorded {self.recorded_topic} {_short(self.recorded)}")
        else:
            what = f"{self.topic}: " + ", ".join(
                f"{k} recorded {a!r} replayed {b!r}" for k, (a, b) in self.fields.items())
        return f"t={self.t_s:.2f} s (tick {self.tick}) {self.node}: {what}"


def _short(msg: Any) -> str:
    text = json.dumps(msg, sort_keys=True)
    return text if len(text) <= 160 else text[:157] + "..."


@dataclass
class ReplayReport:
    path: str
    servers: list[str]
    played_back: list[str] = field(default_factory=list)
    ticks: int = 0
    compared: int = 0                          # recorded server outputs compared
    differences: int = 0
    first: Difference | None = None
    per_node: dict[str, int] = field(default_factory=dict)
    examples: list[Difference] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.differences == 0

    def format(self) -> str:
        lines = [f"replayed {self.path}: {self.ticks} ticks, servers "
                 f"{', '.join(self.servers) or 'none (open loop)'} (played back: "
                 f"{', '.join(self.played_back)}), "
                 f"{self.compared} recorded outputs compared"]
        if self.ok:
            lines.append("no differences: every decision matches the recording")
            return "\n".join(lines)
        per = ", ".join(f"{k} {v}" for k, v in sorted(self.per_node.items()))
        lines.append(f"{self.differences} differing outputs ({per})")
        assert self.first is not None
        lines.append(f"first difference: {self.first.describe()}")
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        first = None
        if self.first is not None:
            first = {"t_s": self.first.t_s, "tick": self.first.tick, "node": self.first.node,
                     "topic": self.first.topic, "recorded_topic": self.first.recorded_topic,
                     "fields": {k: {"recorded": a, "replayed": b}
                                for k, (a, b) in self.first.fields.items()},
                     "recorded": self.first.recorded, "replayed": self.first.replayed}
        return {"path": self.path, "servers": self.servers, "played_back": self.played_back,
                "ticks": self.ticks,
                "compared": self.compared, "differences": self.differences,
                "per_node": self.per_node, "first": first}


# --------------------------------------------------------------------------- playback and capture

class Playback:
    """Stands in for a node: publishes, each tick, the messages that node published then."""

    def __init__(self, name: str, period_s: float) -> None:
        self.name = name
        self.period_s = period_s
        self.subscriptions: tuple[str, ...] = ()
        self.pending: list[tuple[str, Any]] = []

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out, self.pending = self.pending, []
        return out


class Capture:
    """Wraps a server: steps it and keeps what it returned this tick."""

    def __init__(self, node: Any) -> None:
        self.node = node
        self.name: str = node.name
        self.period_s: float = node.period_s
        self.subscriptions: tuple[str, ...] = node.subscriptions
        self.outputs: list[tuple[str, Any]] = []

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.outputs = list(self.node.step(now_s, inbox))
        return self.outputs


def infer_publisher(topic: str, msg: dict[str, Any], servers: Sequence[str]) -> str:
    """Publisher of a message recorded without a publisher index (see the module docstring)."""
    if topic in VEHICLE_TOPICS:
        return "vehicle"
    source = msg.get("source") if isinstance(msg, dict) else None
    if topic == Topic.NOTICE and isinstance(source, str):
        return source
    if topic in SCENARIO_TOPICS:
        return "scenario"
    if topic in SERVER_TOPICS:
        return SERVER_TOPICS[topic]
    if isinstance(source, str) and source in (*servers, *PLAYED_BACK):
        return source
    if topic in (Topic.ADVANCE, Topic.MAX_SPEED):
        return "scenario"                # sources other than the nodes are scenario events
    if topic == Topic.SET_SPEED:
        return "driving" if "driving" in servers else "scenario"
    if topic == Topic.STEERING:
        return "move" if "move" in servers else "scenario"
    raise ReplayError(f"cannot tell who published {topic} {msg}; record with McapRecorder.wrap")


# --------------------------------------------------------------------------- replay

def _scenario(info: RunInfo, path: Path) -> Any:
    if info.scenario_yaml is None:
        raise ReplayError(f"{path}: no scenario.yaml attachment; cannot rebuild the stack")
    return load_scenario_text(info.scenario_yaml, f"{path}:scenario.yaml")


def build_servers(scenario: Any) -> list[Any]:
    """The server nodes ``overdrive sim`` builds for ``scenario``, in tick order."""
    return [n for n in build_nodes(scenario) if n.name not in PLAYED_BACK]


def _canonical(msg: Any) -> Any:
    """A message as the recording holds it: JSON with non-finite floats as null."""
    return json.loads(msgspec.json.encode(msg))


def _equal(a: Any, b: Any) -> bool:
    if REL_TOL == 0.0:
        return bool(a == b)
    if isinstance(a, float) and isinstance(b, float):  # pragma: no cover - exact by default
        return math.isclose(a, b, rel_tol=REL_TOL)
    return bool(a == b)


def replay(path: str | Path, *,
           servers_factory: Callable[[Any], list[Any]] | None = None,
           max_examples: int = 20) -> ReplayReport:
    """Replay ``path`` (a ``run.mcap``) through freshly built servers; see the module docstring.

    ``servers_factory(scenario)`` builds the server nodes (default ``build_servers``): tests use
    it to change a gain.
    """
    path = Path(path)
    info = read_info(path)
    scenario = _scenario(info, path)
    period_s = info.period_s
    servers = (servers_factory or build_servers)(scenario)
    names = [s.name for s in servers]
    order = info.nodes or [*PLAYED_BACK, *names]
    if [n for n in order if n in names] != names:
        raise ReplayError(f"{path}: recorded with nodes {order}; this build makes the servers "
                          f"{names} for its scenario")
    # every recorded node that is not a server is played back, in the recorded tick order
    playback = {name: Playback(name, period_s) for name in order if name not in names}
    captures = [Capture(s) for s in servers]
    by_name: dict[str, Any] = {**playback, **{c.name: c for c in captures}}
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    runtime = LockstepRuntime([by_name[n] for n in order], bus, period_s)
    report = ReplayReport(path=str(path), servers=names, played_back=list(playback),
                          per_node={n: 0 for n in names})
    subscribed = {topic for c in captures for topic in c.subscriptions}
    types: dict[str, type | None] = {}

    for tick in iter_ticks(path):
        tick_no = round(tick.t_s / period_s)
        if tick_no < runtime.tick:
            raise ReplayError(f"{path}: messages at t={tick.t_s} s out of tick order")
        while runtime.tick < tick_no:          # ticks with nothing recorded (none in a sim run)
            _step(runtime, faults, period_s, captures, {}, report, max_examples)
        expected: dict[str, list[tuple[str, Any]]] = {n: [] for n in names}
        for rec in tick.messages:
            publisher = rec.publisher
            if not tick.attributed:
                publisher = infer_publisher(rec.topic, rec.as_dict(), names)
            if publisher in expected:
                expected[publisher].append((rec.topic, rec.as_dict()))
            elif publisher in playback:
                if rec.topic not in subscribed:
                    continue                   # nobody replayed listens: no need to decode
                cls = types.get(rec.schema_name)
                if rec.schema_name not in types:
                    cls = types[rec.schema_name] = resolve_type(rec.schema_name)
                if cls is None:
                    raise ReplayError(f"{path}: cannot import message type {rec.schema_name}")
                playback[publisher].pending.append((rec.topic, decode_lenient(rec.data, cls)))
            else:
                raise ReplayError(f"{path}: t={tick.t_s:.3f} s: message on {rec.topic} from "
                                  f"{publisher!r}, which is neither played back nor replayed")
        _step(runtime, faults, period_s, captures, expected, report, max_examples)
    return report


def _step(runtime: LockstepRuntime, faults: Any, period_s: float, captures: list[Capture],
          expected: dict[str, list[tuple[str, Any]]], report: ReplayReport,
          max_examples: int) -> None:
    faults.now_s = runtime.tick * period_s
    tick_no = runtime.tick
    for c in captures:
        c.outputs = []
    now_s = runtime.step()
    report.ticks += 1
    for c in captures:
        recorded = expected.get(c.name, [])
        replayed = [(topic, _canonical(msg)) for topic, msg in c.outputs]
        report.compared += len(recorded)
        for i in range(max(len(recorded), len(replayed))):
            rec = recorded[i] if i < len(recorded) else None
            rep = replayed[i] if i < len(replayed) else None
            if rec is not None and rep is not None and rec[0] == rep[0] and _equal(rec[1], rep[1]):
                continue
            diff = Difference(
                t_s=now_s, tick=tick_no, node=c.name, index=i,
                topic=(rep or rec)[0],  # type: ignore[index]
                recorded=rec[1] if rec else None, replayed=rep[1] if rep else None,
                recorded_topic=rec[0] if rec else None)
            report.differences += 1
            report.per_node[c.name] = report.per_node.get(c.name, 0) + 1
            if report.first is None:
                report.first = diff
            if len(report.examples) < max_examples:
                report.examples.append(diff)


__all__ = ["Difference", "ReplayError", "ReplayReport", "build_servers", "infer_publisher",
           "replay"]
