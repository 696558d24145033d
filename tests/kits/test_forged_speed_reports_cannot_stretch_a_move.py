"""A third node on the bus forging VEHICLE_SPEED_RPT (speed 0, valid) while the vehicle moves:
the stack's dead reckoning takes every speed report it decodes, from whoever sent it, so its
odometer falls behind the kit's and a MOVE ends past its distance by the kit's own odometry.
Judged from the emulated kit's truth; the drive and the kit on python-can's ``virtual`` bus in
one process (the in-process rig of ``tests/can``)."""

from __future__ import annotations

import threading
import time

import pytest
import yaml

from overdrive.kits.pacmod3 import Pacmod3Codec, VehicleSpeedRpt
from overdrive.run.drive_can import DEFAULT_VEHICLE, run_drive_can
from overdrive.runtime.can_edge import CanPort, resolve_can_config
from overdrive.scenario.schema import load_scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from tests.can.kit_thread import KitThread

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


@pytest.mark.xfail(strict=True, reason="the client takes every VEHICLE_SPEED_RPT it decodes: a "
                   "forged speed 0 interleaved with the kit's halves the dead-reckoned odometer "
                   "and the MOVE runs past its distance")
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
