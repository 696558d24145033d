"""Plant steps per second, and the whole ``overdrive sim`` real-time factor on the demo.

Run: ``.venv/bin/python bench/bench_plant.py``. Target (issue 2): plant alone >= 100,000 steps/s.
"""

from __future__ import annotations

import random
import statistics
import tempfile
import time
from pathlib import Path

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import load_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.plant import Plant, World

ROOT = Path(__file__).resolve().parent.parent


def plant_steps_per_s(preset: str, steps: int = 200_000) -> float:
    params = PRESETS[preset]
    plant = Plant(params, World(obstacles=((500.0, 0.0),)), random.Random(1), engine_running=True,
                  gear=params.drive_gear)
    step = plant.step
    gear = params.drive_gear
    start = time.perf_counter()
    for i in range(steps):
        step(0.01, 30.0 if i % 2000 < 1000 else 0.0, 0.0 if i % 2000 < 1000 else 20.0, 5.0, gear, True)
    return steps / (time.perf_counter() - start)


def sim_real_time_factor(scenario: Path, repeats: int = 3) -> float:
    loaded = load_scenario(scenario)
    factors = []
    for _ in range(repeats):
        with tempfile.TemporaryDirectory() as tmp:
            result = run_scenario(loaded, tmp, keep_trace=False, plot=False)
        factors.append(result.summary["sim_time_s"] / result.summary["wall_time_s"])
    return statistics.median(factors)


def main() -> dict[str, float]:
    results: dict[str, float] = {}
    for preset in PRESETS:
        results[f"plant_steps_per_s[{preset}]"] = plant_steps_per_s(preset)
    results["sim_real_time_factor[demo]"] = sim_real_time_factor(ROOT / "scenarios" / "demo.yaml")
    for key, value in results.items():
        print(f"{key:40s} {value:14,.0f}")
    return results


if __name__ == "__main__":
    main()
