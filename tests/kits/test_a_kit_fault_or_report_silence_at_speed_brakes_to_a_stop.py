"""A kit that goes quiet or faults one system at speed must still be braked to a stop.

Across processes (``overdrive can-hub``, ``overdrive kit-sim pacmod3 --fault ...``, ``overdrive
drive --can pacmod3 --engage``), judged from the kit's own truth (``--truth``). The issue asks
for a stack "stopped when anything goes quiet, wrong or malformed", and says disabling at speed
coasts (a real PACMod hands the pedals back). Today a report silence of 0.5 s, or a stuck
steering actuator, moves the client to ``faulted``, which commands ``enable=0`` on EVERY
system, the brake included: the kit lets go and the vehicle coasts on drag alone.

Measured 2026-11-26 with ``tests/kits/drive_rig.py`` (MOVE 80 m at 6 m/s): silence 8-8.5 s at
3.5 m/s: still 1.07 m/s 22 s later, 48 m rolled after the silence; stuck steering at 8 s at
3.3 m/s: still 0.83 m/s 22 s later, 46 m rolled (the brake was working all along). This test
(fault at 9 s, ~5 m/s): 4.71 m/s (silence) and 4.56 m/s (stuck) 4 s after the fault, 28-29 m
rolled, where a pause-rate stop takes ~2 s and ~5 m."""

from __future__ import annotations

import pytest

from tests.kits.drive_rig import Rig

pytestmark = pytest.mark.wallclock

FAULT_AT_S = 9.0          # kit scenario clock (its first frame); motion starts ~6 s (runwait 5 s)
STOPPED_WITHIN_S = 4.0    # from ~3.5 m/s at a 2 m/s^2 pause rate: 1.75 s; a full brake: < 1 s
STOPPED_MPS = 0.1


@pytest.mark.parametrize("fault", [f"silence::{FAULT_AT_S}:{FAULT_AT_S + 0.5}",
                                   f"stuck:steering:{FAULT_AT_S}"], ids=["silence", "stuck"])
def test_a_kit_fault_or_report_silence_at_speed_brakes_to_a_stop(tmp_path, fault) -> None:
    rig = Rig(tmp_path, ("--fault", fault)).start()
    try:
        drive = rig.drive([{"at_s": 1.5, "move": {"distance_m": 80, "maxspeed_mps": 6,
                                                  "curvature_1pm": 0}}], 16.0)
        drive.communicate(timeout=90)
        rig.kit_summary()
        rows = [r for r in rig.truth_rows() if r["scenario_s"] == r["scenario_s"]]
    finally:
        rig.close()
    at_fault = [r for r in rows if r["scenario_s"] <= FAULT_AT_S]
    assert at_fault and at_fault[-1]["speed_mps"] > 2.0, "at speed when the fault came"
    later = [r for r in rows
             if FAULT_AT_S + STOPPED_WITHIN_S <= r["scenario_s"] <= FAULT_AT_S + 6.0]
    assert later, "the kit's truth covers the seconds after the fault"
    fastest = max(abs(r["speed_mps"]) for r in later)
    rolled = later[-1]["odometer_m"] - at_fault[-1]["odometer_m"]
    assert fastest < STOPPED_MPS, (f"{fastest:.2f} m/s {STOPPED_WITHIN_S} s after the fault, "
                                   f"{rolled:.1f} m rolled")
