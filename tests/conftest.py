"""Shared fixtures: vehicle presets for parametrised base cases, scenario builders."""

from __future__ import annotations

import copy
import itertools
import math
from typing import Any

import pytest

from overdrive.scenario.vehicles import PRESETS

PRESET_NAMES = tuple(PRESETS)


def reachable_mps(preset: str, wanted_mps: float) -> float:
    """``wanted_mps``, or the highest speed ``preset``'s drive gear is asked for (0.9 of its
    top: above, the move server refuses the MOVE as infeasible and the run tests nothing)."""
    params = PRESETS[preset]
    return min(wanted_mps, 0.9 * params.gear(params.drive_gear).max_speed_mps)


@pytest.fixture(params=PRESET_NAMES)
def preset(request: pytest.FixtureRequest):
    return PRESETS[request.param]


def scenario_dict(**overrides: Any) -> dict[str, Any]:
    """A minimal valid open-loop scenario, with top-level keys replaced by ``overrides``."""
    base: dict[str, Any] = {
        "name": "t",
        "vehicle": "escape-hybrid",
        "duration_s": 5,
        "events": [{"at_s": 0.5, "engine": "on"}],
    }
    data = copy.deepcopy(base)
    data.update(overrides)
    return data


VARIANTS_MARKER = "variants"
"""Whole-run variant sweeps (grades x speeds x fault times x presets, ~450 s of CPU) carry this
marker (``pytestmark = pytest.mark.variants`` in their module); pyproject.toml registers it."""
VARIANT_STRIDE = 4
"""`make test` (CI: 10 minutes on 2 cores) runs every ``VARIANT_STRIDE``-th parametrised case of
each test marked ``variants``, rotated by the test's name so every position is covered across
tests; `make test-variants` (``OVERDRIVE_ALL_VARIANTS=1``) runs them all."""


EDGE_MARKER = "variant_edge"
"""On a case of a ``variants`` test (``pytest.param(..., marks=pytest.mark.variant_edge)``): a case
at a limit or an edge of the sweep (its smallest and largest value, either side of a threshold,
a value a defect was found at), run by `make test` too, outside the one-in-four stride."""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    import os
    import zlib

    _mark_lexus_residuals(items)
    if os.environ.get("OVERDRIVE_ALL_VARIANTS") == "1":
        return
    seen: dict[tuple[str, str], int] = {}
    keep, drop = [], []
    for item in items:
        name = getattr(item, "originalname", item.name)
        if item.get_closest_marker(VARIANTS_MARKER) is None or not hasattr(item, "callspec"):
            keep.append(item)
            continue
        if item.get_closest_marker(EDGE_MARKER) is not None:
            keep.append(item)
            continue
        key = (str(item.path), name)
        index = seen[key] = seen.get(key, -1) + 1
        offset = zlib.crc32(name.encode()) % VARIANT_STRIDE
        (keep if index % VARIANT_STRIDE == offset else drop).append(item)
    if drop:
        config.hook.pytest_deselected(items=drop)
        items[:] = keep


def travel_after_m(result, t0_s: float) -> float:
    """Path length the plant drove from ``t0_s`` on (ground truth: the trace's x/y)."""
    rows = [r for r in result.trace if float(r["t_s"]) >= t0_s]
    return sum(math.hypot(float(b["x_m"]) - float(a["x_m"]), float(b["y_m"]) - float(a["y_m"]))
               for a, b in itertools.pairwise(rows))


# --------------------------------------------------------------------------- the PACMod preset
# lexus-rx450h (issue 32's PACMod default, a vehicle file since 2026-11-26) joined every test
# parametrised over PRESETS. These cases failed on it when it was added (`pytest -k lexus` over
# the preset-parametrised files, 2026-11-26); each is a strict xfail (it fails the suite once it
# passes, so the entry must go) until the stack is calibrated on this vehicle.
_LEXUS_DATA = "lexus-rx450h: the test's per-preset data has no entry for this vehicle yet"
_LEXUS_PARK = ("lexus-rx450h: no parking brake by wire (the RX's EPB is not on the PACMod's user "
               "CAN); the test assumes one")
