"""The kit-sim plays a scenario's events and its --fault injections on the scenario clock,
which starts with the first frame received."""

from __future__ import annotations

import pytest

from overdrive.kits.pacmod3 import Gear
from overdrive.run.kit_sim import KitSimServer, parse_fault
from overdrive.runtime.can_edge import resolve_can_config
from overdrive.scenario.schema import parse_scenario


def test_scenario_events_reach_the_kit_on_the_scenario_clock() -> None:
    """A scenario's manual override and stuck brake, and a --fault silence, reach the kit at
    their scenario times (the clock starts with the first frame: here at 2.0 s)."""
    scenario = parse_scenario({
        "name": "kit", "vehicle": "lexus-rx450h", "duration_s": 20, "seed": 3,
        "world": {"friction": 0.6},
        "events": [{"at_s": 3.0, "manual_override": True},
                   {"at_s": 4.0, "actuator": {"brake": {"stuck": True}}}]})
    server = KitSimServer(resolve_can_config(interface="virtual", channel="kit-sim-events"),
                          scenario=scenario, faults=(parse_fault("silence::5:6"),))
    try:
        kit = server.kit
        assert kit.plant.world.friction == 0.6
        server._start_scenario(2.0)
        for i in range(1, 800):
            t = 2.0 + i * 0.01
            server._play(t - 2.0)
            kit.step(t)
        assert [s for s, _ in kit.events.overrides] == ["brake", "steering"]
        assert kit.events.overrides[0][1] == pytest.approx(5.0, abs=0.011)
        assert kit.plant.faults.brake_stuck and kit.systems["brake"].fault
        assert kit.silenced(7.5) and not kit.silenced(6.9) and not kit.silenced(8.0)
        assert Gear(kit._gear_code(kit.plant.gear)) == Gear.PARK
    finally:
        server.close()
