"""Recording a run as MCAP (``run.mcap``): every bus message, ground truth, and a Foxglove pose.

``McapRecorder`` is a bus tap, like ``overdrive.observe.recorder.Recorder``: it never feeds anything
back into the stack. Every bus message is written as JSON on a channel named by its topic, with
the message type's JSON Schema (``msgspec.json.schema``; schema encoding ``jsonschema``, message
encoding ``json``). JSON has no NaN or infinity: non-finite floats (``authorized_m`` when there
is no authorization) are written as ``null``, and the schemas say ``number`` or ``null``.
The simulator's ``sim/truth`` also becomes ``viz/pose`` (``foxglove.PoseInFrame`` in ``map``)
and ``viz/tf`` (``foxglove.FrameTransform`` ``map`` -> ``base_link``), so Foxglove's 3D panel
shows the vehicle and its path.

Time is the runner's, never the wall clock: call ``set_time(now_s)`` before each tick, or give
the runtime the nodes returned by ``wrap(nodes)``, which also tells the recorder which node
published each message. With ``wrap``, an ``overdrive/publishers`` message per tick lists the
publishers in publish order (``TickPublishers``); ``overdrive replay`` uses it to tell the
vehicle's and the scenario's messages (played back) from the servers' (recomputed and compared).

The scenario, normalised to YAML with its seed, is attached as ``scenario.yaml`` and the
resolved vehicle parameters as ``vehicle.json``, so the stack can be rebuilt from the file
alone. Messages are streamed to disk in compressed chunks; nothing is kept in memory.
"""

from __future__ import annotations

import importlib
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import msgspec

from overdrive import __version__
from overdrive.messages import SCHEMA_VERSION, Topic

PROFILE = ""                      # plain MCAP (no ROS profile): JSON messages, JSON Schemas
LIBRARY = f"overdrive/{__version__}"
METADATA_NAME = "overdrive"
SCENARIO_ATTACHMENT = "scenario.yaml"
VEHICLE_ATTACHMENT = "vehicle.json"
PUBLISHERS_TOPIC = "overdrive/publishers"
POSE_TOPIC = "viz/pose"
TF_TOPIC = "viz/tf"
MAP_FRAME = "map"
VEHICLE_FRAME = "base_link"       # centre of the rear axle, x forward, y left, z up (REP 103)
NS_PER_S = 1_000_000_000


class TickPublishers(msgspec.Struct, frozen=True, kw_only=True):
    """Who published the bus messages of one tick, as runs in publish order.

    ``publishers[i]`` published the next ``counts[i]`` messages of the tick (bus channels only,
    in recorded order).
    """

    tick: int
    t_s: float
    publishers: list[str]
    counts: list[int]


# --------------------------------------------------------------------------- Foxglove schemas
# Written from Foxglove's public schema definitions (foxglove-sdk, schemas/jsonschema/
# PoseInFrame.json and FrameTransform.json); optional lineage fields left out.

_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}


def _vector3(description: str) -> dict[str, Any]:
    return {"title": "foxglove.Vector3", "description": description, "type": "object",
            "properties": {k: {"type": "number", "description": f"{k} coordinate length"}
                           for k in ("x", "y", "z")},
            "required": ["x", "y", "z"]}


def _quaternion(description: str) -> dict[str, Any]:
    return {"title": "foxglove.Quaternion", "description": description, "type": "object",
            "properties": {k: {"type": "number", "description": f"{k} value"}
                           for k in ("x", "y", "z", "w")},
            "required": ["x", "y", "z", "w"]}


POSE_IN_FRAME_SCHEMA: dict[str, Any] = {
    "title": "foxglove.PoseInFrame",
    "description": "A timestamped pose for an object or reference frame in 3D space",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of pose"},
        "frame_id": {"type": "string",
                     "description": "Frame of reference for pose position and orientation"},
        "pose": {"title": "foxglove.Pose", "description": "Pose in 3D space", "type": "object",
                 "properties": {
                     "position": _vector3("Point denoting position in 3D space"),
                     "orientation": _quaternion("Quaternion denoting orientation in 3D space")},
                 "required": ["position", "orientation"]},
    },
    "required": ["timestamp", "frame_id", "pose"],
}

