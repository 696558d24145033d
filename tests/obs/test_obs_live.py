"""Live view: a WebSocket client connects to the served port and receives bus messages."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import threading
import time
from typing import Any

import pytest

from overdrive.messages import DrivingStatus, Topic, Truth

pytest.importorskip("foxglove")

from overdrive.observe.live import LiveView, LiveViewError

SUBPROTOCOL = "foxglove.sdk.v1"   # what foxglove-sdk's server accepts
TIMEOUT_S = 5.0


class WsClient:
    """Just enough RFC 6455 for the test: handshake, masked text frames out, frames in."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT_S)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((
            f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            assert chunk, "server closed during the handshake"
            head += chunk
        self.status = head.split(b"\r\n", 1)[0].decode()

    def _exact(self, n: int) -> bytes:
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            assert chunk, "server closed the connection"
            data += chunk
        return data

    def recv(self) -> tuple[int, bytes]:
        b0, b1 = self._exact(2)
        length = b1 & 0x7F
        if length == 126:
            (length,) = struct.unpack(">H", self._exact(2))
        elif length == 127:
            (length,) = struct.unpack(">Q", self._exact(8))
        mask = self._exact(4) if b1 & 0x80 else b""
        payload = self._exact(length)
        if mask:
            payload = bytes(c ^ mask[i % 4] for i, c in enumerate(payload))
        return b0 & 0x0F, payload

    def send_text(self, text: str) -> None:
        data = text.encode()
        mask = os.urandom(4)
        header = bytes([0x81])
        if len(data) < 126:
            header += bytes([0x80 | len(data)])
        else:
            header += bytes([0x80 | 126]) + struct.pack(">H", len(data))
        self.sock.sendall(header + mask + bytes(c ^ mask[i % 4] for i, c in enumerate(data)))

    def close(self) -> None:
        self.sock.close()


def truth(x_m: float) -> Truth:
    return Truth(x_m=x_m, y_m=0.5, heading_rad=0.1, speed_mps=2.0, accel_mps2=0.0,
                 lat_accel_mps2=0.0, curvature_1pm=0.0, pitch_rad=0.0, roll_rad=0.0,
                 odometer_m=x_m, slip=False, contact=False)


def status() -> DrivingStatus:
    return DrivingStatus(goal_speed_mps=1.0, authorized_m=float("nan"), speed_limit_mps=5.0,
                         curvature_1pm=0.0, accel_limit_mps2=2.0, decel_limit_mps2=3.0)


def test_websocket_client_receives_bus_messages() -> None:
    with LiveView(port=0) as live:
        assert live.port > 0
        client = WsClient(live.port)
        try:
            assert " 101 " in client.status + " ", client.status
            live.set_time(0.0)
            live.observe(Topic.TRUTH, truth(0.0))          # advertises the channels
            live.observe(Topic.DRIVING_STATUS, status())
            channels: dict[int, dict[str, Any]] = {}
            deadline = time.monotonic() + TIMEOUT_S
            wanted = {Topic.TRUTH, Topic.DRIVING_STATUS, "viz/pose"}
            while not wanted <= {c["topic"] for c in channels.values()}:
                assert time.monotonic() < deadline, f"advertised only {channels}"
                opcode, payload = client.recv()
                if opcode == 1:
                    msg = json.loads(payload)
                    if msg.get("op") == "advertise":
                        channels.update({c["id"]: c for c in msg["channels"]})
            by_topic = {c["topic"]: c for c in channels.values()}
            assert by_topic[Topic.TRUTH]["schemaName"] == "overdrive.messages.Truth"
            assert by_topic["viz/pose"]["schemaName"] == "foxglove.PoseInFrame"
            assert by_topic[Topic.TRUTH]["encoding"] == "json"
            client.send_text(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": i, "channelId": c["id"]} for i, c in enumerate(channels.values(), 1)]}))
            sub_topic = {i: c["topic"] for i, c in enumerate(channels.values(), 1)}
            received: dict[str, Any] = {}
            stop = threading.Event()

            def publish() -> None:       # the run goes on while the client listens
                step = 1
                while not stop.is_set():
                    live.set_time(step * 0.01)
                    live.observe(Topic.TRUTH, truth(step * 0.1))
                    live.observe(Topic.DRIVING_STATUS, status())
                    step += 1
                    time.sleep(0.01)

            publisher = threading.Thread(target=publish, daemon=True)
            publisher.start()
            try:
                deadline = time.monotonic() + TIMEOUT_S
                while not wanted <= set(received):
                    assert time.monotonic() < deadline, f"received only {sorted(received)}"
                    opcode, payload = client.recv()
                    if opcode == 2 and payload[0] == 1:      # binary messageData
                        sub_id, _log_time_ns = struct.unpack_from("<IQ", payload, 1)
                        received[sub_topic[sub_id]] = json.loads(payload[13:])
            finally:
                stop.set()
                publisher.join()
            assert received[Topic.TRUTH]["y_m"] == 0.5
            assert received[Topic.DRIVING_STATUS]["authorized_m"] is None, "NaN travels as null"
            assert received["viz/pose"]["frame_id"] == "map"
        finally:
            client.close()
    assert_refused(live.port)


def assert_refused(port: int) -> None:
    """The server has stopped listening (stopping is asynchronous in foxglove-sdk)."""
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1.0).close()
        except OSError:
            return
        time.sleep(0.05)
    raise AssertionError(f"port {port} still accepts connections after close()")


def test_live_view_refuses_non_loopback_hosts() -> None:
    with pytest.raises(LiveViewError, match="loopback"):
        LiveView(host="0.0.0.0", port=0)


def test_live_hook_reports_a_taken_port_as_usage_error() -> None:
    from overdrive.cli.observe import start_live

    view = start_live(0)
    try:
        assert view.url.startswith("ws://127.0.0.1:")
        with pytest.raises(SystemExit) as taken:
            start_live(view.port)
        assert taken.value.code == 2
    finally:
        view.close()
    assert_refused(view.port)
