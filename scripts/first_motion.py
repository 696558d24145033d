"""First motion after the first MOVE from ``parked`` and out of a pause, both presets (the
figures of docs/speed-server.md, "Runwaits"): ``.venv/bin/python scripts/first_motion.py``."""

from __future__ import annotations

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS

MOVING_MPS = 0.05
MOVE = {"move": {"distance_m": 10.0, "maxspeed_mps": 3.0, "curvature_1pm": 0.0}}


def first_motion_s(preset: str, start: str, events: list[dict], after_s: float) -> float:
    data = {"name": "first-motion", "vehicle": preset, "start": start, "seed": 1,
            "duration_s": after_s + 16.0, "events": events}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)
    return next(float(r["t_s"]) for r in result.trace
                if float(r["t_s"]) > after_s and abs(float(r["speed_mps"])) > MOVING_MPS) - after_s


def main() -> None:
    for preset in PRESETS:
        parked = first_motion_s(preset, "parked", [{"at_s": 1.0, **MOVE}], 1.0)
        paused = first_motion_s(preset, "ready", [
            {"at_s": 0.5, **MOVE}, {"at_s": 9.0, "safestop": "pause"},
            {"at_s": 10.0, "safestop": "run"}, {"at_s": 11.0, **MOVE}], 11.0)
        print(f"{preset}: from parked {parked:.2f} s, out of a pause {paused:.2f} s "
              f"after the MOVE")


if __name__ == "__main__":
    main()
