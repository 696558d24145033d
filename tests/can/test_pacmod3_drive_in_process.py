"""``drive --can pacmod3`` in one process: the stack's wall-clock nodes and the emulated kit
(``Pacmod3Kit``) on python-can's ``virtual`` bus, judged by the kit's own truth. Driving runs are
judged across processes (``test_pacmod3_drive_across_processes.py``): in one process the kit's
thread and the drive share the interpreter's lock, and a kit starved of it timed out a drive
that was on time (seen under CPU load, 2026-11-26)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from overdrive.run.drive_can import DEFAULT_VEHICLE, run_drive_can
from overdrive.runtime.can_edge import resolve_can_config
from overdrive.scenario.schema import load_scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from tests.can.kit_thread import KitThread

pytestmark = pytest.mark.wallclock


def scenario(tmp_path: Path, name: str, move: dict, duration_s: float, extra=()):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({
        "name": name, "start": "ready", "seed": 1, "duration_s": duration_s,
        "events": [{"at_s": 1.5, "move": move}, *extra]}), encoding="utf-8")
    return load_scenario(path)


def drive(tmp_path: Path, channel: str, move: dict, duration_s: float, extra=(), **options):
    params = KIT_VEHICLES[DEFAULT_VEHICLE]
    with KitThread(params, channel) as kit:
        result = run_drive_can(scenario(tmp_path, channel, move, duration_s, extra),
                               resolve_can_config(interface="virtual", channel=channel),
                               tmp_path / "run", plot=False, **options)
        truth = kit.truth()
    return result, kit, truth


def test_without_engage_the_kit_stays_disabled_and_nothing_moves(tmp_path) -> None:
    _, kit, truth = drive(tmp_path, "e2e-wait", {"distance_m": 10, "maxspeed_mps": 3,
                                                      "curvature_1pm": 0}, 4.0)
    assert truth.odometer_m == 0.0 and truth.enabled == ()
    assert not any(getattr(m, "enable", False) for _, m in kit.received)
