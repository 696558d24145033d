"""The CAN edge: the one place a python-can bus is opened, configured the python-can way.

``resolve_can_config`` asks python-can's own lookup (explicit flags first, then ``can.rc``, the
environment ``CAN_INTERFACE`` / ``CAN_CHANNEL`` / ``CAN_BITRATE`` / ``CAN_CONFIG`` with and
without a context suffix, then its config files, merged key by key) and says where each key came
from, since a stale config file silently supplies values. ``CanPort`` owns the bus: it sends the
frames it is handed, in order and spaced, and drains what arrived. It has no thread and keeps no
cached command: a frame leaves only when the loop that computed it sends it, so a stopped or
killed process sends nothing and the kit's command timeout fires. Bus errors (bus-off, no
acknowledgement, a full transmit buffer, a hub gone) come back as text for the caller to raise
as a fault; they never raise.
"""

from __future__ import annotations

import configparser
import contextlib
import json
import math
import os
import socket
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

import msgspec

import can
from overdrive.kits.frames import CanFrame, KitDecodeError
from overdrive.messages import CanFrameRecord, CanTraffic

MIN_FRAME_GAP_S: Final = 0.0005
"""PACMod 3 user CAN protocol: frames from the user's computer at least 500 us apart."""
CONNECT_CHECK_TIMEOUT_S: Final = 2.0
"""socketcand: how long to wait for the hub's TCP port before saying it is not there (python-can
itself retries for 10 s in a busy loop)."""
STAMP_FUTURE_S: Final = 0.005
"""A bus stamp up to this far ahead of the read is the two clocks' jitter; further is a clock
step, and the frame is taken as read then."""
TRAFFIC_MAX_FRAMES: Final = 4096
"""Frames kept for the recorder between two ``traffic`` calls; beyond, the oldest are counted as
dropped from the log (never from the bus)."""


class CanConfigError(ValueError):
    """A CAN configuration python-can cannot open: no interface, an unknown one, no channel."""


class CanConfig(msgspec.Struct, frozen=True, kw_only=True):
    """A resolved python-can configuration and where each key came from."""

    interface: str
    channel: str
    options: dict[str, Any] = {}
    sources: dict[str, str] = {}

    def bus_kwargs(self) -> dict[str, Any]:
        """Keyword arguments for ``can.Bus``. socketcand gets ``tcp_tune`` (TCP_NODELAY) unless
        set: without it Nagle's algorithm and delayed acknowledgements hold the second frame of
        a period ~40 ms (measured 2026-11-26 through ``CanHub``), past a kit's 100 ms timeout
        within three periods."""
        extra = {"tcp_tune": True} if self.interface == "socketcand" else {}
        return {"interface": self.interface, "channel": self.channel, **extra, **self.options}

    def describe(self) -> str:
        """One line per key: ``interface = socketcand (flag --can-interface)``."""
        keys = {"interface": self.interface, "channel": self.channel, **self.options}
        return "\n".join(f"{k} = {v!r} ({self.sources.get(k, '?')})" for k, v in keys.items())

    def to_json(self) -> dict[str, Any]:
        """For the run folder's ``can.json``."""
        return {"interface": self.interface, "channel": self.channel,
                "options": {k: v if isinstance(v, int | float | str | bool) else repr(v)
                            for k, v in self.options.items()},
                "sources": dict(self.sources)}


def _file_sources(context: str | None) -> list[tuple[str, dict[str, Any]]]:
    """Each of python-can's config files that exists, last read first (a later file replaces
    an earlier one's values, as python-can reads them), per section: ``(source, values)``."""
    found: list[tuple[str, dict[str, Any]]] = []
    sections = [context, "default"] if context else ["default"]
    paths = [Path(os.path.expanduser(p)) for p in can.util.CONFIG_FILES]
    for section in sections:
        for path in reversed(paths):
            if not path.is_file():
                continue
            parser = configparser.ConfigParser()
            try:
                parser.read(path, encoding="utf-8")
            except (configparser.Error, UnicodeDecodeError, OSError) as e:
                raise CanConfigError(f"python-can config file {path}: {one_line(e)}") from e
            if parser.has_section(section):
                found.append((f"config file {path} [{section}]", dict(parser.items(section))))
    return found


def one_line(error: BaseException) -> str:
    """An exception's text on one line (configparser's span several)."""
    return " ".join(str(error).split())


