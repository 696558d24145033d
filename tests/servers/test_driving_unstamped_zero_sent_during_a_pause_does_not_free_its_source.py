"""An unstamped source's 0 sent during a pause is not proof that it knows the vehicle stopped
(issue 31; docs/driving-module.md, "Interruptions"). When an unstamped authorization freed its
source after that source's 0 arrived after the release, a source that sent 0 and then a positive
authorization during the pause, both delayed past the release by the advance channel, was freed
by its own stale 0 and the stale positive drove 18.6-29.7 m: nothing unstamped can show when it
was sent. Now only a stamped authorization issued after the release frees a source. Judged from
the plant's own x/y and the run's judge."""

from __future__ import annotations

import pytest

from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m
from tests.servers.test_driving_unstamped_authorization_across_a_release import UnstampedSource

RELEASE_S = 12.0
ZERO_SENT_S = 11.90     # the lidar's 0, during the pause
AUTH_SENT_S = 11.95     # then 40 m, during the pause too
STILL_M = 0.02          # travel allowed after the release with nothing sent after it


def paused(preset: str, delay_s: float, sends: list[tuple[float, float]]):
    """6 m/s map limit, the unstamped lidar authorizes 60 m at 1 s; a SafeStop pause from 5 s to
    ``RELEASE_S``; the lidar's ``sends``; the advance channel delays what is sent in
    [11.85, 12.0) s by ``delay_s``."""
    events = [{"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
              {"at_s": 5, "safestop": "pause"}, {"at_s": RELEASE_S, "safestop": "run"},
              {"at_s": 11.85, "delay": {"channel": "advance", "for_s": 0.15,
                                         "delay_s": delay_s}}]
    data = {"name": "driving-unstamped-zero-late", "vehicle": preset, "start": "ready",
            "seed": 1, "duration_s": 30.0, "events": events}
    scenario = parse_scenario(data)
    nodes = build_nodes(scenario)
    nodes.insert(1, UnstampedSource([(1.0, 60.0), *sends]))
    return run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)



@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("delay_s", [0.2, 0.5, 1.0])
def test_a_zero_and_an_authorization_sent_during_a_pause_and_delayed_never_drive(
        preset: str, delay_s: float) -> None:
    """Measured 2026-11-26 before the fix (this file's scenario): 0 at 11.90 s then 40 m at
    11.95 s, both delayed past the release at 12.0 s: `resumed` at 12.0 + delay_s + 0.0x s,
    then drove 29.65 / 27.88 / 24.92 m (escape-hybrid, delay 0.2 / 0.5 / 1.0 s) and 23.30 /
    21.50 / 18.58 m (ranger-6x6); the judge reports `unintended_motion` each time."""
    result = paused(preset, delay_s, [(ZERO_SENT_S, 0.0), (AUTH_SENT_S, 40.0)])
    assert travel_after_m(result, RELEASE_S) <= STILL_M
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("delay_s", [0.2, 1.0])
def test_a_zero_sent_long_before_the_release_frees_nothing(preset: str, delay_s: float) -> None:
    """Reference (holds): a 0 sent at 8 s (arrived during the pause) and 40 m at 11.95 s delayed
    past the release: held, 0.000 m on both presets."""
    result = paused(preset, delay_s, [(8.0, 0.0), (AUTH_SENT_S, 40.0)])
    assert travel_after_m(result, RELEASE_S) <= STILL_M