FRAME_TRANSFORM_SCHEMA: dict[str, Any] = {
    "title": "foxglove.FrameTransform",
    "description": "A transform between two reference frames in 3D space",
    "type": "object",
    "properties": {
        "timestamp": {**_TIME, "description": "Timestamp of transform"},
        "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
        "child_frame_id": {"type": "string", "description": "Name of the child frame"},
        "translation": _vector3("Translation component of the transform"),
        "rotation": _quaternion("Rotation component of the transform"),
    },
    "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
}


def quaternion_from_euler(yaw_rad: float, pitch_rad: float, roll_rad: float) -> dict[str, float]:
    """Quaternion (x, y, z, w) of intrinsic Z-Y-X rotations (yaw about z up, then y, then x)."""
    x, y, z, w = _quaternion(yaw_rad, pitch_rad, roll_rad)
    return {"x": x, "y": y, "z": z, "w": w}


def _quaternion(yaw_rad: float, pitch_rad: float,
                roll_rad: float) -> tuple[float, float, float, float]:
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def pose_messages(truth: Any, log_time_ns: int) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(PoseInFrame, FrameTransform)`` dicts for a ``Truth`` (or anything with its pose fields).

    Overdrive's pitch is nose-up positive and roll right-side-down positive; in the z-up,
    y-left ``base_link`` frame nose-up is a negative rotation about y, right-side-down a
    positive rotation about x.
    """
    stamp = {"sec": log_time_ns // NS_PER_S, "nsec": log_time_ns % NS_PER_S}
    position = {"x": truth.x_m, "y": truth.y_m, "z": 0.0}
    orientation = quaternion_from_euler(truth.heading_rad, -truth.pitch_rad, truth.roll_rad)
    pose = {"timestamp": stamp, "frame_id": MAP_FRAME,
            "pose": {"position": position, "orientation": orientation}}
    tf = {"timestamp": stamp, "parent_frame_id": MAP_FRAME, "child_frame_id": VEHICLE_FRAME,
          "translation": position, "rotation": orientation}
    return pose, tf


# --------------------------------------------------------------------------- schemas of bus types

def type_name(cls: type) -> str:
    """Schema name of a message type: its importable path, e.g. ``overdrive.messages.Truth``."""
    return f"{cls.__module__}.{cls.__qualname__}"


def resolve_type(name: str) -> type | None:
    """The class named by ``type_name``, or None when it cannot be imported."""
    module_name, _, qualname = name.rpartition(".")
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError:
        return None
    for part in qualname.split("."):
        obj = getattr(obj, part, None)
        if obj is None:
            return None
    return obj if isinstance(obj, type) else None


NON_FINITE_NOTE = "Non-finite numbers (NaN, infinities) are written as null."


def _simple(node: Any, defs: dict[str, Any]) -> Any:
    """A JSON Schema node every viewer can read: one string ``type`` on each node, ``$ref``s
    inlined, string enums typed, tuples as arrays, ``X | None`` as X.

    Foxglove's schema parser wants a single type per field (no type lists, ``anyOf`` or
    ``prefixItems``); our messages are flat, so nothing of meaning is lost.
    """
    if isinstance(node, list):
        return [_simple(v, defs) for v in node]
    if not isinstance(node, dict):
        return node
    ref = node.get("$ref")
    if isinstance(ref, str) and ref.startswith("#/$defs/") and ref[8:] in defs:
        return _simple({**defs[ref[8:]], **{k: v for k, v in node.items() if k != "$ref"}}, defs)
    out = {k: _simple(v, defs) for k, v in node.items() if k not in ("$defs", "prefixItems")}
    options = node.get("anyOf")
    if isinstance(options, list):
        kept = [o for o in options if not (isinstance(o, dict) and o.get("type") == "null")]
        if len(kept) == 1:
            out.pop("anyOf")
            out.update({k: v for k, v in _simple(kept[0], defs).items() if k not in out})
    if "enum" in out and "type" not in out:
        values = out["enum"]
        if all(isinstance(v, str) for v in values):
            out["type"] = "string"
        elif all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            out["type"] = "integer"
    items = node.get("prefixItems")
    if isinstance(items, list):
        out["type"] = "array"
        kinds = [_simple(i, defs) for i in items]
        out["items"] = kinds[0] if kinds and all(k == kinds[0] for k in kinds) else {}
    return out


def json_schema(cls: type) -> dict[str, Any]:
    """JSON Schema of a bus message type (see ``_simple``); an open schema when msgspec cannot
    describe the type."""
    try:
        schema = msgspec.json.schema(cls)
    except (TypeError, msgspec.ValidationError):
        return {"title": type_name(cls), "type": "object", "description": NON_FINITE_NOTE}
    schema = _simple(schema, schema.get("$defs", {}))
    schema["title"] = type_name(cls)
    schema["description"] = f"{schema.get('description', '')} {NON_FINITE_NOTE}".strip()
    return schema


# --------------------------------------------------------------------------- scenario round trip

def _strip_none(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _strip_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_strip_none(v) for v in value]
    return value


def scenario_yaml(scenario: Any) -> str:
    """The validated scenario (seed included) as YAML that ``parse_scenario`` reads back equal."""
    import yaml

    data = _strip_none(msgspec.to_builtins(scenario.spec))
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True)


# --------------------------------------------------------------------------- recorder

class _TaggedNode:
    """A node as the runtime sees it, telling the recorder when it steps (and so publishes)."""

    def __init__(self, node: Any, recorder: McapRecorder) -> None:
        self.node = node
        self.name: str = node.name
        self.period_s: float = node.period_s
        self.subscriptions: tuple[str, ...] = node.subscriptions
        self._recorder = recorder

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> Any:
        self._recorder.stepping(self.name, now_s)
        return self.node.step(now_s, inbox)


# The Foxglove pose and transform as Structs: the same JSON as ``pose_messages``' dicts (same
# keys in the same order), encoded without building nested dicts for every tick.

class _Stamp(msgspec.Struct):
    sec: int
    nsec: int


class _Vector3(msgspec.Struct):
    x: float
    y: float
    z: float


class _Quaternion(msgspec.Struct):
    x: float
    y: float
    z: float
    w: float


class _Pose(msgspec.Struct):
    position: _Vector3
    orientation: _Quaternion


class _PoseInFrame(msgspec.Struct):
    timestamp: _Stamp
    frame_id: str
    pose: _Pose


class _FrameTransform(msgspec.Struct):
    timestamp: _Stamp
    parent_frame_id: str
    child_frame_id: str
    translation: _Vector3
    rotation: _Quaternion


def _pose_structs(truth: Any, log_time_ns: int) -> tuple[_PoseInFrame, _FrameTransform]:
    stamp = _Stamp(log_time_ns // NS_PER_S, log_time_ns % NS_PER_S)
    position = _Vector3(truth.x_m, truth.y_m, 0.0)
    orientation = _Quaternion(*_quaternion(truth.heading_rad, -truth.pitch_rad, truth.roll_rad))
    return (_PoseInFrame(stamp, MAP_FRAME, _Pose(position, orientation)),
            _FrameTransform(stamp, MAP_FRAME, VEHICLE_FRAME, position, orientation))


class McapRecorder:
    """Bus tap writing ``run.mcap``; usable as a context manager (``close`` finishes the file).

    ``output``: a path or a binary file object (left open). ``scenario``: the ``Scenario`` run,
    attached so ``overdrive replay`` can rebuild the stack. ``pose_topic``: the topic whose
    messages carry the vehicle pose (``x_m``, ``y_m``, ``heading_rad``, ``pitch_rad``,
    ``roll_rad``) for the Foxglove pose and transform; None disables them.

    The file is written by ``overdrive.observe.mcap_writer.McapWriter`` (the ``mcap`` package reads it).
    """

    def __init__(self, output: str | Path | IO[bytes], *, scenario: Any = None,
                 period_s: float = 0.01, metadata: dict[str, str] | None = None,
                 pose_topic: str | None = Topic.TRUTH, chunk_size: int = 1 << 20) -> None:
        from overdrive.observe.mcap_writer import McapWriter

        self._own = isinstance(output, (str, Path))
        self._stream: IO[bytes] = open(output, "wb") if self._own else output  # type: ignore[arg-type]  # noqa: SIM115
        self._writer = McapWriter(self._stream, chunk_size=chunk_size)
        self._writer.start(profile=PROFILE, library=LIBRARY)
        self._encode = msgspec.json.Encoder().encode
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, type | str], int] = {}
        self._bus_channels: dict[str, tuple[type, int]] = {}   # topic -> (type, channel) last used
        self._pose_topic = pose_topic
        self.period_s = period_s
        self.log_time_ns = 0
        self.sequence = 0
        self.counts: dict[str, int] = {}
        """Messages written per topic, derived channels included."""
        self._tagging = False
        self._publisher = ""
        self._bus_messages = 0                      # bus messages observed so far
        self._marks: list[tuple[str, int]] = [("", 0)]   # (publisher, _bus_messages at its start)
        self._closed = False
        info = {"schema_version": str(SCHEMA_VERSION), "overdrive_version": __version__,
                "period_s": repr(period_s), "time": "simulated"}
        if scenario is not None:
            info.update(scenario_name=scenario.name, seed=str(scenario.spec.seed),
                        scenario_source=str(scenario.source),
                        vehicle_preset=str(scenario.vehicle.preset))
            self._writer.add_attachment(0, 0, SCENARIO_ATTACHMENT, "application/yaml",
                                        scenario_yaml(scenario).encode())
            self._writer.add_attachment(0, 0, VEHICLE_ATTACHMENT, "application/json",
                                        msgspec.json.encode(scenario.vehicle))
        info.update(metadata or {})
        self._writer.add_metadata(METADATA_NAME, info)

    # ------------------------------------------------------------------ time and publishers

    def set_time(self, now_s: float) -> None:
        """Time stamp of the messages that follow (simulated seconds); starts a new tick."""
        t_ns = round(now_s * NS_PER_S)
        if t_ns != self.log_time_ns:
            self._flush_tick()
            self.log_time_ns = t_ns

    def wrap(self, nodes: Sequence[Any]) -> list[Any]:
        """Nodes to give the runtime instead of ``nodes``: each step sets the time and publisher."""
        self._tagging = True
        self._writer.add_metadata("overdrive.nodes", {
            "order": ",".join(n.name for n in nodes),
            **{f"node.{n.name}": type_name(type(n)) for n in nodes}})
        return [_TaggedNode(n, self) for n in nodes]

    def stepping(self, name: str, now_s: float) -> None:
        """Node ``name`` is being stepped at ``now_s``: what it returns is published next."""
        self.set_time(now_s)
        self._publisher = name
        self._marks.append((name, self._bus_messages))

    def _flush_tick(self) -> None:
        """Write the tick's ``TickPublishers``: each publisher's run of consecutive messages."""
        marks, end = self._marks, self._bus_messages
        self._marks = [(self._publisher, end)]
        publishers: list[str] = []
        counts: list[int] = []
        for i, (name, first) in enumerate(marks):
            count = (marks[i + 1][1] if i + 1 < len(marks) else end) - first
            if not count:
                continue
            if publishers and publishers[-1] == name:
                counts[-1] += count
            else:
                publishers.append(name)
                counts.append(count)
        if not publishers or not self._tagging:
            return
        index = TickPublishers(tick=round(self.log_time_ns / (self.period_s * NS_PER_S)),
                               t_s=self.log_time_ns / NS_PER_S,
                               publishers=publishers, counts=counts)
        self._write(PUBLISHERS_TOPIC, index, "overdrive")

    # ------------------------------------------------------------------ writing

    def _channel(self, topic: str, key: type | str, schema_name: str, schema: dict[str, Any],
                 origin: str) -> int:
        channel_id = self._channels.get((topic, key))
        if channel_id is None:
            schema_id = self._schemas.get(schema_name)
            if schema_id is None:
                schema_id = self._writer.register_schema(
                    schema_name, "jsonschema", json.dumps(schema, sort_keys=True).encode())
                self._schemas[schema_name] = schema_id
            channel_id = self._writer.register_channel(topic, "json", schema_id,
                                                       {"origin": origin})
            self._channels[(topic, key)] = channel_id
        return channel_id

    def _write(self, topic: str, msg: Any, origin: str, log_time_ns: int | None = None) -> None:
        cls = type(msg)
        channel_id = self._channels.get((topic, cls))
        if channel_id is None:
            channel_id = self._channel(topic, cls, type_name(cls), json_schema(cls), origin)
        t = self.log_time_ns if log_time_ns is None else log_time_ns
        self.sequence += 1
        self._writer.add_message(channel_id, t, self._encode(msg), t, self.sequence)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def _write_derived(self, topic: str, schema: dict[str, Any], msg: Any, t: int) -> None:
        channel_id = self._channel(topic, schema["title"], schema["title"], schema, "derived")
        self.sequence += 1
        self._writer.add_message(channel_id, t, self._encode(msg), t, self.sequence)
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def observe(self, topic: str, msg: Any, log_time_ns: int | None = None) -> None:
        """Bus tap: write ``msg`` on channel ``topic`` (at ``log_time_ns``, else the set time)."""
        if self._closed:
            return
        t = self.log_time_ns if log_time_ns is None else log_time_ns
        # per-message fast path: the topic's channel when the type is the one last seen on it
        cls = type(msg)
        known = self._bus_channels.get(topic)
        if known is not None and known[0] is cls:
            channel_id = known[1]
        else:
            channel_id = self._channels.get((topic, cls))
            if channel_id is None:
                channel_id = self._channel(topic, cls, type_name(cls), json_schema(cls), "bus")
            self._bus_channels[topic] = (cls, channel_id)
        self.sequence += 1
        self._writer.add_message(channel_id, t, self._encode(msg), t, self.sequence)
        counts = self.counts
        counts[topic] = counts.get(topic, 0) + 1
        self._bus_messages += 1
        if topic == self._pose_topic:
            pose, tf = _pose_structs(msg, t)
            self._write_derived(POSE_TOPIC, POSE_IN_FRAME_SCHEMA, pose, t)
            self._write_derived(TF_TOPIC, FRAME_TRANSFORM_SCHEMA, tf, t)

    __call__ = observe

    def close(self) -> None:
        """Write the last tick's index and the MCAP summary; close the file if we opened it."""
        if self._closed:
            return
        self._closed = True
        try:
            self._flush_tick()
            self._writer.finish()
        finally:
            if self._own:
                self._stream.close()

    def __enter__(self) -> McapRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# --------------------------------------------------------------------------- reading

