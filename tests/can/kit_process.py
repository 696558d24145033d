"""The emulated PACMod 3 as a process on the loopback hub (socketcand), for the across-process
acceptance tests: every command frame it takes and its ground truth logged as JSON lines.

    python -m tests.can.kit_process PORT LOG [--press-file PATH]

Times are the kit's own clock (seconds since it started); once ``PATH`` exists the operator
presses the brake pedal for a second (an override). Runs until SIGTERM."""

from __future__ import annotations

import json
import math
import signal
import sys
import time
from pathlib import Path

from overdrive.runtime.can_edge import CanPort, bus_arrival_s, resolve_can_config
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_kit import KitFault, Pacmod3Kit

STEP_S = 0.01


def main(argv: list[str]) -> None:
    port, log_path = int(argv[0]), argv[1]
    press = Path(argv[argv.index("--press-file") + 1]) if "--press-file" in argv else None
    kit = Pacmod3Kit(KIT_VEHICLES["lexus-rx450h"])
    bus = CanPort(resolve_can_config(interface="socketcand", channel="can0",
                                     host="127.0.0.1", port=port))
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    start = time.monotonic()
    wall_minus_mono = time.time() - time.monotonic()   # the hub stamps frames with time.time()
    last_s = 0.0
    next_s = start
    last_truth = -1.0
    with open(log_path, "w", encoding="utf-8", buffering=1) as log:
        log.write(json.dumps({"ready": True, "start": start}) + "\n")
        while not stop:
            now_s = time.monotonic() - start
            if press is not None and press.exists():
                kit.inject(KitFault(kind="override", system="brake", value=0.6, start_s=now_s,
                                    end_s=now_s + 1.0))
                log.write(json.dumps({"t": now_s, "pressed": True}) + "\n")
                press = None
            for stamp, frame in bus.receive(0.0, now_s):
                # a frame's time is the hub's stamp (a kit process starved of CPU reads late
                # frames that were on time), never ahead of now nor behind the last one
                last_s = bus_arrival_s(stamp, wall_minus_mono + start, now_s, last_s, math.inf)
                kit.receive(frame, last_s)
                try:
                    msg = kit.codec.decode(frame)
                except ValueError:
                    continue
                fields = {}
                for name in msg.__struct_fields__:
                    value = getattr(msg, name)
                    fields[name] = float(value) if isinstance(value, float) else int(value)
                log.write(json.dumps({"t": last_s, "cmd": type(msg).__name__, **fields}) + "\n")
            kit.step(now_s)
            bus.send(kit.report_frames(now_s), now_s)
            bus.traffic()
            if now_s - last_truth >= 0.05:
                last_truth = now_s
                truth = kit.truth(now_s)
                log.write(json.dumps({"t": now_s, "truth": {
                    "odometer_m": truth.odometer_m, "speed_mps": truth.speed_mps,
                    "heading_rad": truth.heading_rad, "enabled": list(truth.enabled)}}) + "\n")
            next_s += STEP_S
            delay = next_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_s = time.monotonic()
    bus.close()


if __name__ == "__main__":
    main(sys.argv[1:])
