"""Planner -> CAN frame latency across processes, over the loopback socketcand hub.

The harness: a ``CanHub`` on 127.0.0.1 (this process), a receiver process standing where the
kit stands (``CanPort`` over python-can's ``socketcand`` interface, stamping each frame with
``time.monotonic()`` as it is drained), and a sender standing where the stack's CAN node
stands: every 1/30 s it takes the "planner decision" time, encodes the period's four PACMod 3
commands (STEERING_CMD first, carrying the period number in its position) and sends them
through its own ``CanPort`` (>= 500 us apart). Latency is from the decision to the receiver
holding the period's first frame, and to it holding all four. CLOCK_MONOTONIC is one clock for
every process on the machine, so the two stamps compare.

This measures the codec + CAN edge + hub path the drive uses; the drive's own planner ->
command step sits before it (wire ``overdrive drive --can pacmod3`` in when it lands: the
lead's). Not a timed test: a figure for ``make bench`` and docs/pacmod3.md.

    .venv/bin/python bench/bench_can_latency.py [--periods N]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from typing import Any

from overdrive.kits.pacmod3 import AccelCmd, BrakeCmd, Gear, Pacmod3Codec, ShiftCmd, SteeringCmd
from overdrive.runtime.can_edge import CanPort, resolve_can_config
from overdrive.runtime.can_hub import CanHub

PERIOD_S = 1 / 30          # PACMod user CAN protocol: commands at 30 Hz
FRAMES_PER_PERIOD = 4
POSITION_STEP_RAD = 0.001  # the period number rides in STEERING_CMD.position_rad


def _port(hub_port: int) -> CanPort:
    return CanPort(resolve_can_config(interface="socketcand", channel="can0", host="127.0.0.1",
                                      port=hub_port))


def receiver(hub_port: int, periods: int, timeout_s: float) -> None:
    """The kit's side: print ``{period: [first_arrival_s, last_arrival_s, frames]}`` as JSON."""
    codec = Pacmod3Codec()
    port = _port(hub_port)
    print("ready", flush=True)
    arrivals: dict[int, list[float]] = {}
    current = -1
    deadline = time.monotonic() + timeout_s
    try:
        while time.monotonic() < deadline:
            for _stamp, frame in port.receive(timeout_s=0.05):
                now = time.monotonic()
                msg = codec.decode(frame)
                if isinstance(msg, SteeringCmd):
                    current = round(msg.position_rad / POSITION_STEP_RAD)
                    arrivals[current] = [now, now, 1]
                elif current in arrivals:
                    arrivals[current][1] = now
                    arrivals[current][2] += 1
            if current >= periods - 1 and arrivals[current][2] >= FRAMES_PER_PERIOD:
                break
    finally:
        port.close()
    print(json.dumps(arrivals), flush=True)


def _percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q * len(ordered)) - 1)]


def measure(periods: int) -> dict[str, Any]:
    codec = Pacmod3Codec()
    with CanHub(port=0) as hub:
        child = subprocess.Popen(
            [sys.executable, __file__, "--receiver", str(hub.port), "--periods", str(periods)],
            stdout=subprocess.PIPE, text=True)
        try:
            assert child.stdout is not None
            if child.stdout.readline().strip() != "ready":
                raise RuntimeError("receiver did not start")
            port = _port(hub.port)
            decided: dict[int, float] = {}
            start = time.monotonic()
            for k in range(periods):
                time.sleep(max(0.0, start + k * PERIOD_S - time.monotonic()))
                decided[k] = t = time.monotonic()
                frames = [codec.encode(SteeringCmd(enable=True, position_rad=k * POSITION_STEP_RAD,
                                                   rotation_rate_radps=3.3)),
                          codec.encode(AccelCmd(enable=True, accel_ratio=0.2)),
                          codec.encode(BrakeCmd(enable=True, brake_ratio=0.0)),
                          codec.encode(ShiftCmd(enable=True, gear=Gear.FORWARD))]
                port.send(frames, t)
            port.close()
            out, _ = child.communicate(timeout=10)
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
    arrivals = {int(k): v for k, v in json.loads(out.strip().splitlines()[-1]).items()}
    first_ms = [(arrivals[k][0] - decided[k]) * 1e3 for k in decided if k in arrivals]
    all_ms = [(arrivals[k][1] - decided[k]) * 1e3 for k in decided
              if k in arrivals and arrivals[k][2] == FRAMES_PER_PERIOD]
    return {"periods": periods, "periods_received_whole": len(all_ms),
            "first_frame_ms": {"p50": round(_percentile(first_ms, 0.5), 3),
                               "p99": round(_percentile(first_ms, 0.99), 3),
                               "max": round(max(first_ms), 3)},
            "all_four_frames_ms": {"p50": round(_percentile(all_ms, 0.5), 3),
                                   "p99": round(_percentile(all_ms, 0.99), 3),
                                   "max": round(max(all_ms), 3)}}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=150)
    parser.add_argument("--receiver", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:])
    if args.receiver:
        receiver(args.receiver, args.periods, timeout_s=args.periods * PERIOD_S + 10)
        return {}
    results = measure(args.periods)
    print(json.dumps(results))
    return results


if __name__ == "__main__":
    main()