@dataclass
class Recorded:
    """One recorded bus message: ``data`` is its JSON; ``publisher`` "" when unknown."""

    topic: str
    schema_name: str
    data: bytes
    publisher: str = ""

    def as_dict(self) -> Any:
        return json.loads(self.data)


@dataclass
class Tick:
    """All bus messages recorded at one time stamp, in publish order."""

    log_time_ns: int
    messages: list[Recorded] = field(default_factory=list)
    attributed: bool = False     # publishers come from the recording's TickPublishers

    @property
    def t_s(self) -> float:
        return self.log_time_ns / NS_PER_S


@dataclass
class RunInfo:
    metadata: dict[str, str]
    nodes: list[str]
    scenario_yaml: str | None
    vehicle: dict[str, Any] | None

    @property
    def period_s(self) -> float:
        return float(self.metadata.get("period_s", "0.01"))


def read_info(path: str | Path) -> RunInfo:
    """Metadata and attachments of a recording made by ``McapRecorder``."""
    from mcap.reader import make_reader

    metadata: dict[str, str] = {}
    nodes: list[str] = []
    scenario_text = None
    vehicle = None
    with open(path, "rb") as f:
        reader = make_reader(f)
        for record in reader.iter_metadata():
            if record.name == METADATA_NAME:
                metadata.update(record.metadata)
            elif record.name == "overdrive.nodes":
                nodes = [n for n in record.metadata.get("order", "").split(",") if n]
        for attachment in reader.iter_attachments():
            if attachment.name == SCENARIO_ATTACHMENT:
                scenario_text = bytes(attachment.data).decode()
            elif attachment.name == VEHICLE_ATTACHMENT:
                vehicle = json.loads(bytes(attachment.data))
    return RunInfo(metadata=metadata, nodes=nodes, scenario_yaml=scenario_text, vehicle=vehicle)


