"""The speed server (seed 001): engine, brake and transmission management, speed control.

A lock-step node. Each period it reads the SPSS requests ("set speed") and the vehicle's
sensors from its inbox, validates every request (an invalid one is a fault and is not
executed), runs the watchdog, moves the state machine of ``speed_table`` by at most one
transition, and publishes:

- ``speed/state``: one ``SpeedState`` reply per SPSS received, or one status when none came;
- ``vehicle/pedals`` and ``vehicle/powertrain`` every period (``source="speed"``);
- ``events``: a ``Notice`` per fault (``kind="fault"``) and per emergency stop (``kind="estop"``);
- ``display``: the newest fault in force for the LED sign (``Display``; "" when none): the
  server's current fault or a motion-sensing fault (1101-1119) while its source is distrusted;
  on a change (at most one per ``DISPLAY_CHANGE_MIN_S``, the newest text) and every
  ``DISPLAY_REFRESH_S``; the text made printable and bounded (``messages.sign_text``) (seed 001:
  "Sending a nonzero fault code will result in a message being displayed in the LED sign").

Decisions the seed leaves open (documented in ``docs/speed-server.md``):

- Requests are goals: from parked, a request for run walks parked -> reset -> starting ->
  paused -> runwait -> shifting -> run. Leaving paused always passes the 5 s runwait.
- Gears are engaged only in ``shifting``; ``shifting`` is always entered on the way to run and
  lasts one period when the vehicle is already in the gear.
- An emergency stop (SPSS silent for ``spss_timeout_s``, sensors silent, or a client fault) is
  latched: brakes full on, throttle zero, requests not acted upon; ``run``/``runwait``/
  ``shifting`` fall back to ``idle``. It clears when an SPSS arrives, the sensors are live,
  the vehicle is stopped, and that SPSS is a valid request with fault code 0; after a stop the
  client did not ask for (watchdog, timeouts: not its fault code) only one for a state that
  does not move (paused, idle, parked): a client still asking for ``run`` has not seen the
  stop, so the old command never drives on by itself; a new ``run`` passes the 5 s runwait.
- The vehicle's own command timeout (``VehicleStatus.command_timeout``: it braked because no
  pedal command came, the server or its link stalled) is an emergency stop too (fault 1012;
  simulation only: JAUS does not carry it, an XGV's own 0.5 s timeout acts unreported).
- The latest unasked cause names a latched e-stop; a client's fault code is confined to
  1..999 (it asked for the stop, whatever its code).
- ``SpeedState.unasked_stops`` counts the stops made on the server's own (never reset) and
  ``started_s`` is its first step: a client that lost every report of a stop, or talks to a
  restarted server with no latch, latches on a rise of the one or a change of the other.
- A stall is not one long step: the controllers integrate at most ``MAX_CONTROL_STEP_S`` per
  step, and after a gap the first throttle is no more than the one before it (the loop is
  reset to it, so its integrator holds), rising from there at the loop's own slew rate.
- After the automatic park (``pause_park_s`` in paused) a repeated request for paused does not
  restart the engine; the client must request another state first.
- Secondary braking (issue 30 item 4): a service brake that does not apply or failed latches
  the e-stop for good (like every actuator fault) and raises a takeover request
  (``SpeedState.takeover``, a ``takeover`` notice) with a ``secondary_braking`` notice naming
  what the vehicle has left. Throttle 0; the engine is kept running while moving when the
  vehicle has engine braking (``dynamics.secondary_braking``) and cut once stopped (at once if
  a throttle fault comes too); a gearbox that may shift while moving is downshifted to
  ``secondary_gear``; the parking brake is applied as soon as the speed is at or below the
  vehicle's ``park_brake_max_apply_mps`` and held. The parking brake is never commanded above
  that speed, in any state (a stopped vehicle is always below it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import msgspec

from overdrive.dynamics.control import MAX_CONTROL_STEP_S, first_order_lag
from overdrive.dynamics.secondary_braking import (
    engine_brake_mps2,
    has_engine_braking,
    secondary_gear,
)
from overdrive.dynamics.speed_control import (
    LongitudinalController,
    LongitudinalGains,
    gains_for,
)
from overdrive.dynamics.validation import finite, valid_sigma
from overdrive.dynamics.vehicle_params import G_MPS2, Gear, GearTable, VehicleParams
from overdrive.messages import (
    DISPLAY_CHANGE_MIN_S,
    DISPLAY_REFRESH_S,
    DISPLAY_TEXT_MAX_CHARS,
    Display,
    GpsIns,
    Imu,
    Notice,
    PedalCommand,
    PowertrainCommand,
    SetSpeed,
    SpeedState,
    Topic,
    VehicleStatus,
    WheelSpeed,
    sign_text,
    slippery_ground,
    tyres_at_limit,
)
from overdrive.safety.actuators import BRAKE_LOST, CUTS_ENGINE, PedalMonitor
from overdrive.safety.plausibility import (
    MotionPlausibility,
    PlausibilityFault,
    plausibility_config,
)
from overdrive.safety.watchdog import Watchdog
from overdrive.servers.direction_hold import DirectionHold, DirectionHoldConfig, HoldCommand
from overdrive.servers.dispatch import TypeDispatch
from overdrive.servers.speed_hints import HintConfig, HintInputs, HintMonitor
from overdrive.servers.speed_table import (
    CLIENT_FAULT_MAX,
    REQUESTABLE,
    STATE_TABLE,
    STATES,
    Conditions,
    FaultCode,
    classify_event,
    fault_message,
    next_state,
)

SOURCE = "speed"
INITIAL_GOAL = {"reset": "paused", "starting": "paused", "startwait": "paused",
                "runwait": "idle", "shifting": "idle"}
"""Goal assumed when the server starts in a state that cannot be requested."""
TIME_EPS_S = 1e-9   # float slack when comparing simulated times built from integer ticks
PROBE_SLOWING_MPS = 0.5
"""The brake probe stops when the target falls this far below the speed: a slowdown is the
loop's (its braking verifies the brake anyway); 10x the driving module's accel band."""
PROBE_TARGET_FRACTION = 0.2
"""The brake probe starts only at launch, below this share of the target: before the ramp's
20-80 % stretch whose acceleration the server guarantees (issue 3 acceptance, within 15 %), and
never at cruise, where the speed must hold within 0.2 m/s (issue 4 acceptance)."""
SENSOR_FAULT_SHOWN_MIN_S = 3.0
"""A motion-sensing fault (1101-1119) stays on the sign at least this long after its notice,
and then for as long as it is in force (``_sensor_fault_in_force``): three sign refreshes, so a
one-off GPS step (1105, 1106) is readable by a person who looks up, not a flash. A decision
(docs/speed-server.md, "The fault display"), not a measured figure."""
SENSOR_FAULT_TRACKS = {PlausibilityFault.GPS_FROZEN: "gps_ins",
                       PlausibilityFault.GPS_ODOMETER_JUMP: "gps_ins",
                       PlausibilityFault.GPS_NO_SOLUTION: "gps_ins",
                       PlausibilityFault.WHEEL_SPEED_FROZEN: "wheel_speed",
                       PlausibilityFault.IMU_FROZEN: "imu"}
"""The source whose distrust each motion-sensing fault reports: in force while it is untrusted."""
CLOCK_SKEW_MAX_S = 0.001
"""An SPSS send stamp may lead ``now_s`` by this much (float rounding of one shared clock,
docs/multiprocess.md); further ahead, its clock is not ours and it is timed from receipt."""


class SpeedServerConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Timings, thresholds and gains of the speed server; defaults are the seed's values."""

    monitor_actuators: bool = True       # False where the vehicle reports efforts, not positions
                                         # (JAUS 3.3: the XGV's wrench efforts; hazards H11, H14)
    spss_timeout_s: float = 0.2          # seed 001: "Failure to send one for 200ms ... emergency stop"
    sensor_timeout_s: float = 0.2        # same budget for vehicle status and speed (engineering choice)
    runwait_s: float = 5.0               # seed 001: "five second DARPA-required safety delay"
    start_retry_s: float = 30.0          # seed 001: startwait "Try again after 30 seconds."
    pause_park_s: float = 600.0          # seed 001: "After about ten minutes in paused ... parked"
    reset_s: float = 0.5                 # controller reset time (estimate; not in the seed)
    start_timeout_margin_s: float = 2.0  # crank attempt given up after crank_time_s + this
    shift_timeout_margin_s: float = 3.0  # shift given up after shift_time_s + this
    standstill_mps: float = 0.1          # |filtered speed| below this is "stopped" (5 sigma of GPS noise)
    speed_filter_s: float = 0.1          # filter on the speed used for standstill decisions
    hold_brake_pct: float = 50.0         # seed 000: "once stopped ... 50 % braking effort"
    gear_cap_fraction: float = 0.9       # target capped at this share of the gear's top speed,
                                         # below the plant's redline fade (seed 001 gear limits)
    max_request_speed_mps: float = 70.0  # same bound as the scenario file's speeds
    max_request_accel_mps2: float = 10.0  # above both presets' full-brake deceleration (9 m/s^2);
                                          # a vehicle whose brakes give more accepts its own figure
    invalid_stop_decel_mps2: float = 2.5  # an invalid request stops the vehicle at least this hard:
                                          # the XGV's own pause deceleration (seed 000, xgv.md)
    fault_hold_s: float = 1.0            # a fault stays in the replies at least this long
    hints: HintConfig = HintConfig()     # seed 001 hints' thresholds (servers.speed_hints)
    gains: LongitudinalGains | None = None  # None: the preset's tuned gains (speed_control.GAINS)
    direction_hold: DirectionHoldConfig = DirectionHoldConfig()  # hill start, rollback (issue 16)




