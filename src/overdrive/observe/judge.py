"""The independent safety judge, run on every simulated run.

The monitor is a bus tap, not part of the stack. It judges only from

- **ground truth** (``sim/truth``): the path is integrated from x/y, never from the stack's
  odometer or its remaining distance;
- **commands as their sources issued them** (``observe``, a tap before channel faults): the
  planner's MOVE / REVERSE / STOP, other sources' advance and max-speed messages (the move
  server's own re-publications, source ``move``, are the stack's outputs and are ignored), the
  safety devices, and actuator commands as the controllers issued them;
- **what was delivered** to each node after channel faults and process boundaries
  (``observe_delivered``): the SPSS the speed server actually received.

Rules (docs/reliability.md, docs/safety-case.md):

1. **authorization**: each MOVE / REVERSE the move server accepted, and each other source's
   advance, fixes its end at the true position when it was *issued*; a replacement fixes a
   new end; a STOP binds when it reaches the move server (it cannot be refused) and means
   "stop now" from there. A command
   shorter than the shortest physical stop from that moment (``shortest_stop_m``) is an
   ``impossible_command`` note and is judged against that shortest stop, but a source's
   impossible replacements never move its end further than the end it already had. The
   largest overrun of the run is reported.
2. **direction**: no travel of more than 0.10 m against the commanded direction: rolling back
   under a MOVE (or an SPSS in a forward gear), forward under a REVERSE, either way before the
   first command.
3. **speed**: true speed never above the lowest live limit (the command's maxspeed, other
   sources' limits until they lapse, the engaged gear's top speed) by more than 0.3 m/s for
   longer than 0.5 s. A lowered limit is met along a ramp at 1.0 m/s^2 (or what the road allows)
   from the speed when it was lowered.
4. **unintended_motion**: once an interruption has ended (any safety mode but drive-by-wire by
   the seed-000 table: SafeStop pause or stop, e-stop button, manual overrides, door, internal
   error; or the human taking speed control in a partial mode), the vehicle moves no further
   than its shortest stop from the speed it had then (+0.10 m) until a command issued after
   that moment. The same after a stop the stack did not ask for (issue 38): SPSS delivered to
   the speed server more than 200 ms apart (its watchdog), the vehicle's own command timeout,
   or an emergency stop the speed server raised on its own (a fault code above the clients'
   1..999): once the vehicle has come to rest after it, it moves no more than 0.10 m until a
   new command.
5. **watchdog**: on SPSS as delivered to the speed server, an emergency stop (throttle 0,
   brake >= 99 % from the speed server) within 200 ms plus one control period of the last one,
   held until SPSS are delivered again; the amount is how late (or how long missing).
6. **finite**: any NaN or infinity in ground truth or in a command is a violation.
7. **throttle_while_braking**: no pedal command has throttle and brake both above zero.
8. **control**: every actuator command from a source without control is rejected.
9. **acceleration_ellipse**: achieved acceleration stays inside the physical ellipse (15 %
   plant tolerance), outside emergency stops.
10. **estop_precedence**: in e-stop disable the vehicle brakes >= 95 % within 0.5 s.
11. **contact**: the vehicle never touches an obstacle.
12. **rollover**: the lateral force the tyres supply never exceeds the vehicle's static rollover
    limit, ``|a_lat - g sin(roll)| <= g * SSF * cos(roll) cos(pitch)`` (``SSF = track / (2
    h_cg)``, no margin: the stack plans with a derated limit), from ground truth.

While a human drives (manual override, emergency manual override, partial manual speed) rules
1-3 are suspended and earlier authorizations are void: the stack does not hold the wheel.
Every violation says which rule, when and by how much.

A stop on a lost service brake is audited apart (``observe.secondary_audit``): whether the
stack used everything the vehicle has, and the distance that allows (the summary's
``secondary_braking``; the sweep counts an overrun unavoidable only on its say-so).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from overdrive.dynamics.vehicle_params import AIR_DENSITY_KGPM3, DRY_MU, G_MPS2, VehicleParams
from overdrive.messages import SIM_FAULTS_TOPIC, SIM_WORLD_TOPIC, Topic
from overdrive.observe.secondary_audit import SecondaryBrakingAudit
from overdrive.vehicle.modes import safety_mode

RULES = ("authorization", "direction", "speed", "unintended_motion", "watchdog", "finite",
         "throttle_while_braking", "control", "acceleration_ellipse", "estop_precedence", "contact",
         "rollover")
"""The judge's rules, in the order of the module docstring."""


WATCHDOG_S = 0.200            # seed 001: "Failure to send one for 200ms will result in an emergency stop"
ESTOP_BRAKE_PCT = 99.0        # what counts as "brakes full on"
AUTHORIZATION_TOLERANCE_M = 0.0  # issue 4: "0 m overrun"
DIRECTION_TOLERANCE_M = 0.10  # issue 15: "no travel of more than 0.10 m against the commanded direction"
SPEED_TOLERANCE_MPS = 0.3     # issue 15: "by more than 0.3 m/s ..."
SPEED_TOLERANCE_S = 0.5       # issue 15: "... for longer than 0.5 s"
LIMIT_RAMP_DECEL_MPS2 = 1.0   # a lowered limit must be met at least this fast: ~0.1 g, gentle
                              # service braking (ACC brakes at up to 3.5 m/s^2, ISO 15622). Slow
                              # enough for a speed loop's converging tail, while a stack that
                              # ignores the limit is over it within a second or two
