"""Shared helpers for the observability tests: scenarios and a recorded run."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from overdrive.bus.local import LocalBus
from overdrive.observe.mcap_log import McapRecorder
from overdrive.observe.recorder import Recorder
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.runtime.lockstep import LockstepRuntime
from overdrive.scenario.player import channel_faults
from overdrive.scenario.schema import Scenario, parse_scenario

DEMO = Path(__file__).resolve().parents[2] / "scenarios" / "demo.yaml"


def speed_scenario(**overrides: Any) -> dict[str, Any]:
    """The speed server driven by set_speed: start from parked, run at 5 m/s, slow, stop."""
    data: dict[str, Any] = {
        "name": "speed-replay", "vehicle": "escape-hybrid", "seed": 7, "duration_s": 16,
        "world": {"obstacles": [{"x_m": 80, "y_m": 2}]},
        "events": [
            {"at_s": 0.2, "set_speed": {"speed_mps": 5, "accel_mps2": 1.5, "gear": "drive",
                                        "state": "run"}},
            {"at_s": 11, "set_speed": {"speed_mps": 2, "accel_mps2": 1.0, "gear": "drive",
                                       "state": "run"}},
            {"at_s": 12.5, "drop": {"channel": "set_speed", "for_s": 0.5}},   # e-stop
            {"at_s": 14, "set_speed": {"speed_mps": 0, "accel_mps2": 2.0, "gear": "drive",
                                       "state": "idle"}},
        ],
    }
    data.update(overrides)
    return data


def record_run(scenario: Scenario | dict[str, Any], out_dir: Path) -> Path:
    """Run ``scenario`` and return its run.mcap.

    Uses ``run_scenario`` when it records run.mcap (sim.py wired); until then, the same loop
    with the recorder attached as sim.py will attach it.
    """
    if isinstance(scenario, dict):
        scenario = parse_scenario(scenario)
    run_scenario(scenario, out_dir, plot=False)
    path = out_dir / "run.mcap"
    if path.exists():
        return path
    nodes = build_nodes(scenario)
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    recorder = Recorder(None)
    bus.tap(recorder.observe)
    period_s = 0.01
    with McapRecorder(path, scenario=scenario, period_s=period_s) as mcap:
        bus.tap(mcap.observe)
        runtime = LockstepRuntime(mcap.wrap(nodes), bus, period_s)
        end_tick = round(scenario.spec.duration_s / period_s)
        while runtime.tick <= end_tick:
            faults.now_s = runtime.tick * period_s
            mcap.set_time(faults.now_s)
            now_s = runtime.step()
            recorder.tick(now_s)
    return path
