"""A biased accelerometer neither inflates nor collapses the friction estimate.

Item 6's estimator takes the grip from the IMU's specific force while ABS or traction control
acts (``dynamics.grip_estimate``): a constant accelerometer bias went straight into every sample
(``|f_x + bias|``), up during braking, down during a spin, and the plausibility checks (issue 30)
let a 3 m/s^2 bias through as trusted. Now the IMU's forward force is cross-checked with the
trusted speed's derivative (plus gravity along the pitch), both low-passed alike; a difference
averaging more than ``crosscheck_mps2`` over ``bias_s`` is taken out of every sample. Judged
against the world's friction (ground truth): after the ground drops to 0.25 and a STOP brings ABS
in, the estimate stays within half and one and a half times the true grip (a curve's cap, 0.675 x
the estimate, slides past 1.48 x the truth).

Measured before the fix (2026-11-26, seed 7, friction 0.8 -> 0.25 at 3 s during an 8 m/s MOVE, ``imu_accel``
bias from 2 s, STOP at 6 s, a MOVE of 15 m at 12 s, estimate at 30 s): healthy IMU 0.299
(escape-hybrid) / 0.321 (ranger-6x6); bias -3 m/s^2: 0.466 (1.86 x the grip) / 0.057 (0.23 x:
the second MOVE covered 12.2 m of its 15 m in 18 s, still moving at 0.96 m/s at 30 s).
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES

LOW = 0.25


def drop_run(preset: str, bias_mps2: float) -> Any:
    events: list[dict] = [{"at_s": 0.5, "move": {"distance_m": 300.0, "maxspeed_mps": 8.0}},
                          {"at_s": 3.0, "world": {"friction": LOW}},
                          {"at_s": 6.0, "stop": {}},
                          {"at_s": 12.0, "move": {"distance_m": 15.0, "maxspeed_mps": 8.0}}]
    if bias_mps2:
        events.append({"at_s": 2.0, "sensor_error": {"quantity": "imu_accel",
                                                     "bias": bias_mps2}})
    data = {"name": "imu-bias-grip", "vehicle": preset, "start": "ready", "duration_s": 30.0,
            "seed": 7, "world": {"friction": 0.8}, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def check_estimate_near_the_grip(result: Any) -> None:
    for node in ("driving", "move"):
        estimate = result.nodes[node].grip.estimate
        assert 0.5 * LOW <= estimate <= 1.5 * LOW, (node, estimate)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_healthy_imu_measures_the_drop(preset: str) -> None:
    result = drop_run(preset, 0.0)
    check_estimate_near_the_grip(result)
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_biased_imu_keeps_the_estimate_near_the_grip(preset: str) -> None:
    result = drop_run(preset, -3.0)
    assert result.summary["violations"] == []
    check_estimate_near_the_grip(result)
