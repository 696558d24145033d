"""The speed server's state machine as data (seed 001), and its fault codes.

Three pure pieces, kept apart so each can be tested and documented on its own:

- ``STATE_TABLE``: what each speed state does to throttle, engine, brakes and transmission
  (the seed's table, row for row);
- ``TRANSITIONS[state][event] -> state`` and ``next_state``: the only place where the state
  changes; ``classify_event`` turns a snapshot of the server's inputs (``Conditions``) into at
  most one event per control period;
- ``FaultCode`` and ``FAULT_MESSAGES``: every fault the server raises, with a readable message.

``mermaid_diagram()`` renders ``TRANSITIONS`` for ``docs/speed-server.md``.
"""

from __future__ import annotations

import enum
from typing import Final

import msgspec

# --------------------------------------------------------------------------- states

STATES: Final = ("parked", "reset", "starting", "startwait", "paused", "runwait", "idle",
                 "shifting", "run")
"""Speed states in the seed's order."""

REQUESTABLE: Final = frozenset({"parked", "paused", "idle", "run"})
"""Seed 001: "only parked, pause, idle, and run can be requested"."""


class StateRow(msgspec.Struct, frozen=True):
    """One row of the seed's state table: what the state does to the vehicle.

    ``throttle``: the speed loop may open the throttle (only ``run``); ``engine_on``: the engine
    is requested on (cranking or running); ``brakes_locked``: full service brake plus parking
    brake; ``ignition``: the seed's fourth column (controllers powered; ``reset`` resets them);
    ``in_gear``: the transmission may be in a driving gear; ``False`` means the server commands
    the park gear (``parked``, ``reset``) or neutral (``starting``, ``startwait``, ``paused``).
    """

    description: str
    throttle: bool
    engine_on: bool
    brakes_locked: bool
    ignition: bool
    in_gear: bool
    note: str


STATE_TABLE: Final[dict[str, StateRow]] = {
    # seed 001, "Speed states" table, in its order and with its notes
    "parked": StateRow("Engine stopped, brakes locked.", False, False, True, False, False,
                       "Inactive"),
    "reset": StateRow("Engine stopped, brakes locked.", False, False, True, False, False,
                      "Reset controllers, then start"),
    "starting": StateRow("Cranking/warmup", False, True, True, True, False, "Must be in neutral"),
    "startwait": StateRow("Starting failed, waiting", False, False, True, True, False,
                          "Try again after 30 seconds."),
    "paused": StateRow("Engine running, brakes locked", False, True, True, True, False,
                       "Idle, in neutral"),
    "runwait": StateRow("5-sec wait before move", False, True, True, True, True,
                        "Required by DARPA"),
    "idle": StateRow("Engine running, brakes locked", False, True, True, True, True,
                     "Idle, any gear"),
    "shifting": StateRow("Shifting in progress", False, True, True, True, True,
                         "The Polaris Ranger can only shift when stopped"),
    "run": StateRow("Run mode", True, True, False, True, True,
                    "Normal driving mode, forward or reverse."),
}

# --------------------------------------------------------------------------- events

EVENTS: Final[dict[str, str]] = {
    "client_fault": "the SPSS carries a new nonzero fault code",
    "watchdog": "no SPSS for spss_timeout_s, or no vehicle status/speed for sensor_timeout_s "
                "(emergency stop)",
    "stalled": "the engine stopped while it should run",
    "start": "a state other than parked is requested",
    "park": "parked is requested (from run: once stopped)",
    "reset_done": "controllers reset and the transmission is out of gear",
    "started": "the engine reports running",
    "start_failed": "the crank attempt failed or timed out",
    "retry": "start_retry_s spent in startwait",
    "pause_timeout": "pause_park_s spent in paused (saves fuel)",
    "resume": "idle or run is requested",
    "pause": "paused is requested (from run: once stopped)",
    "wait_done": "runwait_s elapsed, idle requested",
    "wait_done_run": "runwait_s elapsed, run requested",
    "change_gear": "idle is requested with another gear, vehicle stopped",
    "go_run": "run is requested",
    "shifted": "the vehicle reports the requested gear",
    "shifted_run": "the vehicle reports the requested gear and the shift was on the way to run",
    "shift_failed": "the vehicle did not reach the gear within the shift timeout",
    "go_idle": "idle is requested and the vehicle has stopped",
}
"""Every event of the state machine, with what raises it."""

