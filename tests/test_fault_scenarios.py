"""Every fault-injection kind has a shipped scenario that ends stopped and safe (issue 9)."""

from __future__ import annotations

from pathlib import Path

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import load_scenario

FAULTS = sorted((Path(__file__).resolve().parent.parent / "scenarios" / "faults").glob("*.yaml"))
KINDS = {"drop", "delay", "duplicate", "reorder", "sensor", "actuator", "engine_stall", "safestop",
         "manual_override", "door", "sensor_error", "gps_status"}


def test_every_fault_kind_has_a_scenario() -> None:
    covered = set().union(*(load_scenario(p).event_kinds for p in FAULTS))
    assert covered >= KINDS
    sensor_faults = {e.body.fault for p in FAULTS for e in load_scenario(p).events if e.kind == "sensor"}
    assert sensor_faults == {"freeze", "noise", "dropout"}


@pytest.mark.parametrize("path", FAULTS, ids=lambda p: p.stem)
def test_fault_scenario_ends_stopped_and_safe(path: Path) -> None:
    result = run_scenario(load_scenario(path), None, keep_trace=False)
    assert result.summary["violations"] == [], result.summary["violations"]
    assert abs(result.summary["final"]["speed_mps"]) < 0.05
