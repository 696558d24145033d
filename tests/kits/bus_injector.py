"""A third python-can node on the loopback hub (socketcand) injecting PACMod 3 report frames,
for the garbage-on-the-bus attacks across processes.

    python -m tests.kits.bus_injector PORT KIND RATE_HZ

KIND ``speed0``: VEHICLE_SPEED_RPT speed 0, valid. ``replay``: the first valid VEHICLE_SPEED_RPT
the kit sent, sent again and again (a recorded report replayed). Runs until killed."""

from __future__ import annotations

import sys
import time

from overdrive.kits.pacmod3 import Pacmod3Codec, VehicleSpeedRpt
from overdrive.runtime.can_edge import CanPort, resolve_can_config


def main(argv: list[str]) -> None:
    port, kind, rate_hz = int(argv[0]), argv[1], float(argv[2])
    bus = CanPort(resolve_can_config(interface="socketcand", channel="can0",
                                     host="127.0.0.1", port=port))
    codec = Pacmod3Codec()
    speed_id = codec.frame_id(VehicleSpeedRpt)
    frames = [codec.encode(VehicleSpeedRpt(speed_mps=0.0, valid=True))] if kind == "speed0" \
        else []
    start = time.monotonic()
    sent = 0
    while True:
        arrived = bus.receive(0.0)
        if not frames:   # replay: wait for the kit's first valid speed report
            frames = [f for _, f in arrived if f.arbitration_id == speed_id
                      and codec.decode(f).valid][:1]
            time.sleep(0.005)
            continue
        bus.send(frames, 0.0)
        bus.traffic()
        sent += 1
        time.sleep(max(0.0, start + sent / rate_hz - time.monotonic()))


if __name__ == "__main__":
    main(sys.argv[1:])
