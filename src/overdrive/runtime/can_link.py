"""A PACMod 3 over CAN: the wall-clock nodes around ``Pacmod3Client`` and the engage endpoint.

``overdrive drive --can pacmod3`` steps, in tick order, ``CanSensorNode`` ("vehicle": the
frames that arrived in, the stack's sensor messages out), the servers, and ``CanCommandNode``
("pacmod3-client": the stack's commands in, the kit's commands computed AND sent in the same
step, the raw frames out on ``Topic.CAN_FRAMES`` for run.mcap). No thread re-sends anything: a
stalled (SIGSTOP) or killed drive sends nothing and the kit's 100 ms command timeout fires.

A report's time is when it reached the bus (its python-can stamp on the step's clock,
``can_edge.bus_arrival_s``), so reports drained together integrate their true spacing; one
stamped more than ``STAMP_TRUST_S`` before it is read is dropped and counted. Error frames and
receive failures the port counts reach the client as bus errors (a fault: it brakes to a stop).
Ending the drive (its duration, Ctrl-C, SIGTERM) engaged brakes to a standstill before the kit
is let go (``CanCommandNode.close``): disabling at speed would coast.

``EngageEndpoint``: the operator's act against a running drive (``overdrive engage --run
RUN_DIR``). A UDP socket on 127.0.0.1 with an ephemeral port and a random token, both written
to ``RUN_DIR/engage.json`` (mode 0600: only the user who started the drive can read the
token). A request is one JSON datagram ``{"token": ..., "act": "engage" | "status"}``; the
answer ``{"ok": bool, "state": ..., "reason": ...}`` goes back to the sender. Datagrams with a
wrong token, from elsewhere than loopback, or malformed are counted and dropped unanswered.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from overdrive.messages import Topic
from overdrive.runtime.can_edge import CanPort, bus_arrival_s
from overdrive.runtime.udp import open_udp
from overdrive.vehicle.pacmod3_client import Pacmod3Client
from overdrive.vehicle.pacmod3_engage import stop_bound_s

LOOPBACK: Final = "127.0.0.1"
ENGAGE_FILE: Final = "engage.json"
REQUEST_MAX_BYTES: Final = 512           # a request is a token and a word; longer is garbage
REQUESTS_PER_STEP: Final = 8             # a flood cannot hold up the command loop
STAMP_TRUST_S: Final = 1.0
"""A report stamped more than this before it is read is dropped (counted in ``stale_frames``):
what the kit said that long ago is not its state now; younger ones count at their bus time."""
RELEASE_MAX_S: Final = stop_bound_s(40.0) + 1.0
"""The drive's end waits at most this for the client's stop (the client's own bound, at the
highest speed a vehicle file allows, plus a second): then it lets go whatever happened."""


class EngageEndpoint:
    """The drive's side of ``overdrive engage`` (module docstring). Non-blocking; polled by
    ``CanCommandNode`` every step."""

    def __init__(self, run_dir: str | Path | None) -> None:
        self.sock = open_udp((LOOPBACK, 0))
        self.token = secrets.token_hex(16)
        self.port = self.sock.getsockname()[1]
        self.refused = 0
        self.path: Path | None = None
        if run_dir is not None:
            # A fresh file (O_EXCL, no symlink followed, 0600 from its creation) renamed over
            # the name: a stale engage.json of another mode, or a symlink planted there, is
            # replaced, never written through.
            self.path = Path(run_dir) / ENGAGE_FILE
            fresh = self.path.with_name(f".{ENGAGE_FILE}.{secrets.token_hex(8)}")
            fd = os.open(fresh, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
            try:
                with os.fdopen(fd, "w", encoding="utf-8") as f:
                    json.dump({"host": LOOPBACK, "port": self.port, "token": self.token,
                               "pid": os.getpid()}, f)
                os.replace(fresh, self.path)
            except BaseException:
                with contextlib.suppress(OSError):
                    fresh.unlink()
                raise

    def requests(self) -> list[tuple[str, Any]]:
        """(act, sender address) of each valid request waiting."""
        out: list[tuple[str, Any]] = []
        for _ in range(REQUESTS_PER_STEP):
            try:
                data, sender = self.sock.recvfrom(REQUEST_MAX_BYTES + 1)
            except (BlockingIOError, ConnectionRefusedError):
                break
            act = self._parse(data, sender)
            if act is None:
                self.refused += 1
                continue
            out.append((act, sender))
        return out

    def _parse(self, data: bytes, sender: Any) -> str | None:
        if sender[0] != LOOPBACK or len(data) > REQUEST_MAX_BYTES:
            return None
        try:
            request = json.loads(data)
        except (ValueError, UnicodeDecodeError):
            return None
        if not isinstance(request, dict) or not isinstance(request.get("token"), str):
            return None
        if not secrets.compare_digest(request["token"], self.token):
            return None
        act = request.get("act")
        return act if act in ("engage", "status") else None

    def answer(self, sender: Any, reply: dict[str, Any]) -> None:
        with contextlib.suppress(OSError):
            self.sock.sendto(json.dumps(reply).encode(), sender)

    def close(self) -> None:
        self.sock.close()
        if self.path is not None:
            with contextlib.suppress(OSError):
                self.path.unlink()


def request_engage(run_dir: str | Path, act: str = "engage", timeout_s: float = 2.0
                   ) -> dict[str, Any]:
    """``overdrive engage``: send ``act`` to the drive writing ``run_dir`` and return its answer.
    Raises ``OSError`` (no drive: no endpoint file, no answer) or ``ValueError`` (a bad file)."""
    info = json.loads((Path(run_dir) / ENGAGE_FILE).read_text(encoding="utf-8"))
    if not (isinstance(info, dict) and info.get("host") == LOOPBACK
            and type(info.get("port")) is int and 0 < info["port"] < 65536
            and isinstance(info.get("token"), str)):
        raise ValueError(f"{run_dir}/{ENGAGE_FILE}: not an engage endpoint")
    sock = open_udp((LOOPBACK, 0), timeout_s=timeout_s)
    try:
        # Connected: the kernel delivers only the drive's port's datagrams, so another local
        # process cannot answer in the drive's name.
        sock.connect((LOOPBACK, info["port"]))
        sock.send(json.dumps({"token": info["token"], "act": act}).encode())
        data = sock.recv(4096)
    except TimeoutError as e:
        raise OSError(f"no answer from the drive in {timeout_s} s (is it running?)") from e
    finally:
        sock.close()
    reply = json.loads(data)
    if not isinstance(reply, dict):
        raise ValueError("the drive's answer is not an object")
    return reply


class CanSensorNode:
    """The client's sensor side: frames in, the stack's sensor messages out."""

    name = "vehicle"
    period_s = 0.01
    subscriptions: tuple[str, ...] = ()

    def __init__(self, client: Pacmod3Client, port: CanPort,
                 endpoint: EngageEndpoint | None = None, *,
                 wall_clock: Any = time.time) -> None:
        self.client = client
        self.port = port
        self.endpoint = endpoint
        self.wall_clock = wall_clock
        self.wall0_s: float | None = None     # the wall time of the step clock's 0
        self.last_arrival_s = -float("inf")
        self.stale_frames = 0
        self.errors_seen = (0, 0)             # (error frames, receive failures) forwarded

    def drain(self, now_s: float) -> None:
        """Hand every frame that arrived to the client at its bus time; bus errors as faults."""
        if self.wall0_s is None:
            self.wall0_s = self.wall_clock() - now_s
        for stamp, frame in self.port.receive(0.0, now_s):
            arrived = bus_arrival_s(stamp, self.wall0_s, now_s, self.last_arrival_s,
                                    STAMP_TRUST_S)
            if arrived is None:
                self.stale_frames += 1
                continue
            self.last_arrival_s = arrived
            self.client.receive(frame, arrived)
        errors = self.port.errors
        seen = (errors.error_frames, errors.receive_failures)
        if seen != self.errors_seen:
            self.errors_seen = seen
            self.client.bus_error(f"{seen[0]} error frames, {seen[1]} receive failures: "
                                  f"{errors.last or 'error frame'}")

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.drain(now_s)
        return self.client.sensor_outputs(now_s)

    def link_report(self) -> dict[str, Any]:
        """``summary.json`` ``link``: the client's counts, engage transitions and bus errors."""
        return {**self.client.report(), "bus": self.port.errors.as_dict(),
                "frames_sent": self.port.sent, "frames_received": self.port.received,
                "engage_requests_refused": (self.endpoint.refused
                                            if self.endpoint is not None else 0),
                "stale_frames": self.stale_frames}


