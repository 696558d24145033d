"""A rig for ``drive --can pacmod3`` across processes: ``overdrive can-hub``,
``overdrive kit-sim pacmod3`` (its ``--summary`` and ``--truth`` are the ground truth) and
``overdrive drive`` as three processes, and a passive python-can listener on the hub recording
every frame as sent (time, id, data). Nothing here judges: the tests do."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

import can
from overdrive.kits.frames import CanFrame, KitError
from overdrive.kits.pacmod3 import AccelCmd, BrakeCmd, Pacmod3Codec, ShiftCmd, SteeringCmd

ROOT = Path(__file__).resolve().parents[2]
OVERDRIVE = str(Path(sys.executable).parent / "overdrive")
CODEC = Pacmod3Codec("v3")
COMMAND_IDS = frozenset(CODEC.frame_id(c) for c in (AccelCmd, BrakeCmd, SteeringCmd, ShiftCmd))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass
class Frame:
    t: float            # time.monotonic() when the listener read it
    arbitration_id: int
    data: bytes
    stamp: float = 0.0  # the hub's time stamp (time.time() when the hub relayed it)

    def decoded(self) -> Any:
        try:
            return CODEC.decode(CanFrame(arbitration_id=self.arbitration_id, data=self.data))
        except KitError:   # a listener never judges a frame it cannot read
            return None


class Listener:
    """A passive python-can client on the hub: records every frame it reads."""

    def __init__(self, port: int) -> None:
        self.bus = can.Bus(interface="socketcand", channel="can0", host="127.0.0.1", port=port)
        self.frames: list[Frame] = []
        self.lock = threading.Lock()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.is_set():
            try:
                msg = self.bus.recv(0.05)
            except (can.CanError, OSError):
                return
            if msg is not None:
                with self.lock:
                    self.frames.append(Frame(time.monotonic(), msg.arbitration_id,
                                             bytes(msg.data), msg.timestamp))

    def snapshot(self) -> list[Frame]:
        with self.lock:
            return list(self.frames)

    def commands(self) -> list[tuple[float, Any]]:
        """(t, decoded command) of every command frame seen."""
        out = []
        for f in self.snapshot():
            if f.arbitration_id in COMMAND_IDS:
                out.append((f.t, f.decoded()))
        return out

    def last_speed_mps(self) -> float | None:
        for f in reversed(self.snapshot()):
            m = f.decoded()
            if type(m).__name__ == "VehicleSpeedRpt":
                return m.speed_mps
        return None

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2.0)
        with contextlib.suppress(Exception):
            self.bus.shutdown()


@dataclass
class Rig:
    tmp: Path
    kit_args: tuple[str, ...] = ()
    port: int = field(default_factory=free_port)
    procs: list[subprocess.Popen] = field(default_factory=list)

    def can_args(self) -> list[str]:
        return ["--can-interface", "socketcand", "--can-channel", "can0",
                "--can-option", "host=127.0.0.1", "--can-option", f"port={self.port}"]

    def start(self) -> Rig:
        self.hub = subprocess.Popen([OVERDRIVE, "can-hub", "--port", str(self.port)],
                                    cwd=self.tmp, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL)
        self.procs.append(self.hub)
        deadline = time.monotonic() + 20.0
        while True:
            with contextlib.suppress(OSError), socket.create_connection(
                    ("127.0.0.1", self.port), 0.2):
                break
            assert time.monotonic() < deadline, "hub not started"
            time.sleep(0.05)
        self.listener = Listener(self.port)
        self.summary_path = self.tmp / "kit.json"
        self.truth_path = self.tmp / "truth.csv"
        self.kit = subprocess.Popen(
            [OVERDRIVE, "kit-sim", "pacmod3", *self.can_args(), "--summary",
             str(self.summary_path), "--truth", str(self.truth_path), *self.kit_args],
            cwd=self.tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        self.procs.append(self.kit)
        while self.listener.last_speed_mps() is None:
            assert time.monotonic() < deadline and self.kit.poll() is None, "kit not heard"
            time.sleep(0.05)
        self.out = self.tmp / "run"
        return self

    def drive(self, events: list[dict], duration_s: float, engage: bool = True,
              out: str = "run", extra_args: tuple[str, ...] = ()) -> subprocess.Popen:
        path = self.tmp / f"{out}.yaml"
        path.write_text(yaml.safe_dump({"name": out, "start": "ready", "seed": 1,
                                        "duration_s": duration_s, "events": events}))
        self.out = self.tmp / out
        p = subprocess.Popen(
            [OVERDRIVE, "drive", "--can", "pacmod3", str(path), "--out", str(self.out),
             "--quiet", *(["--engage"] if engage else []), *self.can_args(), *extra_args],
            cwd=self.tmp, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.procs.append(p)
        return p

    def wait_speed(self, above_mps: float, within_s: float = 25.0) -> float:
        deadline = time.monotonic() + within_s
        while time.monotonic() < deadline:
            v = self.listener.last_speed_mps()
            if v is not None and abs(v) > above_mps:
                return time.monotonic()
            time.sleep(0.05)
        raise AssertionError(f"never above {above_mps} m/s")

    def kit_summary(self) -> dict[str, Any]:
        """Stop the kit (SIGTERM: it writes its summary) and read the summary."""
        if self.kit.poll() is None:
            self.kit.send_signal(signal.SIGTERM)
            self.kit.wait(20)
        return json.loads(self.summary_path.read_text())

    def truth_rows(self) -> list[dict[str, float]]:
        with self.truth_path.open() as f:
            rows = list(csv.DictReader(f))
        return [{k: float(v) if v else float("nan") for k, v in r.items()} for r in rows]

    def run_summary(self) -> dict[str, Any]:
        return json.loads((self.out / "summary.json").read_text())

    def close(self) -> None:
        self.listener.close()
        for p in reversed(self.procs):
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(p.pid, signal.SIGCONT)
                p.terminate()
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait(10)
