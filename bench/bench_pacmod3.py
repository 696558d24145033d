"""PACMod 3 codec benchmark: frames encoded + decoded per second through ``Pacmod3Codec``.

One round trip is ``decode(encode(msg))``. Measured for each message a drive cycle carries (the
four system commands the stack sends at 30 Hz, the reports it reads, and the v14 GLOBAL_CMD),
and for the mix of one command period (4 commands + 8 reports), next to a baseline that only
``struct.pack``s and ``unpack``s the same bytes in the same run. Rates are per second of CPU
time, best of five runs, so a busy machine does not distort them. A kit at 30 Hz needs 12
frames per period: 360 frames/s, so the figure that matters is the headroom over that.

    .venv/bin/python bench/bench_pacmod3.py [--pairs N]

Prints a table, then the results as one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import struct
import sys
import time
from collections.abc import Callable
from typing import Any

from overdrive.kits.pacmod3 import (
    AccelCmd,
    AccelRpt,
    BrakeCmd,
    BrakeRpt,
    Gear,
    GlobalCmd,
    GlobalRpt,
    Pacmod3Codec,
    ShiftCmd,
    ShiftRpt,
    SteeringCmd,
    SteeringRpt,
    VehicleSpeedRpt,
    YawRateRpt,
)

KIT_FRAMES_PER_S = 12 * 30
"""What one PACMod 3 link carries: 4 commands + 8 reports per 1/30 s period."""


def drive_cycle() -> list[Any]:
    """The frames of one command period: commands out, reports in."""
    flags = dict(enabled=True, override_active=False)
    return [
        AccelCmd(enable=True, accel_ratio=0.25), BrakeCmd(enable=True, brake_ratio=0.0),
        SteeringCmd(enable=True, position_rad=-1.2, rotation_rate_radps=3.3),
        ShiftCmd(enable=True, gear=Gear.FORWARD),
        GlobalRpt(enabled=True, override_active=False, usr_can_timeout=False,
                  str_can_timeout=False, brk_can_timeout=False, subsystem_timeout=False,
                  veh_can_timeout=False, fault_active=False, config_fault_active=False,
                  usr_can_read_errors=0),
        AccelRpt(**flags, manual_input=0.0, commanded_value=0.25, output_value=0.25),
        BrakeRpt(**flags, manual_input=0.0, commanded_value=0.0, output_value=0.0),
        SteeringRpt(**flags, manual_input=0.0, commanded_value=-1.2, output_value=-1.1),
        ShiftRpt(**flags, manual_input=3, commanded_value=3, output_value=3),
        VehicleSpeedRpt(speed_mps=4.2, valid=True), YawRateRpt(yaw_rate_radps=0.1),
        VehicleSpeedRpt(speed_mps=4.2, valid=True),
    ]


def _rate(function: Callable[[], None], calls: int, runs: int = 5) -> float:
    """Calls per second of CPU time, best of ``runs``."""
    best = math.inf
    for _ in range(runs):
        start = time.process_time()
        for _ in range(calls):
            function()
        best = min(best, time.process_time() - start)
    return calls / best if best > 0 else math.inf


def throughput(pairs: int) -> dict[str, Any]:
    v3, v14 = Pacmod3Codec("v3"), Pacmod3Codec("v14")
    cycle = drive_cycle()
    per_message: dict[str, float] = {}
    for msg in cycle[:4] + cycle[7:8] + cycle[9:10]:
        per_message[type(msg).__name__] = round(_rate(lambda m=msg: v3.decode(v3.encode(m)),
                                                      pairs))
    global_cmd = GlobalCmd(counter=7, clear_faults=False)
    per_message["GlobalCmd (v14)"] = round(_rate(lambda: v14.decode(v14.encode(global_cmd)),
                                                 pairs))

    def period() -> None:
        for m in cycle:
            v3.decode(v3.encode(m))

    mix = _rate(period, max(1, pairs // len(cycle))) * len(cycle)
    pack = struct.Struct(">BHHH").pack
    unpack = struct.Struct(">BHHH").unpack

    def baseline() -> None:
        unpack(pack(1, 250, 0, 0))

    return {"frames_per_s_drive_cycle_mix": round(mix),
            "headroom_over_one_kit_x": round(mix / KIT_FRAMES_PER_S),
            "struct_baseline_per_s": round(_rate(baseline, pairs)),
            "per_message_round_trips_per_s": per_message}


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=3000)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:])
    results = throughput(args.pairs)
    for name, value in results.items():
        if isinstance(value, dict):
            for k, v in value.items():
                print(f"  {name}.{k:24s} {v:>12,}")
        else:
            print(f"  {name:48s} {value:>12,}")
    print(json.dumps(results))
    return results


if __name__ == "__main__":
    main()
