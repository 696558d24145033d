"""A third node on the bus forging VEHICLE_SPEED_RPT (speed 0, valid) while the vehicle moves:
the stack's dead reckoning takes every speed report it decodes, from whoever sent it, so its
odometer falls behind the kit's and a MOVE ends past its distance by the kit's own odometry.
Judged from the emulated kit's truth; the drive and the kit on python-can's ``virtual`` bus in
one process (the in-process rig of ``tests/can``)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml

from overdrive.kits.pacmod3 import Pacmod3Codec, VehicleSpeedRpt
from overdrive.run.drive_can import DEFAULT_VEHICLE, run_drive_can
from overdrive.runtime.can_edge import CanPort, resolve_can_config
from overdrive.scenario.schema import load_scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from tests.can.kit_thread import KitThread
from tests.can.test_pacmod3_drive_across_processes import Rig

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.wallclock

AUTHORIZED_OVERRUN_M = 0.2   # issue 32's acceptance: a MOVE of D m ends within D + 0.2 m
FORGE_PERIOD_S = 0.01        # the forger: one zero-speed report every 10 ms (3x the kit's rate)


class SpeedForger:
    """A python-can node on the same bus sending VEHICLE_SPEED_RPT speed 0, valid."""

    def __init__(self, channel: str) -> None:
        self.port = CanPort(resolve_can_config(interface="virtual", channel=channel))
        self.frame = Pacmod3Codec().encode(VehicleSpeedRpt(speed_mps=0.0, valid=True))
        self.stop = threading.Event()
        self.sent = 0
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self.stop.is_set():
            self.port.receive(0.0)       # drained, not kept
            self.port.send([self.frame], 0.0)
            self.port.traffic()
            self.sent += 1
            time.sleep(FORGE_PERIOD_S)

    def __enter__(self) -> SpeedForger:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        self.thread.join(5.0)
        self.port.close()


def test_a_forged_zero_speed_report_does_not_carry_the_vehicle_past_the_move(tmp_path) -> None:
    """Measured 2026-11-26 (this machine, loaded): a 10 m MOVE at 3 m/s with a forger sending
    speed 0 every 10 ms: the kit's odometer read 36.18 m when the 16 s drive ended, the
    vehicle still at 3.55 m/s (`pytest --runxfail` on this file reproduces it); summary.json's
    link counted nothing (malformed 0, unknown 0, foreign_commands 0), the state 'engaged'. Without the forger the same MOVE
    ends at 9.85-9.88 m (docs/pacmod3-stack.md)."""
    channel = "forged-speed"
    path = tmp_path / "move.yaml"
    path.write_text(yaml.safe_dump({
        "name": "forged", "start": "ready", "seed": 1, "duration_s": 16.0,
        "events": [{"at_s": 1.5, "move": {"distance_m": 10, "maxspeed_mps": 3,
                                          "curvature_1pm": 0}}]}), encoding="utf-8")
    params = KIT_VEHICLES[DEFAULT_VEHICLE]
    with KitThread(params, channel) as kit, SpeedForger(channel) as forger:
        result = run_drive_can(load_scenario(path),
                               resolve_can_config(interface="virtual", channel=channel),
                               tmp_path / "run", plot=False, engage=True)
        truth = kit.truth()
    assert forger.sent > 100, "the forger was on the bus"
    assert truth.odometer_m <= 10.0 + AUTHORIZED_OVERRUN_M, (
        f"kit odometer {truth.odometer_m:.2f} m for a 10 m MOVE; link "
        f"{result.summary['link']}")


@pytest.mark.parametrize("kind", ["speed0", "replay"])
def test_a_third_node_on_the_hub_cannot_carry_the_vehicle_past_the_move(tmp_path, kind) -> None:
    """Across processes (the kit, the drive and a third python-can client on a socketcand
    hub), 2026-11-26: the third client sending at 100 Hz a VEHICLE_SPEED_RPT of speed 0
    (``speed0``) or the kit's first valid speed report replayed (``replay``, speed 0: recorded
    at standstill). A 10 m MOVE at 3 m/s ended at 23.46 and 34.32 m (speed0, two runs) and
    29.77 and 44.35 m (replay) by the kit's odometer, the vehicle still at 3.6-4.0 m/s when
    the drive ended; the link counted nothing (malformed 0, unknown 0); only the judge saw it
    (acceleration_ellipse: 91.88 and -101.07 m/s^2 from the dead reckoning). Reproduce:
    ``pytest --runxfail`` on this test."""
    rig = Rig(tmp_path)
    injector = subprocess.Popen([sys.executable, "-m", "tests.kits.bus_injector",
                                 str(rig.hub.port), kind, "100"], cwd=ROOT,
                                stdout=subprocess.DEVNULL)
    try:
        rig.run_drive({"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0}, 18.0)
        rig.drive.communicate(timeout=120)
        _, truths = rig.records()
    finally:
        injector.kill()
        injector.wait(10)
        rig.close()
    odometer_m = truths[-1]["truth"]["odometer_m"]
    assert odometer_m <= 10.0 + AUTHORIZED_OVERRUN_M, f"kit odometer {odometer_m:.2f} m"
