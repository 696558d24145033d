"""A JAUS link cut one way only (lock-step, ``interface: jaus``, real UDP on loopback): the
stack's commands lost while the XGV's reports still arrive (``to_vehicle``), or the reverse
(``from_vehicle``). Found: in motion profile a cut towards the XGV let its motion lapse, the
vehicle stopped by itself, and when the link came back the old MOVE drove on with no event
(a 4.3 s cut: at rest at 33.9 m, then on to 59.8 m; 1-3.9 s: slowed to 0.2 m/s, then on).

Judged from ground truth (the trace of a lock-step jaus run is the simulated XGV's own state):
no overrun, no speed above the MOVE's limit, and once the vehicle came to rest after the cut
began nothing moves again (no new command is sent); a stop short of the end is never silent.
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.jaus import ReportVehicleMode
from overdrive.scenario.schema import ScenarioError, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv_client import (
    FOLLOW_FALL_MPS,
    FOLLOW_MARGIN_MPS,
    FOLLOW_REST_REPORTS,
    FollowCheck,
    XgvClient,
    XgvClientConfig,
)
from tests.xgv.test_xgv_link_loss import LIMIT_MPS, MOVE_M, SPEED_TOLERANCE_MPS, codes, run, truth

CUT_AT_S = 5.5                                  # at cruise, 7.7 m/s
CUTS_S = (0.1, 0.3, 0.5, 0.8, 1.0, 1.5, 2.0, 3.0, 4.3, 4.5)
AT_REST_MPS = 0.01
MOVED_AFTER_REST_M = 0.05


def cut(for_s: float, direction: str) -> dict[str, Any]:
    return {"at_s": CUT_AT_S, "drop": {"channel": "jaus", "for_s": for_s,
                                       "direction": direction}}


def assert_judged_safe(trace: list[dict[str, Any]], summary: dict[str, Any]) -> None:
    t, x, v = truth(trace)
    assert max(x) <= MOVE_M, max(x)
    assert max(v) <= LIMIT_MPS + SPEED_TOLERANCE_MPS, max(v)
    rest = next((i for i, ti in enumerate(t) if ti > CUT_AT_S and v[i] < AT_REST_MPS), None)
    if rest is not None:   # at rest after the cut began: nothing moves again (no new command)
        assert max(x[rest:]) - x[rest] < MOVED_AFTER_REST_M, (t[rest], x[rest], max(x[rest:]))
    if x[-1] < MOVE_M - 0.5:   # stopped short: never silently
        assert summary["violations"] and codes(summary, "interrupted")


EDGE_CUTS_S = (0.1, 0.3, 0.5, 4.3, 4.5)
"""Cuts `make test` always runs: the shortest and the longest, either side of the XGV's 0.4 s
motion / 0.5 s effort hold, and the 4.3 s cut the defect was found at; the ones between are
neighbouring values of the same sweep (one in four, tests/conftest.py)."""


@pytest.mark.variants
@pytest.mark.parametrize("for_s", [
    pytest.param(for_s, marks=pytest.mark.variant_edge) if for_s in EDGE_CUTS_S else for_s
    for for_s in CUTS_S])
@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
@pytest.mark.parametrize("direction", ["to_vehicle", "from_vehicle"])
def test_a_link_cut_one_way_never_overruns_speeds_or_drives_on_after_a_stop(
        control: str, direction: str, for_s: float) -> None:
    result, _, trace = run([cut(for_s, direction)], control=control)
    assert_judged_safe(trace, result.summary)


def test_a_long_cut_towards_the_xgv_in_motion_profile_stops_latched_and_faulted() -> None:
    """The reviewer's case: 4.3 s at 5.5 s. The XGV's motion lapses; the client sees it slow
    against its command, latches the vehicle's command timeout (fault 1012, the MOVE
    interrupted) and the run fails on the link fault; control lost later changes nothing."""
    result, _, trace = run([cut(4.3, "to_vehicle")], control="motion-profile")
    summary = result.summary
    assert "xgv_not_following" in codes(summary, "fault")
    assert codes(summary, "interrupted") == ["command_timeout"]
    assert any(m.startswith("link fault xgv_not_following") for m in summary["violations"])
    _, x, _ = truth(trace)
    assert x[-1] < MOVE_M - 20.0
    assert_judged_safe(trace, summary)


def test_in_wrench_mode_the_xgvs_own_timeout_pause_is_an_unasked_stop() -> None:
    result, _, trace = run([cut(1.0, "to_vehicle")], control="wrench")
    summary = result.summary
    assert "xgv_error_pause" in codes(summary, "fault")
    assert "1012" in codes(summary, "fault")
    assert any(m.startswith("link fault xgv_error_pause") for m in summary["violations"])
    assert_judged_safe(trace, summary)


def test_a_short_cut_towards_the_xgv_passes_without_a_stop() -> None:
    """Under the XGV's 0.4 s motion / 0.5 s effort hold the commands simply resume."""
    for control in ("wrench", "motion-profile"):
        result, _, trace = run([cut(0.3, "to_vehicle")], control=control)
        assert codes(result.summary, "fault") == [] and result.summary["violations"] == []
        assert truth(trace)[1][-1] > MOVE_M - 0.5


# ----------------------------------------------------------------------------- pieces

