"""Availability of the interruption latch (issue 31): a pause of a vehicle that no source had
authorized yet ends like any other, and the first authorization issued after the release
drives. The module once marked the release only for sources latched when the vehicle came
back; with none, no release was ever marked, so the first authorization after it was held at 0
as one sent during the pause, and a source that authorizes once (a lidar) never moved the
vehicle.
Judged from the plant's own x/y."""

from __future__ import annotations

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m

SEND_S = 14.0      # 2 s after the release at 12 s


def paused_at_rest(preset: str, before_m: float | None):
    """At rest; ``before_m``: a lidar authorization at 1 s (driven before the pause), or none.
    A SafeStop pause from 5 s to 12 s; the lidar authorizes 10 m once, at 14 s."""
    events = [{"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
              {"at_s": 5, "safestop": "pause"}, {"at_s": 12, "safestop": "run"},
              {"at_s": SEND_S, "advance": {"source": "lidar", "distance_m": 10}}]
    if before_m is not None:
        events.append({"at_s": 1, "advance": {"source": "lidar", "distance_m": before_m}})
    data = {"name": "driving-pause-nothing-authorized", "vehicle": preset, "start": "ready",
            "seed": 1, "duration_s": 40.0, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)



@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("before_m", [
    5.0,    # reference: a source latched at the pause; its new authorization drives
    None,
], ids=["authorized-before", "nothing-authorized-before"])
def test_the_first_authorization_after_a_pause_at_rest_drives(preset: str,
                                                               before_m: float | None) -> None:
    """Measured 2026-11-26 (this file): with nothing authorized before the pause, the lidar's
    10 m sent 2 s after the release drove 0.000 m on both presets (a `rejected` notice "held at
    0" at 14.0 s, the latch never `resumed`); sent again at 16 s it drove 9.79 m, first motion
    at 27.0 s (escape-hybrid). With 5 m authorized (and driven) before the pause the same 10 m
    at 14 s drove 9.82 m (escape-hybrid) / 9.79 m (ranger-6x6)."""
    result = paused_at_rest(preset, before_m)
    moved_m = travel_after_m(result, SEND_S)
    assert 9.0 <= moved_m <= 10.0, moved_m      # stops before its end (margin), never past it
    assert result.summary["violations"] == []
    assert any(e["kind"] == "resumed" and e["source"] == "driving"
               for e in result.summary["events"])
