"""Actuator monitoring (issue 16): does each actuator do what it is told?

Pure and clock-free: the owners step these checks with ``dt_s`` and what they commanded and
measured; nothing here reads a clock, a socket or the simulator's truth.

- **Stuck actuators** (``FollowCheck``): the position the vehicle reports
  (``VehicleStatus.throttle_pct`` / ``brake_pct`` / ``steer_pct``) stays still while the command
  is away from it. A healthy actuator is a first-order lag (``*_lag_s`` in the presets): with a gap
  of ``gap_pct`` it moves at ``gap / lag`` at least, so "still for ``hold_s``" never happens to a
  healthy one, nor to a slow one (lag x 5, the sweep's ``brake_slow``) or a rate-limited one.
- **Brake response** (``BrakeResponse``): the deceleration achieved per brake % against the
  preset's ``max_brake_decel_mps2``, from the IMU's specific force along the direction of travel
  (gravity is not in it: grade compensated) minus rolling resistance and drag, as the adaptive
  model of ``servers/adaptive.py`` measures it. A brake not yet seen working at cruise is
  *probed* once (``BrakeProbe``): throttle closed, a light brake for a few tenths of a second,
  so a weak brake is known (and learned by the move server's model) long before the stop.
- **Steering** (``SteeringMonitor``): stuck road wheels (``FollowCheck``); the curvature the
  vehicle actually drives is measured from yaw rate / speed (the wheels' angle when too slow).

Reactions (by the owners): a brake that does not apply and a throttle that does not follow cut
the engine and raise the speed server's emergency stop; a weak brake is a notice and the move
server's envelope tightens from the probe's samples; stuck steering stops the vehicle under
the lateral limit of the curvature it actually drives (driving module).
"""

from __future__ import annotations

import enum
import math

import msgspec

from overdrive.dynamics.vehicle_params import AIR_DENSITY_KGPM3, G_MPS2, VehicleParams


class ActuatorFault(enum.IntEnum):
    """Fault codes of actuator monitoring (issue 16 range 1131-1149)."""

    THROTTLE_STUCK_OPEN = 1131     # reported throttle stays above the command: does not close
    THROTTLE_STUCK_CLOSED = 1132   # reported throttle stays below an opening command
    BRAKE_NOT_APPLYING = 1133      # reported brake stays below the command: stuck released
    BRAKE_WEAK = 1134              # deceleration per brake % well below the preset's
    STEERING_STUCK = 1135          # road wheels stay still while the command is away from them
    BRAKE_FAILED = 1136            # full brake could not hold the vehicle on a rated grade


FAULT_MESSAGES: dict[ActuatorFault, str] = {
    ActuatorFault.THROTTLE_STUCK_OPEN: "throttle stuck at {actual_pct:.1f} % (commanded "
                                       "{command_pct:.1f} %): engine cut, emergency stop",
    ActuatorFault.THROTTLE_STUCK_CLOSED: "throttle stuck at {actual_pct:.1f} % (commanded "
                                         "{command_pct:.1f} %): engine cut, emergency stop",
    ActuatorFault.BRAKE_NOT_APPLYING: "brake stuck at {actual_pct:.1f} % (commanded "
                                      "{command_pct:.1f} %): emergency stop, secondary braking",
    ActuatorFault.BRAKE_WEAK: "brake gives {ratio:.0%} of the expected deceleration: envelope "
                              "tightened",
    ActuatorFault.BRAKE_FAILED: "brake gives {ratio:.0%} of the expected deceleration, too little "
                                "to hold a 15 % grade: emergency stop, secondary braking",
    ActuatorFault.STEERING_STUCK: "steering stuck at {actual_pct:.1f} % (commanded "
                                  "{command_pct:.1f} %), driving curvature {curvature_1pm:.3f} "
                                  "1/m: stopping",
}
"""Readable message per fault, formatted with the details of the onset."""

CUTS_ENGINE = frozenset({ActuatorFault.THROTTLE_STUCK_OPEN, ActuatorFault.THROTTLE_STUCK_CLOSED,
                         ActuatorFault.BRAKE_NOT_APPLYING, ActuatorFault.BRAKE_FAILED})
