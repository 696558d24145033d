"""Live view: the bus served to the Foxglove app over its WebSocket protocol, as a bus tap.

``LiveView`` starts a ``foxglove-sdk`` WebSocket server (loopback only, port 8765 by default)
with its own context, and publishes every bus message on a channel named by its topic, with
the same JSON Schemas and encoding as ``run.mcap`` (``overdrive.observe.mcap_log``), plus the vehicle's
pose (``viz/pose``, ``viz/tf``) for the 3D panel. Open Foxglove, "Open connection", Foxglove
WebSocket, ``ws://localhost:8765``.

Time stamps are the run's simulated time placed on the wall clock at the start of the run
(``start + now_s``), so a run paced with ``--realtime`` plays at the app's real time.
"""

from __future__ import annotations

import ipaddress
import time
from typing import Any

import msgspec

from overdrive.messages import Topic
from overdrive.observe.mcap_log import (
    FRAME_TRANSFORM_SCHEMA,
    POSE_IN_FRAME_SCHEMA,
    POSE_TOPIC,
    TF_TOPIC,
    json_schema,
    pose_messages,
)

DEFAULT_PORT = 8765          # the port the Foxglove app proposes for a Foxglove WebSocket
NS_PER_S = 1_000_000_000


class LiveViewError(RuntimeError):
    """The live view cannot start (foxglove-sdk missing, port taken, non-loopback host)."""


def _require_loopback(host: str) -> None:
    if host == "localhost":
        return
    try:
        if ipaddress.ip_address(host).is_loopback:
            return
    except ValueError:
        pass
    raise LiveViewError(f"live view serves loopback only (127.0.0.1, ::1, localhost), not {host!r}")


class LiveView:
    """Bus tap serving a Foxglove WebSocket; ``close()`` (or the context manager) stops it.

    ``port`` 0 picks a free port (``self.port`` says which).
    """

    def __init__(self, *, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
                 name: str = "overdrive", pose_topic: str | None = Topic.TRUTH) -> None:
        _require_loopback(host)
        try:
            import foxglove
        except ImportError as exc:
            raise LiveViewError("the live view needs foxglove-sdk: pip install foxglove-sdk") from exc
        self._foxglove = foxglove
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name=name, host=host, port=port,
                                                 context=self._context)
        except Exception as exc:   # the SDK raises its own error types (e.g. address in use)
            raise LiveViewError(f"cannot serve on {host}:{port}: {exc}") from exc
        self.host = host
        self.port: int = self._server.port
        self._channels: dict[tuple[str, Any], Any] = {}
        self._encoder = msgspec.json.Encoder()
        self._pose_topic = pose_topic
        self._start_ns = time.time_ns()
        self.log_time_ns = self._start_ns
        self.sent = 0
        self._closed = False

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def set_time(self, now_s: float) -> None:
        self.log_time_ns = self._start_ns + round(now_s * NS_PER_S)

    def _channel(self, topic: str, key: Any, schema: dict[str, Any]) -> Any:
        channel = self._channels.get((topic, key))
        if channel is None:
            channel = self._foxglove.Channel(topic, schema=schema, context=self._context)
            self._channels[(topic, key)] = channel
        return channel

    def observe(self, topic: str, msg: Any) -> None:
        if self._closed:
            return
        cls = type(msg)
        channel = self._channels.get((topic, cls)) or self._channel(topic, cls, json_schema(cls))
        t = self.log_time_ns
        channel.log(self._encoder.encode(msg), log_time=t)
        self.sent += 1
        if topic == self._pose_topic:
            pose, tf = pose_messages(msg, t)
            self._channel(POSE_TOPIC, "pose", POSE_IN_FRAME_SCHEMA).log(
                self._encoder.encode(pose), log_time=t)
            self._channel(TF_TOPIC, "tf", FRAME_TRANSFORM_SCHEMA).log(
                self._encoder.encode(tf), log_time=t)
            self.sent += 2

    __call__ = observe

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for channel in self._channels.values():
            channel.close()
        self._server.stop()

    def __enter__(self) -> LiveView:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["DEFAULT_PORT", "LiveView", "LiveViewError"]