_LEXUS_STACK = "lexus-rx450h: the stack is not yet validated on this vehicle (docs/safety-case.md H85)"
DATA, PARK, STACK = _LEXUS_DATA, _LEXUS_PARK, _LEXUS_STACK
EVERY_LEXUS_CASE = "[*lexus-rx450h*]"
LEXUS_NOT_YET_VALIDATED: dict[str, str] = {
    "tests/safety/test_faults_actuators.py::test_stuck_steering_stops_inside_the_ellipse[*lexus-rx450h*]": DATA,
    "tests/servers/test_abs_is_not_slippery_ground.py::test_a_hard_stop_with_abs_changes_no_gear_and_waits_for_nothing[*lexus-rx450h*]": DATA,
    "tests/servers/test_gear_hints.py::test_an_upshift_stops_the_move_only_when_the_rest_is_long_enough[*lexus-rx450h*]": DATA,
    "tests/servers/test_gear_hints.py::test_an_upshift_stops_the_move_only_while_the_goal_is_near_the_speed[*lexus-rx450h*]": DATA,
    "tests/servers/test_hard_stop_in_a_gentle_curve_is_not_slippery_ground.py::test_a_hard_stop_in_a_gentle_curve_changes_no_gear[*lexus-rx450h*]": DATA,
    "tests/servers/test_hard_stop_in_a_gentle_curve_is_not_slippery_ground.py::test_a_straight_hard_stop_changes_no_gear[*lexus-rx450h*]": DATA,
    "tests/safety/test_secondary_braking.py::test_a_stack_that_leaves_the_parking_brake_off_is_judged_avoidable[*lexus-rx450h*]": PARK,
    "tests/safety/test_secondary_braking.py::test_each_means_left_out_lengthens_the_stop[*lexus-rx450h*]": PARK,
    "tests/safety/test_estop_engine_cut_as_configured.py::test_a_throttle_that_does_not_close_has_the_engine_cut_while_moving[False-lexus-rx450h]": STACK,
    "tests/safety/test_faults_noise.py::test_noisy_gps_at_standstill_does_not_cut_the_engine_of_a_healthy_vehicle[lexus-rx450h]": STACK,
    "tests/safety/test_faults_rollback.py::test_a_healthy_hill_start_completes_without_a_fault[ready-lexus-rx450h-30-reverse]": STACK,
    "tests/safety/test_faults_sense.py::test_healthy_vehicle_raises_no_plausibility_fault[gps-noise-lexus-rx450h]": STACK,
    "tests/safety/test_grip_lost_in_curve.py::test_a_drop_the_curve_cannot_hold_is_always_caught[lexus-rx450h--0.05-0.8-0.25-0.7]": STACK,
    "tests/safety/test_unasked_stops.py::test_a_stalled_driving_module_resumes_without_a_steering_jump[0.5-lexus-rx450h]": STACK,
    "tests/servers/test_speed_hints.py::test_upshift_at_the_low_gears_top_not_on_the_way_there[lexus-rx450h]": STACK,
    "tests/servers/test_weak_throttle_envelope.py::test_a_weak_throttle_caps_the_speed_at_what_it_still_reaches[lexus-rx450h-0.3-8.0]": STACK,
}
"""Test ids (as pytest names them, or ``TEST[*lexus-rx450h*]``: every Lexus case of the test)
-> why they are expected to fail on the PACMod preset. The exact ids are the cases `make test`
runs; `make test-variants` may find more of the same tests failing on it."""


def _mark_lexus_residuals(items: list[pytest.Item]) -> None:
    for item in items:
        if "lexus-rx450h" not in item.nodeid:
            continue
        test = item.nodeid.split("[", 1)[0]
        reason = LEXUS_NOT_YET_VALIDATED.get(item.nodeid,
                                             LEXUS_NOT_YET_VALIDATED.get(f"{test}{EVERY_LEXUS_CASE}"))
        if reason is not None:
            item.add_marker(pytest.mark.xfail(strict=True, reason=reason))