class SpeedServer:
    """Seed-001 speed server node (see the module docstring)."""

    name = "speed"
    period_s = 0.01
    subscriptions = (Topic.SET_SPEED, Topic.VEHICLE_STATUS, Topic.WHEEL_SPEED, Topic.GPS_INS,
                     Topic.IMU)

    def __init__(self, params: VehicleParams, *, initial_state: str = "parked",
                 initial_gear: str | None = None, config: SpeedServerConfig | None = None) -> None:
        if initial_state not in STATES:
            raise ValueError(f"initial_state: unknown speed state {initial_state!r}")
        if initial_gear is not None and initial_gear not in params.gear_names:
            raise ValueError(f"initial_gear: {params.preset} has no gear {initial_gear!r}")
        self.params = params
        self.config = cfg = config or SpeedServerConfig()
        self.max_accel_mps2 = max(cfg.max_request_accel_mps2, params.max_brake_decel_mps2)
        self.gears = GearTable(params)
        self._start_timeout_s = params.crank_time_s + cfg.start_timeout_margin_s
        self._shift_timeout_s = params.shift_time_s + cfg.shift_timeout_margin_s
        self._dispatch = TypeDispatch(   # every input but SPSS, by its type
            ((VehicleStatus, self._status_input), (GpsIns, self._gps_input),
             (WheelSpeed, self._wheel_input), (Imu, self._imu_input)), self._ignore_input)
        self.neutral_gear = next(
            (g.name for g in params.gears if g.direction == 0 and not g.holds), params.park_gear)
        self.controller = LongitudinalController(params, cfg.gains or gains_for(params),
                                                 cfg.hold_brake_pct)
        self.state = initial_state
        in_gear = STATE_TABLE[initial_state].in_gear
        self.gear_cmd = initial_gear or (params.drive_gear if in_gear else params.park_gear)
        self.goal = INITIAL_GOAL.get(initial_state, initial_state)
        self.goal_gear = self.gear_cmd if in_gear else params.drive_gear
        self.target_mps = 0.0
        self.rate_mps2 = 1.0
        self.auto_parked = False
        self.state_since_s: float | None = None
        self.shift_for_run = False
        self.saw_cranking = False
        # inputs
        self.status: VehicleStatus | None = None
        self.gps: GpsIns | None = None
        self.wheel_mps: float | None = None
        self.imu: Imu | None = None
        self.speed_mps = 0.0           # signed ground speed (GPS/INS, else wheel speed)
        self.speed_filt_mps = 0.0
        self.accel_mps2 = 0.0          # longitudinal acceleration, gravity removed
        self.accel_filt_mps2 = 0.0
        self.last_now_s: float | None = None
        self.first_step_s = 0.0
        self.spss_watchdog = Watchdog(self.config.spss_timeout_s)
        self.last_sensor_s: float | None = None   # last VehicleStatus
        self.last_status_rx_s: float | None = None   # its receipts, for the status period
        self.status_period_s = 0.0
        self.status_new = False           # a VehicleStatus arrived since the actuator checks ran
        self.monitored_status_s: float | None = None   # receipt the actuator checks last ran on
        self.last_gps_s: float | None = None
        self.last_wheel_s: float | None = None
        self.last_imu_s: float | None = None
        self.speed_live = False
        self.sensor_lost = False
        self.motion = MotionPlausibility(SOURCE, plausibility_config(params))   # issue 16: never close on an untrusted speed
        # faults and e-stop
        self.client_fault = 0
        self.estop_reason = ""
        self.estop_code = 0      # the fault code that latched the e-stop (SpeedState.estop_code)
        self.estop_since_s = -math.inf   # when it was latched (by its latest unasked cause)
        self.unasked_stops = 0   # SpeedState.unasked_stops: never reset within this process
        self.fault = 0
        self.fault_message = ""
        self.fault_since_s = -math.inf
        self.last_rejection: tuple[int, str] | None = None
        self.last_input_rejection = ""
        self.display: Display | None = None   # the last Display sent, and when
        self.display_sent_s = -math.inf
        self.display_changed_s = -math.inf   # the last change sent (DISPLAY_CHANGE_MIN_S)
        self.fault_shown: tuple[int, str, float] = (0, "", -math.inf)   # fault, message, onset
        self.sensor_faults: dict[int, tuple[float, str]] = {}   # on the sign: code -> (raised, reason)
        # hints
        self.hints = HintMonitor(params, cfg.hints, cfg.gear_cap_fraction)
        self.hint = "none"
        self.pedals = PedalCommand(throttle_pct=0.0, brake_pct=100.0, source=SOURCE)
        # actuator monitoring (issue 16, safety.actuators): a throttle or brake that does not
        # follow cuts the engine for good (engine_cut) under a latched emergency stop
        self.actuator_monitor = PedalMonitor(params)
        self.engine_cut = False
        # secondary braking (issue 30 item 4): the service brake lost, what is used instead
        self.brake_lost = False
        self.takeover = False            # SpeedState.takeover: latched, the safety driver must drive
        self.park_applied = False        # the parking brake applied on a lost service brake
        self.park_commanded = False      # this period's PowertrainCommand.park_brake
        self.monitor_actuators = cfg.monitor_actuators
        # direction hold (issue 16): hill-start hold, rollback catch, rollback faults
        self.direction_hold = DirectionHold(params, cfg.direction_hold)
        self.hold_command: HoldCommand | None = None   # this period's, for its notices
        self.vehicle_timeout = False     # the vehicle reports its own command-timeout brake
        self.stalls = 0                  # gaps longer than MAX_CONTROL_STEP_S seen
        self.resume_throttle_pct: float | None = None   # after a gap: the throttle before it

    # ------------------------------------------------------------------ node

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        dt_s = 0.0 if self.last_now_s is None else max(0.0, now_s - self.last_now_s)
        self.last_now_s = now_s
        if dt_s > MAX_CONTROL_STEP_S + TIME_EPS_S:
            # a stall: no harder than before it (the controllers integrate a bounded step)
            self.stalls += 1
            self.resume_throttle_pct = self.pedals.throttle_pct
        control_dt_s = min(dt_s, MAX_CONTROL_STEP_S)
        if self.state_since_s is None:
            self.state_since_s = now_s
        if self.last_sensor_s is None:
            self.last_sensor_s = now_s   # grace period: the sensors get one timeout to appear
            self.first_step_s = now_s
        requests = self._read_inputs(now_s, inbox, out)
        gear = self.gears.get(self.gear_cmd)
        motion_notices = self.motion.step(now_s, gear.direction if gear is not None else 0)
        self._note_sensor_faults(now_s, motion_notices)
        out.extend((Topic.NOTICE, n) for n in motion_notices)
        self._update_measurements(now_s, dt_s)
        self._monitor_actuators(now_s, out)
        if self.brake_lost and not self.engine_cut and self.stopped:
            self.engine_cut = True   # engine braking kept it running while moving; at rest, cut
        self._vehicle_timeout(now_s, out)

        client_fault_edge = False
        reply_faults: list[tuple[int, str]] = []
        for spss, sent_s in requests:
            client_fault_edge |= self._handle_request(now_s, spss, out, sent_s)
            reply_faults.append((self.fault, self.fault_message))
        watchdog_edge = self._watchdog(now_s, out)

        event = classify_event(self.state, self._conditions(now_s, client_fault_edge,
                                                           watchdog_edge))
        new_state = next_state(self.state, event)
        if new_state != self.state:
            self._enter(now_s, new_state, event, out)

        self.hold_command = None
        pedals, powertrain = self._actuators(control_dt_s, dt_s)
        pedals = self._after_gap(pedals)
        self.pedals = pedals
        self.park_commanded = powertrain.park_brake
        self._hold_notices(now_s, out)
        self._update_hint(now_s)
        out.append((Topic.PEDALS, pedals))
        out.append((Topic.POWERTRAIN, powertrain))
        for code, message in reply_faults or [(self.fault, self.fault_message)]:
            if not code:
                code, message = self.fault, self.fault_message
            out.append((Topic.SPEED_STATE, self._speed_state(code, message)))
        self._display(now_s, out)
        return out

    def _note_sensor_faults(self, now_s: float, notices: Sequence[Notice]) -> None:
        """Put each motion-sensing fault raised this period on the sign (a repeat re-dates it)."""
        for notice in notices:
            if notice.kind == "fault" and notice.code.isdigit():
                self.sensor_faults.pop(int(notice.code), None)   # kept in raising order
                self.sensor_faults[int(notice.code)] = (now_s, notice.reason)

    def _sensor_fault_in_force(self, code: int) -> bool:
        """Whether the condition a motion-sensing fault reported still holds: its source
        untrusted, the speeds still disagreeing, no trusted speed; a step (1105, 1106) is an
        event and holds only ``SENSOR_FAULT_SHOWN_MIN_S``."""
        if code in SENSOR_FAULT_TRACKS:
            return not self.motion.trusted(SENSOR_FAULT_TRACKS[PlausibilityFault(code)])
        if code == PlausibilityFault.SPEED_DISAGREE:
            return self.motion.disagree_fault
        return code == PlausibilityFault.NO_TRUSTED_SPEED and self.motion.no_speed

    def _sign(self, now_s: float) -> Display:
        """What the sign should show now: the newest fault in force, the server's current fault
        (the one the replies carry, dated by its onset) or a motion-sensing fault, the others
        in force listed after it (``also_in_force``); blank when none. Faults raised in one
        period: the last raised first (the server's own after the sensors')."""
        if (self.fault, self.fault_message) != self.fault_shown[:2]:
            self.fault_shown = (self.fault, self.fault_message, now_s)
        for code, (raised_s, _) in list(self.sensor_faults.items()):
            if (now_s - raised_s >= SENSOR_FAULT_SHOWN_MIN_S - TIME_EPS_S
                    and not self._sensor_fault_in_force(code)):
                del self.sensor_faults[code]
        # newest first; of one period, the last raised first (reversed, then a stable sort)
        in_force = [(raised_s, code, reason)
                    for code, (raised_s, reason) in self.sensor_faults.items()]
        if self.fault:
            in_force.append((self.fault_shown[2], self.fault, self.fault_message))
        if not in_force:
            return Display(text="")
        in_force.reverse()
        in_force.sort(key=lambda fault: -fault[0])
        (_, code, message), others = in_force[0], tuple(c for _, c, _ in in_force[1:])
        also = f" (also {', '.join(map(str, others))})" if others else ""
        return Display(text=sign_text(message, DISPLAY_TEXT_MAX_CHARS - len(also)) + also,
                       code=code, also_in_force=others)

    def _display(self, now_s: float, out: list) -> None:
        """The LED sign: ``_sign`` sent when it changes, at most once per
        ``DISPLAY_CHANGE_MIN_S`` (a change held back is sent as the newest text once that has
        passed), and re-sent every ``DISPLAY_REFRESH_S``."""
        shown = self._sign(now_s)
        changed = shown != self.display
        if changed and now_s - self.display_changed_s < DISPLAY_CHANGE_MIN_S - TIME_EPS_S:
            return   # a flood: the newest text goes out once the interval has passed
        if changed or now_s - self.display_sent_s >= DISPLAY_REFRESH_S - TIME_EPS_S:
            if changed:
                self.display_changed_s = now_s
            self.display, self.display_sent_s = shown, now_s
            out.append((Topic.DISPLAY, shown))

    # ------------------------------------------------------------------ inputs

    def _feed_watchdog(self, now_s: float, sent_s: float) -> None:
        """Time the SPSS watchdog from the SPSS's send time (issue 20), never from the future.

        Across processes an SPSS arrives after a hop; timing from its send time keeps the
        emergency stop at 200 ms + one period after the last SPSS *sent*. A stamp ahead of
        ``now_s`` by more than ``CLOCK_SKEW_MAX_S`` (a clock not shared) counts as received now.
        """
        if sent_s > now_s + CLOCK_SKEW_MAX_S:
            sent_s = now_s
        last_s = self.spss_watchdog.last_s
        self.spss_watchdog.feed(min(now_s, sent_s if last_s is None else max(last_s, sent_s)))

    def _read_inputs(self, now_s: float, inbox: Sequence[tuple[str, Any]],
                     out: list) -> list[tuple[SetSpeed, float]]:
        requests: list[tuple[SetSpeed, float]] = []
        dispatch = self._dispatch
        for envelope in inbox:
            topic, msg = envelope
            if topic == Topic.SET_SPEED and isinstance(msg, SetSpeed):
                sent_s = getattr(envelope, "sent_s", now_s)   # stamped across processes
                requests.append((msg, sent_s if math.isfinite(sent_s) else now_s))
                continue
            dispatch(now_s, msg, out)
        return requests

    def _status_input(self, now_s: float, msg: VehicleStatus, out: list) -> None:
        if self._accept_input(finite(msg.engine_rpm, msg.throttle_pct, msg.brake_pct),
                              "vehicle_status: rpm or pedal not finite", out):
            self.status, self.last_sensor_s = msg, now_s
            if self.last_status_rx_s is not None and now_s > self.last_status_rx_s:
                # the status period: up at once, down slowly (~10 receipts): jitter-proof
                interval_s = now_s - self.last_status_rx_s
                self.status_period_s = max(interval_s, self.status_period_s
                                           + (interval_s - self.status_period_s) * 0.1)
                self.actuator_monitor.set_status_period(self.status_period_s)
            self.last_status_rx_s, self.status_new = now_s, True

    def _gps_input(self, now_s: float, msg: GpsIns, out: list) -> None:
        if self._accept_input(finite(msg.speed_mps, msg.pitch_rad, msg.odometer_m)
                              and valid_sigma(msg.position_sigma_m),
                              "gps_ins: speed, pitch, odometer or position sigma not finite",
                              out):
            self.gps, self.last_gps_s = msg, now_s
            self.motion.gps(now_s, msg)

    def _wheel_input(self, now_s: float, msg: WheelSpeed, out: list) -> None:
        if self._accept_input(finite(msg.speed_mps), "wheel_speed: not finite", out):
            self.wheel_mps, self.last_wheel_s = msg.speed_mps, now_s
            self.motion.wheel(now_s, msg)

    def _imu_input(self, now_s: float, msg: Imu, out: list) -> None:
        if self._accept_input(finite(msg.accel_x_mps2), "imu: accel_x not finite", out):
            self.imu, self.last_imu_s = msg, now_s
            self.motion.imu(now_s, msg)

    def _ignore_input(self, now_s: float, msg: Any, out: list) -> None:
        pass

    def _accept_input(self, ok: bool, reason: str, out: list) -> bool:
        """Reject a non-finite sensor message with a Notice (once per run of identical ones)."""
        if ok:
            if self.last_input_rejection == reason:
                self.last_input_rejection = ""
            return True
        if self.last_input_rejection != reason:
            self.last_input_rejection = reason
            out.append((Topic.NOTICE, Notice(kind="rejected", source=SOURCE, code="sensor",
                                             reason=reason)))
        return False

    def _fresh(self, last_s: float | None, now_s: float) -> bool:
        return last_s is not None and now_s - last_s < self.config.sensor_timeout_s - TIME_EPS_S

    def _update_measurements(self, now_s: float, dt_s: float) -> None:
        """Speed from the GPS/INS (ground truth of motion), else the wheels; acceleration from
        the IMU with gravity along the pitch removed, else from the speed's derivative."""
        cfg = self.config
        last_speed = self.speed_mps
        # issue 16: an untrusted source counts as silent (none left: the sensor e-stop)
        gps_fresh = self._fresh(self.last_gps_s, now_s) and self.motion.trusted("gps_ins")
        wheel_fresh = self._fresh(self.last_wheel_s, now_s) and self.motion.trusted("wheel_speed")
        if self.gps is not None and gps_fresh:
            self.speed_mps = self.gps.speed_mps
            if self.motion.gps_reads_low and self.wheel_mps is not None and wheel_fresh:
                # issue 30: the GPS/INS reads below the wheels, which are not slipping: the
                # higher reading (a GPS/INS under-reading by a drift is outvoted)
                self.speed_mps = self.wheel_mps
        elif self.wheel_mps is not None and wheel_fresh:
            self.speed_mps = self.wheel_mps
        self.speed_live = gps_fresh or wheel_fresh
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        if (self.imu is not None and self._fresh(self.last_imu_s, now_s)
                and self.motion.trusted("imu")):
            self.accel_mps2 = self.imu.accel_x_mps2 - G_MPS2 * math.sin(pitch)
        elif dt_s > 0.0:
            self.accel_mps2 = first_order_lag((self.speed_mps - last_speed) / dt_s,
                                              self.accel_mps2, cfg.speed_filter_s, dt_s)
        self.speed_filt_mps = first_order_lag(self.speed_mps, self.speed_filt_mps,
                                              cfg.speed_filter_s, dt_s)
        self.accel_filt_mps2 = first_order_lag(self.accel_mps2, self.accel_filt_mps2,
                                               cfg.speed_filter_s, dt_s)

    @property
    def stopped(self) -> bool:
        return abs(self.speed_filt_mps) < self.config.standstill_mps

    @property
    def latched(self) -> bool:
        return bool(self.estop_reason)

    # ------------------------------------------------------------------ requests

    def _handle_request(self, now_s: float, spss: SetSpeed, out: list,
                        sent_s: float | None = None) -> bool:
        """Validate and apply one SPSS; return True on a new client fault.

        Only a well-formed request feeds the watchdog (a client fault is one: it asks for the
        stop). An invalid request is not executed and stops the vehicle (issue 17).
        """
        if spss.fault != 0:
            self._feed_watchdog(now_s, now_s if sent_s is None else sent_s)
            new = spss.fault != self.client_fault
            self.client_fault = spss.fault
            if new:
                code = spss.fault if 1 <= spss.fault <= CLIENT_FAULT_MAX else FaultCode.OUT_OF_RANGE
                message = (fault_message(code) if code != FaultCode.OUT_OF_RANGE else fault_message(
                    code, field="fault", value=spss.fault, low=0, high=CLIENT_FAULT_MAX)
                    + "; stopping anyway")
                self._raise_fault(now_s, int(code), message, out)
                # confined to the clients' range: an out-of-range code is still the client's
                # own stop (it asked), never one of the server's (an unasked stop)
                self._estop(f"client fault {spss.fault}", out,
                            min(max(spss.fault, 1), CLIENT_FAULT_MAX))
            return new
        self.client_fault = 0
        invalid = self._validate(spss)
        if invalid is not None:
            self._stop_on_invalid(spss)
            code, message = invalid
            if self.last_rejection != invalid:
                self.last_rejection = invalid
                self._raise_fault(now_s, code, message, out)
            else:
                self.fault, self.fault_message, self.fault_since_s = code, message, now_s
            return False
        self.last_rejection = None
        self._feed_watchdog(now_s, now_s if sent_s is None else sent_s)
        if self.latched:
            sent = now_s if sent_s is None else sent_s
            if (self.engine_cut or self.brake_lost or self.sensor_lost or not self.stopped
                    or (self.estop_code > CLIENT_FAULT_MAX
                        and (spss.state == "run" or not now_s > self.estop_since_s + TIME_EPS_S
                             or not sent > self.estop_since_s))):
                return False   # not executed: the e-stop holds until the vehicle has stopped;
                               # one the client did not ask for (the server's own code) until
                               # it asks for a state that does not move (it has seen the stop:
                               # the old command never drives on by itself), sent after the
                               # stop began (a request queued during a stall of this server
                               # was sent before the client could know); an actuator fault
                               # holds for good: the actuator needs a human
            self.estop_reason, self.estop_code = "", 0
        self._accept(spss)
        if self.fault and now_s - self.fault_since_s >= self.config.fault_hold_s - TIME_EPS_S:
            self.fault, self.fault_message = 0, ""
        return False

    def _validate(self, spss: SetSpeed) -> tuple[int, str] | None:
        """``(code, message)`` of the first problem with ``spss``, or None when valid."""
        cfg = self.config
        p = self.params
        for field, value in (("speed_mps", spss.speed_mps), ("accel_mps2", spss.accel_mps2)):
            if not math.isfinite(value):
                return FaultCode.NOT_FINITE, fault_message(FaultCode.NOT_FINITE, field=field)
        if not 0.0 <= spss.speed_mps <= cfg.max_request_speed_mps:
            return FaultCode.OUT_OF_RANGE, fault_message(
                FaultCode.OUT_OF_RANGE, field="speed_mps", value=spss.speed_mps, low=0.0,
                high=cfg.max_request_speed_mps)
        if not 0.0 < spss.accel_mps2 <= self.max_accel_mps2:
            return FaultCode.OUT_OF_RANGE, fault_message(
                FaultCode.OUT_OF_RANGE, field="accel_mps2", value=spss.accel_mps2,
                low="0 (exclusive)", high=self.max_accel_mps2)
        if spss.state not in REQUESTABLE:
            return FaultCode.BAD_STATE, fault_message(FaultCode.BAD_STATE, state=spss.state)
        gear = self.gears.get(spss.gear)
        if gear is None:
            return FaultCode.UNKNOWN_GEAR, fault_message(FaultCode.UNKNOWN_GEAR, preset=p.preset,
                                                         gear=spss.gear)
        if spss.state not in ("idle", "run"):
            return None   # seed 001: "Gear selection only matters for run" (and idle's shifts)
        if spss.state == "run" and gear.direction == 0:
            return FaultCode.NO_DRIVE_GEAR, fault_message(FaultCode.NO_DRIVE_GEAR, gear=spss.gear)
        if (spss.state == "run" and self.state in ("runwait", "shifting", "run")
                and spss.gear != self.goal_gear
                and not (self.brake_lost and spss.gear == self.gear_cmd)):
            # (the server's own downshift on a lost brake, echoed by its client, is no change)
            # seed 001: "go to idle and specify a new gear": idle with a new gear is accepted
            # (the vehicle stops, goes idle, then shifts); run with a new gear is not
            return FaultCode.GEAR_CHANGE_OUTSIDE_IDLE, fault_message(
                FaultCode.GEAR_CHANGE_OUTSIDE_IDLE, gear=spss.gear, state=self.state)
        if self.state == "idle" and spss.gear != self.gear_cmd and not self.stopped:
            return FaultCode.SHIFT_WHILE_MOVING, fault_message(
                FaultCode.SHIFT_WHILE_MOVING, gear=spss.gear, speed_mps=self.speed_filt_mps)
        return None

    def _stop_on_invalid(self, spss: SetSpeed) -> None:
        """A controlled stop in the current state: a request to stop harder than allowed stops at
        the allowed maximum; anything else at least at ``invalid_stop_decel_mps2``."""
        cfg = self.config
        self.target_mps = 0.0
        if math.isfinite(spss.accel_mps2) and spss.accel_mps2 > self.max_accel_mps2:
            self.rate_mps2 = self.max_accel_mps2
        else:
            self.rate_mps2 = max(self.rate_mps2, cfg.invalid_stop_decel_mps2)

    def _accept(self, spss: SetSpeed) -> None:
        if spss.state == "paused" and self.auto_parked:
            pass   # parked to save fuel: a repeated "paused" does not restart the engine
        else:
            self.auto_parked = False
            self.goal = spss.state
        if spss.state in ("idle", "run"):
            self.goal_gear = spss.gear
        self.target_mps = spss.speed_mps if spss.state == "run" else 0.0
        self.rate_mps2 = spss.accel_mps2

    # ------------------------------------------------------------------ faults

    def _raise_fault(self, now_s: float, code: int, message: str, out: list) -> None:
        self.fault, self.fault_message, self.fault_since_s = code, message, now_s
        out.append((Topic.NOTICE, Notice(kind="fault", source=SOURCE, code=str(code),
                                         reason=message)))

    def _estop(self, reason: str, out: list, code: int) -> None:
        """Latch an e-stop. A stop of the server's own (code above the clients') is counted
        and names the stop from then on, over any earlier cause: the latest unasked cause is
        the one a clearing request must have been sent after. A client's code names it only
        when nothing else latched it."""
        unasked = code > CLIENT_FAULT_MAX
        if unasked:
            self.unasked_stops += 1
        if unasked or not self.estop_reason:
            self.estop_code = code
            self.estop_since_s = self.last_now_s if self.last_now_s is not None else 0.0
        self.estop_reason = reason
        out.append((Topic.NOTICE, Notice(kind="estop", source=SOURCE, code=str(code),
                                         reason=reason)))

    def _watchdog(self, now_s: float, out: list) -> bool:
        """SPSS and sensor timeouts; True on the period an e-stop starts."""
        cfg = self.config
        edge = False
        if self.spss_watchdog.check(now_s):
            self._raise_fault(now_s, FaultCode.SPSS_TIMEOUT, fault_message(
                FaultCode.SPSS_TIMEOUT, timeout_s=cfg.spss_timeout_s), out)
            self._estop(f"no SPSS for {cfg.spss_timeout_s:.3f} s", out, FaultCode.SPSS_TIMEOUT)
            edge = True
        assert self.last_sensor_s is not None
        silent = (now_s - self.last_sensor_s >= cfg.sensor_timeout_s - TIME_EPS_S
                  or (not self.speed_live and now_s - self.first_step_s
                      >= cfg.sensor_timeout_s - TIME_EPS_S))
        if silent and not self.sensor_lost:
            self._raise_fault(now_s, FaultCode.SENSOR_TIMEOUT, fault_message(
                FaultCode.SENSOR_TIMEOUT, timeout_s=cfg.sensor_timeout_s), out)
            self._estop(f"no vehicle status or speed for {cfg.sensor_timeout_s:.3f} s", out,
                        FaultCode.SENSOR_TIMEOUT)
            edge = True
        self.sensor_lost = silent
        return edge

    def _vehicle_timeout(self, now_s: float, out: list) -> None:
        """The vehicle braked on its own command timeout (this server or its link stalled): an
        emergency stop, latched like the SPSS watchdog's, on the report's rising edge."""
        status = self.status
        timeout = bool(status is not None and status.command_timeout)
        if timeout and not self.vehicle_timeout:
            self._raise_fault(now_s, FaultCode.VEHICLE_TIMEOUT,
                              fault_message(FaultCode.VEHICLE_TIMEOUT), out)
            self._estop("the vehicle's command timeout braked", out, FaultCode.VEHICLE_TIMEOUT)
        self.vehicle_timeout = timeout

    def _after_gap(self, pedals: PedalCommand) -> PedalCommand:
        """After a stall the throttle starts from no more than it was before the stall: the
        throttle loop is reset to that output (its integrator holds, no wind-up) and rises
        from there at its own slew rate."""
        cap = self.resume_throttle_pct
        if cap is None:
            return pedals
        self.resume_throttle_pct = None
        if pedals.throttle_pct <= cap:
            return pedals
        self.controller.throttle_pid.reset(cap)
        return msgspec.structs.replace(pedals, throttle_pct=cap)

    def _monitor_actuators(self, now_s: float, out: list) -> None:
        """Issue 16: last period's pedal commands against the reported positions and response
        (``safety.actuators.PedalMonitor``). A throttle or brake that does not follow cuts the
        engine and latches an emergency stop that no request clears; each onset is a fault."""
        status = self.status
        if status is None or not self.monitor_actuators or not self.status_new:
            return   # a repeated status is no news: the checks step on each new one only
        self.status_new = False
        last_s, self.monitored_status_s = self.monitored_status_s, now_s
        dt_s = 0.0 if last_s is None else now_s - last_s
        # the stuck checks need only the reported positions: armed through a sensor loss (its
        # e-stop's full brake must not fight a stuck-open throttle); the brake response is not
        armed = (status.computer_speed and status.safety_mode == "drive-by-wire"
                 and not status.shifting)
        gear = self.gears.get(status.gear)
        # an untrusted IMU (frozen, plausibility fault 1103) would read as a brake that does not
        # decelerate: its samples are left out, the brake check waits for a trusted IMU
        imu_fresh = (self.imu is not None and self._fresh(self.last_imu_s, now_s)
                     and self.motion.trusted("imu"))
        findings = self.actuator_monitor.update(
            dt_s, armed=armed, throttle_cmd_pct=self.pedals.throttle_pct,
            brake_cmd_pct=self.pedals.brake_pct, throttle_pct=status.throttle_pct,
            brake_pct=status.brake_pct, direction=gear.direction if gear is not None else 0,
            speed_mps=self.speed_mps,
            accel_x_mps2=self.imu.accel_x_mps2 if imu_fresh and self.imu is not None else None,
            pitch_rad=self.gps.pitch_rad if self.gps is not None else 0.0,
            slipping=tyres_at_limit(status),
            # the brake's response is not judged while the parking brake adds to it (a weak
            # service brake would read as healthy, a failed one as weak)
            sample_response=not self.sensor_lost and not self.park_commanded,
            engine_brake_mps2=engine_brake_mps2(
                gear, status.throttle_pct * 0.01, self.speed_mps * gear.direction,
                status.engine == "running") if gear is not None else 0.0)
        for finding in findings:
            self._raise_fault(now_s, int(finding.code), finding.message, out)
            if finding.code in BRAKE_LOST and not self.brake_lost:
                self._brake_lost(finding.message, int(finding.code), out)
            elif finding.code in CUTS_ENGINE and not self.engine_cut:
                self.engine_cut = True
                self.goal, self.target_mps = "parked", 0.0
                self._estop(finding.message, out, int(finding.code))

    def _brake_lost(self, message: str, code: int, out: list) -> None:
        """The service brake does not apply or failed: an e-stop for good, a takeover request,
        and what the vehicle has left (engine braking keeps the engine running while moving)."""
        p = self.params
        self.brake_lost = self.takeover = True
        self.goal, self.target_mps = "parked", 0.0
        self._estop(message, out, code)
        gear = self._gear()
        speed = abs(self.speed_mps)
        means = []
        if has_engine_braking(p, gear, speed) and not self.actuator_monitor.cut_throttle:
            shift = secondary_gear(p, gear, speed)
            means.append(f"engine braking in {shift.name}"
                         + (f" (downshift from {gear.name})" if shift is not gear else "")
                         + ("" if p.shift_only_stopped else ", downshifting as the speed allows"))
        else:
            self.engine_cut = True
        if p.park_brake_decel_mps2 > 0.0:
            means.append(f"parking brake at or below {p.park_brake_max_apply_mps:g} m/s")
        used = ", ".join(means) if means else "none (coasting)"
        out.append((Topic.NOTICE, Notice(kind="secondary_braking", source=SOURCE, code=str(code),
                                         reason=f"service brake lost; secondary braking: {used}")))
        out.append((Topic.NOTICE, Notice(kind="takeover", source=SOURCE, code=str(code),
                                         reason=f"take over: service brake lost ({message})")))

    # ------------------------------------------------------------------ state machine

    def _conditions(self, now_s: float, client_fault_edge: bool, watchdog_edge: bool) -> Conditions:
        cfg = self.config
        status = self.status
        assert self.state_since_s is not None
        gear = status.gear if status is not None else self.gear_cmd
        if status is not None and status.engine == "cranking" and self.state == "starting":
            self.saw_cranking = True
        gear_info = self.gears.get(gear)
        return Conditions(
            goal=self.goal, goal_gear=self.goal_gear,
            time_in_state_s=now_s - self.state_since_s + TIME_EPS_S,
            client_fault_edge=client_fault_edge, watchdog_edge=watchdog_edge,
            latched=self.latched, client_fault_active=self.client_fault != 0,
            engine=status.engine if status is not None else "",
            saw_cranking=self.saw_cranking,
            gear=gear, gear_neutral=gear_info is not None and gear_info.direction == 0,
            shifting=status.shifting if status is not None else False,
            stopped=self.stopped, shift_for_run=self.shift_for_run,
            reset_s=cfg.reset_s, start_timeout_s=self._start_timeout_s,
            start_retry_s=cfg.start_retry_s, pause_park_s=cfg.pause_park_s,
            runwait_s=cfg.runwait_s, shift_timeout_s=self._shift_timeout_s,
        )

    def _enter(self, now_s: float, new_state: str, event: str | None, out: list) -> None:
        old = self.state
        self.state = new_state
        self.state_since_s = now_s
        self.shift_for_run = new_state == "shifting" and old == "runwait"
        self.saw_cranking = False
        if event == "pause_timeout":
            self.goal, self.auto_parked = "parked", True
        elif event == "stalled" and not self.engine_cut:
            self.unasked_stops += 1   # no e-stop (the engine restarts) but a stop all the same
            self._raise_fault(now_s, FaultCode.ENGINE_STALLED,
                              fault_message(FaultCode.ENGINE_STALLED, state=old), out)
        elif event == "shift_failed":
            self._raise_fault(now_s, FaultCode.SHIFT_FAILED, fault_message(
                FaultCode.SHIFT_FAILED, gear=self.goal_gear,
                timeout_s=self.params.shift_time_s + self.config.shift_timeout_margin_s), out)
            if self.status is not None:
                self.gear_cmd = self.status.gear
            self.goal, self.goal_gear = "idle", self.gear_cmd
        if new_state == "run":
            self.direction_hold.reset()
            direction = self._gear().direction
            self.controller.reset(direction * self.speed_filt_mps,
                                  direction * self.accel_filt_mps2, self.pedals.brake_pct)

    def _gear(self) -> Gear:
        gear = self.gears.get(self.gear_cmd)
        return gear if gear is not None else self.params.gear(self.gear_cmd)   # raises KeyError

    # ------------------------------------------------------------------ outputs

    def _actuators(self, dt_s: float, elapsed_s: float) -> tuple[PedalCommand, PowertrainCommand]:
        """This period's pedals and powertrain. ``dt_s``: the bounded step the controllers
        integrate; ``elapsed_s``: the real time since the last step, which the direction hold
        measures with (a rollback during a stall is travel all the same)."""
        p = self.params
        row = STATE_TABLE[self.state]
        state = self.state
        if state in ("parked", "reset"):
            self.gear_cmd = p.park_gear
        elif state in ("starting", "startwait", "paused"):
            self.gear_cmd = self.neutral_gear
        elif state == "shifting" and self.stopped:
            self.gear_cmd = self.goal_gear
        speed = abs(self.speed_mps)
        if self.brake_lost and not self.stopped and not self.engine_cut and row.in_gear:
            # downshift for engine braking where the gearbox allows it at this speed
            self.gear_cmd = secondary_gear(p, self._gear(), speed).name
        engine_on = row.engine_on and not self.engine_cut
        if state == "starting" and self.status is not None:
            # seed 001: starting "Must be in neutral": crank only out of gear
            status_gear = self.gears.get(self.status.gear)
            engine_on = status_gear.direction == 0 if status_gear is not None else False
        park_ok = self.stopped or speed <= p.park_brake_max_apply_mps
        if self.brake_lost and park_ok and p.park_brake_decel_mps2 > 0.0:
            self.park_applied = True   # held from here on
        park_brake = (row.brakes_locked and park_ok) or self.park_applied
        powertrain = PowertrainCommand(gear=self.gear_cmd, engine_on=engine_on,
                                       horn=state == "runwait", park_brake=park_brake,
                                       source=SOURCE)
        if row.brakes_locked:
            return PedalCommand(throttle_pct=0.0, brake_pct=100.0, source=SOURCE), powertrain
        # run
        gear = self._gear()
        direction = gear.direction
        v_g = direction * self.speed_mps
        a_g = direction * self.accel_mps2
        status = self.status
        pitch = self.gps.pitch_rad if self.gps is not None else 0.0
        sin_pitch = direction * math.sin(pitch)
        if self.latched or status is None or not status.computer_speed:
            return self._paused_pedals(dt_s, v_g, a_g, sin_pitch, gear), powertrain
        target = 0.0
        if self.goal == "run":
            target = min(self.target_mps, gear.max_speed_mps * self.config.gear_cap_fraction)
        result = self.controller.step(dt_s, target, self.rate_mps2, v_g, a_g, sin_pitch, gear,
                                      self.stopped)
        hold = self.hold_command = self.direction_hold.step(
            elapsed_s, target_mps=target, speed_mps=v_g, stopped=self.stopped, sin_pitch=sin_pitch,
            throttle_pct=status.throttle_pct, gear=gear,
            source_speeds_mps=self._source_speeds_mps(direction))
        if hold.mode == "brake":   # a rollback caught or a fault: full brake, throttle closed
            self.controller.reset(direction * self.speed_filt_mps, a_g, 100.0)
            return (PedalCommand(throttle_pct=0.0, brake_pct=100.0, source=SOURCE),
                    msgspec.structs.replace(powertrain, park_brake=park_ok))
        if hold.mode == "park":    # hill start (throttle building) or auto-hold at a standstill
            powertrain = msgspec.structs.replace(powertrain, park_brake=park_ok)
        probe = self._brake_probe(dt_s, result, target, v_g, direction, pitch, status)
        if probe is not None:
            return probe, powertrain
        return (PedalCommand(throttle_pct=result.throttle_pct, brake_pct=result.brake_pct,
                             source=SOURCE), powertrain)

    def _paused_pedals(self, dt_s: float, v_g: float, a_g: float, sin_pitch: float,
                       gear: Gear) -> PedalCommand:
        """Pedals while the vehicle's pause logic owns them (it takes the larger brake), or
        under a latched e-stop (full brake). Moving, the stop the vehicle makes (seed 000: a
        pause "brings the vehicle to a stop using a constant (user set) acceleration"): the
        loop brings the speed to 0 at the vehicle's ``pause_decel_mps2``, or at the client's
        rate when it asks a harder stop (an authorization that needs it; full deceleration:
        hard braking, issue 17); at a standstill the hold (seed 000's 50 %)."""
        p, status = self.params, self.status
        if self.latched or status is None or self.stopped:
            hard = (status is None and self.target_mps == 0.0 and not self.stopped
                    and self.rate_mps2 >= p.max_brake_decel_mps2)
            brake = 100.0 if self.latched or hard else self.config.hold_brake_pct
            self.controller.reset(gear.direction * self.speed_filt_mps, a_g, brake)
            self.direction_hold.reset()
            return PedalCommand(throttle_pct=0.0, brake_pct=brake, source=SOURCE)
        rate = max(p.pause_decel_mps2, self.rate_mps2 if self.target_mps == 0.0 else 0.0)
        result = self.controller.step(dt_s, 0.0, rate, v_g, a_g, sin_pitch, gear, self.stopped)
        self.direction_hold.reset()
        return PedalCommand(throttle_pct=0.0, brake_pct=result.brake_pct, source=SOURCE)

    def _brake_probe(self, dt_s: float, loop: Any, target_mps: float, v_g: float,
                     direction: int, pitch_rad: float, status: VehicleStatus) -> PedalCommand | None:
        """Issue 16: the once-a-run brake probe (``safety.actuators.BrakeProbe``) overriding the
        loop's pedals: throttle shut, never less brake than the loop asks; None: the loop's."""
        if not self.monitor_actuators:
            return None
        probe_pct = self.actuator_monitor.probe_brake_pct(
            dt_s, loop_braking=loop.brake_pct > 0.0 or v_g > PROBE_TARGET_FRACTION * target_mps,
            keep_ok=(target_mps > 0.0 and target_mps >= v_g - PROBE_SLOWING_MPS
                     and not tyres_at_limit(status)),
            direction=direction, speed_mps=self.speed_mps, pitch_rad=pitch_rad,
            throttle_pct=status.throttle_pct, throttle_cmd_pct=loop.throttle_pct)
        if probe_pct is None:
            return None
        self.controller.throttle_pid.reset(0.0)   # no wind-up while the probe holds the throttle
        return PedalCommand(throttle_pct=0.0, brake_pct=max(probe_pct, loop.brake_pct),
                            source=SOURCE)

    def _source_speeds_mps(self, direction: int) -> list[float]:
        """Each live, trusted speed source (GPS/INS, wheels), in the gear frame: an untrusted one
        (frozen GPS reading 0) must not hide a real rollback (as in ``_update_measurements``)."""
        now_s = self.last_now_s if self.last_now_s is not None else 0.0
        return [direction * s for s, last_s, name in (
            (self.gps.speed_mps if self.gps is not None else None, self.last_gps_s, "gps_ins"),
            (self.wheel_mps, self.last_wheel_s, "wheel_speed"))
            if s is not None and self._fresh(last_s, now_s) and self.motion.trusted(name)]

    def _hold_notices(self, now_s: float, out: list) -> None:
        """The direction hold's fault (once per onset) and rollback-caught notices."""
        hold = self.hold_command
        if hold is None:
            return
        if hold.caught:
            out.append((Topic.NOTICE, Notice(kind="rollback", source=SOURCE, reason=hold.caught)))
        if hold.fault is not None:
            self._raise_fault(now_s, *hold.fault, out)

    def _update_hint(self, now_s: float) -> None:
        """Seed 001 hints (``servers.speed_hints``), from the vehicle as this period saw it."""
        status = self.status
        view = None
        if self.state == "run" and status is not None:
            gear = self._gear()
            target = 0.0
            if self.goal == "run":
                target = min(self.target_mps, gear.max_speed_mps * self.config.gear_cap_fraction)
            pitch = self.gps.pitch_rad if self.gps is not None else 0.0
            view = HintInputs(gear=gear, speed_mps=self.speed_mps, wheel_mps=self.wheel_mps,
                              accel_mps2=self.accel_filt_mps2, target_mps=target,
                              sin_pitch=math.sin(pitch), engine_rpm=status.engine_rpm,
                              throttle_pct=status.throttle_pct,
                              traction_control=slippery_ground(status),
                              abs_active=status.abs_active is True,
                              held_cannot_climb=self.direction_hold.cannot_climb)
        self.hint = self.hints.update(now_s, view)

    def _speed_state(self, fault: int, fault_message: str) -> SpeedState:
        status = self.status
        return SpeedState(
            speed_mps=self.speed_mps, accel_mps2=self.accel_filt_mps2,
            gear=status.gear if status is not None else self.gear_cmd,
            state=self.state, fault=fault, fault_message=fault_message,
            hint=self.hint, estop=self.latched,  # type: ignore[arg-type]
            estop_code=self.estop_code if self.latched else 0,
            unasked_stops=self.unasked_stops, started_s=self.first_step_s,
            direction_hold=self.direction_hold.state,  # type: ignore[arg-type]
            takeover=self.takeover,
        )


__all__ = ["SpeedServer", "SpeedServerConfig"]