def _check_environment() -> None:
    """python-can reads ``CAN_CONFIG`` with ``json.loads`` and merges it as a mapping: say what
    is wrong with it before python-can raises (a traceback)."""
    for key, value in os.environ.items():
        if not key.startswith("CAN_CONFIG"):
            continue
        try:
            parsed = json.loads(value)
        except ValueError as e:
            raise CanConfigError(f"{key} is not JSON: {e}") from e
        if not isinstance(parsed, dict):
            raise CanConfigError(f"{key} must be a JSON object of python-can options, "
                                 f"got {type(parsed).__name__}")


def resolve_can_config(interface: str | None = None, channel: str | None = None,
                       bitrate: int | None = None, context: str | None = None,
                       **options: Any) -> CanConfig:
    """python-can's configuration with explicit values first, each key's source named.

    Raises ``CanConfigError`` when no interface or channel results, or the interface is unknown.
    """
    given: dict[str, Any] = {k: v for k, v in (("interface", interface), ("channel", channel),
                                               ("bitrate", bitrate)) if v is not None}
    given.update({k: v for k, v in options.items() if v is not None})
    _check_environment()
    layers: list[tuple[str, dict[str, Any]]] = [("flag", dict(given)), ("can.rc", dict(can.rc))]
    if context:
        layers.append((f"environment (context {context})",
                       dict(can.util.load_environment_config(context))))
    layers.append(("environment", dict(can.util.load_environment_config())))
    layers += _file_sources(context)
    try:
        merged = dict(can.util.load_config(config=dict(given), context=context))
    except (can.CanInterfaceNotImplementedError, ValueError, TypeError,
            configparser.Error) as e:
        raise CanConfigError(f"CAN configuration: {one_line(e)}") from e
    sources: dict[str, str] = {}
    for key in merged:
        for name, layer in layers:
            if key in layer or (key == "interface" and "bustype" in layer):
                sources[key] = name
                break
        else:
            sources[key] = "python-can default"
    found_interface = merged.pop("interface", None)
    found_channel = merged.pop("channel", None)
    if not found_interface:
        raise CanConfigError("no CAN interface: give --can-interface, or set CAN_INTERFACE or "
                             "a python-can config file (see docs/pacmod3.md)")
    if found_interface not in can.VALID_INTERFACES:
        raise CanConfigError(f"unknown CAN interface {found_interface!r}; python-can knows "
                             f"{', '.join(sorted(can.VALID_INTERFACES))}")
    if found_channel is None or str(found_channel) == "":
        raise CanConfigError(f"no CAN channel for {found_interface}: give --can-channel or "
                             f"set CAN_CHANNEL")
    options_out = {k: v for k, v in merged.items() if v is not None}
    for key, value in options_out.items():
        if isinstance(value, float) and not math.isfinite(value):
            raise CanConfigError(f"CAN option {key} = {value} ({sources.get(key, '?')}): "
                                 f"not a finite number")
    return CanConfig(interface=str(found_interface), channel=str(found_channel),
                     options=options_out, sources=sources)


def _check_reachable(config: CanConfig) -> None:
    """socketcand: fail at once, naming the address, when nothing listens there."""
    if config.interface != "socketcand":
        return
    host = config.options.get("host")
    port = config.options.get("port")
    if host is None or port is None:
        raise CanConfigError("socketcand needs host and port (CAN_CONFIG='{\"host\": "
                             "\"127.0.0.1\", \"port\": 29536}' or the config file)")
    if isinstance(port, bool) or not isinstance(port, int | str):
        raise CanConfigError(f"socketcand port {port!r}: expected an integer")
    try:
        port_number = int(port)
    except ValueError as e:
        raise CanConfigError(f"socketcand port {port!r}: expected an integer") from e
    if not 0 < port_number < 65536:
        raise CanConfigError(f"socketcand port {port_number}: outside 1..65535")
    try:
        with socket.create_connection((str(host), port_number),
                                      timeout=CONNECT_CHECK_TIMEOUT_S) as probe:
            greeting = b""
            while not greeting.endswith(b">") and len(greeting) < 64:
                chunk = probe.recv(64)
                if not chunk:
                    break
                greeting += chunk
    except TimeoutError as e:
        raise CanConfigError(f"{host}:{port_number} accepts connections but says nothing: not "
                             f"a socketcand server (no '< hi >' within "
                             f"{CONNECT_CHECK_TIMEOUT_S:g} s)") from e
    except OSError as e:
        raise CanConfigError(f"no socketcand server at {host}:{port_number}: {e}") from e
    if greeting.strip() != b"< hi >":
        raise CanConfigError(f"{host}:{port_number} is not a socketcand server (it said "
                             f"{greeting[:40]!r}, expected '< hi >')")


