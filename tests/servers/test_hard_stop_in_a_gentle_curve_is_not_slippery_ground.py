"""A hard stop with the wheels barely turned is still braking at the limit, not slippery ground.

Issue 31's acceptance: "A hard stop on dry road: no gear change, no runwait afterwards." On a
curve of radius 200 m (curvature 0.005 1/m: 0.04 g sideways at 8.9 m/s) the vehicle reports its
traction control together with the ABS on every sample of the stop (the plant counts a saturated
ellipse in a curve as a slide). That was taken as slippery ground: idle, a shift to the low gear,
a runwait. Now traction control while the ABS acts and the brake outweighs the throttle
(``messages.braking_at_limit``) is braking at the limit: no low gear, no sticky reduction, no
"slipping" hint; the slide checks still see it.

Measured before the fix (2026-11-26, seed 5, STOP at 8 s from a 10 m/s MOVE, next MOVE at
14 s): escape-hybrid on 0.8, curvature 0.005 / 0.02 / 0.04: ABS and traction control on 99 / 101 / 105 samples, gears
drive -> low, states idle, shifting, runwait, first motion 1.74 s after the next MOVE (0.49 s
straight); ranger-6x6 on 0.6, curvature 0.005 / 0.02: 120 / 126 samples, high -> low6wd, first
motion 2.89 s after. Straight (curvature 0) the same stops pass (reference).
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from tests.conftest import PRESET_NAMES
from tests.servers.test_abs_is_not_slippery_ground import Tap

# frictions at which the preset's full brake from ~9 m/s brings the ABS in (dry / wet road)
ABS_FRICTION = {"escape-hybrid": 0.8, "ranger-6x6": 0.6}
STOP_AT_S = 8.0
NEXT_MOVE_AT_S = 14.0


def curve_stop(preset: str, curvature_1pm: float) -> tuple[Any, Tap]:
    tap = Tap()
    data = {"name": "curve-stop", "vehicle": preset, "start": "ready", "seed": 5,
            "duration_s": NEXT_MOVE_AT_S + 4.0, "world": {"friction": ABS_FRICTION[preset]},
            "events": [{"at_s": 0.5, "move": {"distance_m": 300.0, "maxspeed_mps": 10.0,
                                              "curvature_1pm": curvature_1pm}},
                       {"at_s": STOP_AT_S, "stop": {}},
                       {"at_s": NEXT_MOVE_AT_S, "move": {"distance_m": 20.0,
                                                         "maxspeed_mps": 5.0}}]}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False,
                          observers=[tap])
    return result, tap


def check_no_slippery_ground(preset: str, curvature_1pm: float) -> None:
    params = PRESETS[preset]
    result, tap = curve_stop(preset, curvature_1pm)
    assert any(s.abs_active for t, s in tap.status if t >= STOP_AT_S), "the stop brought ABS in"
    after = [s for t, s in tap.speed if t >= STOP_AT_S]
    assert {s.gear for t, s in tap.status if t >= STOP_AT_S} == {params.drive_gear}, curvature_1pm
    assert not {s.state for s in after} & {"shifting", "runwait", "idle"}, curvature_1pm
    moving = [t for t, s in tap.speed if t >= NEXT_MOVE_AT_S and s.speed_mps > 0.5]
    assert moving and min(moving) - NEXT_MOVE_AT_S < 1.5
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_straight_hard_stop_changes_no_gear(preset: str) -> None:
    check_no_slippery_ground(preset, 0.0)


@pytest.mark.parametrize("curvature_1pm", [0.005, 0.02])
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_hard_stop_in_a_gentle_curve_changes_no_gear(preset: str, curvature_1pm: float) -> None:
    check_no_slippery_ground(preset, curvature_1pm)
