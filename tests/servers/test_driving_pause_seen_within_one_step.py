"""A pause the driving module receives inside one step's inbox, followed in the same inbox by the
status of a vehicle back in drive-by-wire, still latches (issue 31, seed 000's pause). When the
module kept only the last ``VehicleStatus`` of a step and looked for the edge once per step, a
short pause read together with its end (a step that came 20-40 ms late, as a stalled or
descheduled process steps once with its queue) was never seen: the old authorization drove on.
Each status is now looked at on its own (``DrivingModule._interruption_edge``).
Judged from the plant's own x/y and the run's judge."""

from __future__ import annotations

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m

STILL_M = 0.02      # travel allowed once the vehicle has stopped, with no new authorization
SETTLED_S = 9.0     # 4 s after the pause: stopped from 6 m/s at any deceleration the stack uses


def paused_briefly(preset: str, pause_s: float, stall: tuple[float, float] | None):
    """Lidar 60 m at 6 m/s, a SafeStop pause at 5 s for ``pause_s``; ``stall``: the driving
    module not stepped from ``stall[0]`` for ``stall[1]`` s (one step with the queue after)."""
    events = [{"at_s": 1, "advance": {"source": "lidar", "distance_m": 60}},
              {"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
              {"at_s": 5.0, "safestop": "pause"}, {"at_s": 5.0 + pause_s, "safestop": "run"}]
    if stall is not None:
        events.append({"at_s": stall[0], "stall": {"node": "driving", "for_s": stall[1]}})
    data = {"name": "driving-pause-in-one-step", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": 20.0, "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)



@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("pause_s", "stall"), [
    (0.01, None),                                     # reference: every status in its own step
    (0.01, (4.99, 0.02)),                             # a 20 ms step ending on the pause
    (0.01, (4.99, 0.03)),                             # 10 ms pause, 30 ms step
    (0.02, (4.98, 0.05)),                             # 20 ms pause, 50 ms step
], ids=["10ms-own-steps", "10ms-late-step-ends-on-it", "10ms-in-a-30ms-step", "20ms-in-a-50ms-step"])
def test_a_pause_read_in_one_step_with_its_end_still_latches(preset: str, pause_s: float,
                                                           stall: tuple[float, float] | None
                                                           ) -> None:
    """Measured 2026-11-26 (tests/servers/test_driving_pause_seen_within_one_step.py): a 10 ms
    pause inside a 30 ms step drove 24.7 m after 9 s on escape-hybrid (25.2 m on ranger-6x6),
    the judge's unintended_motion 48.5 m (48.9 m) after the pause with at most 2.9 m (3.3 m)
    to stop, no `latched` notice; a 20 ms pause inside a 50 ms step the same (48.4 m, 48.8 m).
    The same pause stepped every 10 ms, or by a 20 ms step whose last status is the pause,
    latches and nothing moves after it."""
    result = paused_briefly(preset, pause_s, stall)
    assert travel_after_m(result, SETTLED_S) <= STILL_M
    assert result.summary["violations"] == []
    assert any(e["kind"] == "latched" and e["source"] == "driving"
               for e in result.summary["events"])