TRANSITIONS: Final[dict[str, dict[str, str]]] = {
    "parked": {"client_fault": "reset", "start": "reset"},
    "reset": {"park": "parked", "reset_done": "starting"},
    "starting": {"client_fault": "reset", "park": "parked", "started": "paused",
                 "start_failed": "startwait"},
    "startwait": {"client_fault": "reset", "park": "parked", "retry": "starting"},
    "paused": {"client_fault": "reset", "stalled": "reset", "park": "parked",
               "pause_timeout": "parked", "resume": "runwait"},
    "runwait": {"client_fault": "reset", "watchdog": "idle", "stalled": "reset", "park": "parked",
                "pause": "paused", "wait_done": "idle", "wait_done_run": "shifting"},
    "idle": {"client_fault": "reset", "stalled": "reset", "park": "parked", "pause": "paused",
             "change_gear": "shifting", "go_run": "runwait"},
    "shifting": {"client_fault": "reset", "watchdog": "idle", "stalled": "reset",
                 "park": "parked", "pause": "paused", "shifted": "idle", "shifted_run": "run",
                 "shift_failed": "idle"},
    "run": {"client_fault": "idle", "watchdog": "idle", "stalled": "reset", "park": "parked",
            "pause": "paused", "go_idle": "idle"},
}
"""``TRANSITIONS[state][event] -> next state``. An event a state does not list leaves it as is."""


def next_state(state: str, event: str | None) -> str:
    """The state after ``event`` (``None``: no event)."""
    if event is None:
        return state
    return TRANSITIONS[state].get(event, state)


class Conditions(msgspec.Struct, frozen=True, kw_only=True):
    """Everything ``classify_event`` looks at, as plain values (no clock, no messages)."""

    goal: str                      # requested state the server works towards
    goal_gear: str                 # gear for idle/run
    time_in_state_s: float
    client_fault_edge: bool = False
    watchdog_edge: bool = False
    latched: bool = False          # e-stop latched: requests are not acted upon
    client_fault_active: bool = False
    engine: str = "off"            # VehicleStatus.engine ("" when no status yet)
    saw_cranking: bool = False     # the engine reported cranking since entering starting
    gear: str = ""                 # VehicleStatus.gear
    gear_neutral: bool = False     # the vehicle's gear does not drive the wheels
    shifting: bool = False         # VehicleStatus.shifting
    stopped: bool = True           # filtered speed below the standstill threshold
    shift_for_run: bool = False    # shifting was entered from runwait
    reset_s: float = 0.5
    start_timeout_s: float = 4.0
    start_retry_s: float = 30.0
    pause_park_s: float = 600.0
    runwait_s: float = 5.0
    shift_timeout_s: float = 5.0


ENGINE_STATES: Final = frozenset({"paused", "runwait", "idle", "shifting", "run"})
"""States in which the engine must be running; it stopping there is a stall."""


def classify_event(state: str, c: Conditions) -> str | None:
    """The single most urgent event in ``state`` under ``c``, or ``None``.

    Order: client fault, watchdog, stall, then the state's own progress and the requested
    goal. While an e-stop is latched the (stale) goal is not pursued, except towards parked.
    """
    if c.client_fault_edge:
        return "client_fault"
    if c.watchdog_edge and "watchdog" in TRANSITIONS[state]:
        return "watchdog"
    if state in ENGINE_STATES and c.engine == "off":
        return "stalled"
    goal = c.goal
    t = c.time_in_state_s
    if state == "parked":
        return "start" if goal != "parked" and not c.latched else None
    if state == "reset":
        if goal == "parked":
            return "park"
        done = t >= c.reset_s and c.gear_neutral and not c.shifting
        return "reset_done" if done and not c.client_fault_active else None
    if state == "starting":
        if goal == "parked":
            return "park"
        if c.engine == "running":
            return "started"
        if (c.saw_cranking and c.engine == "off") or t >= c.start_timeout_s:
            return "start_failed"
        return None
    if state == "startwait":
        if goal == "parked":
            return "park"
        return "retry" if t >= c.start_retry_s else None
    if state == "paused":
        if goal == "parked":
            return "park"
        if t >= c.pause_park_s:
            return "pause_timeout"
        return "resume" if goal in ("idle", "run") and not c.latched else None
    if state == "shifting":
        if goal == "parked":
            return "park"
        if goal == "paused":
            return "pause"
        if c.gear == c.goal_gear and not c.shifting:
            return "shifted_run" if c.shift_for_run and goal == "run" else "shifted"
        return "shift_failed" if t >= c.shift_timeout_s else None
    if c.latched:
        return "park" if goal == "parked" and c.stopped else None
    if state == "runwait":
        if goal == "parked":
            return "park"
        if goal == "paused":
            return "pause"
        if t >= c.runwait_s:
            return "wait_done_run" if goal == "run" else "wait_done"
        return None
    if state == "idle":
        if goal == "parked":
            return "park"
        if goal == "paused":
            return "pause"
        if goal == "run":
            return "go_run"
        return "change_gear" if c.gear != c.goal_gear and c.stopped else None
    if state == "run" and c.stopped:
        return {"parked": "park", "paused": "pause", "idle": "go_idle"}.get(goal)
    return None


