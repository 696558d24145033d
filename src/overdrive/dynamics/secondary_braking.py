"""Secondary braking (issue 30 item 4): what a vehicle has left when its service brake fails,
and the stopping distance that allows.

Pure functions of the vehicle file (``VehicleParams``): engine braking per gear, whether the
gearbox may downshift while moving, the parking brake (deceleration, application ramp, the speed
at or below which it may be applied). The plant (``vehicle.plant``) models the same forces with
the same constants; the speed server uses ``secondary_gear``; the judge states
``secondary_stop_m`` as the distance a run with a failed service brake is allowed.
"""

from __future__ import annotations

import math

from overdrive.dynamics.vehicle_params import AIR_DENSITY_KGPM3, G_MPS2, Gear, VehicleParams

ENGINE_BRAKE_FADE_MPS = 1.0
"""Engine braking fades linearly to 0 below this speed: engineering estimate, the torque
converter or centrifugal clutch slips near idle and a hybrid's regeneration fades out."""
ENGINE_BRAKE_CLOSED_THROTTLE = 0.05
"""Engine braking fades linearly from closed throttle to 0 at this throttle (5 %): engineering
estimate, the throttle that balances an engine's friction at low load. Above it nominal
driving sees no engine braking."""
SECONDARY_STEP_S = 0.01
"""Integration step of ``secondary_stop_m``: the plant's and the controllers' period."""
SECONDARY_HORIZON_S = 600.0
"""``secondary_stop_m`` gives up (infinite distance) after this long: a grade the secondary
brakes cannot hold."""


def engine_brake_factor(throttle: float, along_mps: float) -> float:
    """Share (0..1) of a gear's engine braking at this throttle (0..1) and speed along the
    gear's direction: full at closed throttle above ``ENGINE_BRAKE_FADE_MPS``."""
    closed = max(0.0, 1.0 - throttle / ENGINE_BRAKE_CLOSED_THROTTLE)
    return closed * min(max(along_mps, 0.0) / ENGINE_BRAKE_FADE_MPS, 1.0)


def engine_brake_mps2(gear: Gear, throttle: float, along_mps: float,
                      engine_running: bool = True) -> float:
    """The engine braking deceleration in ``gear`` at this throttle (0..1) and speed along the
    gear's direction, as the plant gives it (0 with the engine off or out of gear): the
    brake checks and the actuator model take it out of what they credit to the brake."""
    if not engine_running or gear.direction == 0:
        return 0.0
    return gear.engine_brake_decel_mps2 * engine_brake_factor(throttle, along_mps)


def secondary_gear(params: VehicleParams, gear: Gear, speed_mps: float) -> Gear:
    """The gear that brakes hardest at ``speed_mps`` (magnitude): the current one, or on a gearbox
    that may shift while moving a gear of the same direction whose top speed exceeds the speed
    and whose engine braking is stronger (a downshift never overspeeds the engine)."""
    best = gear
    if params.shift_only_stopped or gear.direction == 0:
        return best
    for candidate in params.gears:
        if (candidate.direction == gear.direction and candidate.max_speed_mps > abs(speed_mps)
                and candidate.engine_brake_decel_mps2 > best.engine_brake_decel_mps2):
            best = candidate
    return best


def has_engine_braking(params: VehicleParams, gear: Gear, speed_mps: float) -> bool:
    """True when the engine can brake the vehicle now or once it is slower: in this gear, or
    on a gearbox that may shift while moving in any gear of its direction (a gear whose top
    speed is below ``speed_mps`` is shifted into once the vehicle has slowed under it, so the
    engine is worth keeping running above it too)."""
    if gear.engine_brake_decel_mps2 > 0.0:
        return True
    if params.shift_only_stopped or gear.direction == 0 or not math.isfinite(speed_mps):
        return False
    return any(g.direction == gear.direction and g.engine_brake_decel_mps2 > 0.0
               for g in params.gears)


def secondary_stop_m(params: VehicleParams, speed_mps: float, gear: Gear, *,
                     pitch_rad: float = 0.0, friction: float = 0.8, reaction_s: float = 0.0,
                     engine_braking: bool = True, park_brake: bool = True,
                     downshift: bool = True) -> float:
    """Distance to rest from ``speed_mps`` (>= 0, in the gear's direction; ``pitch_rad`` > 0
    uphill along it) with the service brake gone, using what the vehicle has.

    ``reaction_s`` at closed throttle in the current gear (detection and response), then: a
    downshift to ``secondary_gear`` whenever the speed allows one (at the start or once the
    vehicle has slowed under a braking gear's top speed; ``shift_time_s`` without engine
    braking each), engine braking in the gear reached, the parking brake applied as soon as the speed is at or below
    ``park_brake_max_apply_mps`` and ramped linearly over ``park_brake_apply_s``, rolling
    resistance, drag and gravity as the plant has them; the braking (engine and parking brake)
    capped by the grip ``friction * g * cos(pitch)``. ``engine_braking``, ``park_brake`` and
    ``downshift`` False leave that means out (a failed parking brake, a cut engine). Infinite
    when the vehicle does not stop within ``SECONDARY_HORIZON_S`` (a grade too steep).
    """
    if not (math.isfinite(speed_mps) and speed_mps >= 0.0):
        raise ValueError(f"speed_mps must be finite and >= 0, got {speed_mps}")
    dt = SECONDARY_STEP_S
    m = params.mass_kg
    cos_p, sin_p = math.cos(pitch_rad), math.sin(pitch_rad)
    grip_mps2 = friction * G_MPS2 * cos_p
    resist_mps2 = params.rolling_resistance * G_MPS2 * cos_p
    drag_k = 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2 / m
    current = gear
    shift_until: float | None = None   # a downshift under way until then
    park_ok = park_brake and params.park_brake_decel_mps2 > 0.0
    v, distance, t = speed_mps, 0.0, 0.0
    park_since: float | None = None
    while v > 0.0:
        if t >= SECONDARY_HORIZON_S:
            return math.inf
        in_gear: Gear | None = current
        if shift_until is not None:
            if t < shift_until:
                in_gear = None   # shifting: no engine braking
            else:
                shift_until = None
        elif downshift and t >= reaction_s:
            want = secondary_gear(params, current, v)
            if want is not current:
                current, shift_until, in_gear = want, t + params.shift_time_s, None
        engine = (in_gear.engine_brake_decel_mps2 * engine_brake_factor(0.0, v)
                  if engine_braking and in_gear is not None else 0.0)
        park = 0.0
        if park_ok and t >= reaction_s and v <= params.park_brake_max_apply_mps:
            park_since = t if park_since is None else park_since
            ramp = min((t - park_since) / params.park_brake_apply_s, 1.0)
            park = ramp * params.park_brake_decel_mps2
        decel = (min(engine + park, grip_mps2) + resist_mps2 + drag_k * v * v
                 + G_MPS2 * sin_p)
        v_next = v - decel * dt
        if v_next <= 0.0 < decel:
            distance += 0.5 * v * v / decel
            break
        distance += 0.5 * (v + v_next) * dt
        v, t = v_next, t + dt
    return distance


__all__ = ["ENGINE_BRAKE_CLOSED_THROTTLE", "ENGINE_BRAKE_FADE_MPS", "engine_brake_factor",
           "engine_brake_mps2",
           "has_engine_braking", "secondary_gear", "secondary_stop_m"]
