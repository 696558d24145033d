"""The engage workflow's table (``overdrive.vehicle.pacmod3_engage``), swept: every transition,
every refusal, and no event from anything but the operator's act leaves a disengaged or
latched state."""

from __future__ import annotations

import itertools
import math

import pytest

from overdrive.vehicle.pacmod3_engage import (
    ENGAGE_STANDSTILL_MPS,
    ENGAGE_TIMEOUT_S,
    EVENTS,
    LATCHED,
    STATES,
    TRANSITIONS,
    Conditions,
    classify_event,
    mermaid_diagram,
    next_state,
    refusal,
)

FLAGS = ("engage_request", "fault", "override", "kit_timeout", "all_enabled")


def every_conditions():
    for bits in itertools.product((False, True), repeat=len(FLAGS)):
        for elapsed in (0.0, ENGAGE_TIMEOUT_S, ENGAGE_TIMEOUT_S + 0.01):
            for speed in (0.0, ENGAGE_STANDSTILL_MPS, ENGAGE_STANDSTILL_MPS + 0.01, math.nan):
                yield Conditions(**dict(zip(FLAGS, bits, strict=True)),
                                 engage_elapsed_s=elapsed, speed_mps=speed)


def test_the_table_names_only_known_states_and_events() -> None:
    assert set(TRANSITIONS) == set(STATES)
    for rows in TRANSITIONS.values():
        assert set(rows) <= set(EVENTS)
        assert set(rows.values()) <= set(STATES)


@pytest.mark.parametrize(("state", "event"), [(s, e) for s in STATES for e in EVENTS])
def test_next_state_follows_the_table_and_unlisted_events_change_nothing(state, event) -> None:
    assert next_state(state, event) == TRANSITIONS[state].get(event, state)
    assert next_state(state, None) == state


def test_only_the_operator_leaves_disengaged_or_a_latched_state() -> None:
    for state in ("disengaged", *LATCHED):
        ways_out = {e for e, to in TRANSITIONS[state].items() if to in ("engaging", "engaged")}
        # stopping brakes to a standstill first: not even the operator engages from it
        assert ways_out == (set() if state == "stopping" else {"engage_request"}), state
        assert "engaged" not in TRANSITIONS[state].values()
    for state in STATES:   # engaged is reached only through engaging's all_enabled
        for event, target in TRANSITIONS[state].items():
            if target == "engaged":
                assert (state, event) == ("engaging", "all_enabled")


@pytest.mark.parametrize("state", STATES)
def test_without_an_operator_request_no_classified_event_engages(state: str) -> None:
    for c in every_conditions():
        if c.engage_request:
            continue
        to = next_state(state, classify_event(state, c))
        if state not in ("engaging", "engaged"):
            assert to not in ("engaging", "engaged"), (state, c)


@pytest.mark.parametrize("state", STATES)
def test_classification_takes_the_most_urgent_event(state: str) -> None:
    for c in every_conditions():
        event = classify_event(state, c)
        rows = TRANSITIONS[state]
        if c.fault and "fault" in rows:
            assert event == "fault"
        elif c.override and "override" in rows:
            assert event == "override"
        elif c.kit_timeout and "kit_timeout" in rows:
            assert event == "kit_timeout"
        elif state == "engaging":
            expected = ("all_enabled" if c.all_enabled else "engage_timeout"
                        if c.engage_elapsed_s > ENGAGE_TIMEOUT_S else None)
            assert event == expected
        elif c.engage_request and "engage_request" in rows and refusal(state, c) is None:
            assert event == "engage_request"
        else:
            assert event is None, (state, c, event)


@pytest.mark.parametrize("speed", [0.0, 0.05, ENGAGE_STANDSTILL_MPS, -ENGAGE_STANDSTILL_MPS])
@pytest.mark.parametrize("state", ["disengaged", *sorted(LATCHED - {"stopping"})])
def test_an_engage_at_a_standstill_is_accepted(state: str, speed: float) -> None:
    c = Conditions(engage_request=True, speed_mps=speed)
    assert refusal(state, c) is None
    assert next_state(state, classify_event(state, c)) == "engaging"


@pytest.mark.parametrize("speed", [ENGAGE_STANDSTILL_MPS + 1e-6, -0.2, 5.0, math.nan, math.inf])
def test_an_engage_while_moving_is_refused(speed: float) -> None:
    c = Conditions(engage_request=True, speed_mps=speed)
    assert "standstill" in refusal("disengaged", c)
    assert classify_event("disengaged", c) is None


@pytest.mark.parametrize(("conditions", "words"), [
    (Conditions(engage_request=True, reports_fresh=False), "not heard"),
    (Conditions(engage_request=True, fault=True), "fault"),
])
def test_an_engage_without_a_heard_healthy_kit_is_refused(conditions, words) -> None:
    for state in ("disengaged", "overridden", "timed_out"):
        assert words in refusal(state, conditions)
    assert classify_event("faulted", conditions) is None


@pytest.mark.parametrize("state", ["engaging", "engaged"])
def test_an_engage_while_engaging_or_engaged_is_refused(state: str) -> None:
    assert refusal(state, Conditions(engage_request=True)) == f"already {state}"


def test_engaging_times_out_into_a_fault_not_into_engaged() -> None:
    late = Conditions(engage_elapsed_s=ENGAGE_TIMEOUT_S + 1e-6)
    assert next_state("engaging", classify_event("engaging", late)) == "faulted"
    on_time = Conditions(engage_elapsed_s=ENGAGE_TIMEOUT_S)
    assert classify_event("engaging", on_time) is None


def test_the_diagram_draws_every_transition() -> None:
    text = mermaid_diagram()
    for state, rows in TRANSITIONS.items():
        for event, target in rows.items():
            assert f"{state} --> {target}: {event}" in text
