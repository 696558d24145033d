"""The speed server's state machine as data: table, transitions, event classification, docs."""

from __future__ import annotations

import re
from pathlib import Path
from typing import get_args

import pytest

from overdrive.messages import RequestableState, SpeedStateName
from overdrive.servers.speed_table import (
    EVENTS,
    REQUESTABLE,
    STATE_TABLE,
    STATES,
    TRANSITIONS,
    Conditions,
    FaultCode,
    classify_event,
    estop_cause,
    fault_message,
    mermaid_diagram,
    next_state,
)

DOC = Path(__file__).resolve().parents[2] / "docs" / "speed-server.md"


def test_states_match_the_message_literal_and_the_seed():
    assert set(STATES) == set(get_args(SpeedStateName))
    assert set(REQUESTABLE) == set(get_args(RequestableState))
    assert STATES == ("parked", "reset", "starting", "startwait", "paused", "runwait", "idle",
                      "shifting", "run")
    assert frozenset({"parked", "paused", "idle", "run"}) == REQUESTABLE
    assert set(STATE_TABLE) == set(STATES) == set(TRANSITIONS)


# seed 001 "Speed states": throttle, engine, brakes locked, ignition, transmission in gear
SEED_ROWS = {
    "parked": (False, False, True, False, False),
    "reset": (False, False, True, False, False),
    "starting": (False, True, True, True, False),
    "startwait": (False, False, True, True, False),
    "paused": (False, True, True, True, False),
    "runwait": (False, True, True, True, True),
    "idle": (False, True, True, True, True),
    "shifting": (False, True, True, True, True),
    "run": (True, True, False, True, True),
}


@pytest.mark.parametrize("state", STATES)
def test_state_table_row_is_the_seeds(state):
    row = STATE_TABLE[state]
    assert (row.throttle, row.engine_on, row.brakes_locked, row.ignition, row.in_gear) == SEED_ROWS[state]


ALLOWED = [(s, e, t) for s, row in TRANSITIONS.items() for e, t in row.items()]
FORBIDDEN = [(s, e) for s in STATES for e in EVENTS if e not in TRANSITIONS[s]]


@pytest.mark.parametrize(("state", "event", "target"), ALLOWED)
def test_allowed_transition(state, event, target):
    assert next_state(state, event) == target
    assert target != state


@pytest.mark.parametrize(("state", "event"), FORBIDDEN)
def test_event_not_in_the_table_leaves_the_state(state, event):
    assert next_state(state, event) == state


def test_every_event_is_used_and_every_target_is_a_state():
    used = {e for row in TRANSITIONS.values() for e in row}
    assert used == set(EVENTS)
    assert {t for row in TRANSITIONS.values() for t in row.values()} <= set(STATES)
    assert next_state("run", None) == "run"


def test_seed_sequences_are_paths_in_the_table():
    def walk(start, events):
        states = [start]
        for event in events:
            states.append(next_state(states[-1], event))
        return states

    # "parked to reset to starting to paused, possibly with a detour through startwait"
    assert walk("parked", ["start", "reset_done", "start_failed", "retry", "started"]) == [
        "parked", "reset", "starting", "startwait", "starting", "paused"]
    # gear change: "idle to shifting and back to idle"
    assert walk("idle", ["change_gear", "shifted"]) == ["idle", "shifting", "idle"]
    # "idle to runwait to shifting to run"
    assert walk("idle", ["go_run", "wait_done_run", "shifted_run"]) == [
        "idle", "runwait", "shifting", "run"]
    # out of pause: "runwait for the required five second delay, then go to idle"
    assert walk("paused", ["resume", "wait_done"]) == ["paused", "runwait", "idle"]
    # nonzero fault code: idle from run, reset otherwise
    assert next_state("run", "client_fault") == "idle"
    for state in STATES:
        if state not in ("run", "reset"):
            assert next_state(state, "client_fault") == "reset"
    assert next_state("paused", "pause_timeout") == "parked"


def test_only_run_reaches_run_through_shifting():
    assert [s for s, row in TRANSITIONS.items() if "run" in row.values()] == ["shifting"]
    # runwait is the only way into shifting-on-the-way-to-run, so motion always follows the 5 s wait
    assert [s for s, row in TRANSITIONS.items() if row.get("wait_done_run")] == ["runwait"]


def cond(**kw):
    base = dict(goal="paused", goal_gear="high", time_in_state_s=0.0, engine="running",
                gear="neutral", gear_neutral=True)
    base.update(kw)
    return Conditions(**base)


