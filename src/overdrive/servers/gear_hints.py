"""The driving module acting on the speed server's gear hints (seed 001).

Seed 001: "the move server, upon seeing a hint, should gracefully take corrective action as
indicated. This usually means finishing the current move, coming to a stop, requesting a gear
change, and restarting. But because gear changing requires a stop, it's not worth doing unless
you intend to spend some time in that gear." The driving module is the speed server's only
client here, so it is the one that acts (docs/driving-module.md, "Acting on hints"):

- ``suggest_downshift`` (lugging) makes the preset's low gear preferred; ``suggest_upshift``
  (the drive gear could carry this speed here) lifts that preference, unless the speed limit
  is no higher than the current gear's cap (nothing to gain). The preference joins the
  other reasons for low gear (``wants_low_gear``: a low limit, steep or slippery ground).
- **Worth the stop.** A hinted gear is taken at once (stop, idle, shift, restart) only when
  that reaches the end of the authorization sooner (``change_time_s < time_to_cover_s``): the
  stop, the shift (preset), the runwait (seed 001: five seconds), the request round trips, then
  the rest of ``d`` (what is left of the authorization) from a standstill in the new gear;
  against ``d`` driven as now. A vehicle losing speed at full throttle that would stall before
  the end never covers ``d`` as it is: it always changes at once. Otherwise the move is
  finished in the current gear and the gear changes at the stop that ends it
  (``_plan_gear``'s rule for a natural stop).
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.servers.speed_hints import HintConfig

_LUG = HintConfig()   # the speed server's lugging thresholds, defaults


class GearHintConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Costs of a gear change (every number says where it comes from)."""

    runwait_s: float = 5.0         # seed 001: a restart from idle waits five seconds in runwait
    sequencing_s: float = 0.5      # request round trips run -> idle -> shifting -> idle -> runwait
                                   # -> shifting -> run (measured 0.3-0.4 s at the 100 ms SPSS rate)
    stopped_mps: float = 0.05      # below this a lugging vehicle has stalled (the driving
                                   # module's standstill)
    lug_gap_mps: float = _LUG.lug_gap_mps            # a downshift stops the move only while
    lug_gap_fraction: float = _LUG.lug_gap_fraction  # the goal still leads the speed as the
                                                     # hint's lugging needs (speed_hints); a
                                                     # module slowing on purpose is not lugging
    asking_band_mps: float = 0.3   # an upshift stops the move only while the goal is at most
                                   # this below the speed (the speed loop's overshoot bound,
                                   # tests/servers/test_speed_acceptance.py): not while slowing


def time_to_cover_s(distance_m: float, speed_mps: float, accel_mps2: float,
                    top_mps: float) -> float:
    """Time to drive ``distance_m`` from ``speed_mps`` accelerating at ``accel_mps2`` up to
    ``top_mps``, then cruising; ``inf`` when the speed runs out first (a stall)."""
    if distance_m <= 0.0:
        return 0.0
    v, a, top = max(speed_mps, 0.0), accel_mps2, max(top_mps, 0.0)
    if a > 0.0 and v < top:
        ramp_m = (top * top - v * v) / (2.0 * a)
        if ramp_m >= distance_m:
            return (math.sqrt(v * v + 2.0 * a * distance_m) - v) / a
        return (top - v) / a + (distance_m - ramp_m) / top
    if a < 0.0:
        disc = v * v + 2.0 * a * distance_m
        return math.inf if disc < 0.0 else (v - math.sqrt(disc)) / -a
    return distance_m / v if v > 0.0 else math.inf


def change_time_s(params: VehicleParams, distance_m: float, speed_mps: float,
                  stop_decel_mps2: float, accel_mps2: float, top_mps: float,
                  config: GearHintConfig) -> float:
    """Time to drive ``distance_m`` by stopping now, changing gear and restarting: the stop
    (at ``stop_decel_mps2``), the shift (preset), the runwait (seed 001), the round trips, then
    the rest from a standstill at ``accel_mps2`` up to ``top_mps`` in the new gear."""
    v = max(speed_mps, 0.0)
    decel = max(stop_decel_mps2, 1e-3)
    overhead_s = v / decel + params.shift_time_s + config.runwait_s + config.sequencing_s
    rest_m = distance_m - v * v / (2.0 * decel)
    return overhead_s + time_to_cover_s(rest_m, 0.0, accel_mps2, top_mps)


