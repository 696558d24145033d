"""Shared fixtures: vehicle presets for parametrised base cases, scenario builders."""

from __future__ import annotations

import copy
import itertools
import math
from typing import Any

import pytest
from hypothesis import settings

from overdrive.scenario.vehicles import PRESETS

settings.register_profile("overdrive", deadline=None)
settings.load_profile("overdrive")
"""No per-example deadline: on a busy 2-core CI machine one example can take over hypothesis's
default 200 ms and fail a property that holds (speed targets live in bench/, never in tests).
A test that sets its own ``deadline`` keeps it."""

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
