"""The driving module alone (no move server) latches every interruption (issue 31, seed 000's
pause, override and e-stop; seed 004's "nothing moves until a new command"): a source's old
authorization, or one re-sent during the interruption, never drives the vehicle on after the
release; an authorization sent once the vehicle is back does. Judged from the plant's own x/y."""

from __future__ import annotations

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES, travel_after_m

INTERRUPTIONS = {
    "pause": ({"safestop": "pause"}, {"safestop": "run"}, "paused"),
    "override": ({"manual_override": True}, {"manual_override": False}, "paused"),
    "estop": ({"safestop": "stop"}, {"safestop": "run"}, "parked"),
    "door": ({"door": "open"}, {"door": "closed"}, "paused"),
}
ON_S, OFF_S = 5.0, 12.0
STILL_M = 0.02      # travel allowed after the release with no new authorization


def drive(preset: str, kind: str, extra: list[dict] = (), duration_s: float = 30.0):
    on, off, _ = INTERRUPTIONS[kind]
    data = {"name": "driving-interrupted", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": duration_s,
            "events": [{"at_s": 1, "advance": {"source": "lidar", "distance_m": 60}},
                       {"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
                       {"at_s": ON_S, **on}, {"at_s": OFF_S, **off}, *extra]}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)



def speed_states(result) -> list[str]:
    return [e["to"] for e in result.summary["events"] if e["kind"] == "speed_state"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", sorted(INTERRUPTIONS))
def test_after_an_interruption_the_old_authorization_never_drives_on(preset: str,
                                                                    kind: str) -> None:
    result = drive(preset, kind)
    assert travel_after_m(result, OFF_S) <= STILL_M
    assert result.summary["violations"] == []
    assert speed_states(result)[-1] == INTERRUPTIONS[kind][2]
    interrupted = [e for e in result.summary["events"]
                   if e["kind"] == "latched" and e["source"] == "driving"]
    assert len(interrupted) == 1 and interrupted[0]["t_s"] == pytest.approx(ON_S, abs=0.05)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", ["pause", "estop"])
def test_an_authorization_resent_during_the_interruption_is_held(preset: str, kind: str) -> None:
    result = drive(preset, kind, [{"at_s": 8.0, "advance": {"source": "lidar", "distance_m": 40}}])
    assert travel_after_m(result, OFF_S) <= STILL_M
    held = [e for e in result.summary["events"]
            if e["kind"] == "rejected" and "held at 0" in e.get("reason", "")]
    assert held and held[0]["t_s"] == pytest.approx(8.0, abs=0.05)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", ["pause", "override", "estop"])
def test_an_authorization_after_the_release_drives_it(preset: str, kind: str) -> None:
    result = drive(preset, kind, [{"at_s": 14.0, "advance": {"source": "lidar", "distance_m": 10}}],
                   duration_s=40.0)
    moved_m = travel_after_m(result, 14.0)
    assert 9.0 <= moved_m <= 10.0, moved_m      # stops before its end (margin), never past it
    assert result.summary["violations"] == []
    assert any(e["kind"] == "resumed" for e in result.summary["events"])
    assert abs(float(result.trace[-1]["speed_mps"])) < 0.05


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_speed_server_emergency_stop_latches_until_a_new_authorization(preset: str) -> None:
    """The SPSS stream dropped 0.5 s at cruise: the speed server's watchdog e-stop (an unasked
    stop); the old authorization never drives on, a new one does."""
    data = {"name": "driving-watchdog", "vehicle": preset, "start": "ready", "seed": 1,
            "duration_s": 40,
            "events": [{"at_s": 1, "advance": {"source": "lidar", "distance_m": 60}},
                       {"at_s": 1, "max_speed": {"source": "map", "speed_mps": 6}},
                       {"at_s": 6, "drop": {"channel": "set_speed", "for_s": 0.5}},
                       {"at_s": 20, "advance": {"source": "lidar", "distance_m": 10}}]}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)
    assert travel_after_m(result, 10.0) - travel_after_m(result, 20.0) <= STILL_M
    assert 9.0 <= travel_after_m(result, 20.0) <= 10.0
    assert any(e["kind"] == "latched" and e["source"] == "driving"
               and e["code"].startswith("speed_stop") for e in result.summary["events"])


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_authorization_sent_before_the_release_and_delivered_after_it_is_held(
        preset: str) -> None:
    """Sent at 11.8 s, 0.2 s before the release, delayed 0.4 s on the way: it arrived after
    the release and drove 29.8 m (judge: unintended_motion). Only one issued after it counts."""
    result = drive(preset, "pause", [
        {"at_s": 11.7, "delay": {"channel": "advance", "for_s": 0.2, "delay_s": 0.4}},
        {"at_s": 11.8, "advance": {"source": "lidar", "distance_m": 40}}])
    assert travel_after_m(result, OFF_S) <= STILL_M
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_each_source_is_released_only_by_its_own_authorization_after_the_release(
        preset: str) -> None:
    """Two sources authorized before the pause; after it only the map sends anew: the lidar's
    old 60 m stays held at 0 (the most restrictive applies), so nothing moves; once the lidar
    sends 8 m too, the vehicle drives the shorter of the two."""
    result = drive(preset, "pause", [
        {"at_s": 1, "advance": {"source": "map", "distance_m": 80}},
        {"at_s": 14.0, "advance": {"source": "map", "distance_m": 30}},
        {"at_s": 20.0, "advance": {"source": "lidar", "distance_m": 8}}], duration_s=40.0)
    assert travel_after_m(result, OFF_S) - travel_after_m(result, 20.0) <= STILL_M
    assert 7.0 <= travel_after_m(result, 20.0) <= 8.0
