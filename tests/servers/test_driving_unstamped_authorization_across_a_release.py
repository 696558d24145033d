"""An authorization without a stamp (``issued_s`` None) sent before a pause ends and delivered
after it never drives (issue 31: each source is released only by its own authorization issued
after the vehicle came back). An unstamped one cannot show when it was sent: one sent 50 ms
before the release and delayed 0.2 s drove the vehicle on 29.8 m when the module took anything
arriving a full SPSS period after the release as new (and 29.65 m when a 0 arrived first, both
sent during the pause). Nothing unstamped frees a source: after the release only its stamped
authorization does (availability), and the source is told so (never a silent hold). Judged from
the plant's own x/y and the run's judge."""

from __future__ import annotations

import pytest

from overdrive.messages import AdvanceAuthorization, Topic
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m

RELEASE_S = 12.0
STILL_M = 0.02      # travel allowed after the release with no authorization sent after it


class UnstampedSource:
    """A source that sends unstamped authorizations at given times (the scenario player
    stamps every ``advance`` it plays, so this one stands beside it)."""

    name = "unstamped"
    period_s = 0.01
    subscriptions = ()

    def __init__(self, sends: list[tuple[float, float]]) -> None:
        self.sends = sorted(sends)   # (at_s, distance_m)

    def step(self, now_s: float, inbox):
        out = []
        while self.sends and self.sends[0][0] <= now_s + 1e-9:
            _, distance_m = self.sends.pop(0)
            out.append((Topic.ADVANCE, AdvanceAuthorization(source="lidar",
                                                            distance_m=distance_m)))
        return out


def paused(preset: str, sends: list[tuple[float, float]], delay_s: float | None,
           duration_s: float = 30.0, stamped: list[tuple[float, float]] = ()):
    """6 m/s, a SafeStop pause from 5 s to ``RELEASE_S``; the lidar's unstamped ``sends`` (and
    its ``stamped`` ones, played by the scenario); ``delay_s``: the advance channel delays what
    is sent in [11.9, 12.0) s by that much."""
    events = [{"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
              {"at_s": 5, "safestop": "pause"}, {"at_s": RELEASE_S, "safestop": "run"},
              *({"at_s": at_s, "advance": {"source": "lidar", "distance_m": d}}
                for at_s, d in stamped)]
    if delay_s is not None:
        events.append({"at_s": 11.9, "delay": {"channel": "advance", "for_s": 0.1,
                                                "delay_s": delay_s}})
    data = {"name": "driving-unstamped-release", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": duration_s, "events": events}
    scenario = parse_scenario(data)
    nodes = build_nodes(scenario)
    nodes.insert(1, UnstampedSource([(1.0, 60.0), *sends]))   # after the vehicle, like the player
    return run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)



@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("delay_s", [
    0.05, 0.15,     # delivered within the SPSS period of the release
    0.2, 0.5,       # delivered later: drove 21.5-30 m when anything that late counted as new
])
def test_an_unstamped_authorization_sent_before_the_release_never_drives(preset: str,
                                                                        delay_s: float) -> None:
    """Measured 2026-11-26 (this file) before the fix: 40 m sent unstamped at 11.95 s, delayed
    0.2 s, was taken at 12.15 s (`resumed`) and drove 29.8 m by 30 s on escape-hybrid (23.3 m on
    ranger-6x6); delayed 0.5 s, 28.0 m (21.5 m). Now held: 0 m."""
    result = paused(preset, [(11.95, 40.0)], delay_s)
    assert travel_after_m(result, RELEASE_S) <= STILL_M
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_after_the_release_only_a_stamped_authorization_frees_the_source(preset: str) -> None:
    """Availability: 0 then 10 m unstamped 2 s after the release are held (0 m); the same
    source's stamped 10 m at 16 s drives 9.79 m (both presets, through one runwait)."""
    held = paused(preset, [(14.0, 0.0), (14.05, 10.0)], None, duration_s=40.0)
    assert travel_after_m(held, 14.0) <= STILL_M
    freed = paused(preset, [(14.0, 0.0), (14.05, 10.0)], None, duration_s=40.0,
                   stamped=[(16.0, 10.0)])
    assert 9.0 <= travel_after_m(freed, 16.0) <= 10.0
    assert freed.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_unstamped_authorization_after_the_release_is_held_and_its_source_told(
        preset: str) -> None:
    """10 m sent unstamped 2 s after the release: held (0 m), and the source is told to stamp
    it (never a silent hold)."""
    result = paused(preset, [(14.0, 10.0)], None, duration_s=20.0)
    assert travel_after_m(result, 14.0) <= STILL_M
    held = [e for e in result.summary["events"] if e.get("kind") == "rejected"
            and "held at 0" in e.get("reason", "") and "stamped" in e.get("reason", "")]
    assert held, result.summary["events"]