"""Faults after which the speed loop cannot be trusted: engine off and emergency stop (a lost
brake keeps the engine running while it brakes the moving vehicle: ``BRAKE_LOST``)."""

BRAKE_LOST = frozenset({ActuatorFault.BRAKE_NOT_APPLYING, ActuatorFault.BRAKE_FAILED})
"""The service brake lost (issue 30 item 4): the speed server brakes with what the vehicle has
left (``dynamics.secondary_braking``) and asks the safety driver to take over."""


def fault_message(code: ActuatorFault, **details: float) -> str:
    return FAULT_MESSAGES[code].format(**details)


class ActuatorMonitorConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Thresholds of the checks; each default says where it comes from."""

    pedal_gap_pct: float = 5.0       # command this far from the position: it must move (covers a
                                     # real actuator's deadband and 1 % quantised positions; a
                                     # healthy throttle, lag 0.15 s, moves 4.3 % per 0.3 s here)
    steer_gap_pct: float = 2.0       # same for the road wheels (lag 0.05 s; rate >= 24 %/s even
                                     # at the sweep's slowest steering, rate_scale 0.2)
    still_pct: float = 0.2           # moved less than this in hold_s: still (below one 1 % step
                                     # and below the slowest healthy or slow motion at the gap)
    hold_s: float = 0.3              # still this long while the gap holds: stuck; at least
    hold_periods: float = 3.0        # this many status periods (a 10 Hz status, or a real XGV's
                                     # 120-200 ms over JAUS, repeats one position for a period).
                                     # The checks step only on a new status (see ``set_status_
                                     # period``); 0.3 s: 3 periods of a 10 Hz status
    full_travel_pct: float = 90.0    # a command near full travel is followed by a position beyond
                                     # this: a healthy actuator may saturate a few % short of its
                                     # end stop (calibration, deadband; every e-stop asks 100 %)
    brake_short_fraction: float = 0.5  # BRAKE_NOT_APPLYING: the brake is clearly short only below
    brake_short_pct: float = 20.0    # this share of the command and this absolute (a stuck-released
                                     # brake sits near 0; a partly applied one is the response
                                     # check's: BRAKE_WEAK / BRAKE_FAILED)
    brake_strict_below_pct: float = 10.0  # commands below this keep the strict pedal_gap_pct
                                     # (min_brake_pct: below it half the command is within the gap)
    pedal_off_pct: float = 0.5       # a pedal counts as released below this (adaptive.py)
    min_brake_pct: float = 10.0      # brake samples only above this (adaptive.py)
    min_speed_mps: float = 0.5       # no brake samples below (the last instants of a stop)
    min_predicted_mps2: float = 0.3  # predicted deceleration below this carries too little signal
    sample_bounds: tuple[float, float] = (0.0, 1.5)   # per-sample ratio clamp (outliers)
    response_tau_s: float = 0.2      # averaging of the ratio over braking time (~2.5 brake lags)
    verify_s: float = 0.3            # this much braking time: the brake's response is known
    weak_ratio: float = 0.6          # below: BRAKE_WEAK (between the sweep's weakest healthy-
                                     # enough brake, 0.3, and the adaptive's degraded 0.9)
    recover_ratio: float = 0.7       # above again: the weak onset re-arms (hysteresis)
    failed_ratio: float = 0.16       # below: BRAKE_FAILED. Full brake (9 m/s^2 presets) then gives
                                     # < 1.44 m/s^2, less than gravity along a 15 % grade (1.46):
                                     # the vehicle could not hold itself on the grades it drives
    probe_enabled: bool = True       # issue 16 case 6: brakes at 20 % from the start overran a
                                     # 40 m MOVE by 6 m when learned only at the first stop; the
                                     # probe costs a healthy launch ~1.5 s and ~0.6 m/s once a run
    probe_brake_pct: float = 12.0    # the probe's brake: 1.08 m/s^2 nominal (9 m/s^2 presets),
                                     # a comfortable 0.11 g, 1.2 x min_brake_pct of signal
    probe_max_s: float = 2.0         # probe braking at most this long: a weak brake is probed
                                     # until the move server's estimate (tau 0.3 s) has ~6 tau
    probe_start_throttle_pct: float = 100.0  # start only with the loop's throttle below this
                                     # (100: at launch, as soon as fast enough; a weak brake
                                     # must be known before a 40 m MOVE at 8 m/s must stop)
    probe_retry_s: float = 5.0       # after an aborted probe, wait this long (no limit cycle)
    probe_close_max_s: float = 1.0   # wait at most this long for the throttle to close first
    probe_min_speed_mps: float = 1.5  # probe only above this: a healthy probe takes ~0.6 m/s ...
    probe_margin_s: float = 2.0      # ... plus what an uphill grade takes in this long (closing
                                     # ~0.7 s + braking up to probe_max_s)
    min_curvature_speed_mps: float = 1.0  # below: the curvature is the wheels', not yaw / speed


class FollowCheck:
    """A position that stays still while its command is away from it, in one sense.

    ``sense=+1``: stuck below the command (does not rise), ``-1``: stuck above (does not fall).
    ``update`` returns True while stuck; it clears once the position reaches the command or
    moves again (not while disarmed: a pause does not make a stuck actuator healthy).
    """

    __slots__ = ("_anchor_pct", "_still_s", "full_travel_pct", "gap_pct", "hold_s", "sense",
                 "still_pct", "stuck")

    def __init__(self, sense: int, gap_pct: float, still_pct: float, hold_s: float,
                 full_travel_pct: float = 100.0) -> None:
        self.sense, self.gap_pct, self.still_pct, self.hold_s = sense, gap_pct, still_pct, hold_s
        self.full_travel_pct = full_travel_pct
        self._anchor_pct: float | None = None
        self._still_s = 0.0
        self.stuck = False

    def set_hold(self, hold_s: float) -> None:
        self.hold_s = hold_s

    def away(self, command_pct: float, actual_pct: float) -> bool:
        """The position is short of the command, in this check's sense, by more than the gap; a
        command near full travel is followed by any position beyond ``full_travel_pct``."""
        gap = max(self.gap_pct, abs(command_pct) - self.full_travel_pct)
        return self.sense * (command_pct - actual_pct) > gap

    def update(self, dt_s: float, command_pct: float, actual_pct: float, armed: bool) -> bool:
        away = self.away(command_pct, actual_pct)
        if not armed or not away:
            self._anchor_pct, self._still_s = None, 0.0
            if armed and self.sense * (command_pct - actual_pct) <= 0.0:
                self.stuck = False   # at or past the command again: it follows
            return self.stuck
        if self._anchor_pct is None:
            self._anchor_pct, self._still_s = actual_pct, 0.0
            return self.stuck
        if abs(actual_pct - self._anchor_pct) > self.still_pct:
            self._anchor_pct, self._still_s = actual_pct, 0.0
            self.stuck = False   # it moves: not stuck (maybe slow)
            return False
        self._still_s += dt_s
        if self._still_s >= self.hold_s - 1e-9:
            self.stuck = True
        return self.stuck


class BrakeApplyCheck(FollowCheck):
    """A brake stuck released: the reported brake *clearly* short of the command (below
    ``brake_short_fraction`` of it and below ``brake_short_pct``); commands below
    ``brake_strict_below_pct`` keep the strict gap. A brake reaching 97 % of an e-stop's 100 %
    follows; one partly applied is judged by its response (BRAKE_WEAK / BRAKE_FAILED)."""

    __slots__ = ("config",)

    def __init__(self, config: ActuatorMonitorConfig) -> None:
        super().__init__(+1, config.pedal_gap_pct, config.still_pct, config.hold_s)
        self.config = config

    def away(self, command_pct: float, actual_pct: float) -> bool:
        cfg = self.config
        if not super().away(command_pct, actual_pct):
            return False
        if command_pct < cfg.brake_strict_below_pct:
            return True
        return actual_pct < min(cfg.brake_short_fraction * command_pct, cfg.brake_short_pct)


def brake_ratio(params: VehicleParams, direction: int, speed_mps: float, accel_x_mps2: float,
                pitch_rad: float, brake_pct: float, engine_brake_mps2: float = 0.0) -> float | None:
    """Achieved / predicted deceleration of ``brake_pct`` (None: no usable sample).

    ``accel_x_mps2`` is the IMU's specific force (no gravity in it); rolling resistance, drag
    and the engine braking of the gear (``engine_brake_mps2``, issue 30 item 4) are taken out,
    so the grade needs no model (the adaptive model's formula).
    """
    v_along = direction * speed_mps
    predicted = brake_pct * 0.01 * params.max_brake_decel_mps2
    if direction == 0 or v_along <= 0.0 or predicted <= 0.0:
        return None
    cos_pitch = math.cos(pitch_rad)
    losses = (params.rolling_resistance * G_MPS2 * cos_pitch
              + 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2 * v_along * v_along / params.mass_kg
              + engine_brake_mps2)
    return (-direction * accel_x_mps2 - losses) / predicted


class BrakeResponse:
    """Exponential average of ``brake_ratio`` over braking time, and the BRAKE_WEAK onset."""

    __slots__ = ("config", "excited_s", "failed", "ratio", "weak")

    def __init__(self, config: ActuatorMonitorConfig) -> None:
        self.config = config
        self.ratio = 1.0
        self.excited_s = 0.0
        self.weak = False
        self.failed = False   # latched: BRAKE_FAILED reported

    @property
    def verified(self) -> bool:
        return self.excited_s >= self.config.verify_s - 1e-9

    def update(self, dt_s: float, ratio: float) -> list[ActuatorFault]:
        """Feed one sample; the onsets it makes (BRAKE_WEAK, BRAKE_FAILED once)."""
        cfg = self.config
        lo, hi = cfg.sample_bounds
        r = min(max(ratio, lo), hi)
        self.ratio += (r - self.ratio) * (1.0 - math.exp(-dt_s / cfg.response_tau_s))
        self.excited_s += dt_s
        onsets = []
        if self.weak:
            self.weak = self.ratio < cfg.recover_ratio
        elif self.verified and self.ratio < cfg.weak_ratio:
            self.weak = True
            onsets.append(ActuatorFault.BRAKE_WEAK)
        if self.verified and self.ratio < cfg.failed_ratio and not self.failed:
            self.failed = True
            onsets.append(ActuatorFault.BRAKE_FAILED)
        return onsets


class BrakeProbe:
    """One light brake application at cruise while the brake's response is unknown.

    Phases: ``idle`` -> ``closing`` (throttle commanded shut until it reports closed) ->
    ``braking`` (``probe_brake_pct``) -> ``done``. It starts only when ``start_ok`` (the loop
    is not braking and the vehicle is fast enough for the grade, ``suitable``); it ends once the
    response is verified and not weak, or after ``probe_max_s`` of braking. When ``keep_ok``
    fails (a stop asked, slipping, too slow) it aborts and waits ``probe_retry_s`` to start again.
    """

    __slots__ = ("_phase_s", "_retry_s", "config", "phase")

    def __init__(self, config: ActuatorMonitorConfig) -> None:
        self.config = config
        self.phase = "idle"
        self._phase_s = 0.0
        self._retry_s = 0.0

    def suitable(self, v_along_mps: float, sin_pitch: float) -> bool:
        """Fast enough that the probe (~0.6 m/s healthy) and an uphill grade over
        ``probe_margin_s`` cannot stop the vehicle."""
        cfg = self.config
        uphill_mps2 = G_MPS2 * max(sin_pitch, 0.0)
        return v_along_mps >= cfg.probe_min_speed_mps + uphill_mps2 * cfg.probe_margin_s

    def step(self, dt_s: float, start_ok: bool, keep_ok: bool, response: BrakeResponse,
             throttle_pct: float) -> float | None:
        """The brake % to command instead of the speed loop's pedals (None: the loop drives)."""
        cfg = self.config
        if self.phase == "done" or not cfg.probe_enabled:
            return None
        if self.phase == "idle":
            self._retry_s = max(0.0, self._retry_s - dt_s)
            if response.verified:
                self.phase = "done"
            if self.phase == "done" or not (start_ok and keep_ok) or self._retry_s > 0.0:
                return None
            self.phase, self._phase_s = "closing", 0.0
        if not keep_ok:
            self.phase, self._retry_s = "idle", cfg.probe_retry_s
            return None
        self._phase_s += dt_s
        if self.phase == "closing":
            if throttle_pct <= cfg.pedal_off_pct:
                self.phase, self._phase_s = "braking", 0.0
            elif self._phase_s >= cfg.probe_close_max_s:
                self.phase, self._retry_s = "idle", cfg.probe_retry_s   # the stuck check speaks
                return None
            return 0.0
        if ((response.verified and not response.weak) or response.failed
                or self._phase_s >= cfg.probe_max_s):
            self.phase = "done"
            return None
        return cfg.probe_brake_pct


class Finding(msgspec.Struct, frozen=True):
    """A fault onset: its code and readable message."""

    code: ActuatorFault
    message: str


class PedalMonitor:
    """Throttle and brake checks of the speed server (see the module doc)."""

    def __init__(self, params: VehicleParams, config: ActuatorMonitorConfig | None = None) -> None:
        self.params = params
        self.config = cfg = config or ActuatorMonitorConfig()
        self.throttle_open = FollowCheck(-1, cfg.pedal_gap_pct, cfg.still_pct, cfg.hold_s,
                                         cfg.full_travel_pct)
        self.throttle_closed = FollowCheck(+1, cfg.pedal_gap_pct, cfg.still_pct, cfg.hold_s,
                                           cfg.full_travel_pct)
        self.brake_released = BrakeApplyCheck(cfg)
        self.response = BrakeResponse(cfg)
        self.probe = BrakeProbe(cfg)
        self.reported: set[str] = set()   # pedals whose stuck onset was reported
        self.cut = False   # latched: an actuator the speed loop relies on does not follow

    @property
    def cut_throttle(self) -> bool:
        """A throttle stuck onset was reported: the engine must be cut (no engine braking)."""
        return "THROTTLE" in self.reported

    def set_status_period(self, period_s: float) -> None:
        """The vehicle status's period as measured from its receipts: a position repeats for a
        period, so "still" needs ``hold_periods`` of them (never less than ``hold_s``)."""
        hold_s = max(self.config.hold_s, self.config.hold_periods * period_s)
        for check in (self.throttle_open, self.throttle_closed, self.brake_released):
            check.set_hold(hold_s)

    def update(self, dt_s: float, *, armed: bool, throttle_cmd_pct: float, brake_cmd_pct: float,
               throttle_pct: float, brake_pct: float, direction: int, speed_mps: float,
               accel_x_mps2: float | None, pitch_rad: float, slipping: bool,
               sample_response: bool = True, engine_brake_mps2: float = 0.0) -> list[Finding]:
        """One new vehicle status (``dt_s`` since the last one): the commands sent last period
        and the positions it reports; new onsets. Step it only on a new status: a repeated one
        would count as an actuator standing still.

        ``sample_response``: the speed and IMU are live (False while the sensors are lost: the
        brake response needs them, the stuck checks only the reported positions, and must go on
        running, so that a throttle stuck open under a sensor-loss emergency stop is cut)."""
        cfg = self.config
        found: list[Finding] = []
        if dt_s <= 0.0:
            return found
        released = brake_pct <= cfg.pedal_off_pct
        checks = (
            (self.throttle_open, throttle_cmd_pct, throttle_pct, armed,
             ActuatorFault.THROTTLE_STUCK_OPEN),
            # a throttle kept closed by a braking vehicle (its own command watchdog) is no fault
            (self.throttle_closed, throttle_cmd_pct, throttle_pct, armed and released,
             ActuatorFault.THROTTLE_STUCK_CLOSED),
            (self.brake_released, brake_cmd_pct, brake_pct, armed,
             ActuatorFault.BRAKE_NOT_APPLYING),
        )
        for check, command, actual, on, code in checks:
            was = check.stuck
            pedal = code.name.split("_")[0]   # THROTTLE or BRAKE: one stuck onset per pedal
            if check.update(dt_s, command, actual, on) and not was and pedal not in self.reported:
                self.cut = True
                self.reported.add(pedal)   # the engine stays cut: one onset per run
                found.append(Finding(code, fault_message(code, actual_pct=actual,
                                                         command_pct=command)))
        if (armed and sample_response and accel_x_mps2 is not None and not slipping
                and brake_pct >= cfg.min_brake_pct and throttle_pct <= cfg.pedal_off_pct
                and direction * speed_mps >= cfg.min_speed_mps
                and brake_pct * 0.01 * self.params.max_brake_decel_mps2 >= cfg.min_predicted_mps2):
            ratio = brake_ratio(self.params, direction, speed_mps, accel_x_mps2, pitch_rad,
                                brake_pct, engine_brake_mps2)
            for code in self.response.update(dt_s, ratio) if ratio is not None else ():
                self.cut |= code in CUTS_ENGINE
                found.append(Finding(code, fault_message(code, ratio=self.response.ratio)))
        return found

    def probe_brake_pct(self, dt_s: float, *, loop_braking: bool, keep_ok: bool, direction: int,
                        speed_mps: float, pitch_rad: float, throttle_pct: float,
                        throttle_cmd_pct: float = 0.0) -> float | None:
        """The probe's brake % this period (None: the speed loop's pedals stand).

        ``keep_ok``: the speed loop drives towards a nonzero target without slipping.
        """
        v_along = direction * speed_mps
        keep = keep_ok and not self.cut and v_along >= self.config.min_speed_mps
        start = not loop_braking and throttle_cmd_pct <= self.config.probe_start_throttle_pct \
            and self.probe.suitable(v_along, direction * math.sin(pitch_rad))
        return self.probe.step(dt_s, start, keep, self.response, throttle_pct)


class SteeringMonitor:
    """Stuck road wheels, and the curvature the vehicle actually drives."""

    def __init__(self, params: VehicleParams, config: ActuatorMonitorConfig | None = None) -> None:
        self.params = params
        self.config = cfg = config or ActuatorMonitorConfig()
        self.above = FollowCheck(-1, cfg.steer_gap_pct, cfg.still_pct, cfg.hold_s,
                                 cfg.full_travel_pct)
        self.below = FollowCheck(+1, cfg.steer_gap_pct, cfg.still_pct, cfg.hold_s,
                                 cfg.full_travel_pct)
        self.actual_curvature_1pm = 0.0
        self.stuck = False

    def update(self, dt_s: float, *, armed: bool, command_pct: float, actual_pct: float,
               speed_mps: float, yaw_rate_rps: float | None) -> Finding | None:
        """One period: the command sent last period and the reported position; an onset."""
        p, cfg = self.params, self.config
        if abs(speed_mps) >= cfg.min_curvature_speed_mps and yaw_rate_rps is not None:
            self.actual_curvature_1pm = -yaw_rate_rps / speed_mps   # the IMU's sign convention
        else:
            wheel_rad = actual_pct * 0.01 * p.max_steer_rad
            self.actual_curvature_1pm = math.tan(wheel_rad) / p.wheelbase_m
        if dt_s <= 0.0:
            return None
        was = self.stuck
        up = self.above.update(dt_s, command_pct, actual_pct, armed)
        down = self.below.update(dt_s, command_pct, actual_pct, armed)
        self.stuck = up or down
        if self.stuck and not was:
            return Finding(ActuatorFault.STEERING_STUCK, fault_message(
                ActuatorFault.STEERING_STUCK, actual_pct=actual_pct, command_pct=command_pct,
                curvature_1pm=self.actual_curvature_1pm))
        return None


__all__ = ["BRAKE_LOST", "CUTS_ENGINE", "FAULT_MESSAGES", "ActuatorFault", "ActuatorMonitorConfig",
           "BrakeApplyCheck", "BrakeProbe", "BrakeResponse", "Finding", "FollowCheck", "PedalMonitor",
           "SteeringMonitor", "brake_ratio", "fault_message"]