MAX_SPEED_TTL_S = 0.5         # docs/driving-module.md: a limit not refreshed for 0.5 s lapses
MOTION_TOLERANCE_M = 0.10     # unintended motion: same as the direction tolerance
CLIENT_FAULT_MAX = 999        # seed 001: a client's fault codes; the speed server's own start at 1001
FAULT_CODE_DIGITS_MAX = 9     # fault codes are 1..999 (clients') and 1001+ (the speed server's)
ENGINE_STALLED = 1009         # servers.speed_table.FaultCode.ENGINE_STALLED: a stop, though no e-stop
UNASKED_CODES = frozenset({"command_timeout", "xgv_control", "xgv_heartbeat"})
"""Notice codes of stops the stack did not ask for, from any source: the vehicle's own command
timeout (the simulated vehicle's and the XGV client's e-stop), the JAUS client's lost control
and lost heartbeat (the XGV then pauses on its own)."""
ELLIPSE_TOLERANCE = 0.15      # plant tolerance: actuator lags and tyre-model transients
ESTOP_DISABLE_BRAKE_S = 0.5   # brake actuator reaches full effort within ~5 time constants
MIN_DECEL_MPS2 = 0.1          # floor of the physical decel: on a slope steeper than the tyres
                              # hold, the "shortest stop" is long but finite (no division by 0)
ESTOP_DISABLE_BRAKE_PCT = 95.0  # "full brake" in e-stop disable, less the actuator's settling
EPS_S = 1e-6
EPS_M = 1e-9                  # float slack on distances integrated from x/y
MOVING_MPS = 0.05             # a stop is recorded when the speed falls from above this ...
STOPPED_MPS = 0.001           # ... to below this
PLANNER_KEY = "authorization[planner]"   # MOVE / REVERSE / STOP; other sources: [advance NAME]
MOVE_SERVER_SOURCE = "move"   # advance / max-speed re-published by the move server: stack output
                              # (a reserved source name: scenario files may not use it)
MANUAL = frozenset({"manual-override", "emergency-manual-override", "manual-speed"})
PENDING_MAX = 64              # planner commands awaiting the move server's reply, at most
STOP_DELIVERY_S = 1.0         # a STOP not delivered within this is noted as lost (the anchoring
                              # bound of servers.anchoring: later it would be stale anyway)

COMMAND_FIELDS: dict[str, tuple[str, ...]] = {
    Topic.MOVE_COMMAND: ("distance_m", "maxspeed_mps", "curvature_1pm"),
    Topic.ADVANCE: ("distance_m",),
    Topic.MAX_SPEED: ("speed_mps",),
    Topic.STEERING: ("curvature_1pm",),
    Topic.SET_SPEED: ("speed_mps", "accel_mps2"),
    Topic.PEDALS: ("throttle_pct", "brake_pct"),
    Topic.STEER: ("steer_pct",),
}
"""Numeric fields of the commands the finite rule checks."""

DELIVERED_TOPICS = (Topic.SET_SPEED, Topic.MOVE_COMMAND)
"""Topics the judge needs as delivered (``observe_delivered``), after channel faults: the SPSS
the speed server received, and when a STOP reached the move server."""

TRUTH_FIELDS = ("x_m", "y_m", "heading_rad", "speed_mps", "accel_mps2", "lat_accel_mps2",
                "curvature_1pm", "pitch_rad", "roll_rad", "odometer_m")


def _ascii_int(text: str) -> int | None:
    """``text`` as a non-negative integer if it is ASCII digits only (``str.isdigit`` also
    accepts "²", which ``int`` refuses) and at most ``FAULT_CODE_DIGITS_MAX`` of them (a longer
    one is no fault code, and ``int`` refuses over 4300 digits), else None."""
    if len(text) > FAULT_CODE_DIGITS_MAX or not (text.isascii() and text.isdigit()):
        return None
    return int(text)


def _unasked_notice(msg: Any) -> bool:
    """A Notice (e-stop or fault) of a stop the stack did not ask for: any e-stop of the
    vehicle's, the speed server's own e-stops (codes above a client's) and engine stall, the
    vehicle's command timeout and the JAUS client's lost control or heartbeat."""
    code = msg.code if isinstance(msg.code, str) else ""
    if code in UNASKED_CODES:
        return True
    if msg.kind == "estop" and msg.source == "vehicle":
        return True
    number = _ascii_int(code)
    if msg.source != "speed" or number is None:
        return False
    return number > CLIENT_FAULT_MAX if msg.kind == "estop" else number == ENGINE_STALLED


def _key(msg: Any) -> tuple[int, int]:
    """A planner command's identity: (session, command id)."""
    return (getattr(msg, "session", 0), msg.command_id)