def test_following_the_command_never_trips_and_a_lapse_does() -> None:
    check = FollowCheck()
    for v in [0.0, 1.0, 3.0, 6.0, 7.8, 7.9, 8.0, 7.9]:        # accelerating, cruising
        assert check.check(8.0, v) is None
    for v in [8.0, 6.0, 4.0, 2.0, 0.0]:                       # asked to slow: it slows
        assert check.check(0.0 if v == 0.0 else 1.0, v) is None
    check.reset()
    falling = [7.9 - 0.025 * i for i in range(80)]            # 2.5 m/s^2 at 100 Hz
    tripped = next(i for i, v in enumerate(falling) if check.check(8.0, v) is not None)
    assert 7.9 - falling[tripped] > FOLLOW_FALL_MPS
    assert 7.9 - falling[tripped] < FOLLOW_FALL_MPS + FOLLOW_MARGIN_MPS + 0.05


def test_a_slow_vehicle_that_comes_to_rest_against_its_command_trips() -> None:
    check = FollowCheck()
    assert [check.check(3.0, v) for v in (0.0, 0.2, 0.4, 0.3, 0.1)] == [None] * 5
    assert check.check(3.0, 0.0) is not None
    reverse = FollowCheck()
    assert reverse.check(-3.0, -0.4) is None
    assert reverse.check(-3.0, 0.0) is not None


def test_without_control_the_xgv_profile_reports_a_software_pause() -> None:
    client = XgvClient(PRESETS["escape-hybrid"])
    client.mode = ReportVehicleMode(control_mode=2, ready_mode=2, safety_mode=1)
    client.control = True
    assert client.vehicle_status(0.0).safety_mode == "drive-by-wire"
    client.control = False
    status = client.vehicle_status(0.0)
    assert status.safety_mode == "software-pause" and not status.computer_speed


@pytest.mark.parametrize(("body", "field"), [
    ({"channel": "gps", "for_s": 1, "direction": "to_vehicle"}, "direction"),
    ({"channel": "jaus", "for_s": 1, "direction": "sideways"}, "direction"),
])
def test_a_direction_is_only_for_channel_jaus_and_one_of_its_names(body: dict[str, Any],
                                                                   field: str) -> None:
    with pytest.raises(ScenarioError, match=field):
        parse_scenario({"name": "x", "interface": "jaus", "duration_s": 5,
                        "events": [{"at_s": 1, "drop": body}]}, "t")


def test_a_one_way_fault_acts_on_that_direction_only() -> None:
    from overdrive.runtime.xgv_link import JausFault, LoopbackLink
    link = LoopbackLink("memory", [JausFault("drop", 0.0, 1.0, direction="to_vehicle")])
    link.send("client", b"to the xgv", 0.5)
    link.send("xgv", b"to the client", 0.5)
    assert link.receive("xgv", 0.5) == []
    assert [d for d, _ in link.receive("client", 0.5)] == [b"to the client"]
    back = LoopbackLink("memory", [JausFault("drop", 0.0, 1.0, direction="from_vehicle")])
    back.send("client", b"to the xgv", 0.5)
    back.send("xgv", b"to the client", 0.5)
    assert [d for d, _ in back.receive("xgv", 0.5)] == [b"to the xgv"]
    assert back.receive("client", 0.5) == []


def test_a_driver_holding_the_speed_is_not_the_xgv_ignoring_its_command() -> None:
    """Partial mode manual-speed: the human slows the vehicle, no unasked stop."""
    client = XgvClient(PRESETS["escape-hybrid"], XgvClientConfig(control="motion-profile"))
    client.control = True
    client.mode = ReportVehicleMode(control_mode=3, ready_mode=2, safety_mode=1,
                                    partial_mode_overrides=2)
    client.motion_command = lambda: (8.0, 1.0, 0.0)   # type: ignore[method-assign]
    for v in (8.0, 7.0, 5.0, 2.0, 0.0):
        client.speed_mps = v
        client._follow_check()
    assert not client.timeout_latched
    client.mode = ReportVehicleMode(control_mode=3, ready_mode=2, safety_mode=1)
    for v in (8.0, 7.0, 5.0):
        client.speed_mps = v
        client._follow_check()
    assert client.timeout_latched


def test_an_xgv_standing_against_a_slow_command_after_moving_is_not_following() -> None:
    """Under the follow margin (0.3 m/s) a lapsed motion at 0.2 m/s still stands against its
    command: 0.3 s at rest after it moved is a stop nobody asked for."""
    check = FollowCheck()
    assert check.check(0.2, 0.2) is None
    found = [check.check(0.2, 0.0) for _ in range(FOLLOW_REST_REPORTS)]
    assert found[:-1] == [None] * (FOLLOW_REST_REPORTS - 1) and "stands against" in found[-1]


def test_an_xgv_that_has_not_moved_yet_or_is_asked_to_stop_is_following() -> None:
    """Starting from rest (never moved under this command), and a command at rest speed, are
    no lapse however long they last."""
    check = FollowCheck()
    assert [check.check(0.3, 0.0) for _ in range(200)] == [None] * 200
    check = FollowCheck()
    assert check.check(0.5, 0.5) is None
    assert [check.check(0.04, 0.0) for _ in range(200)] == [None] * 200