def iter_ticks(path: str | Path) -> Iterator[Tick]:
    """The recorded bus messages tick by tick (derived ``viz/`` channels left out), streaming.

    When the recording has ``TickPublishers``, each message's ``publisher`` is set from it.
    """
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        reader = make_reader(f)
        current: Tick | None = None
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            origin = channel.metadata.get("origin", "bus")
            if current is not None and message.log_time != current.log_time_ns:
                yield current
                current = None
            if current is None:
                current = Tick(message.log_time)
            if channel.topic == PUBLISHERS_TOPIC:
                _attribute(current, msgspec.json.decode(message.data, type=TickPublishers))
            elif origin == "bus":
                current.messages.append(Recorded(channel.topic, schema.name if schema else "",
                                                 bytes(message.data)))
        if current is not None:
            yield current


def _attribute(tick: Tick, index: TickPublishers) -> None:
    if sum(index.counts) != len(tick.messages):
        raise ValueError(f"t={tick.t_s:.3f} s: publisher index lists {sum(index.counts)} "
                         f"messages, the recording has {len(tick.messages)}")
    i = 0
    for name, count in zip(index.publishers, index.counts, strict=True):
        for message in tick.messages[i:i + count]:
            message.publisher = name
        i += count
    tick.attributed = True


def decode_lenient(data: bytes | str, cls: type) -> Any:
    """Decode JSON into ``cls``, reading ``null`` as NaN where the field is a plain float.

    The recorder writes non-finite floats as ``null``; NaN is what the stack's validation treats
    every non-finite float as, so playback of such a value is faithful to its handling.
    """
    try:
        return msgspec.json.decode(data, type=cls)
    except msgspec.ValidationError:
        pass
    info = _TYPE_INFO.get(cls)
    if info is None:
        info = _TYPE_INFO[cls] = msgspec.inspect.type_info(cls)
    return msgspec.convert(_nan_for_null(json.loads(data), info), cls)


_TYPE_INFO: dict[type, Any] = {}


def _nan_for_null(value: Any, info: Any) -> Any:
    mi = msgspec.inspect
    if value is None and isinstance(info, mi.FloatType):
        return math.nan
    if isinstance(info, mi.StructType) and isinstance(value, dict):
        fields = {f.encode_name: f.type for f in info.fields}
        return {k: _nan_for_null(v, fields[k]) if k in fields else v for k, v in value.items()}
    if isinstance(info, (mi.ListType, mi.VarTupleType)) and isinstance(value, list):
        return [_nan_for_null(v, info.item_type) for v in value]
    if isinstance(info, mi.TupleType) and isinstance(value, list):
        return [_nan_for_null(v, t) for v, t in zip(value, info.item_types, strict=False)]
    return value


__all__ = ["FRAME_TRANSFORM_SCHEMA", "POSE_IN_FRAME_SCHEMA", "McapRecorder", "Recorded", "RunInfo",
           "Tick", "TickPublishers", "decode_lenient", "iter_ticks", "json_schema", "pose_messages",
           "read_info", "scenario_yaml"]
