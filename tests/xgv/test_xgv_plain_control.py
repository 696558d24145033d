"""The plain JAUS profile's control of the Primitive Driver (issue 19): control is what the PD
says it is (a late Confirm, a Report naming another controller, queries left unanswered take
it away: no throttle, a software pause), queried about once a second while held; and in
lock-step runs control taken mid-drive and released does not resume the move, judged from the
simulated vehicle's ground truth and its PD's own controller."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

import msgspec
import pytest

from overdrive.jaus import (
    ComponentStatus,
    ConfirmComponentControl,
    JausId,
    QueryComponentControl,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportComponentControl,
    RequestComponentControl,
    SetWrenchEffort,
    encode_datagram,
)
from overdrive.messages import Topic, VehicleStatus
from overdrive.run.compose import build_servers, lockstep_nodes
from overdrive.run.sim import run_scenario
from overdrive.vehicle.xgv_client import (
    CONTROL_QUERIES_UNANSWERED,
    CONTROL_QUERY_PERIOD_S,
    REGISTRATION_GRACE_S,
    XgvClient,
)
from tests.conftest import PRESET_NAMES
from tests.xgv.plain_runs import (
    MOVE_M,
    faults,
    judged,
    mode_of,
    throttling,
)
from tests.xgv.test_xgv_plain_profile import (
    ME,
    PD,
    controlling,
    deliver,
    fix,
    ready,
    report,
    sent,
)

LATER_S = REGISTRATION_GRACE_S + 1.0   # past OpenJAUS's registration grace: a Reject is real
OTHER = JausId(1, 5, 1, 1)    # another controller, with a higher authority than ours (6)


def wrench(client: XgvClient, now_s: float) -> list[SetWrenchEffort]:
    return [m for m in sent(client, now_s) if isinstance(m, SetWrenchEffort)]


# --------------------------------------------------------- Confirm and Report Component Control

def test_a_duplicated_confirm_after_control_was_taken_away_is_not_control() -> None:
    """Found: a Confirm Component Control arriving with no request outstanding (a UDP
    duplicate or a late copy of the first one, after another controller took the PD and it
    sent us a Reject) put the client back in control: drive-by-wire and throttle sent to a
    PD that someone else controls."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, RejectComponentControl(), PD, LATER_S)
    deliver(client, ConfirmComponentControl(response=0), PD, LATER_S + 0.001)   # the duplicate
    out = report(client, LATER_S + 0.01, pose=fix())
    assert mode_of(out) == "software-pause"
    commands = sent(client, LATER_S + 0.01)
    assert not [m for m in commands if isinstance(m, SetWrenchEffort)]
    assert [m for m in commands if isinstance(m, RequestComponentControl)]     # asks again
    # the answer to that request is control again
    deliver(client, ConfirmComponentControl(response=0), PD, LATER_S + 0.02)
    assert mode_of(report(client, LATER_S + 0.03, pose=fix())) == "drive-by-wire"


@pytest.mark.parametrize("controller", [JausId(1, 3, 1, 1), JausId(0, 0, 0, 0)])
def test_report_component_control_naming_another_controller_takes_control_away(
        controller: JausId) -> None:
    """Found: a Report Component Control from the PD naming someone else (or nobody) was
    ignored; the client went on sending throttle and telling the stack drive-by-wire."""
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, ReportComponentControl(controller=controller, authority=7), PD, 0.2)
    # a fault, and the stop latched (the vehicle's command timeout until a runwait)
    assert [n.code for n in client.notices] == ["xgv_control", "command_timeout"]
    assert client.timeout_latched
    out = report(client, 0.21, pose=fix())
    assert mode_of(out) == "software-pause"
    assert not wrench(client, 0.21)


def test_report_component_control_naming_us_keeps_control() -> None:
    client = throttling(controlling())
    report(client, 0.1, pose=fix())
    deliver(client, ReportComponentControl(controller=ME, authority=6), PD, 0.2)
    assert mode_of(report(client, 0.21, pose=fix())) == "drive-by-wire"
    assert [w.propulsive_linear_x_pct for w in wrench(client, 0.21)] == [pytest.approx(40.0, abs=0.01)]


# ---------------------------------------------------------------------- Query Component Control

def drive(client: XgvClient, start_s: float, end_s: float,
          answer: Callable[[float], JausId | None] | None = None) -> list[Any]:
    """Step the client every 10 ms with healthy reports; each Query Component Control is
    answered with a Report naming ``answer(t)`` (None: no answer). What it sent."""
    out: list[Any] = []
    t = start_s
    while t < end_s - 1e-9:
        report(client, t, pose=fix(), speed_mps=0.0)
        messages = sent(client, t)
        out.extend((t, m) for m in messages)
        if answer is not None and any(isinstance(m, QueryComponentControl) for m in messages):
            controller = answer(t)
            if controller is not None:
                deliver(client, ReportComponentControl(controller=controller, authority=6),
                        PD, t + 0.005)
        t = round(t + 0.01, 6)
    return out


def mode_at(client: XgvClient, now_s: float) -> str:
    status = dict(report(client, now_s, pose=fix(), speed_mps=0.0))[Topic.VEHICLE_STATUS]
    assert isinstance(status, VehicleStatus)
    return status.safety_mode


def test_control_is_queried_once_a_period_while_held() -> None:
    client = throttling(controlling())
    out = drive(client, 0.1, 5.05, answer=lambda t: ME)
    queries = [t for t, m in out if isinstance(m, QueryComponentControl)]
    assert len(queries) == round(5.0 / CONTROL_QUERY_PERIOD_S) and all(m.header.destination == PD for _, m in out
                                     if isinstance(m, QueryComponentControl))
    gaps = [b - a for a, b in itertools.pairwise(queries)]
    assert all(g == pytest.approx(CONTROL_QUERY_PERIOD_S, abs=0.011) for g in gaps)
    assert mode_at(client, 5.06) == "drive-by-wire"


