"""``drive --can pacmod3`` end to end in one process: the stack's wall-clock nodes and the
emulated kit (``Pacmod3Kit``) on python-can's ``virtual`` bus, judged by the kit's own truth."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

from overdrive.kits.pacmod3 import AccelCmd, BrakeCmd
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


def test_a_10_m_move_ends_within_0_2_m_by_the_kit_and_engages_brake_first(tmp_path) -> None:
    result, kit, truth = drive(tmp_path, "e2e-move", {"distance_m": 10, "maxspeed_mps": 3,
                                                      "curvature_1pm": 0}, 18.0, engage=True)
    why = (result.summary["violations"], result.summary["link"]["transitions"],
           result.summary["wall_clock"])   # a kit timeout under load: how late the drive was
    assert truth.odometer_m == pytest.approx(10.0, abs=0.2), why
    assert abs(truth.speed_mps) < 0.05
    commands = [m for _, m in kit.received]
    first_on = next(i for i, m in enumerate(commands) if getattr(m, "enable", False))
    assert isinstance(commands[first_on], BrakeCmd) and commands[first_on].brake_ratio >= 0.5
    first_throttle = next(i for i, m in enumerate(commands)
                          if isinstance(m, AccelCmd) and m.accel_ratio > 0)
    assert first_throttle > first_on
    run = tmp_path / "run"
    can = json.loads((run / "can.json").read_text())
    assert can["dbc"]["sha256"] and can["python_can"]["interface"] == "virtual"
    assert yaml.safe_load((run / "vehicle.yaml").read_text())["name"] == DEFAULT_VEHICLE
    directions = set()
    with (run / "run.mcap").open("rb") as f:
        for _, _, message in make_reader(f).iter_messages(topics=["can/frames"]):
            directions |= {r["direction"] for r in json.loads(message.data)["frames"]}
    assert directions == {"rx", "tx"}, "raw frames both ways in run.mcap"
    assert not (run / "engage.json").exists(), "the endpoint goes with the drive"


def test_without_engage_the_kit_stays_disabled_and_nothing_moves(tmp_path) -> None:
    _, kit, truth = drive(tmp_path, "e2e-wait", {"distance_m": 10, "maxspeed_mps": 3,
                                                      "curvature_1pm": 0}, 4.0)
    assert truth.odometer_m == 0.0 and truth.enabled == ()
    assert not any(getattr(m, "enable", False) for _, m in kit.received)


@pytest.mark.parametrize("curvature", [0.05, -0.05])
def test_a_curve_turns_the_way_asked(tmp_path, curvature) -> None:
    _, _, truth = drive(tmp_path, f"e2e-curve{curvature}", {
        "distance_m": 8, "maxspeed_mps": 2.5, "curvature_1pm": curvature}, 16.0, engage=True)
    assert truth.odometer_m > 6.0
    # curvature positive turns right: heading clockwise (negative), y to the right (negative)
    assert math.copysign(1.0, truth.heading_rad) == -math.copysign(1.0, curvature)


@pytest.mark.parametrize("node", ["move", "driving"])
def test_a_silent_planner_brakes_to_a_stop_and_the_kit_stays_engaged(tmp_path, node) -> None:
    _, kit, truth = drive(tmp_path, f"e2e-silent-{node}", {
        "distance_m": 40, "maxspeed_mps": 3, "curvature_1pm": 0}, 16.0,
        extra=[{"at_s": 9.0, "stall": {"node": node, "for_s": 6.9}}], engage=True)
    moving = [t for t in kit.truths if 8.5 <= t.t_s <= 9.0]
    assert moving and moving[-1].speed_mps > 1.0, "moving when the planner went quiet"
    # the kit's state up to the drive's end (its close hands the kit back: enable=0)
    engaged = [t for t in kit.truths if set(t.enabled) == {"accel", "brake", "steering", "shift"}]
    assert engaged[-1].t_s >= truth.t_s - 0.1, "engaged to the end of the drive"
    assert engaged[-1].odometer_m < 30.0, "stopped short of the MOVE's end"
    assert abs(engaged[-1].speed_mps) < 0.05
