"""Longitudinal control for the speed server: speed reference, throttle loop, brake loop.

Structure (seed 003, "Brake control" / "Throttle control"):

- a speed reference ``v_ref`` ramps towards the target at the requested rate and eases into it
  over ``approach_s`` (so the actuator lags do not overshoot); it never leads the measured speed
  by more than ``max_ref_lead_mps`` (no wind-up when the vehicle cannot follow);
- an outer speed loop turns ``v_ref`` and its slope into an acceleration command ``a_cmd``;
- the force model of the preset (rolling resistance, drag, grade from the INS pitch) says how
  much drive force ``a_cmd`` needs. Positive: the throttle loop (PID on acceleration, measured
  through ``throttle_filter_s`` ~ 200 ms of filtering); coasting gives whatever negative part it
  can, simply by easing the throttle. Below ``-coast_band_mps2``: the brake loop (PID on
  deceleration, tight loop from the IMU through ``brake_filter_s``).
- Both PIDs work on accelerations scaled to pedal percent by the model's pedal authority, so
  one set of gains is a fraction of the model gain whatever the speed; both have
  back-calculation anti-windup and output rate limits; the idle pedal's PID is reset, so
  throttle and brake are never commanded together.

Everything runs in the gear's frame: speeds and accelerations are positive in the gear's
direction of travel (negative ground speed in reverse).
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.control import Pid, PidGains, clamp, first_order_lag
from overdrive.dynamics.vehicle_params import AIR_DENSITY_KGPM3, G_MPS2, Gear, VehicleParams

MIN_AUTHORITY_SPEED_MPS = 0.5      # power-limited force is evaluated at no less than this
REDLINE_TAPER_FRACTION = 0.9       # drive force fades over the last 10 % below the gear's top speed
ROLLBACK_MPS = 0.1                 # rolling back faster than this while holding: full brake
REF_SNAP_MPS = 1e-3                # the reference's exponential approach ends within this


class LongitudinalGains(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Gains of the speed, throttle and brake loops (tuned per preset, see ``GAINS``)."""

    speed_kp_1ps: float = 1.5            # a_cmd per m/s of speed error
    approach_s: float = 0.3              # time constant of the reference's final approach
    max_ref_lead_mps: float = 0.3        # v_ref stays within this of the measured speed
    max_accel_cmd_mps2: float = 4.0      # outer-loop command limits
    max_decel_cmd_mps2: float = 8.0
    coast_band_mps2: float = 0.08        # hysteresis between throttle and brake
    throttle_filter_s: float = 0.2       # seed 003: "about 200ms" of filtering on the throttle loop
    brake_filter_s: float = 0.03         # tight loop from the inertial sensor
    throttle: PidGains = PidGains(kp=0.3, ki=0.8, output_min=0.0, output_max=100.0,
                                  output_rate_per_s=300.0, tracking_time_s=0.3)
    brake: PidGains = PidGains(kp=0.4, ki=2.0, output_min=0.0, output_max=100.0,
                               output_rate_per_s=400.0, tracking_time_s=0.1)


GAINS: dict[str, LongitudinalGains] = {
    # tuned in closed loop against overdrive.vehicle.plant (tests/servers/test_speed_acceptance.py)
    "escape-hybrid": LongitudinalGains(),
    "ranger-6x6": LongitudinalGains(),
}
"""Default gains per vehicle preset; unknown presets use ``LongitudinalGains()``."""


def gains_for(params: VehicleParams) -> LongitudinalGains:
    return GAINS.get(params.preset, LongitudinalGains())


def drive_authority_mps2(params: VehicleParams, gear: Gear, speed_mps: float) -> float:
    """Acceleration full throttle gives in ``gear`` at ``speed_mps`` (gear frame), before losses.

    The preset's powertrain: gear force up to the power limit, fading to zero at the gear's
    top speed (the plant's model; a real vehicle's would be a measured map).
    """
    if gear.direction == 0 or gear.max_speed_mps <= 0.0:
        return 0.0
    force_n = min(gear.max_force_n, params.max_power_w / max(abs(speed_mps), MIN_AUTHORITY_SPEED_MPS))
    top = gear.max_speed_mps
    if speed_mps > REDLINE_TAPER_FRACTION * top:
        force_n *= max(0.0, (top - speed_mps) / ((1.0 - REDLINE_TAPER_FRACTION) * top))
    return force_n / params.mass_kg


def resistance_mps2(params: VehicleParams, speed_mps: float, sin_pitch: float) -> float:
    """Deceleration from rolling resistance, drag and grade in the gear frame (+ slows down).

    ``sin_pitch`` is positive when the direction of travel points uphill.
    """
    cos_pitch = math.sqrt(max(0.0, 1.0 - sin_pitch * sin_pitch))
    rolling = params.rolling_resistance * G_MPS2 * cos_pitch
    drag = 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2 * speed_mps * abs(speed_mps) / params.mass_kg
    return rolling + drag + G_MPS2 * sin_pitch