@pytest.mark.parametrize(("offset_s", "lost"), [(-0.1, False), (0.1, True)])
def test_queries_left_unanswered_mean_control_lost(offset_s: float, lost: bool) -> None:
    """Found: a lost Reject Component Control left the client believing it held control,
    sending throttle and telling the stack drive-by-wire. Now: the PD answers none of
    CONTROL_QUERIES_UNANSWERED queries (one a period) by the time the next is due: control
    lost, a fault, no throttle, a software pause (the stack stops), and control is asked
    for again. Just before that time: still in control."""
    client = throttling(controlling())
    answered = {"n": 0}

    def answer(t: float) -> JausId | None:
        answered["n"] += 1
        return ME if answered["n"] == 1 else None   # the first answered, then silence

    answered_s = CONTROL_QUERY_PERIOD_S     # the first query: a period after the Confirm at 0
    end_s = answered_s + (CONTROL_QUERIES_UNANSWERED + 1) * CONTROL_QUERY_PERIOD_S + offset_s
    out = drive(client, 0.1, end_s + 0.05, answer)
    late = [m for t, m in out if t >= end_s - abs(offset_s) - 1e-6]
    efforts = [m for m in late if isinstance(m, SetWrenchEffort)]
    if lost:
        assert mode_at(client, end_s + 0.06) == "software-pause"
        assert not efforts
        assert any(isinstance(m, RequestComponentControl) for m in late)
    else:
        assert mode_at(client, end_s + 0.06) == "drive-by-wire"
        assert efforts and efforts[-1].propulsive_linear_x_pct == pytest.approx(40.0, abs=0.01)


@pytest.mark.parametrize("controller", [OTHER, JausId(0, 0, 0, 0)])
def test_a_query_answered_with_another_controller_stops_the_throttle(controller: JausId) -> None:
    """A lost Reject, then the answer to our query names someone else (or nobody: OpenJAUS
    reports 0.0.0.0 for a PD with no controller): lost at once, a fault."""
    client = throttling(controlling())
    out = drive(client, 0.1, 2.2, answer=lambda t: ME if t < 1.5 else controller)
    after = [m for t, m in out if t > 2.12]
    assert not [m for m in after if isinstance(m, SetWrenchEffort)]
    assert mode_at(client, 2.21) == "software-pause"


# ---------------------------------------------------------------------- control taken mid-drive

def takeover_run(preset: str, take_s: float, release_s: float, *, reject_lost: bool) -> Any:
    """openjaus-wrench-drive.yaml (plain) where another client with a higher authority takes
    the PD at ``take_s`` (its Reject to us lost or not) and releases it at ``release_s``."""
    scenario = ready("openjaus-wrench-drive.yaml", preset)
    nodes = lockstep_nodes(scenario, build_servers(scenario, over_jaus=True), profile="plain")
    sim_node = nodes[0]
    simulator, link = sim_node.simulator, sim_node.link
    step = sim_node.step
    done: set[str] = set()
    other_address = ("127.0.0.9", 3794)

    def from_other(message: Any, now_s: float) -> None:
        data = encode_datagram([message.with_header(source=OTHER, destination=PD)])
        for reply, address in simulator.receive(data, other_address, now_s):
            if address != other_address and not reject_lost:
                link.send("xgv", reply, now_s, to=address)   # the Reject reaches us

    def stepped(now_s: float, inbox: Any) -> Any:
        if now_s >= take_s and "take" not in done:
            done.add("take")
            from_other(RequestComponentControl(authority=7), now_s)
            simulator.pd.status = ComponentStatus.READY     # the other Resumed it
        if now_s >= release_s and "release" not in done:
            done.add("release")
            from_other(ReleaseComponentControl(), now_s)
        return step(now_s, inbox)

    sim_node.step = stepped   # type: ignore[method-assign]
    scenario = msgspec.structs.replace(scenario, spec=msgspec.structs.replace(
        scenario.spec, duration_s=14.0))
    result = run_scenario(scenario, None, keep_trace=True, nodes=nodes, plot=False)
    return result, simulator


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("reject_lost", [False, True])
@pytest.mark.parametrize("take_s", [3.0, 4.5])
def test_control_taken_mid_drive_then_released_does_not_resume_the_move(
        preset: str, reject_lost: bool, take_s: float) -> None:
    """Control taken by another controller mid-move (its Reject delivered, or lost: then
    found by Query Component Control within CONTROL_QUERIES_UNANSWERED periods) and released
    2 s later: the client takes control back (the PD's own controller is us again at the
    end), but the stack does not drive the old move on by itself (the move server takes the
    pause as an interruption and discards it): the vehicle stays stopped (ground truth)."""
    release_s = take_s + 2.0 + (CONTROL_QUERY_PERIOD_S if reject_lost else 0.0)
    result, simulator = takeover_run(preset, take_s, release_s, reject_lost=reject_lost)
    summary = result.summary
    codes = faults(summary)
    assert codes and codes[0][0] == "xgv_control", codes
    assert codes[0][1] <= take_s + (2.0 * CONTROL_QUERY_PERIOD_S if reject_lost else 0.1)
    assert simulator.pd.controller == ME           # control is back at the end
    after = [r for r in result.trace if float(r["t_s"]) >= release_s]
    assert after and max(float(r["speed_mps"]) for r in after) < 0.05
    odometer_at_release = float(after[0]["odometer_m"])
    assert float(result.trace[-1]["odometer_m"]) == pytest.approx(odometer_at_release, abs=0.05)
    assert odometer_at_release < MOVE_M - 1.0      # the move was not finished before
    assert judged(summary) == []
