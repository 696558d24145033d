"""The PACMod 3 engage workflow as data: states, events and a pure transition function.

Engaging is the operator's act, never the planner's (issue 32 item 3). The only event that
leaves ``disengaged`` or a latched state is ``engage_request``, raised by an operator act
(``overdrive drive --can pacmod3 --engage`` at start, ``overdrive engage --run RUN_DIR`` on a
running drive); no message of the stack (a MOVE, a pedal or steering command) is an event here.

- ``disengaged``: every system commanded with ``enable=0``; the stack sees a software pause.
- ``engaging``: ``enable=0`` on every system for ``DISABLE_FRAMES`` frames (the kit enables only on
  a DISABLE->ENABLE edge), then the BRAKE edge with the brake held at ``ENGAGE_BRAKE_RATIO`` and
  the throttle 0; only once the kit reports BRAKE enabled, the ACCEL, STEERING and SHIFT edges
  (throttle still 0, the steering at its measured angle, the gear it reports). ``clear_override``
  rides on every frame of the sequence, so a released override is cleared with the edge.
- ``engaged``: the stack's commands go out, ``enable=1``. A planner gone quiet stays engaged:
  the stack's watchdogs brake it to a stop (disabling at speed would coast).
- ``stopping``: a fault the CLIENT detected while engaged (reports silent, a bus error, another
  node's command frames, a report it cannot act on): the kit still drives, so the client keeps
  ``enable=1`` with the brake full on (``STOP_BRAKE_RATIO``), the throttle 0 and the steering
  held, until the kit reports a standstill held ``STANDSTILL_HOLD_S`` or the time bound
  (``stop_bound_s``: silent reports cannot say the vehicle stopped) runs out; then ``stopped``
  disables and latches ``faulted``. Disabling at speed would coast (issue 32 review).
- ``overridden`` / ``timed_out`` / ``faulted``: latched, commands go out with ``enable=0``.
  ``faulted`` is entered directly only for faults the KIT reports (it has already disabled).

``classify_event`` turns a snapshot of what the client knows (``Conditions``) into at most one
event per frame, the most urgent first; ``refusal`` says why an ``engage_request`` is refused.
``mermaid_diagram()`` renders ``TRANSITIONS`` for ``docs/state-machines.md``.
"""

from __future__ import annotations

import math
from typing import Final

import msgspec

STATES: Final = ("disengaged", "engaging", "engaged", "stopping", "overridden", "timed_out",
                  "faulted")
LATCHED: Final = frozenset({"stopping", "overridden", "timed_out", "faulted"})
"""Stops the stack did not ask for: only an operator's ``engage_request`` leaves them."""

EVENTS: Final[dict[str, str]] = {
    "fault": "the KIT reports a fault (its fault bits) or disabled a system the client still "
             "enables: the kit has already let go",
    "client_fault": "the CLIENT detects a fault: reports silent, a bus error, command frames "
                    "from another node, a gear ERROR report",
    "drive_end": "the drive ends (duration over, Ctrl-C, SIGTERM): engaged, brake to a "
                 "standstill before letting go",
    "released": "stopping for the drive's end: stopped (or the bound ran out); let go, not "
                "latched (nothing went wrong)",
    "stopped": "stopping: the kit reports a standstill held STANDSTILL_HOLD_S, or the stop's "
               "time bound ran out",
    "override": "a system report (or GLOBAL_RPT) says an operator override is active",
    "kit_timeout": "GLOBAL_RPT says the kit timed out the user commands (usr_can_timeout)",
    "engage_timeout": "the kit did not report every system enabled within ENGAGE_TIMEOUT_S",
    "all_enabled": "engaging: the kit reports every system of the workflow enabled",
    "engage_request": "the operator's act (--engage, overdrive engage), accepted (refusal None)",
}

TRANSITIONS: Final[dict[str, dict[str, str]]] = {
    "disengaged": {"engage_request": "engaging", "fault": "faulted", "client_fault": "faulted"},
    "engaging": {"all_enabled": "engaged", "override": "overridden", "kit_timeout": "timed_out",
                 "fault": "faulted", "client_fault": "faulted", "engage_timeout": "faulted",
                 "drive_end": "disengaged"},
    "engaged": {"override": "overridden", "kit_timeout": "timed_out", "fault": "faulted",
                "client_fault": "stopping", "drive_end": "stopping"},
    "stopping": {"override": "overridden", "kit_timeout": "timed_out", "fault": "faulted",
                 "stopped": "faulted", "released": "disengaged"},
    "overridden": {"engage_request": "engaging", "fault": "faulted", "client_fault": "faulted"},
    "timed_out": {"engage_request": "engaging", "fault": "faulted", "client_fault": "faulted"},
    "faulted": {"engage_request": "engaging"},
}
"""``TRANSITIONS[state][event] -> next state``; an event a state does not list leaves it as is."""

