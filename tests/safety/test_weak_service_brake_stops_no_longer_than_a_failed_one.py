"""A service brake that is weak (too strong to count as failed) must not stop the vehicle
further past its authorization than a weaker one that counts as failed: the failed brake gets
the parking brake, engine braking and a takeover request; a weak one gets none of them and
overruns more. Judged from ground truth (the simulated vehicle's own x)."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario

MOVE_M = 60.0
CRUISE_MPS = 8.0
FAILED_EFFECTIVENESS = (0.1, 0.15)
"""Brakes the stack counts as failed (1136: secondary braking, takeover) in these runs."""
MARGIN_M = 0.1


def run(preset: str, effectiveness: float) -> Any:
    data = {"name": "weak-brake", "vehicle": preset, "start": "ready", "duration_s": 40,
            "events": [
                {"at_s": 0.5, "move": {"distance_m": MOVE_M, "maxspeed_mps": CRUISE_MPS,
                                       "curvature_1pm": 0}},
                {"at_s": 5.0, "actuator": {"brake": {"effectiveness": effectiveness}}}]}
    return run_scenario(parse_scenario(data), None)


def overrun_m(result: Any) -> float:
    """Ground truth: how far past the MOVE's end the vehicle came to rest."""
    rows = result.trace
    assert abs(float(rows[-1]["speed_mps"])) < 0.01
    return float(rows[-1]["x_m"]) - MOVE_M


@pytest.mark.xfail(strict=True, reason="a weak brake (1134) gets no secondary braking: it "
                   "overruns further than a weaker brake counted as failed (1136)")
@pytest.mark.parametrize(("preset", "effectiveness"), [("escape-hybrid", 0.2),
                                                      ("escape-hybrid", 0.25),
                                                      ("ranger-6x6", 0.2)])
def test_a_weak_brake_overruns_no_further_than_a_failed_one(preset: str,
                                                             effectiveness: float) -> None:
    """Measured (2026-11-26, this file), metres past the 60 m MOVE at 8 m/s, brake weakened at
    5 s: Escape 0.1: 0.73, 0.15: 1.24 (both 1136, parking brake, L, takeover); 0.2: 4.92,
    0.25: 2.05 (1134 "envelope tightened" only: no parking brake, no takeover, engine in D).
    Ranger 0.1: 1.13, 0.15: 0.89 (1136); 0.2: 3.92 (1134 only, though 20 % of its 6.5 m/s^2
    is under the 1.47 m/s^2 a 15 % grade needs). Suspected cause: BRAKE_WEAK is not in
    ``safety.actuators.BRAKE_LOST``, and nothing adds the parking brake when the weakened
    brake cannot meet the stop already under way."""
    weak = overrun_m(run(preset, effectiveness))
    failed = max(overrun_m(run(preset, e)) for e in FAILED_EFFECTIVENESS)
    assert weak <= failed + MARGIN_M, (weak, failed)