@pytest.mark.parametrize(("state", "conditions", "event"), [
    ("parked", cond(goal="parked", engine="off"), None),
    ("parked", cond(goal="paused", engine="off"), "start"),
    ("parked", cond(goal="run", engine="off", latched=True), None),
    ("reset", cond(engine="off", time_in_state_s=0.49), None),
    ("reset", cond(engine="off", time_in_state_s=0.5), "reset_done"),
    ("reset", cond(engine="off", time_in_state_s=5, gear_neutral=False), None),
    ("reset", cond(engine="off", time_in_state_s=5, client_fault_active=True), None),
    ("reset", cond(goal="parked", engine="off"), "park"),
    ("starting", cond(engine="off"), None),
    ("starting", cond(engine="cranking"), None),
    ("starting", cond(engine="running"), "started"),
    ("starting", cond(engine="off", saw_cranking=True), "start_failed"),
    ("starting", cond(engine="off", time_in_state_s=4.0), "start_failed"),
    ("startwait", cond(engine="off", time_in_state_s=29.99), None),
    ("startwait", cond(engine="off", time_in_state_s=30.0), "retry"),
    ("paused", cond(), None),
    ("paused", cond(goal="idle"), "resume"),
    ("paused", cond(goal="run"), "resume"),
    ("paused", cond(goal="run", latched=True), None),
    ("paused", cond(time_in_state_s=600.0), "pause_timeout"),
    ("paused", cond(engine="off"), "stalled"),
    ("runwait", cond(goal="run", time_in_state_s=4.99), None),
    ("runwait", cond(goal="run", time_in_state_s=5.0), "wait_done_run"),
    ("runwait", cond(goal="idle", time_in_state_s=5.0), "wait_done"),
    ("runwait", cond(goal="paused"), "pause"),
    ("idle", cond(goal="idle", gear="high"), None),
    ("idle", cond(goal="idle", gear="low"), "change_gear"),
    ("idle", cond(goal="idle", gear="low", stopped=False), None),
    ("idle", cond(goal="run", gear="low"), "go_run"),
    ("idle", cond(goal="run", latched=True), None),
    ("shifting", cond(goal="idle", gear="low", shifting=True), None),
    ("shifting", cond(goal="idle", gear="high", shifting=True), None),
    ("shifting", cond(goal="idle", gear="high"), "shifted"),
    ("shifting", cond(goal="run", gear="high"), "shifted"),
    ("shifting", cond(goal="run", gear="high", shift_for_run=True), "shifted_run"),
    ("shifting", cond(goal="idle", gear="low", time_in_state_s=5.0), "shift_failed"),
    ("run", cond(goal="run", stopped=False), None),
    ("run", cond(goal="paused", stopped=False), None),
    ("run", cond(goal="paused"), "pause"),
    ("run", cond(goal="idle"), "go_idle"),
    ("run", cond(goal="parked"), "park"),
    ("run", cond(goal="run", watchdog_edge=True), "watchdog"),
    ("run", cond(goal="run", client_fault_edge=True, watchdog_edge=True), "client_fault"),
    ("paused", cond(watchdog_edge=True), None),
])
def test_classify_event(state, conditions, event):
    assert classify_event(state, conditions) == event


def test_fault_codes_have_messages_and_do_not_collide_with_client_codes():
    for code in FaultCode:
        assert code > 999
        assert fault_message(code, timeout_s=0.2, field="x", value=1, low=0, high=1, preset="p",
                             gear="g", state="s", speed_mps=1.0)
    assert fault_message(7) == "client fault 7: brakes on, throttle cut"


def test_docs_diagram_is_the_generated_one():
    text = DOC.read_text(encoding="utf-8")
    blocks = re.findall(r"```mermaid\n(.*?)```", text, re.S)
    assert blocks, "docs/speed-server.md has no mermaid block"
    assert blocks[0] == mermaid_diagram()


def test_docs_fault_table_lists_every_code():
    text = DOC.read_text(encoding="utf-8")
    for code in FaultCode:
        assert f"| {int(code)} | `{code.name}` |" in text


PARK_FROM = ["reset", "starting", "startwait", "paused", "runwait", "idle", "shifting"]


@pytest.mark.parametrize("state", PARK_FROM)
def test_parked_requested_from_every_intermediate_state(state):
    """A client may always ask for parked: the engine stops and the brakes lock."""
    engine = "off" if state in ("reset", "startwait") else "running"
    assert classify_event(state, cond(goal="parked", engine=engine)) == "park"
    assert next_state(state, "park") == "parked"


@pytest.mark.parametrize("state", ["runwait", "shifting"])
def test_paused_requested_on_the_way_to_run(state):
    assert classify_event(state, cond(goal="paused", gear_neutral=False, gear="high")) == "pause"
    assert next_state(state, "pause") == "paused"


def test_latched_estop_only_allows_parking_once_stopped():
    latched = dict(latched=True, goal="parked", gear="high", gear_neutral=False)
    assert classify_event("idle", cond(**latched, stopped=True)) == "park"
    assert classify_event("idle", cond(**latched, stopped=False)) is None
    assert classify_event("idle", cond(latched=True, goal="run", gear="high")) is None


def test_idle_to_paused_on_request():
    assert classify_event("idle", cond(goal="paused", gear="high", gear_neutral=False)) == "pause"
    assert next_state("idle", "pause") == "paused"


@pytest.mark.parametrize(("code", "cause"), [(0, ""), (40, ""), (999, ""), (1001, "watchdog"),
                                             (1009, "engine_stall"), (1133, "actuator")])
def test_an_emergency_stop_is_named_by_who_caused_it(code: int, cause: str) -> None:
    """A client's fault (1..999) is a stop it asked for: no name; the server's own codes name
    the unasked stop the move server reports (``interrupted``)."""
    assert estop_cause(code) == cause
