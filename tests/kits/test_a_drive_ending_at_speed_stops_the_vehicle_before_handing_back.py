"""A drive that ends while the vehicle moves must stop it before handing the kit back.

Across processes (``overdrive can-hub``, ``overdrive kit-sim pacmod3``, ``overdrive drive --can
pacmod3 --engage``), judged from the kit's own truth. When the drive ends, by its scenario's
``duration_s`` or by the operator's Ctrl-C (SIGINT), ``CanCommandNode.close`` sends one frame of
every system with ``enable=0`` at once: at speed the kit lets go of the brake and the vehicle
coasts, nobody commanding it (a real PACMod hands the pedals to a driver who did not ask).

Measured 2026-11-26 with ``tests/kits/drive_rig.py`` (MOVE 80 m at 6 m/s): the duration ending
at 5.95 m/s: the kit disabled within 0.1 s, 5.49 m/s 4 s later; SIGINT at 4.16 m/s: the drive
exited in 0.1 s (rc 1, "Aborted!"), 3.93 m/s 4 s later."""

from __future__ import annotations

import signal
import time

import pytest

from tests.kits.drive_rig import Rig

pytestmark = pytest.mark.wallclock

STOPPED_WITHIN_S = 4.0    # from 6 m/s at the Lexus's 2.5 m/s^2 pause rate: 2.4 s
STOPPED_MPS = 0.1


@pytest.mark.parametrize("end", ["duration", "sigint"])
def test_a_drive_ending_at_speed_stops_the_vehicle_before_handing_back(tmp_path, end) -> None:
    rig = Rig(tmp_path).start()
    try:
        drive = rig.drive([{"at_s": 1.5, "move": {"distance_m": 80, "maxspeed_mps": 6,
                                                  "curvature_1pm": 0}}],
                          10.0 if end == "duration" else 40.0)
        if end == "sigint":
            rig.wait_speed(4.0)
            drive.send_signal(signal.SIGINT)
        drive.communicate(timeout=60)
        exit_s = time.monotonic()                     # the listener's read times
        speeds = [(f.t, f.decoded().speed_mps) for f in rig.listener.snapshot()
                  if type(f.decoded()).__name__ == "VehicleSpeedRpt"]
        # the kit's own VEHICLE_SPEED_RPT over the drive's last 5 s: moving when its end began
        # (the drive now brakes to a standstill before it exits)
        at_exit_mps = max((abs(v) for t, v in speeds if t > exit_s - 5.0), default=None)
        time.sleep(STOPPED_WITHIN_S)
        truth = rig.kit_summary()["truth"]
    finally:
        rig.close()
    assert at_exit_mps is not None and at_exit_mps > 3.0, "moving when the drive ended"
    assert abs(truth["speed_mps"]) < STOPPED_MPS, (
        f"{truth['speed_mps']:.2f} m/s {STOPPED_WITHIN_S} s after the drive ended at "
        f"{at_exit_mps:.2f} m/s; kit enabled: {truth['enabled']}")