@dataclass
class Violation:
    """One rule broken: the worst instance of the run (``amount`` in ``unit``) and when."""

    rule: str
    key: str
    t_s: float
    amount: float
    unit: str
    message: str

    def __str__(self) -> str:
        return f"{self.key}: {self.message} (t={self.t_s:.2f} s)"


@dataclass
class End:
    """The end of one authorization, fixed where the vehicle truly was when it was issued."""

    end_m: float
    reverse: bool
    issued_s: float
    label: str


def interruption(devices: Any) -> str | None:
    """The interruption the safety devices impose (the seed-000 safety mode, or the human
    taking speed control in a partial mode); None in drive-by-wire."""
    mode = safety_mode(devices)
    if mode != "drive-by-wire":
        return mode
    return "manual-speed" if devices.partial_mode == "manual-speed" else None


def physical_decel_mps2(params: VehicleParams, friction: float, pitch_rad: float,
                        reverse: bool, lat_accel_mps2: float = 0.0) -> float:
    """Hardest possible braking: brakes or tyres, whichever gives first, with gravity along the
    slope. In a curve the tyres give only what the lateral acceleration leaves (friction circle)."""
    pitch = -pitch_rad if reverse else pitch_rad
    grip = friction * G_MPS2 * math.cos(pitch)
    tyre = min(params.max_brake_decel_mps2, math.sqrt(max(grip * grip - lat_accel_mps2 ** 2, 0.0)))
    return max(tyre + G_MPS2 * math.sin(pitch), MIN_DECEL_MPS2)


def shortest_stop_m(speed_mps: float, params: VehicleParams, friction: float, pitch_rad: float,
                    period_s: float, reverse: bool = False, *, drive_accel_mps2: float = 0.0,
                    lat_accel_mps2: float = 0.0) -> float:
    """Distance no vehicle can beat from ``speed_mps`` (in the direction of travel judged).

    One control period at speed (the command's latency); the brake actuator's first-order lag
    (it costs its time constant at speed: an upper bound by about ``decel * lag^2 / 2``); the
    throttle's lag when the tyres were driving (``drive_accel_mps2`` > 0 decays with the
    throttle's time constant, and the speed it still adds is kept until the stop); then the
    physical deceleration. Not modelled: gravity's pull during the latency (under 1 cm).
    """
    v = max(speed_mps, 0.0)
    decel = physical_decel_mps2(params, friction, pitch_rad, reverse, lat_accel_mps2)
    carried_mps = max(drive_accel_mps2, 0.0) * params.throttle_lag_s
    return (v * (period_s + params.brake_lag_s) + v * v / (2.0 * decel)
            + carried_mps * v / decel)