DISABLE_FRAMES: Final = 3
"""Frames of ``enable=0`` on every system before the first edge: one full command timeout's
worth (3 periods, docs/pacmod3.md), so the kit has seen the disable whatever it held before."""
ENGAGE_BRAKE_RATIO: Final = 0.5
"""The brake held while engaging (0..1 of the pedal's travel): engineering estimate, half the
travel holds a car at rest on any grade it may drive (the stack's own hold is learnt later)."""
ENGAGE_TIMEOUT_S: Final = 2.0
"""The kit reports every system enabled within this of the request, or the engage failed: 60
frames, against the few a kit needs to answer an edge."""
ENGAGE_STANDSTILL_MPS: Final = 0.1
"""An engage is refused above this speed: the held brake would be a hard stop at speed."""
STOP_BRAKE_RATIO: Final = 1.0
"""``stopping``'s brake: the full pedal, as the XGV client's command-timeout brake (100 %)."""
STANDSTILL_HOLD_S: Final = 0.5
"""``stopping`` ends once the kit reports below ``ENGAGE_STANDSTILL_MPS`` for this long (15
reports: a vehicle still rolling shows it)."""
STOP_DECEL_MPS2: Final = 2.0
"""The stop's time bound assumes this deceleration: conservative against the full brake (the
vehicle files give 6-9 m/s^2 dry; 2 still holds on a wet, worn road)."""
STOP_MARGIN_S: Final = 1.0
"""Added to the bound: the brake's lag and the kit's reports' latency, with room to spare."""


def stop_bound_s(speed_mps: float) -> float:
    """How long ``stopping`` may brake before it disables anyway: the last known speed braked at
    ``STOP_DECEL_MPS2``, plus ``STOP_MARGIN_S`` (a NaN speed: the bound of 40 m/s)."""
    v = abs(speed_mps) if math.isfinite(speed_mps) else 40.0
    return v / STOP_DECEL_MPS2 + STOP_MARGIN_S


class Conditions(msgspec.Struct, frozen=True, kw_only=True):
    """What the client knows when it classifies (one frame)."""

    engage_request: bool = False       # an operator act arrived this frame
    fault: bool = False                # the kit reports a fault (it has let go)
    client_fault: bool = False         # the client detects one: silence, bus error, foreign
    stopped: bool = False              # stopping: standstill held, or the stop's bound ran out
    drive_end: bool = False            # the drive is ending (stopping: and that is why)
    override: bool = False             # any system (or GLOBAL_RPT) reports an override
    kit_timeout: bool = False          # GLOBAL_RPT usr_can_timeout
    all_enabled: bool = False          # every system of the workflow reports enabled
    engage_elapsed_s: float = 0.0      # since the engaging state was entered
    speed_mps: float = 0.0             # reported vehicle speed
    reports_fresh: bool = True         # reports arriving (a kit that is heard)


def next_state(state: str, event: str | None) -> str:
    """The state after ``event`` (None: no event, no change)."""
    if event is None:
        return state
    return TRANSITIONS[state].get(event, state)


def refusal(state: str, c: Conditions) -> str | None:
    """Why an operator's engage request is refused now (None: accepted)."""
    if state in ("engaging", "engaged"):
        return f"already {state}"
    if state == "stopping":
        return "stopping: braking to a standstill after a fault first"
    if not c.reports_fresh:
        return "the kit is not heard (no reports): nothing to engage"
    if c.fault:
        return "the kit reports a fault (clear it on the kit first)"
    if c.client_fault:
        return "a fault the client detects"
    if not abs(c.speed_mps) <= ENGAGE_STANDSTILL_MPS:   # NaN refused too
        return (f"moving at {c.speed_mps:.2f} m/s: engage at a standstill (above "
                f"{ENGAGE_STANDSTILL_MPS} m/s the held brake would be a hard stop)")
    return None


def classify_event(state: str, c: Conditions) -> str | None:
    """At most one event for this frame, the most urgent first: a fault, an override, the
    kit's timeout, then the engage sequence's own events; an engage request last (and only
    when ``refusal`` says none)."""
    rows = TRANSITIONS[state]
    if c.fault and "fault" in rows:
        return "fault"
    if c.client_fault and "client_fault" in rows:
        return "client_fault"
    if c.drive_end and "drive_end" in rows:
        return "drive_end"
    if c.override and "override" in rows:
        return "override"
    if c.kit_timeout and "kit_timeout" in rows:
        return "kit_timeout"
    if state == "stopping":
        if not c.stopped:
            return None
        return "released" if c.drive_end else "stopped"
    if state == "engaging":
        if c.all_enabled:
            return "all_enabled"
        if c.engage_elapsed_s > ENGAGE_TIMEOUT_S:
            return "engage_timeout"
        return None
    if c.engage_request and "engage_request" in rows and refusal(state, c) is None:
        return "engage_request"
    return None


def mermaid_diagram() -> str:
    """``TRANSITIONS`` as a Mermaid ``stateDiagram-v2`` (the docs page embeds this text)."""
    lines = ["stateDiagram-v2", "    [*] --> disengaged"]
    for state in STATES:
        for event, target in TRANSITIONS[state].items():
            lines.append(f"    {state} --> {target}: {event}")
    return "\n".join(lines) + "\n"


__all__ = ["DISABLE_FRAMES", "ENGAGE_BRAKE_RATIO", "ENGAGE_STANDSTILL_MPS", "ENGAGE_TIMEOUT_S",
           "EVENTS", "LATCHED", "STANDSTILL_HOLD_S", "STATES", "STOP_BRAKE_RATIO",
           "STOP_DECEL_MPS2", "STOP_MARGIN_S", "TRANSITIONS", "Conditions", "classify_event",
           "mermaid_diagram", "next_state", "refusal", "stop_bound_s"]