# --------------------------------------------------------------------------- faults

class FaultCode(enum.IntEnum):
    """The server's own fault codes. Client fault codes (1..999) are reported unchanged."""

    SPSS_TIMEOUT = 1001
    NOT_FINITE = 1002
    OUT_OF_RANGE = 1003
    UNKNOWN_GEAR = 1004
    BAD_STATE = 1005
    GEAR_CHANGE_OUTSIDE_IDLE = 1006
    SHIFT_WHILE_MOVING = 1007
    NO_DRIVE_GEAR = 1008
    ENGINE_STALLED = 1009
    SHIFT_FAILED = 1010
    SENSOR_TIMEOUT = 1011
    VEHICLE_TIMEOUT = 1012   # simulation only: JAUS does not report the vehicle's timeout brake


CLIENT_FAULT_MAX: Final = 999
"""Largest fault code a client may send; the server's own codes start at 1001."""

FAULT_MESSAGES: Final[dict[FaultCode, str]] = {
    FaultCode.SPSS_TIMEOUT: "no SPSS for {timeout_s:.3f} s: emergency stop",
    FaultCode.NOT_FINITE: "invalid request: {field} is not a finite number",
    FaultCode.OUT_OF_RANGE: "invalid request: {field} = {value} outside {low}..{high}",
    FaultCode.UNKNOWN_GEAR: "invalid request: {preset} has no gear {gear!r}",
    FaultCode.BAD_STATE: "invalid request: state {state!r} cannot be requested "
                         "(parked, paused, idle, run)",
    FaultCode.GEAR_CHANGE_OUTSIDE_IDLE: "invalid request: gear change to {gear!r} in {state}; "
                                        "change gears in idle",
    FaultCode.SHIFT_WHILE_MOVING: "invalid request: gear change to {gear!r} while moving at "
                                  "{speed_mps:.2f} m/s",
    FaultCode.NO_DRIVE_GEAR: "invalid request: run in gear {gear!r}, which does not drive",
    FaultCode.ENGINE_STALLED: "engine stopped in {state}: restarting",
    FaultCode.SHIFT_FAILED: "gear {gear!r} not reached within {timeout_s:.1f} s",
    FaultCode.SENSOR_TIMEOUT: "no vehicle status or speed for {timeout_s:.3f} s: emergency stop",
    FaultCode.VEHICLE_TIMEOUT: "the vehicle braked on its own command timeout: emergency stop",
}
"""Message templates, formatted with the details of each occurrence."""

CLIENT_FAULT_MESSAGE: Final = "client fault {code}: brakes on, throttle cut"

ESTOP_CAUSES: Final[dict[int, str]] = {
    FaultCode.SPSS_TIMEOUT: "watchdog",
    FaultCode.SENSOR_TIMEOUT: "sensor_timeout",
    FaultCode.VEHICLE_TIMEOUT: "command_timeout",
    FaultCode.ENGINE_STALLED: "engine_stall",
}
"""Names of the emergency stops the server raises on its own (the stack did not ask for them),
as the move server reports them (``Notice(kind="interrupted", code=...)``); any other of the
server's own codes (an actuator that does not follow) is ``actuator``. An engine stall is no
e-stop (the server restarts the engine, seed 001) but it stops the vehicle unasked all the
same: the move server interrupts on it too."""


def estop_cause(code: int) -> str:
    """The name of the e-stop latched by fault ``code``; "" for a client's (asked for)."""
    if code <= CLIENT_FAULT_MAX:
        return ""
    return ESTOP_CAUSES.get(code, "actuator")


def fault_message(code: int, **details: object) -> str:
    """Readable message for ``code``, filled with ``details``."""
    if 1 <= code <= CLIENT_FAULT_MAX:
        return CLIENT_FAULT_MESSAGE.format(code=code)
    return FAULT_MESSAGES[FaultCode(code)].format(**details)


# --------------------------------------------------------------------------- diagram

def mermaid_diagram() -> str:
    """``TRANSITIONS`` as a Mermaid ``stateDiagram-v2`` (the docs page embeds this text)."""
    lines = ["stateDiagram-v2", "    [*] --> parked"]
    for state in STATES:
        for event, target in TRANSITIONS[state].items():
            lines.append(f"    {state} --> {target} : {event}")
    return "\n".join(lines) + "\n"