def worth_changing_now(remaining_m: float, keep_s: float, change_s: float) -> bool:
    """Stop and change gear now when that reaches the end of the authorization sooner."""
    if not math.isfinite(remaining_m) or remaining_m <= 0.0:
        return False
    return change_s < keep_s


class GearHints:
    """The driving module's memory of the hints: the low-gear preference, and the gear to
    change to at once this period (``now_gear``, None when the move is finished first)."""

    def __init__(self, params: VehicleParams, *, gear_speed_fraction: float, accel_mps2: float,
                 config: GearHintConfig | None = None) -> None:
        self.params = params
        self.config = config or GearHintConfig()
        self.accel_mps2 = accel_mps2
        self._caps = {g.name: g.max_speed_mps * gear_speed_fraction for g in reversed(params.gears)}
        self._forward = {g.name for g in params.gears if g.direction > 0}
        self.prefer_low = False
        self.now_gear: str | None = None

    def update(self, hint: str, server_state: str, server_gear: str, speed_mps: float,
               accel_mps2: float, remaining_m: float, limit_mps: float, sin_pitch: float,
               goal_mps: float) -> None:
        """One period: ``hint``, gear, state and acceleration from the speed server's reply,
        ``speed_mps`` the module's (unsigned), ``remaining_m`` what is left of the
        authorization, ``limit_mps`` the lowest live speed limit, ``sin_pitch`` + uphill,
        ``goal_mps`` the goal speed last sent. A vehicle slowing because its goal is lower
        (the end of a move) is not lugging, whatever hint is still held: only the preference
        is noted then."""
        p = self.params
        self.now_gear = None
        if server_state != "run" or server_gear not in self._forward:
            return
        cfg = self.config
        lug_gap = min(cfg.lug_gap_mps, cfg.lug_gap_fraction * goal_mps)
        if hint == "suggest_downshift" and server_gear != p.low_gear:
            self.prefer_low = True
            accel = -math.inf if speed_mps < cfg.stopped_mps else accel_mps2
            if goal_mps - speed_mps >= lug_gap:   # still lugging now, not slowing on purpose
                self._consider(p.low_gear, server_gear, accel, speed_mps, remaining_m,
                               limit_mps, sin_pitch)
        elif hint == "suggest_upshift" and server_gear != p.drive_gear:
            if min(limit_mps, self._caps[p.drive_gear]) <= self._caps.get(server_gear, 0.0):
                return   # under this limit the drive gear would go no faster: nothing to gain
            self.prefer_low = False
            if goal_mps >= speed_mps - cfg.asking_band_mps:
                self._consider(p.drive_gear, server_gear, 0.0, speed_mps, remaining_m,
                               limit_mps, sin_pitch)

    def _consider(self, gear: str, current: str, accel_mps2: float, speed_mps: float,
                  remaining_m: float, limit_mps: float, sin_pitch: float) -> None:
        """``now_gear = gear`` when stopping to change to it now reaches the end sooner."""
        if not math.isfinite(remaining_m) or remaining_m <= 0.0:
            return
        keep_top = min(limit_mps, self._caps.get(current, 0.0))
        if accel_mps2 == -math.inf:
            keep_s = math.inf   # stalled at full throttle
        else:
            keep_s = time_to_cover_s(remaining_m, speed_mps, min(accel_mps2, self.accel_mps2),
                                     keep_top)
        new_top = min(limit_mps, self._caps.get(gear, 0.0))
        new = self.params.gear(gear)
        climb = (drive_authority_mps2(self.params, new, 0.5 * new_top)
                 - resistance_mps2(self.params, 0.5 * new_top, sin_pitch))
        new_accel = min(self.accel_mps2, climb)
        if new_accel <= 0.0 or new_top <= 0.0:
            return   # the new gear would not get it there either
        change_s = change_time_s(self.params, remaining_m, speed_mps, self.accel_mps2, new_accel,
                                 new_top, self.config)
        if worth_changing_now(remaining_m, keep_s, change_s):
            self.now_gear = gear


__all__ = ["GearHintConfig", "GearHints", "change_time_s", "time_to_cover_s",
           "worth_changing_now"]