def bus_arrival_s(stamp_wall_s: float, wall0_s: float, read_s: float, last_s: float,
                  trust_s: float) -> float | None:
    """A frame's arrival on the reader's clock from its bus stamp (python-can's, wall clock;
    ``wall0_s`` the wall time of the reader's time 0), never before ``last_s`` (the previous
    frame's) nor after ``read_s``. None: stamped more than ``trust_s`` before the read, a frame
    too old to act on (the caller drops and counts it). A stamp not finite or in the future (a
    clock step) is taken as read at ``read_s``."""
    t = stamp_wall_s - wall0_s
    if not math.isfinite(t) or t > read_s + STAMP_FUTURE_S:
        t = read_s
    elif t < read_s - trust_s:
        return None
    return min(max(t, last_s), read_s)


class CanErrors:
    """What went wrong on the bus, counted: never raised."""

    def __init__(self) -> None:
        self.send_failures = 0
        self.receive_failures = 0
        self.error_frames = 0
        self.malformed = 0
        self.log_dropped = 0
        self.last: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in vars(self).items()}


class CanPort:
    """An open python-can bus: ``send`` spaced frames, ``receive`` what arrived. No thread."""

    def __init__(self, config: CanConfig, *, clock: Any = time.monotonic,
                 sleep: Any = time.sleep) -> None:
        _check_reachable(config)
        try:
            self.bus = can.Bus(**config.bus_kwargs())
        except (can.CanError, OSError, ValueError, TimeoutError) as e:
            raise CanConfigError(f"cannot open CAN {config.interface} {config.channel}: "
                                 f"{e}") from e
        self.config = config
        self.errors = CanErrors()
        self._clock = clock
        self._sleep = sleep
        self._last_send_s = -math.inf
        self._log: list[CanFrameRecord] = []
        self.sent = 0
        self.received = 0

    def send(self, frames: Sequence[CanFrame], now_s: float) -> list[str]:
        """Send ``frames`` in order, at least ``MIN_FRAME_GAP_S`` apart (also from the previous
        call's last frame). Returns the errors, one text per frame that failed."""
        problems: list[str] = []
        for frame in frames:
            wait_s = self._last_send_s + MIN_FRAME_GAP_S - self._clock()
            if wait_s > 0:
                self._sleep(wait_s)
            message = can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                                  is_extended_id=frame.is_extended)
            try:
                self.bus.send(message, timeout=0.0)
            except (can.CanError, OSError, ValueError) as e:
                self.errors.send_failures += 1
                self.errors.last = f"send 0x{frame.arbitration_id:X}: {e}"
                problems.append(self.errors.last)
            else:
                self.sent += 1
                self._remember(now_s, frame, "tx")
            self._last_send_s = self._clock()
        return problems

    def receive(self, timeout_s: float = 0.0, now_s: float | None = None
                ) -> list[tuple[float, CanFrame]]:
        """Every frame that arrived, with python-can's timestamp (``now_s`` in the log when given).

        Error frames, remote frames and CAN FD frames are counted and skipped."""
        out: list[tuple[float, CanFrame]] = []
        wait_s = timeout_s
        while True:
            try:
                message = self.bus.recv(timeout=wait_s)
            except (can.CanError, OSError, ValueError) as e:
                self.errors.receive_failures += 1
                self.errors.last = f"receive: {e}"
                break
            if message is None:
                break
            wait_s = 0.0
            if message.is_error_frame:
                self.errors.error_frames += 1
                continue
            if message.is_remote_frame or message.is_fd:
                self.errors.malformed += 1
                continue
            try:
                frame = CanFrame(arbitration_id=message.arbitration_id, data=bytes(message.data),
                                 is_extended=message.is_extended_id)
            except KitDecodeError:
                self.errors.malformed += 1
                continue
            self.received += 1
            stamp = message.timestamp
            out.append((stamp, frame))
            self._remember(stamp if now_s is None else now_s, frame, "rx")
        return out

    def _remember(self, time_s: float, frame: CanFrame, direction: str) -> None:
        if len(self._log) >= TRAFFIC_MAX_FRAMES:
            self._log.pop(0)
            self.errors.log_dropped += 1
        self._log.append(CanFrameRecord(time_s=time_s, arbitration_id=frame.arbitration_id,
                                        data=frame.data, direction=direction,  # type: ignore[arg-type]
                                        is_extended=frame.is_extended))

    def traffic(self) -> CanTraffic | None:
        """The frames sent and received since the last call (None: none)."""
        if not self._log:
            return None
        frames, self._log = tuple(self._log), []
        return CanTraffic(channel=self.config.channel, frames=frames)

    def close(self) -> None:
        with contextlib.suppress(can.CanError, OSError):   # a hub already gone
            self.bus.shutdown()
