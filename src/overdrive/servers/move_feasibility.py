"""Checking a MOVE / REVERSE / STOP before it is executed (seed 004): the reply codes.

Pure functions over plain values: ``check_command(cmd, situation, params, config)`` returns
``None`` (accept) or a ``Verdict`` with the reply code and a readable message. The checks run in
this order and the first failure is the answer:

1. ``invalid``: not a MoveCommand, unknown kind, a field that is not a finite number, a negative
   distance or speed. Nothing about the vehicle can make such a command valid.
2. ``infeasible``: the command can never be executed by this vehicle here: curvature tighter
   than the minimum turning radius, a speed above what the gear of that direction can reach,
   or the ground (GPS/INS pitch) steeper than the vehicle is allowed to drive.
3. ``not_ready``: the vehicle cannot move now but may later: no position yet, a safety mode
   other than drive-by-wire, the computer does not control speed, the speed server's e-stop
   is latched, or the move server's own collision e-stop is latched and the radar still sees
   the obstacle within the command's reach.
4. ``busy``: the command is fine but conflicts with what is under way: the brakes of an
   emergency stop are still on (wait for the standstill).

A change of direction is never ``busy`` (issue 31 item 9): seed 004, "If a subsequent command
is received before the current one has completed, the new command replaces the current one and
gets immediately executed". A command against the way the vehicle moves replaces the one in
force like any other: the old direction's authorization is void at once (a stop now, as a
STOP's), and once the vehicle stands the speed server shifts from idle as seed 001 requires.
One that arrives while a change of direction is under way waits for that shift to end, then
shifts back (``busy_reason``).

STOP is always accepted (stopping is always allowed), unless it is malformed.
"""

from __future__ import annotations

import math
from typing import Literal

import msgspec

from overdrive.dynamics.ellipse import Ellipse, stopping_distance_m
from overdrive.dynamics.validation import finite
from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.messages import MoveCommand

ReplyCode = Literal["ok", "infeasible", "busy", "not_ready", "invalid", "stale", "clock"]
KINDS = ("move", "reverse", "stop")
CURVATURE_TOL_1PM = 1e-9   # float slack on the turning-radius limit


class Verdict(msgspec.Struct, frozen=True):
    code: ReplyCode
    message: str


class Situation(msgspec.Struct, frozen=True, kw_only=True):
    """What the checks need to know about the vehicle and the server, as plain values."""

    have_position: bool = True
    speed_mps: float = 0.0           # signed ground speed
    pitch_rad: float = 0.0
    safety_mode: str = "drive-by-wire"
    computer_speed: bool = True
    speed_server_estop: bool = False
    speed_server_fault: str = ""
    moving_direction: str = ""       # "forward" / "reverse" while the vehicle moves, else ""
    shifting_to: str = ""            # direction of a change of direction still in progress
    estop_braking: bool = False      # the move server's e-stop fault is still asserted
    latched_estop: bool = False
    radar_target: bool = False
    radar_range_m: float = math.inf
    ellipse: Ellipse | None = None   # for the stopping distance of the reach check
    standstill_mps: float = 0.05
    obstacle_margin_m: float = 2.0


def direction_of(kind: str) -> str:
    return "reverse" if kind == "reverse" else "forward"




def invalid_reason(cmd: object) -> str:
    """Why ``cmd`` is malformed, or ""."""
    if not isinstance(cmd, MoveCommand):
        return f"not a MoveCommand ({type(cmd).__name__})"
    if cmd.kind not in KINDS:
        return f"kind {cmd.kind!r} is not one of {', '.join(KINDS)}"
    for name in ("issued_s", "status_sent_s", "status_received_s"):
        value = getattr(cmd, name)
        if value is not None and not finite(value):
            return f"{name} {value!r} is not a finite number"
    if cmd.kind == "stop":
        return ""
    for name in ("distance_m", "maxspeed_mps", "curvature_1pm"):
        value = getattr(cmd, name)
        if not finite(value):
            return f"{name} {value!r} is not a finite number"
    if cmd.distance_m < 0.0:
        return f"distance_m {cmd.distance_m} is negative"
    if cmd.maxspeed_mps < 0.0:
        return f"maxspeed_mps {cmd.maxspeed_mps} is negative"
    return ""


def top_speed_mps(params: VehicleParams, direction: str, gear_fraction: float) -> float:
    """Highest speed a gear of ``direction`` reaches (below the redline fade)."""
    sign = -1 if direction == "reverse" else 1
    tops = [g.max_speed_mps for g in params.gears if g.direction == sign]
    return max(tops, default=0.0) * gear_fraction


