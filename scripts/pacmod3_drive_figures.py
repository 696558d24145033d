"""Figures of ``drive --can pacmod3`` against the emulated kit, in one process on python-can's
``virtual`` bus (the kit stepped every 10 ms in a thread, each frame taken at its bus stamp):
a 10 m MOVE at 3 m/s with ``--engage``. Prints the kit's own odometer at the end, the stack's
dead-reckoned one, the command rate and the longest gap between BRAKE_CMD frames as the kit
received them, and when the kit saw each enable edge. Wall clock: the figures vary with the
machine's load. ``.venv/bin/python scripts/pacmod3_drive_figures.py [RUNS]``."""

from __future__ import annotations

import itertools
import sys
import tempfile
import threading
import time
from pathlib import Path

from overdrive.kits.pacmod3 import BrakeCmd
from overdrive.run.drive_can import DEFAULT_VEHICLE, run_drive_can
from overdrive.runtime.can_edge import CanPort, resolve_can_config
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_kit import Pacmod3Kit

STEP_S = 0.01
SCENARIO = {"name": "pacmod3-figures", "start": "ready", "seed": 1, "duration_s": 18.0,
            "events": [{"at_s": 1.5, "move": {"distance_m": 10.0, "maxspeed_mps": 3.0,
                                              "curvature_1pm": 0.0}}]}


def kit_loop(kit: Pacmod3Kit, port: CanPort, stop: threading.Event, brake_s: list[float]) -> None:
    start = time.monotonic()
    offset = time.time() - time.monotonic()
    last = 0.0
    next_s = start
    while not stop.is_set():
        now = time.monotonic() - start
        for stamp, frame in port.receive(0.0, now):
            last = min(max(stamp - offset - start, last), now)
            kit.receive(frame, last)
            if frame.arbitration_id == kit.codec.frame_id(BrakeCmd):
                brake_s.append(last)
        kit.step(now)
        port.send(kit.report_frames(now), now)
        port.traffic()
        next_s += STEP_S
        time.sleep(max(0.0, next_s - time.monotonic()))


def one_run(channel: str) -> None:
    params = KIT_VEHICLES[DEFAULT_VEHICLE]
    kit = Pacmod3Kit(params)
    port = CanPort(resolve_can_config(interface="virtual", channel=channel))
    stop = threading.Event()
    brake_s: list[float] = []
    thread = threading.Thread(target=kit_loop, args=(kit, port, stop, brake_s), daemon=True)
    thread.start()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            result = run_drive_can(parse_scenario(SCENARIO), resolve_can_config(
                interface="virtual", channel=channel), Path(tmp) / "run", engage=True,
                plot=False)
    finally:
        stop.set()
        thread.join(5.0)
        port.close()
    summary = kit.summary(kit.now_s)
    engaged = [b - a for a, b in itertools.pairwise(brake_s)]
    edges = ", ".join(f"{e['system']} {e['t_s']:.3f}" for e in summary["enable_edges"])
    print(f"kit odometer {summary['odometer_m']:.3f} m (stack {result.summary['odometer_m']:.3f}"
          f" m); BRAKE_CMD {len(brake_s) / (brake_s[-1] - brake_s[0]):.1f} Hz, longest gap "
          f"{max(engaged) * 1000:.0f} ms; edges (kit s): {edges}; violations "
          f"{len(result.summary['violations'])}; late steps "
          f"{result.summary['wall_clock']['late_steps']}")


def main() -> None:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    for i in range(runs):
        one_run(f"figures-{i}")


if __name__ == "__main__":
    main()
