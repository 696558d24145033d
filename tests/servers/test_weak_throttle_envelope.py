"""A weak throttle's estimate feeds the move server's envelope (issue 31 item 6, seed 004).

The audit: "the throttle estimate is only reported". Now, as a weak brake caps the speed by
its stopping distance and slow steering by its turn-in, a throttle measured below
``degraded_throttle`` caps the speed at what it can still reach on the grade in the gear
engaged, with ``throttle_reserve_mps2`` in hand. Judged against the plant: driven at full
throttle with that weakness, the vehicle does reach the cap and has about the reserve left there.
"""

from __future__ import annotations

import math
import random

import pytest

from overdrive.messages import SpeedState
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.move import MoveServer
from overdrive.vehicle.plant import ActuatorFaults, Plant, World
from tests.conftest import PRESET_NAMES

DT_S = 0.01


def server_with_throttle(preset: str, effectiveness: float) -> MoveServer:
    params = PRESETS[preset]
    server = MoveServer(params)
    server.speed_state = SpeedState(speed_mps=0.0, accel_mps2=0.0, gear=params.drive_gear,
                                    state="run")
    for _ in range(2000):   # 20 s of samples at this ratio: both averages settle on it
        server.model.throttle.update(effectiveness, DT_S)
    return server


def plant_at_full_throttle(preset: str, effectiveness: float, grade_percent: float,
                           until_mps: float) -> tuple[float, float]:
    """(speed, acceleration) of the plant when it first reaches ``until_mps`` (or after 120 s)."""
    params = PRESETS[preset]
    plant = Plant(params, World(grade_segments=((0.0, grade_percent),)), random.Random(1),
                  engine_running=True, gear=params.drive_gear)
    plant.faults = ActuatorFaults(throttle_effectiveness=effectiveness)
    for _ in range(12000):
        plant.step(DT_S, 100.0, 0.0, 0.0, plant.gear, True)
        if plant.speed_mps >= until_mps:
            break
    return plant.speed_mps, plant.accel_mps2


@pytest.mark.parametrize("grade_percent", [0.0, 4.0, 8.0])
@pytest.mark.parametrize("effectiveness", [0.3, 0.5, 0.7])
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_weak_throttle_caps_the_speed_at_what_it_still_reaches(
        preset: str, effectiveness: float, grade_percent: float) -> None:
    server = server_with_throttle(preset, effectiveness)
    grade = math.atan(grade_percent / 100.0)
    maxspeed = 0.9 * PRESETS[preset].gear(PRESETS[preset].drive_gear).max_speed_mps
    reach = server._throttle_reach_mps(server.model.throttle.value, grade, maxspeed)
    cap, why = server._actuator_cap(maxspeed, 0.0, grade, 0.0)
    reserve = server.config.throttle_reserve_mps2
    if reach is None:   # cannot even start with the reserve: no cap, the hold's business
        _, accel = plant_at_full_throttle(preset, effectiveness, grade_percent, 0.5)
        assert accel < reserve + 0.02
        assert "throttle" in why
        return
    assert cap == pytest.approx(reach) and "throttle" in why
    v, accel = plant_at_full_throttle(preset, effectiveness, grade_percent, reach)
    assert v >= reach - 1e-9, "the vehicle reaches the cap"
    if reach < maxspeed:
        # at the cap the vehicle has the reserve left, no more (the cap is not too low)
        assert accel == pytest.approx(reserve, abs=0.03)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_healthy_throttle_caps_nothing(preset: str) -> None:
    server = server_with_throttle(preset, 1.0)
    cap, why = server._actuator_cap(20.0, 0.0, 0.0, 0.0)
    assert cap == math.inf and why == ""
