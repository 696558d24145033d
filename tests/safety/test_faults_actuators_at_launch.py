"""Whole runs: an actuator already weak or sticking when the MOVE starts stays inside the
authorization: brakes at 20-30 % from the start (on the flat, and downhill), a throttle sticking
at launch downhill.

Judged only by the independent judge (``summary["violations"]``) and by ground truth (the
trace's x/y and speed), never by the stack's view of itself. A known defect is a strict xfail
naming what happens, with figures.
"""

from __future__ import annotations

import pytest

from tests.conftest import PRESET_NAMES
from tests.safety.fault_runs import (
    actuator,
    estops,
    final_x_m,
    move,
    run,
)


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_weak_brake_on_a_downhill_stays_inside_the_authorization(preset: str) -> None:
    result = run(preset, duration_s=14.0, world={"grade_percent": -10}, events=[
        actuator(0.2, brake={"effectiveness": 0.3}), move(0.5, 40, 8)])
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_brakes_at_20_percent_from_the_start_as_shipped_stay_inside_a_40_m_move(preset: str) -> None:
    result = run(preset, duration_s=14.0, events=[
        actuator(0.2, brake={"effectiveness": 0.2}), move(0.5, 40, 8)])
    assert result.summary["violations"] == []


@pytest.mark.parametrize("at_s", [0.55, 0.9])
def test_throttle_stuck_at_launch_downhill_barely_moves(at_s: float) -> None:
    result = run("escape-hybrid", duration_s=6.0, world={"grade_percent": -15}, events=[
        move(0.5, 15, 3), actuator(at_s, throttle={"stuck": True})])
    assert result.summary["violations"] == []
    assert estops(result)
    assert final_x_m(result) < 1.0   # the stuck check needs 0.3 s (three status periods at most)
