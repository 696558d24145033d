"""``overdrive can-hub`` and ``overdrive can-monitor``: a loopback CAN bus for machines without
SocketCAN, and a listener that decodes a live bus without sending anything."""

from __future__ import annotations

import contextlib
import signal
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
from overdrive.kits.frames import KitDecodeError, KitError, UnknownFrame
from overdrive.kits.pacmod3 import Dialect, Pacmod3Codec
from overdrive.runtime.can_edge import CanConfig, CanConfigError, CanPort, resolve_can_config
from overdrive.runtime.can_hub import CanHub

__all__ = ["CanConfigError", "KitError", "cast_option", "monitor", "resolve_can_config",
           "serve_hub"]


def cast_option(text: str) -> Any:
    """A ``--can-option`` value as python-can casts config-file values (int, float, bool, str)."""
    return can.util.cast_from_string(text)


def serve_hub(host: str, port: int, say: Callable[[str], Any]) -> int:
    """Serve a socketcand-protocol hub in the foreground until SIGINT / SIGTERM."""
    try:
        hub = CanHub(host, port)
    except OSError as e:   # not this machine's address, a name that does not resolve, port taken
        say(f"error: can-hub cannot listen on {host}:{port}: {e}")
        return 2
    say(f"can-hub: socketcand protocol on {hub.host}:{hub.port}; python-can: "
        f"interface=socketcand host={hub.host} port={hub.port} channel=can0")
    signal.signal(signal.SIGTERM, lambda *_: hub.stop())
    with contextlib.suppress(KeyboardInterrupt):
        hub.serve_forever()
    say(f"can-hub: relayed {hub.relayed} frames, dropped {hub.malformed} malformed, "
        f"{hub.overflowed} to clients that did not read")
    hub.close()
    return 0


def monitor(config: CanConfig, say: Callable[[str], Any], *, dialect: Dialect = "v3",
            dbc: Path | None = None, duration_s: float | None = None,
            count: int | None = None) -> int:
    """Print every frame on the bus decoded as PACMod 3; send nothing. Exit 1 when no frame
    arrived at all (a silent bus is said, never passed over)."""
    codec = Pacmod3Codec(dialect, dbc)
    say(f"can-monitor: {config.interface} {config.channel}; DBC {codec.dbc_path.name} "
        f"({codec.dbc_version}, sha256 {codec.dbc_sha256[:12]}), dialect {dialect}")
    for line in config.describe().splitlines():
        say(f"  {line}")
    port = CanPort(config)
    seen: Counter[str] = Counter()
    start = time.monotonic()
    try:
        while (duration_s is None or time.monotonic() - start < duration_s) and (
                count is None or seen.total() < count):
            for stamp_s, frame in port.receive(timeout_s=0.1):
                try:
                    message = codec.decode(frame)
                except UnknownFrame:
                    seen["unknown"] += 1
                    say(f"{stamp_s:.6f} {frame}  unknown id")
                    continue
                except KitDecodeError as e:
                    seen["malformed"] += 1
                    say(f"{stamp_s:.6f} {frame}  MALFORMED: {e}")
                    continue
                seen[type(message).__name__] += 1
                say(f"{stamp_s:.6f} {frame}  {message!r}")
    except KeyboardInterrupt:
        pass
    finally:
        port.close()
    say("can-monitor: " + (", ".join(f"{k} {v}" for k, v in sorted(seen.items()))
                           or "no frame received"))
    if port.errors.last:
        say(f"can-monitor: bus errors: {port.errors.as_dict()}")
    return 0 if seen.total() else 1
