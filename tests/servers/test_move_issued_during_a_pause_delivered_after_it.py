"""With the move server as the driving module's client, a MOVE the planner issued during a pause
and that reaches the move server after the release never drives (issue 31; docs/move-server.md,
"Interruptions are latched": "the next MOVE/REVERSE (a new id, issued after the interruption
ended) starts again"). The move server answers one that arrives during the pause `not_ready`;
one delayed past the release was taken as new (39.8 m driven) and its own authorization,
stamped on arrival, freed the driving module's latch. Now one issued before the vehicle came
back is answered `not_ready` too (``MoveServer._issued_before_back``). Judged from the plant's own x/y."""

from __future__ import annotations

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m

RELEASE_S = 12.0
SENT_S = 11.9       # 0.1 s before the release, issued_s 11.9 on the planner's clock
STILL_M = 0.02      # travel allowed after the release with no command issued after it


def paused_with_a_late_move(preset: str, delay_s: float | None, sends: tuple = ()):
    """MOVE 80 m at 6 m/s from 1 s, a SafeStop pause from 5 s to ``RELEASE_S``; a MOVE of 40 m
    sent at ``SENT_S``, its channel delaying it ``delay_s``; further MOVEs ``sends``."""
    events = [{"at_s": 1, "move": {"distance_m": 80, "maxspeed_mps": 6, "curvature_1pm": 0}},
              {"at_s": 5, "safestop": "pause"}, {"at_s": RELEASE_S, "safestop": "run"},
              *({"at_s": at_s, "move": {"distance_m": d, "maxspeed_mps": 6, "curvature_1pm": 0}}
                for at_s, d in sends)]
    if delay_s is not None:
        events += [{"at_s": 11.8, "delay": {"channel": "move", "for_s": 0.2, "delay_s": delay_s}},
                   {"at_s": SENT_S, "move": {"distance_m": 40, "maxspeed_mps": 6,
                                             "curvature_1pm": 0}}]
    data = {"name": "move-late-after-pause", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": 40.0, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)



@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("delay_s", [
    0.1,            # reference: arrives at the release, answered not_ready, nothing moves
    0.3,
    0.6,
])
def test_a_move_issued_during_a_pause_never_drives_after_the_release(preset: str,
                                                                     delay_s: float) -> None:
    """Measured 2026-11-26 (this file): the MOVE sent at 11.9 s, delayed 0.3 s, was accepted at
    12.2 s (driving `resumed`) and drove 39.79 m (escape-hybrid) / 39.82 m (ranger-6x6);
    delayed 0.6 s, 39.79 m / 39.81 m; no violation reported. Delayed 0.1 s it was refused
    `not_ready` at 12.0 s and nothing moved."""
    result = paused_with_a_late_move(preset, delay_s)
    assert travel_after_m(result, RELEASE_S) <= STILL_M


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_move_issued_after_the_release_drives(preset: str) -> None:
    """Reference (availability): a MOVE of 10 m issued 2 s after the release drives it."""
    result = paused_with_a_late_move(preset, None, ((14.0, 10.0),))
    assert 9.0 <= travel_after_m(result, 14.0) <= 10.0
    assert result.summary["violations"] == []