class Monitor:
    def __init__(self, params: VehicleParams, friction: float, period_s: float,
                 pedal_sources: frozenset[str] = frozenset({"speed", "scenario"}),
                 steer_sources: frozenset[str] = frozenset({"driving", "scenario"}),
                 *, spss_is_command: bool = False, position_noise_m: float = 0.0) -> None:
        """``spss_is_command``: the scenario itself is the speed server's client (set_speed runs),
        so an SPSS it issues is a command (its gear gives the direction) rather than the stack's
        output. ``position_noise_m``: where "truth" is a measured pose (``overdrive drive``
        against an XGV), its error bound, added to every distance tolerance."""
        self.params = params
        self.position_noise_m = position_noise_m
        self.period_s = period_s
        self.pedal_sources = pedal_sources
        self.steer_sources = steer_sources
        self.spss_is_command = spss_is_command
        self._spss_request: tuple[str, str, int] | None = None   # last issued (set_speed runs)
        self.friction = friction
        self.now_s = 0.0
        self.records: dict[str, Violation] = {}
        self.notes: list[dict[str, Any]] = []
        self._gear_direction = {g.name: g.direction for g in params.gears}
        self._gear_top = {g.name: g.max_speed_mps for g in params.gears if g.direction}
        # ground truth
        self.progress_m = 0.0           # signed travel along the heading, integrated from x/y
        self._last_xyh: tuple[float, float, float] | None = None
        self._last_truth_s: float | None = None
        self.speed_mps = 0.0
        self.pitch_rad = 0.0
        self.accel_mps2 = 0.0
        self.lat_accel_mps2 = 0.0
        self.gear_cap_mps = math.inf
        # authorization: key -> end; planner commands wait for the move server's reply
        self.ends: dict[str, End] = {}
        # by (session, command id): a restarted planner's ids start again
        self._pending: dict[tuple[int, int], tuple[Any, float, float, float]] = {}
        self._stops: dict[tuple[int, int], float] = {}   # STOPs issued, not delivered: issue time
        self._noted: set[str] = set()   # keys with an impossible command noted, until a possible one
        # direction: +1 forward, -1 reverse, 0 held (no command yet), None not judged
        self.direction: int | None = 0
        self.furthest_m = 0.0           # furthest progress in the commanded direction (the anchor
                                        # of a hold)
        self._direction_slack_m = 0.0   # a direction change at speed: the stop it still needs
        self.planner_seen = False
        # speed
        self.command_limit_mps = math.inf
        self.source_limits: dict[str, tuple[float, float]] = {}   # source -> (limit, last heard)
        self._ramp_mps = math.inf
        self._last_speed_mps = 0.0
        self._excess_since_s: float | None = None
        # interruptions
        self.interrupt: str | None = None
        self._interrupt_since_s = 0.0
        self.after_interrupt: tuple[float, float, float] | None = None  # (anchor, allowed, ended at)
        self.unasked_stop: tuple[str, float] | None = None   # (cause, since): not at rest yet
        self._speed_seen: tuple[float, int] | None = None    # SpeedState (started_s, unasked_stops)
        self.after_stop: tuple[float, float, str] | None = None  # (anchor, at rest since, cause)
        # watchdog (delivered SPSS)
        self.last_spss_s: float | None = None
        self.estop_active = False       # the speed server's latest pedals are the emergency stop
        self.estop_since_s = 0.0        # ... since then
        # control, e-stop precedence, stop margins
        self.rejected_expected = 0
        self.rejected_seen = 0
        self.estop_disable_since: float | None = None
        self.stop_margins_m: list[float] = []
        self.moving = False
        self._handlers = {Topic.TRUTH: self._truth, Topic.ADVANCE: self._advance,
                          Topic.MOVE_COMMAND: self._move_command, Topic.MOVE_REPLY: self._move_reply,
                          Topic.MAX_SPEED: self._max_speed,
                          Topic.PEDALS: self._pedals, Topic.STEER: self._steer,
                          Topic.POWERTRAIN: self._powertrain, Topic.SET_SPEED: self._issued_spss,
                          Topic.NOTICE: self._notice, Topic.VEHICLE_STATUS: self._vehicle_status,
                          Topic.SPEED_STATE: self._speed_state,
                          Topic.SAFETY: self._safety, SIM_WORLD_TOPIC: self._world,
                          SIM_FAULTS_TOPIC: self._faults_injected}
        self.secondary = SecondaryBrakingAudit(params)

    # ------------------------------------------------------------------ bookkeeping

    @property
    def violations(self) -> list[str]:
        return [str(v) for v in self.records.values()]

    def _violate(self, rule: str, key: str, amount: float, unit: str, message: str,
                 worst: bool = False) -> None:
        """Record a violation: the first occurrence, or with ``worst`` the largest ``amount``."""
        old = self.records.get(key)
        if old is None or (worst and amount > old.amount):
            self.records[key] = Violation(rule, key, self.now_s, amount, unit, message)

    def _tyre_accel_mps2(self, speed_mps: float, accel_mps2: float, pitch_rad: float) -> float:
        """The tyres' longitudinal force per unit mass: gravity, rolling and air resistance removed."""
        p = self.params
        resist = (p.rolling_resistance * G_MPS2 * math.cos(pitch_rad)
                  + 0.5 * AIR_DENSITY_KGPM3 * p.drag_area_m2 * speed_mps * speed_mps / p.mass_kg)
        return accel_mps2 + G_MPS2 * math.sin(pitch_rad) + math.copysign(resist, speed_mps)

    def _shortest_stop(self, speed_mps: float, reverse: bool) -> float:
        drive = self._tyre_accel_mps2(self.speed_mps, self.accel_mps2, self.pitch_rad)
        return shortest_stop_m(speed_mps, self.params, self.friction, self.pitch_rad,
                               self.period_s, reverse,
                               drive_accel_mps2=-drive if reverse else drive,
                               lat_accel_mps2=self.lat_accel_mps2)

    def _finite(self, topic: str, msg: Any, fields: tuple[str, ...]) -> bool:
        """Every one of ``fields`` is finite, else a violation naming the others too (every
        message of a run passes here: no list built unless one is not)."""
        for name in fields:
            if not math.isfinite(getattr(msg, name)):
                break
        else:
            return True
        bad = [f for f in fields if not math.isfinite(getattr(msg, f))]
        self._violate("finite", f"finite[{topic}]", 1.0, "",
                      f"non-finite {', '.join(bad)} in {type(msg).__name__}")
        return False

    def _manual(self) -> bool:
        return self.interrupt in MANUAL

    # ------------------------------------------------------------------ taps

    def observe(self, topic: str, msg: Any) -> None:
        """Every message as its source published it (before channel faults)."""
        fields = COMMAND_FIELDS.get(topic)
        if fields is not None and not self._finite(topic, msg, fields):
            return
        handler = self._handlers.get(topic)
        if handler is not None:
            handler(msg)

    def observe_delivered(self, topic: str, msg: Any) -> None:
        """Every message on ``DELIVERED_TOPICS`` as it reached its subscribers (after channel
        faults): the SPSS the speed server was delivered; a STOP binds when it first arrives
        ("stop now" cannot mean before the stack could know)."""
        if topic == Topic.SET_SPEED:
            self.last_spss_s = self.now_s
            return
        pending = self._stops.pop(_key(msg), None) if msg.kind == "stop" else None
        if pending is None or self._manual():
            return
        moving_back = self.speed_mps < -MOVING_MPS or (
            self.direction == -1 and self.speed_mps <= MOVING_MPS)
        self._set_end(PLANNER_KEY, 0.0, moving_back, f"STOP #{msg.command_id}", self._here(),
                      stop=True)
        self.command_limit_mps = math.inf
        if self.direction is None:          # hold against rolling back from here on
            self._new_command(-1 if moving_back else (1 if self.speed_mps > MOVING_MPS else 0))

    # ------------------------------------------------------------------ commands as issued

    def _new_command(self, direction: int | None, slack_m: float = 0.0) -> None:
        """A command binds now: it ends a hold and any post-interruption stand-still."""
        self.after_interrupt = None
        self.unasked_stop = self.after_stop = None
        if direction is not None and direction != self.direction:
            self.furthest_m = self.progress_m
            self._direction_slack_m = slack_m
        self.direction = direction

    def _set_end(self, key: str, distance_m: float, reverse: bool, label: str, at: tuple[float, float, float],
                 stop: bool = False) -> None:
        """Fix the end of ``key``'s authorization ``distance_m`` from ``at`` = (progress, speed,
        time) when it was issued, or its shortest stop when that is longer."""
        progress, speed, issued_s = at
        shortest = self._shortest_stop(-speed if reverse else speed, reverse)
        sign = -1.0 if reverse else 1.0
        end = progress + sign * max(distance_m, shortest)
        old = self.ends.get(key)
        if distance_m < shortest:
            if old is not None and old.reverse == reverse:
                # an impossible replacement never moves the end further than it already was
                end = progress + sign * distance_m
                end = (max(end, min(old.end_m, progress + shortest)) if not reverse
                       else min(end, max(old.end_m, progress - shortest)))
            if not stop and key not in self._noted:
                self._noted.add(key)
                self.notes.append({"t_s": round(issued_s, 3), "kind": "impossible_command",
                                   "key": key, "command": label,
                                   "distance_m": round(distance_m, 4),
                                   "shortest_stop_m": round(shortest, 4),
                                   "speed_mps": round(speed, 4)})
        else:
            self._noted.discard(key)
        self.ends[key] = End(end, reverse, issued_s, label)

    def _here(self) -> tuple[float, float, float]:
        return (self.progress_m, self.speed_mps, self.now_s)

    def _move_command(self, msg: Any) -> None:
        self.planner_seen = True
        if msg.kind == "stop":
            if len(self._stops) >= PENDING_MAX:
                self._stops.pop(next(iter(self._stops)))
            self._stops[_key(msg)] = self.now_s   # binds when delivered
            return
        if not (msg.distance_m >= 0.0 and msg.maxspeed_mps >= 0.0):
            return   # invalid: the move server must reject it; nothing to hold the vehicle to
        if len(self._pending) >= PENDING_MAX:
            self._pending.pop(next(iter(self._pending)))
        self._pending[_key(msg)] = (msg, *self._here())

    def _move_reply(self, reply: Any) -> None:
        """A MOVE / REVERSE binds once the move server accepts it, from where it was issued;
        one refused as stale, or accepted though issued before the command that binds now,
        binds only what it restricts (an end closer than the one in force in its direction, a
        lower max speed): the planner's newest command is its intent, and what slows or stops
        is always obeyed."""
        pending = self._pending.pop(_key(reply), None)
        if pending is None or self._manual():
            return
        msg, progress, speed, issued_s = pending
        reverse = msg.kind == "reverse"
        old = self.ends.get(PLANNER_KEY)
        older = old is not None and issued_s < old.issued_s
        if not reply.accepted or older:
            # refused as stale, or accepted though the planner issued it before the command
            # that binds now (a late message): it binds only what it restricts
            if (older or reply.code == "stale") and old is not None and old.reverse == reverse:
                self._set_end(PLANNER_KEY, msg.distance_m, reverse,
                              f"stale {msg.kind.upper()} #{msg.command_id} of "
                              f"{msg.distance_m:g} m", (progress, speed, issued_s))
                new = self.ends[PLANNER_KEY]
                if (new.end_m > old.end_m) != reverse:    # further: it may not extend
                    self.ends[PLANNER_KEY] = old
                self.command_limit_mps = min(self.command_limit_mps, msg.maxspeed_mps)
            return
        self._set_end(PLANNER_KEY, msg.distance_m, reverse,
                      f"{msg.kind.upper()} #{msg.command_id} of {msg.distance_m:g} m",
                      (progress, speed, issued_s))
        self.command_limit_mps = msg.maxspeed_mps
        direction = -1 if reverse else 1
        slack = 0.0
        if direction != self.direction and abs(self.speed_mps) > MOVING_MPS:
            slack = self._shortest_stop(abs(self.speed_mps), self.speed_mps < 0.0)
        self._new_command(direction, slack)

    def _advance(self, msg: Any) -> None:
        if msg.source == MOVE_SERVER_SOURCE or not msg.distance_m >= 0.0:
            return
        key = f"authorization[advance {msg.source}{' reverse' if msg.reverse else ''}]"
        self._set_end(key, msg.distance_m, msg.reverse,
                      f"advance of {msg.distance_m:g} m from {msg.source}", self._here())
        if not self.planner_seen and not msg.reverse:
            # no planner: the other sources command the driving module, forward by default
            self._new_command(1)

    def _max_speed(self, msg: Any) -> None:
        if msg.source != MOVE_SERVER_SOURCE and msg.speed_mps >= 0.0:
            self.source_limits[msg.source] = (msg.speed_mps, self.now_s)

    def _issued_spss(self, msg: Any) -> None:
        """In set_speed runs an SPSS is a new command when it changes the request (state, gear
        or fault): the client repeats its request every 100 ms, and a repeat is the old
        command, which must not move the vehicle after a stop the stack did not ask for (the
        speed server clears such a stop only on a non-moving request: a change)."""
        if not self.spss_is_command:
            return
        request = (msg.state, msg.gear, msg.fault)
        if request == self._spss_request:
            return
        self._spss_request = request
        direction = self._gear_direction.get(msg.gear, 0)
        self._new_command(direction or None)

    def _pedals(self, msg: Any) -> None:
        if msg.throttle_pct > 0.0 and msg.brake_pct > 0.0:
            self._violate("throttle_while_braking", "throttle_while_braking",
                          min(msg.throttle_pct, msg.brake_pct), "%",
                          f"{msg.source} commanded throttle {msg.throttle_pct:.1f} % with brake "
                          f"{msg.brake_pct:.1f} %")
        if msg.source not in self.pedal_sources:
            self.rejected_expected += 1
        if msg.source == "scenario":
            self._new_command(None)     # open loop: the scenario drives the pedals itself
        if msg.source == "speed":
            active = msg.throttle_pct == 0.0 and msg.brake_pct >= ESTOP_BRAKE_PCT
            if active and not self.estop_active:
                self.estop_since_s = self.now_s
            self.estop_active = active

    def _steer(self, msg: Any) -> None:
        if msg.source not in self.steer_sources:
            self.rejected_expected += 1

    def _powertrain(self, msg: Any) -> None:
        if msg.source not in self.pedal_sources:
            self.rejected_expected += 1
        self.secondary.powertrain(msg)

    def _faults_injected(self, msg: Any) -> None:
        self.secondary.fault_injected(msg)

    def _notice(self, msg: Any) -> None:
        self.secondary.notice(msg, self.now_s)
        if msg.kind == "rejected" and msg.code == "no_control":
            self.rejected_seen += 1
        elif msg.kind in ("estop", "fault") and _unasked_notice(msg):
            self._unasked_stop(msg.code or msg.source)

    def _speed_state(self, msg: Any) -> None:
        """A restarted speed server (``started_s`` changed: nothing it latched survived) or a
        rise of ``unasked_stops`` (an e-stop of its own, an engine stall) is a stop the stack
        did not ask for, as the move server counts it (docs/speed-server.md)."""
        seen = self._speed_seen
        self._speed_seen = (msg.started_s, msg.unasked_stops)
        if seen is None:
            return
        if msg.started_s != seen[0]:
            self._unasked_stop("speed server restart")
        elif msg.unasked_stops > seen[1]:
            self._unasked_stop(f"speed server unasked stop #{msg.unasked_stops}")

    def _unasked_stop(self, cause: str) -> None:
        """A stop the stack did not ask for began: once at rest, the vehicle stays there."""
        if self.unasked_stop is None and self.after_stop is None:
            self.unasked_stop = (cause, self.now_s)

    def _world(self, msg: Any) -> None:
        self.friction = msg.friction

    def _safety(self, devices: Any) -> None:
        now = interruption(devices)
        if self.interrupt is not None and now is None and self.now_s > self._interrupt_since_s + EPS_S:
            speed = abs(self.speed_mps)
            allowed = (self._shortest_stop(speed, self.speed_mps < 0.0) + MOTION_TOLERANCE_M
                       + self.position_noise_m)
            self.after_interrupt = (self.progress_m, allowed, self.now_s)
        if now in MANUAL and not self._manual():
            self.ends.clear()               # the human drives: earlier authorizations are void
            self._pending.clear()
            self.direction = None
            self.command_limit_mps = math.inf
        if now is not None and self.interrupt is None:
            self._interrupt_since_s = self.now_s
        self.interrupt = now

    def _vehicle_status(self, status: Any) -> None:
        self.gear_cap_mps = self._gear_top.get(status.gear, math.inf)
        if status.safety_mode == "estop-disable":
            if self.estop_disable_since is None:
                self.estop_disable_since = self.now_s
            elif (self.now_s - self.estop_disable_since > ESTOP_DISABLE_BRAKE_S
                  and status.brake_pct < ESTOP_DISABLE_BRAKE_PCT):
                self._violate("estop_precedence", "estop_precedence",
                              ESTOP_DISABLE_BRAKE_PCT - status.brake_pct, "%",
                              f"e-stop disable but brake only {status.brake_pct:.0f} %")
        else:
            self.estop_disable_since = None

    # ------------------------------------------------------------------ ground truth

    def _truth(self, truth: Any) -> None:
        if not self._finite(Topic.TRUTH, truth, TRUTH_FIELDS):
            return
        x, y, h = truth.x_m, truth.y_m, truth.heading_rad
        ds_m = 0.0
        if self._last_xyh is not None:
            x0, y0, h0 = self._last_xyh
            mid = h0 + 0.5 * math.remainder(h - h0, math.tau)
            self.progress_m += (x - x0) * math.cos(mid) + (y - y0) * math.sin(mid)
            ds_m = math.hypot(x - x0, y - y0)
        self.secondary.truth(self.now_s, truth.speed_mps, truth.pitch_rad, ds_m, self.friction)
        self._last_xyh = (x, y, h)
        dt_s = self.period_s if self._last_truth_s is None else self.now_s - self._last_truth_s
        self._last_truth_s = self.now_s
        self.speed_mps = truth.speed_mps
        self.pitch_rad = truth.pitch_rad
        self.accel_mps2 = truth.accel_mps2
        self.lat_accel_mps2 = truth.lat_accel_mps2
        self._record_stop(truth.speed_mps)
        if not self._manual():
            self._authorization()
            self._direction()
            self._speed(dt_s)
        if self.unasked_stop is not None and abs(truth.speed_mps) < STOPPED_MPS:
            self.after_stop = (self.progress_m, self.now_s, self.unasked_stop[0])
            self.unasked_stop = None
        self._unintended_motion()
        if truth.contact:
            self._violate("contact", "contact", abs(truth.speed_mps), "m/s",
                          f"the vehicle touched an obstacle at {abs(truth.speed_mps):.2f} m/s")
        self._ellipse(truth)
        self._rollover(truth)

    def _record_stop(self, speed_mps: float) -> None:
        if abs(speed_mps) > MOVING_MPS:
            self.moving = True
        elif self.moving and abs(speed_mps) < STOPPED_MPS:
            self.moving = False
            margin = self.authorization_margin_m()
            if margin is not None:
                self.stop_margins_m.append(margin)

    def _authorization(self) -> None:
        p = self.progress_m
        tolerance = AUTHORIZATION_TOLERANCE_M + self.position_noise_m + EPS_M
        for key, end in self.ends.items():
            overrun = (end.end_m - p) if end.reverse else (p - end.end_m)
            if overrun > tolerance:
                self._violate("authorization", key, overrun, "m",
                              f"passed the end of {end.label} (issued at t={end.issued_s:.2f} s) "
                              f"by {overrun:.3f} m", worst=True)

    def _direction(self) -> None:
        direction, p = self.direction, self.progress_m
        if direction is None:
            return
        if direction == 0:
            travel = abs(p - self.furthest_m)
            what = "moved {:.3f} m with no command"
        elif direction > 0:
            self.furthest_m = max(self.furthest_m, p)
            travel = self.furthest_m - p
            what = "rolled back {:.3f} m under a forward command"
        else:
            self.furthest_m = min(self.furthest_m, p)
            travel = p - self.furthest_m
            what = "moved forward {:.3f} m under a REVERSE"
        excess = travel - self._direction_slack_m
        if excess > DIRECTION_TOLERANCE_M + self.position_noise_m:
            self._violate("direction", "direction", travel, "m", what.format(travel), worst=True)

    def _speed(self, dt_s: float) -> None:
        now = self.now_s
        limit = min(self.command_limit_mps, self.gear_cap_mps)
        for value, heard_s in self.source_limits.values():
            if now - heard_s <= MAX_SPEED_TTL_S + EPS_S:
                limit = min(limit, value)
        speed = abs(self.speed_mps)
        # a limit lowered below the speed is met along a ramp from the speed it was lowered at,
        # never steeper than the road allows
        decel = min(LIMIT_RAMP_DECEL_MPS2,
                    physical_decel_mps2(self.params, self.friction, self.pitch_rad,
                                        self.speed_mps < 0.0, self.lat_accel_mps2))
        ramp_from = min(self._ramp_mps, self._last_speed_mps)
        self._ramp_mps = max(limit, ramp_from - decel * dt_s)
        self._last_speed_mps = speed
        excess = speed - self._ramp_mps
        if excess <= SPEED_TOLERANCE_MPS:
            self._excess_since_s = None
            return
        if self._excess_since_s is None:
            self._excess_since_s = now
        if now - self._excess_since_s > SPEED_TOLERANCE_S + EPS_S:
            self._violate("speed", "speed", excess, "m/s",
                          f"{speed:.2f} m/s against a limit of {self._ramp_mps:.2f} m/s "
                          f"(over by more than {SPEED_TOLERANCE_MPS} m/s since "
                          f"t={self._excess_since_s:.2f} s)", worst=True)

    def _unintended_motion(self) -> None:
        if self.after_stop is not None:
            anchor, rest_s, cause = self.after_stop
            travel = abs(self.progress_m - anchor)
            allowed = MOTION_TOLERANCE_M + self.position_noise_m
            if travel > allowed:
                self._violate("unintended_motion", "unintended_motion", travel - allowed, "m",
                              f"moved {travel:.3f} m after the stop the stack did not ask for "
                              f"({cause}; at rest at t={rest_s:.2f} s) with no new command",
                              worst=True)
        if self.after_interrupt is None or self.interrupt is not None:
            return
        anchor, allowed, ended_s = self.after_interrupt
        travel = abs(self.progress_m - anchor)
        if travel > allowed:
            self._violate("unintended_motion", "unintended_motion", travel - allowed, "m",
                          f"moved {travel:.3f} m after the interruption ended at t={ended_s:.2f} s "
                          f"with no new command (at most {allowed:.3f} m to stop)", worst=True)

    def _ellipse(self, truth: Any) -> None:
        if self.estop_active or abs(truth.speed_mps) < 0.05:
            return
        p = self.params
        # longitudinal: the brakes, or the tyres' grip when that gives first; lateral: the
        # vehicle's skid-pad figure, measured on dry pavement, scaled down on slippery roads
        ax_max = min(max(p.max_decel_mps2, p.max_brake_decel_mps2), self.friction * G_MPS2)
        ay_max = p.skidpad_lat_g * G_MPS2 * min(self.friction / DRY_MU, 1.0)
        ax = self._tyre_accel_mps2(truth.speed_mps, truth.accel_mps2, truth.pitch_rad)
        ay = truth.lat_accel_mps2
        usage = math.hypot(ax / ax_max, ay / ay_max)
        if usage > 1.0 + ELLIPSE_TOLERANCE:
            self._violate("acceleration_ellipse", "acceleration_ellipse", usage, "",
                          f"achieved acceleration ({ax:.2f}, {ay:.2f}) m/s^2 uses {usage:.0%} of the "
                          f"ellipse ({ax_max:.2f}, {ay_max:.2f})", worst=True)

    def _rollover(self, truth: Any) -> None:
        """Rule 12: the tyres' lateral force against the static stability factor's limit."""
        lateral = truth.lat_accel_mps2 - G_MPS2 * math.sin(truth.roll_rad)
        limit = (G_MPS2 * self.params.static_stability_factor * math.cos(truth.roll_rad)
                 * math.cos(truth.pitch_rad))
        if abs(lateral) > limit:
            self._violate("rollover", "rollover", abs(lateral) / limit, "",
                          f"lateral {lateral:.2f} m/s^2 beyond the rollover limit {limit:.2f} "
                          f"m/s^2 (SSF {self.params.static_stability_factor:.2f})", worst=True)

    # ------------------------------------------------------------------ per tick

    def tick(self, now_s: float) -> None:
        """Time-based checks, after every node has stepped at ``now_s``: from the deadline on,
        the speed server's pedals must be the emergency stop until an SPSS is delivered; a STOP
        not delivered within ``STOP_DELIVERY_S`` is noted (the stack never had it)."""
        if self._stops:
            for key, issued_s in list(self._stops.items()):
                if now_s - issued_s > STOP_DELIVERY_S + EPS_S:
                    del self._stops[key]
                    self.notes.append({"t_s": round(issued_s, 3), "kind": "stop_not_delivered",
                                       "command": f"STOP #{key[1]}",
                                       "reason": f"not delivered to the move server within "
                                                 f"{STOP_DELIVERY_S:.1f} s: not judged"})
        if self.last_spss_s is None:
            return
        if now_s - self.last_spss_s > WATCHDOG_S + EPS_S:
            self._unasked_stop("watchdog")   # the speed server's watchdog must stop it
        deadline_s = self.last_spss_s + WATCHDOG_S + self.period_s
        if now_s <= deadline_s + EPS_S:
            return
        # late: missing now (for as long as it is missing), or begun after the deadline
        late_s = (now_s if not self.estop_active else self.estop_since_s) - deadline_s
        if late_s > EPS_S:
            gap = now_s - self.last_spss_s
            self._violate("watchdog", "watchdog", late_s, "s",
                          f"no SPSS delivered for {gap * 1000:.0f} ms and no emergency stop held "
                          f"{late_s * 1000:.0f} ms past the {(WATCHDOG_S + self.period_s) * 1000:.0f} "
                          f"ms deadline", worst=True)

    def authorization_margin_m(self) -> float | None:
        """Distance still authorized ahead of the vehicle by the most restrictive source, now."""
        if not self.ends:
            return None
        p = self.progress_m
        return min((p - e.end_m) if e.reverse else (e.end_m - p) for e in self.ends.values())

    def finish(self) -> list[str]:
        if self.rejected_seen < self.rejected_expected:
            self._violate("control", "control", self.rejected_expected - self.rejected_seen, "",
                          f"{self.rejected_expected} actuator commands from sources without "
                          f"control, only {self.rejected_seen} rejected")
        return self.violations

    def details(self) -> list[dict[str, Any]]:
        """Every violation as a record: rule, key, time, amount and unit, message."""
        return [asdict(v) | {"t_s": round(v.t_s, 3), "amount": round(v.amount, 4)}
                for v in self.records.values()]