def infeasible_reason(cmd: MoveCommand, params: VehicleParams, pitch_rad: float,
                      gear_fraction: float) -> str:
    """Why this vehicle can never execute ``cmd`` here, or ""."""
    k_max = params.max_curvature_1pm
    if abs(cmd.curvature_1pm) > k_max + CURVATURE_TOL_1PM:
        return (f"curvature {cmd.curvature_1pm:.4g} 1/m is tighter than the minimum turning "
                f"radius {1.0 / k_max:.2f} m (|curvature| <= {k_max:.4g} 1/m)")
    direction = direction_of(cmd.kind)
    top = top_speed_mps(params, direction, gear_fraction)
    if cmd.maxspeed_mps > top:
        return (f"maxspeed {cmd.maxspeed_mps:.3g} m/s is above the {top:.3g} m/s the "
                f"{params.preset} reaches in {direction}")
    if abs(pitch_rad) > params.max_pitch_rad:
        return (f"grade {math.degrees(abs(pitch_rad)):.1f} deg is beyond the vehicle's "
                f"{math.degrees(params.max_pitch_rad):.1f} deg limit")
    return ""


def obstacle_in_reach(cmd: MoveCommand, s: Situation) -> str:
    """While the collision e-stop is latched: the radar target still within the forward reach."""
    if cmd.kind != "move" or not s.radar_target:
        return ""
    braking = 0.0
    if s.ellipse is not None:
        braking = stopping_distance_m(s.ellipse, cmd.maxspeed_mps)
    reach = cmd.distance_m + braking + s.obstacle_margin_m
    if s.radar_range_m < reach:
        return (f"collision e-stop latched: obstacle at {s.radar_range_m:.1f} m is still within "
                f"{reach:.1f} m (distance + stopping distance + margin)")
    return ""


def not_ready_reason(cmd: MoveCommand, s: Situation) -> str:
    if not s.have_position:
        return "no position yet (GPS/INS)"
    if s.safety_mode != "drive-by-wire":
        return f"vehicle in safety mode {s.safety_mode}"
    if not s.computer_speed:
        return "the computer does not control speed (partial manual mode)"
    if s.speed_server_estop:
        detail = f" ({s.speed_server_fault})" if s.speed_server_fault else ""
        return f"speed server e-stop latched{detail}"
    if s.latched_estop:
        return obstacle_in_reach(cmd, s)
    return ""


def busy_reason(cmd: MoveCommand, s: Situation) -> str:
    """Only an emergency stop still braking. A change of direction while the vehicle moves, or
    while another one is under way, is accepted (module doc): ``direction_change_note`` says
    what it costs."""
    if s.estop_braking:
        return "emergency stop in progress: wait for the standstill"
    return ""


def direction_change_note(cmd: MoveCommand, s: Situation) -> str:
    """What an accepted change of direction does first, for the reply ("" when none): stop
    from the speed it moves at, or wait for the shift under way to end."""
    direction = direction_of(cmd.kind)
    if s.moving_direction and s.moving_direction != direction:
        return (f"replaces the {s.moving_direction} command: stopping now from "
                f"{abs(s.speed_mps):.2f} m/s, then the shift to {direction} through idle and "
                "runwait (seed 001)")
    if s.shifting_to and s.shifting_to != direction:
        return (f"replaces the {s.shifting_to} command: the shift to {s.shifting_to} under way "
                f"ends first, then the shift to {direction} through idle and runwait (seed 001)")
    return ""


def check_command(cmd: object, s: Situation, params: VehicleParams,
                  gear_fraction: float = 0.9) -> Verdict | None:
    """``None`` to accept ``cmd``, else the reply code and message (order: module doc)."""
    reason = invalid_reason(cmd)
    if reason:
        return Verdict("invalid", reason)
    assert isinstance(cmd, MoveCommand)
    if cmd.kind == "stop":
        return None
    for code, reason in (("infeasible", infeasible_reason(cmd, params, s.pitch_rad, gear_fraction)),
                         ("not_ready", not_ready_reason(cmd, s)),
                         ("busy", busy_reason(cmd, s))):
        if reason:
            return Verdict(code, reason)   # type: ignore[arg-type]
    return None


__all__ = ["Situation", "Verdict", "busy_reason", "check_command", "direction_change_note",
           "direction_of", "infeasible_reason", "invalid_reason", "not_ready_reason",
           "obstacle_in_reach", "top_speed_mps"]
