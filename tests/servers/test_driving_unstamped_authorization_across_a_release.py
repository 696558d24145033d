"""An authorization without a stamp (``issued_s`` None) sent before a pause ends and delivered
after it never drives (issue 31: each source is released only by its own authorization issued
after the vehicle came back). The module takes an unstamped one as issued after the release
when it arrives a full SPSS period (0.1 s) after it: one sent 50 ms before the release and
delayed 0.2 s on the way counts as new and drives the vehicle on. One sent after the release
still drives (availability). Judged from the plant's own x/y and the run's judge."""

from __future__ import annotations

import itertools
import math

import pytest

from overdrive.messages import AdvanceAuthorization, Topic
from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES

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
           duration_s: float = 30.0):
    """6 m/s, a SafeStop pause from 5 s to ``RELEASE_S``; the lidar's unstamped ``sends``;
    ``delay_s``: the advance channel delays what is sent in [11.9, 12.0) s by that much."""
    events = [{"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
              {"at_s": 5, "safestop": "pause"}, {"at_s": RELEASE_S, "safestop": "run"}]
    if delay_s is not None:
        events.append({"at_s": 11.9, "delay": {"channel": "advance", "for_s": 0.1,
                                                "delay_s": delay_s}})
    data = {"name": "driving-unstamped-release", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": duration_s, "events": events}
    scenario = parse_scenario(data)
    nodes = build_nodes(scenario)
    nodes.insert(1, UnstampedSource([(1.0, 60.0), *sends]))   # after the vehicle, like the player
    return run_scenario(scenario, None, plot=False, record_mcap=False, nodes=nodes)


def travel_after_m(result, t0_s: float) -> float:
    rows = [r for r in result.trace if float(r["t_s"]) >= t0_s]
    return sum(math.hypot(float(b["x_m"]) - float(a["x_m"]), float(b["y_m"]) - float(a["y_m"]))
               for a, b in itertools.pairwise(rows))


DELIVERED_LATE = pytest.mark.xfail(strict=True, reason=(
    "an unstamped authorization arriving 0.1 s after the release counts as issued after it: "
    "sent 50 ms before the release and delayed 0.2-0.5 s it drives 21.5-30 m (judge: "
    "unintended_motion)"))


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("delay_s", [
    0.05, 0.15,     # references: delivered within the SPSS period of the release, held
    pytest.param(0.2, marks=DELIVERED_LATE),
    pytest.param(0.5, marks=DELIVERED_LATE),
])
def test_an_unstamped_authorization_sent_before_the_release_never_drives(preset: str,
                                                                        delay_s: float) -> None:
    """Measured 2026-11-26 (this file): 40 m sent unstamped at 11.95 s, delayed 0.2 s, was
    taken at 12.15 s (`resumed`) and drove 29.8 m by 30 s on escape-hybrid (23.3 m on
    ranger-6x6), still at 6 m/s; delayed 0.5 s, 28.0 m (21.5 m). Delayed 0.05 s or 0.15 s it
    arrived before 12.1 s and was held: 0 m."""
    result = paused(preset, [(11.95, 40.0)], delay_s)
    assert travel_after_m(result, RELEASE_S) <= STILL_M
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_unstamped_authorization_sent_after_the_release_drives(preset: str) -> None:
    """Reference (availability): 10 m sent unstamped 2 s after the release drives 9.79 m
    (both presets; through two runwaits)."""
    result = paused(preset, [(14.0, 10.0)], None, duration_s=40.0)
    assert 9.0 <= travel_after_m(result, 14.0) <= 10.0
    assert result.summary["violations"] == []