class PedalOutput(msgspec.Struct, frozen=True):
    throttle_pct: float
    brake_pct: float
    v_ref_mps: float      # speed reference, gear frame
    a_cmd_mps2: float     # acceleration command, gear frame


class LongitudinalController:
    """Speed reference plus throttle and brake loops; stepped with an explicit ``dt_s``."""

    def __init__(self, params: VehicleParams, gains: LongitudinalGains,
                 hold_brake_pct: float) -> None:
        self.params = params
        self.gains = gains
        self.hold_brake_pct = hold_brake_pct
        self.throttle_pid = Pid(gains.throttle)
        self.brake_pid = Pid(gains.brake)
        self.reset(0.0, 0.0)

    def reset(self, speed_mps: float, accel_mps2: float, brake_pct: float = 0.0) -> None:
        """Start from the measured speed (gear frame) with the current brake effort."""
        self.v_ref_mps = max(0.0, speed_mps)
        self.a_slow_mps2 = accel_mps2
        self.a_fast_mps2 = accel_mps2
        self.braking = True
        self.throttle_pid.reset(0.0)
        self.brake_pid.reset(brake_pct)

    def step(self, dt_s: float, target_mps: float, rate_mps2: float, speed_mps: float,
             accel_mps2: float, sin_pitch: float, gear: Gear, stopped: bool) -> PedalOutput:
        """One control period. All inputs in the gear frame; ``target_mps`` >= 0 is capped already.

        ``stopped``: the (filtered) speed is below the standstill threshold.
        """
        g = self.gains
        p = self.params
        self.a_slow_mps2 = first_order_lag(accel_mps2, self.a_slow_mps2, g.throttle_filter_s, dt_s)
        self.a_fast_mps2 = first_order_lag(accel_mps2, self.a_fast_mps2, g.brake_filter_s, dt_s)

        # reference: ramp at the requested rate, ease in exponentially, stay near the vehicle
        last_ref = self.v_ref_mps
        gap = target_mps - last_ref
        if g.approach_s > 0.0:
            slope = clamp(gap / g.approach_s, -rate_mps2, rate_mps2)
        else:
            slope = math.copysign(rate_mps2, gap) if gap else 0.0
        ref = last_ref + slope * dt_s
        if (ref - target_mps) * (last_ref - target_mps) <= 0.0 or abs(ref - target_mps) < REF_SNAP_MPS:
            ref = target_mps
        # the lead limit moves the reference, never the feed-forward slope: a slope taken from
        # a reference pinned to the (noisy) measured speed would feed noise / dt forward
        ref = max(clamp(ref, speed_mps - g.max_ref_lead_mps, speed_mps + g.max_ref_lead_mps), 0.0)
        if ref == target_mps and target_mps == last_ref:
            slope = 0.0
        self.v_ref_mps = ref

        stopping = target_mps <= 0.0
        if stopping and (stopped or speed_mps <= 0.0):
            # standstill hold: a fixed brake effort (all of it if rolling back against the
            # gear), loops reset for a clean start
            hold = self.hold_brake_pct if speed_mps > -ROLLBACK_MPS else 100.0
            self.braking = True
            self.throttle_pid.reset(0.0)
            self.brake_pid.reset(hold)
            self.v_ref_mps = 0.0
            return PedalOutput(0.0, hold, 0.0, 0.0)

        if stopping and rate_mps2 >= p.max_brake_decel_mps2:
            # a stop asked at the brakes' full deceleration or more (issue 17 hard braking): full
            # brake now, not after the reference and the brake loop have ramped up
            self.braking = True
            self.throttle_pid.reset(0.0)
            self.brake_pid.reset(100.0)
            self.v_ref_mps = 0.0
            return PedalOutput(0.0, 100.0, 0.0, -p.max_brake_decel_mps2)

        a_cmd = clamp(slope + g.speed_kp_1ps * (ref - speed_mps),
                      -g.max_decel_cmd_mps2, g.max_accel_cmd_mps2)
        need = a_cmd + resistance_mps2(p, max(speed_mps, 0.0), sin_pitch)
        if stopping:
            need = min(need, -2.0 * g.coast_band_mps2)   # never throttle while bringing it to rest
        if self.braking and need > g.coast_band_mps2:
            self.braking = False
            self.brake_pid.reset(0.0)
        elif not self.braking and need < -g.coast_band_mps2:
            self.braking = True
            self.throttle_pid.reset(0.0)

        if self.braking:
            scale = 100.0 / p.max_brake_decel_mps2
            ff = scale * max(0.0, -need)
            brake = self.brake_pid.update(-a_cmd * scale, -self.a_fast_mps2 * scale, dt_s,
                                          feedforward=ff)
            return PedalOutput(0.0, brake, ref, a_cmd)
        authority = drive_authority_mps2(p, gear, max(speed_mps, 0.0))
        scale = 100.0 / max(authority, 0.1)
        ff = scale * max(0.0, need)
        throttle = self.throttle_pid.update(a_cmd * scale, self.a_slow_mps2 * scale, dt_s,
                                            feedforward=ff)
        return PedalOutput(throttle, 0.0, ref, a_cmd)
