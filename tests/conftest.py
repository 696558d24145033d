"""Shared fixtures: vehicle presets for parametrised base cases, scenario builders."""

from __future__ import annotations

import copy
from typing import Any

import pytest

from overdrive.vehicle.presets import PRESETS

PRESET_NAMES = tuple(PRESETS)


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