class CanCommandNode:
    """The client's command side: the stack's commands in, the kit's commands out, sent here."""

    name = "pacmod3-client"
    period_s = 0.01
    subscriptions = (Topic.PEDALS, Topic.STEER, Topic.POWERTRAIN)

    def __init__(self, client: Pacmod3Client, port: CanPort,
                 endpoint: EngageEndpoint | None = None, engage_at_start: bool = False, *,
                 sensor: CanSensorNode | None = None, clock: Any = time.monotonic,
                 sleep: Any = time.sleep) -> None:
        self.client = client
        self.port = port
        self.endpoint = endpoint
        self.engage_at_start = engage_at_start
        self.sensor = sensor          # drained while the drive's end brakes to a stop
        self.clock = clock
        self.sleep = sleep
        self.last_now_s = 0.0
        self.last_clock_s: float | None = None

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.last_now_s = now_s
        self.last_clock_s = self.clock()
        client = self.client
        out = client.take_inputs(inbox, now_s)
        if self.engage_at_start and client.heard:   # --engage: once the kit is heard
            self.engage_at_start = False
            client.request_engage(now_s)
        if self.endpoint is not None:
            for act, sender in self.endpoint.requests():
                reason = client.request_engage(now_s) if act == "engage" else None
                self.endpoint.answer(sender, {"ok": reason is None, "state": client.state,
                                              "reason": reason or ""})
        for problem in self.port.send(client.command_frames(now_s), now_s):
            client.bus_error(problem)
        traffic = self.port.traffic()
        if traffic is not None:
            out.append((Topic.CAN_FRAMES, traffic))
        return out

    def close(self) -> None:
        """Hand the kit back: engaged, brake to a standstill first (``Pacmod3Client.end_drive``,
        at most ``RELEASE_MAX_S``), then one frame of every system disabled; close the bus."""
        try:
            now_s = self.last_now_s
            with contextlib.suppress(OSError, ValueError):   # a bus gone: let go all the same
                now_s = self.brake_to_a_stop()
            with contextlib.suppress(OSError, ValueError):
                self.port.send(self.client.release_frames(), now_s)
        finally:
            if self.endpoint is not None:
                self.endpoint.close()
            self.port.close()

    def brake_to_a_stop(self) -> float:
        """Step the client on the step clock until it no longer holds the kit (returns the time)."""
        client = self.client
        start = self.clock()
        clock0 = self.last_clock_s if self.last_clock_s is not None else start
        client.end_drive(self.last_now_s)
        now_s = self.last_now_s
        while client.releasing and self.clock() - start < RELEASE_MAX_S:
            now_s = self.last_now_s + self.clock() - clock0
            if self.sensor is not None:
                self.sensor.drain(now_s)
                client.sensor_outputs(now_s)
            for problem in self.port.send(client.command_frames(now_s), now_s):
                client.bus_error(problem)
            self.sleep(self.period_s)
        return now_s


__all__ = ["ENGAGE_FILE", "CanCommandNode", "CanSensorNode", "EngageEndpoint", "request_engage"]
