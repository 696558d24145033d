"""Vehicle parameters: every physical parameter the plant, the dynamics model and the servers
use, their plausible ranges and their validation (plain data in, ``VehicleParams`` or a
``VehicleSpecError`` naming the field out).

The vehicles themselves are files, one per vehicle (``dynamics/vehicles/*.yaml``: every number
with its source); ``overdrive.scenario.vehicles`` reads them, with the hostile-input-safe
reader, into ``PRESETS``. This module reads no file. Two presets ship: ``escape-hybrid`` (the
ByWire XGV base vehicle, a 2005-2008 Ford Escape Hybrid, gears P/R/N/D/L) and ``ranger-6x6``
(Team Overbot's Polaris Ranger 6x6, gears neutral/low6wd/low/high/reverse). A scenario may
override any parameter by name.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

import msgspec

from overdrive.dynamics.steering_ratio import SteeringRatioError, check_steering_ratio

G_MPS2 = 9.80665  # standard gravity
AIR_DENSITY_KGPM3 = 1.225  # ISA sea level: the drag model of the plant, the loops and the judge
DRY_MU = 0.9  # friction the preset's braking and skid-pad figures were measured on


class Gear(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One gear: direction of travel, top speed (engine redline) and tractive force at the wheels."""

    name: str
    direction: int          # +1 forward, -1 reverse, 0 neutral/park
    max_speed_mps: float    # drive force tapers to zero here (redline)
    max_force_n: float      # tractive force at full throttle below the power limit
    holds: bool = False     # park pawl: holds the vehicle like locked brakes
    all_wheel: bool = False  # every wheel driven (Ranger low6wd): full weight available for traction
    engine_brake_decel_mps2: float = 0.0  # deceleration the engine (or regeneration) gives in this
                                          # gear at closed throttle, running, above ~1 m/s; 0: none


class VehicleParams(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    preset: str
    # geometry (contract summary.json "vehicle")
    length_m: float
    width_m: float
    wheelbase_m: float
    rear_overhang_m: float
    # mass and resistance
    mass_kg: float
    drag_area_m2: float                 # Cd * frontal area
    rolling_resistance: float           # C_rr, dimensionless
    # powertrain
    driven_weight_fraction: float       # share of the weight on driven wheels (traction limit)
    max_power_w: float
    idle_rpm: float
    redline_rpm: float
    gears: tuple[Gear, ...]
    park_gear: str                      # gear selected when parked (brakes locked)
    drive_gear: str                     # default forward gear
    low_gear: str                       # forward gear for low limits / slippery / steep ground
    reverse_gear: str
    shift_time_s: float
    shift_only_stopped: bool            # the Ranger's transmission only shifts at a standstill
    crank_time_s: float
    start_failures: int = 0             # number of first crank attempts that fail (deterministic)
    start_failure_prob: float = 0.0     # chance each later attempt fails (seeded)
    # actuators
    throttle_lag_s: float = 0.15        # first-order lag of the throttle actuator
    brake_lag_s: float = 0.08           # first-order lag of the brake actuator
    max_brake_decel_mps2: float = 9.0   # deceleration at 100 % brake on dry pavement
    max_steer_rad: float = 0.5          # road-wheel angle at full lock
    steer_rate_rps: float = 0.6         # road-wheel angle rate limit of the steering actuator
    steer_lag_s: float = 0.05
    # steering-wheel angle / road-wheel angle (dynamics.steering_ratio): a number, a table
    # [[wheel_rad, ratio], ...] (variable), or None (not stated: steered by road-wheel effort)
    steering_ratio: float | tuple[tuple[float, float], ...] | None = None
    # envelope (seed 003)
    skidpad_lat_g: float = 0.8          # lateral g on the skid pad
    stopping_distance_60mph_m: float = 40.0  # 60-0 mph stopping distance (26.82 m/s)
    max_pitch_rad: float = 0.35         # steepest grade the vehicle is allowed to drive
    # rollover (seed 003; docs/driving-module.md "Rollover"): static stability factor
    track_width_m: float = 1.55         # between the tyres' centre lines (the narrower axle's)
    cg_height_m: float = 0.66           # centre of gravity above the ground, loaded as driven
    # sensors
    radar_range_m: float = 100.0        # Eaton VORAD EVT-300: ~107 m (350 ft)
    radar_half_angle_rad: float = 0.105  # VORAD beam: 12 deg wide (6 deg either side)
    gps_noise_m: float = 0.02           # RTK-grade GPS/INS position noise (1 sigma)
    speed_noise_mps: float = 0.02
    accel_noise_mps2: float = 0.05
    # sensor cross-checks (issue 30; safety.plausibility)
    speed_agree_mps: float = 0.1        # GPS/INS and wheel speeds agree within this; beyond it
                                        # (the wheels not slipping) the higher one is used
    speed_disagree_fault_mps: float = 0.3   # a disagreement beyond this (plus the fraction) ...
    speed_disagree_fault_frac: float = 0.03  # ... of the speed, for ...
    speed_disagree_confirm_s: float = 0.5   # ... this long, is a fault
    position_step_m: float = 0.25       # a GPS/INS position step beyond what the speed explains
    position_step_sigmas: float = 6.0   # ... and this many of the receiver's sigmas, is a fault
    heading_step_rad: float = 0.05      # a GPS/INS heading step beyond what the gyro explains
    # secondary braking (issue 30 item 4; dynamics.secondary_braking): what is left when the
    # service brake fails. Defaults: no parking brake usable while moving
    park_brake_decel_mps2: float = 0.0  # deceleration the parking brake gives a moving vehicle
                                        # (fully applied, dry); 0: none, or none by wire
    park_brake_apply_s: float = 1.0     # released to fully applied (a linear ramp)
    park_brake_max_apply_mps: float = 0.0   # the stack applies it while moving only at or below
                                            # this speed (rear wheels locking at speed: instability)
    park_brake_survives_hydraulic: bool = True   # it still works with the service brake's
                                                 # hydraulics failed (weak brake: its force scales)
    park_brake_survives_actuator: bool = True    # it still works with the service brake's
                                                 # by-wire actuator stuck (its own actuator)
    # the vehicle's safety devices (seed 000; issue 31 items 2 and 5): set on the vehicle
    # itself (an XGV's configuration), stated here so the stack and the simulator agree
    pause_decel_mps2: float = 2.5       # a SafeStop pause, software pause (door) or override
                                        # stop "brings the vehicle to a stop using a constant
                                        # (user set) acceleration": this one (the XGV's 2.5)
    estop_engine_cut: str = "standstill"  # e-stop disable shuts the engine off "if configured
                                          # to do so": never | standstill | always (ESTOP_ENGINE_CUTS)

    @property
    def front_overhang_m(self) -> float:
        return self.length_m - self.wheelbase_m - self.rear_overhang_m

    @property
    def max_curvature_1pm(self) -> float:
        """Tightest curvature the steering can reach (minimum turning radius)."""
        return math.tan(self.max_steer_rad) / self.wheelbase_m

    @property
    def static_stability_factor(self) -> float:
        """SSF = track / (2 h_cg): the lateral acceleration, in g, at which a rigid vehicle on
        level ground lifts its inner wheels (NHTSA's rollover measure)."""
        return self.track_width_m / (2.0 * self.cg_height_m)

    @property
    def max_decel_mps2(self) -> float:
        """Peak deceleration implied by the 60-0 mph stopping distance: v^2 / (2 d)."""
        return 26.8224**2 / (2.0 * self.stopping_distance_60mph_m)

    def gear(self, name: str) -> Gear:
        for gear in self.gears:
            if gear.name == name:
                return gear
        raise KeyError(f"{self.preset} has no gear {name!r}")

    @property
    def gear_names(self) -> tuple[str, ...]:
        return tuple(g.name for g in self.gears)


class GearTable:
    """``VehicleParams.gear`` as a dict, for code that looks gears up every control period.

    Params are frozen Structs (no cached attributes), and ``gear``/``gear_names`` search or
    build a tuple on every call; a node builds this once in ``__init__``.
    """

    __slots__ = ("_by_name",)

    def __init__(self, params: VehicleParams) -> None:
        self._by_name: dict[str, Gear] = {}
        for gear in params.gears:
            self._by_name.setdefault(gear.name, gear)   # the first of a name, as ``gear`` finds

    def get(self, name: Any) -> Gear | None:
        """The gear ``params.gear(name)`` returns; None where it would raise (no such gear)."""
        try:
            return self._by_name.get(name)
        except TypeError:   # unhashable: not a gear name
            return None

    def direction(self, name: Any) -> int:
        """The gear's direction; 0 for a name that is not a gear."""
        gear = self.get(name)
        return gear.direction if gear is not None else 0


PLAUSIBLE_RANGES: dict[str, tuple[float, float, str]] = {
    # name: (lowest, highest, where the bounds come from); both ends allowed. A bound is where
    # a value stops describing a wheeled vehicle this stack could drive (a typo, a unit
    # mistake), not a limit on ordinary vehicles.
    "length_m": (1.0, 30.0, "a 1 m robot base to a 25.25 m EU modular road train"),
    "width_m": (0.5, 3.0, "road vehicles are at most 2.55 m (EU) / 2.6 m (US) wide"),
    "wheelbase_m": (0.5, 12.0, "a golf cart has ~1.6 m; a city bus up to ~7.5 m, a coach ~8 m"),
    "rear_overhang_m": (0.0, 5.0, "zero with the axle at the back; buses reach ~3.5 m"),
    "mass_kg": (50.0, 60_000.0, "a small robot to a 44 t EU truck (US: 36 t)"),
    "drag_area_m2": (0.0, 15.0, "Cd x frontal area: a car ~0.7 m^2, a truck ~6-10 m^2"),
    "rolling_resistance": (0.0, 0.3, "C_rr: road tyres ~0.01, knobbly tyres ~0.03, sand ~0.3"),
    "driven_weight_fraction": (0.1, 1.0,
                               "a tractor's drive axle in a 5-axle rig ~0.25; all-wheel drive 1"),
    "max_power_w": (500.0, 2_000_000.0, "a 0.5 kW robot to the ~1.4 MW of the strongest road cars"),
    "idle_rpm": (300.0, 3_000.0, "large diesels idle at ~500 rpm, small engines at ~1,500"),
    "redline_rpm": (1_000.0, 20_000.0, "truck diesels ~2,500 rpm, motorcycle engines ~15,000"),
    "shift_time_s": (0.01, 10.0, "a dual-clutch shift ~0.1 s, a manual truck box a few seconds"),
    "crank_time_s": (0.1, 30.0, "an engine cranks for ~1 s; starters are rated for ~30 s"),
    "start_failures": (0, 100, "failed crank attempts to simulate: a handful is a test"),
    "start_failure_prob": (0.0, 1.0, "a probability"),
    "throttle_lag_s": (0.005, 5.0, "electronic throttles ~0.05 s, cable actuators ~0.3 s"),
    "brake_lag_s": (0.005, 5.0, "hydraulic brakes ~0.1 s, air brakes ~0.5 s"),
    "max_brake_decel_mps2": (1.0, 15.0, "road tyres give ~1.0-1.2 g; 15 m/s^2 is ~1.5 g"),
    "max_steer_rad": (0.05, 1.05, "road-wheel angle at full lock: cars ~0.6 rad, 60 deg at most"),
    "steer_rate_rps": (0.05, 5.0, "road-wheel rate: power steering ~1 rad/s"),
    "steer_lag_s": (0.005, 5.0, "first-order lag of the steering actuator"),
    "skidpad_lat_g": (0.1, 1.5, "road cars 0.7-1.0 g; 1.5 g only with downforce"),
    "stopping_distance_60mph_m": (25.0, 300.0,
                                  "60-0 mph: the best cars ~30 m, loaded trucks ~100 m"),
    "max_pitch_rad": (0.01, 0.8, "steepest grade driven: 0.8 rad (~100 %) is beyond most vehicles"),
    "track_width_m": (0.3, 3.0, "a small robot base ~0.3 m; road vehicles are at most 2.6 m wide"),
    "cg_height_m": (0.1, 4.0, "a go-kart ~0.25 m, cars ~0.5 m, a loaded truck ~2 m; 4 m is the "
                              "tallest road vehicle"),
    "radar_range_m": (1.0, 500.0, "automotive long-range radars reach ~250 m"),
    "radar_half_angle_rad": (0.005, 1.6, "half the beam width: up to +-90 deg"),
    "gps_noise_m": (0.0, 50.0, "1 sigma: RTK ~0.02 m, standalone GPS ~5 m"),
    "speed_noise_mps": (0.0, 5.0, "1 sigma of the wheel-speed reading"),
    "accel_noise_mps2": (0.0, 5.0, "1 sigma of the accelerometer reading"),
    "speed_agree_mps": (0.01, 5.0, "a few sigma of two speed readings' difference"),
    "speed_disagree_fault_mps": (0.05, 10.0, "above the agreement band, below a speed limit's "
                                             "worth"),
    "speed_disagree_fault_frac": (0.0, 0.3, "tyre rolling radius: ~3 % with wear and pressure"),
    "speed_disagree_confirm_s": (0.01, 10.0, "a few control periods to a few seconds"),
    "position_step_m": (0.01, 100.0, "RTK ~0.02 m noise to standalone GPS ~5 m"),
    "position_step_sigmas": (3.0, 100.0, "a step is at least 3 sigma of the reported noise"),
    "heading_step_rad": (0.001, 3.2, "INS heading noise ~0.002-0.02 rad"),
    "park_brake_decel_mps2": (0.0, 9.8, "0: none; a parking brake on one axle gives at most "
                                        "that axle's share of ~1 g"),
    "park_brake_apply_s": (0.01, 10.0, "electric parking brakes ~0.5-1 s, a lever actuator a "
                                       "few seconds"),
    "park_brake_max_apply_mps": (0.0, 70.0, "0: only at rest; up to the fastest speed driven"),
    "pause_decel_mps2": (1.0, 15.0, "at least 1 m/s^2 (8 m/s stops in 32 m; the XGV simulator's "
                                    "link-loss stop uses it too: at 0.1 it took 320 m); at most "
                                    "the brakes' full deceleration (checked against this vehicle's)"),
}
"""Physically plausible range of every number a scenario may override (docs/scenarios.md)."""


GEAR_RANGES: dict[str, tuple[float, float, str]] = {
    # the numbers of one gear, bounded like PLAUSIBLE_RANGES: a typo or a unit mistake
    "max_speed_mps": (0.0, 100.0, "top speed in the gear: 100 m/s (360 km/h) is beyond any "
                                  "vehicle this stack drives"),
    "max_force_n": (0.0, 1_000_000.0, "force at the wheels: a car ~5 kN, a 44 t truck in its "
                                      "lowest gear ~200 kN"),
    "engine_brake_decel_mps2": (0.0, 5.0, "closed-throttle retardation: a car's engine ~0.3-1 "
                                          "m/s^2, a truck's exhaust brake ~1-2; 5 is ~0.5 g"),
}
"""Plausible range of each number of a gear in a vehicle file."""

MAX_GEARS = 32
"""Gears a vehicle may list: an 18-speed truck box has 18 forward and 4 reverse."""

GEAR_ROLES: dict[str, tuple[int, str]] = {
    "park_gear": (0, "a gear that does not drive (direction 0)"),
    "drive_gear": (1, "a forward gear (direction 1)"),
    "low_gear": (1, "a forward gear (direction 1)"),
    "reverse_gear": (-1, "a reverse gear (direction -1)"),
}
"""The roles a vehicle's gears play and the direction each must have."""

SENSOR_CHECKS: tuple[str, ...] = (
    "speed_agree_mps", "speed_disagree_fault_mps", "speed_disagree_fault_frac",
    "speed_disagree_confirm_s", "position_step_m", "position_step_sigmas", "heading_step_rad")
"""The sensor cross-checks' thresholds (issue 30): the shipped files state them; a file written
before them gets the defaults above (RTK-grade GPS/INS, 0.02 m/s speed noise)."""

SECONDARY_BRAKING: tuple[str, ...] = (
    "park_brake_decel_mps2", "park_brake_apply_s", "park_brake_max_apply_mps",
    "park_brake_survives_hydraulic", "park_brake_survives_actuator")
"""The parking brake's parameters (issue 30 item 4): the shipped files state them; a file
written before them gets the defaults above (no parking brake usable while moving)."""

SAFETY_DEVICES: tuple[str, ...] = ("pause_decel_mps2", "estop_engine_cut")
"""How the vehicle's own pause and e-stop act (issue 31): the shipped files state them; a file
written before them gets the defaults above (the XGV's 2.5 m/s^2 pause, the engine cut at rest)."""

ESTOP_ENGINE_CUTS: dict[str, str] = {
    "never": "the engine keeps running in e-stop disable",
    "standstill": "cut once the vehicle stands (at once if the throttle does not close)",
    "always": "cut at once, moving or not (power steering and brake assist lost while moving)",
}
"""``estop_engine_cut`` values (seed 000's e-stop disable: "shut off the engine (if configured
to do so)"); docs/drive-your-own-vehicle.md, "Safety devices", justifies the default."""

CHOICES: dict[str, dict[str, str]] = {"estop_engine_cut": ESTOP_ENGINE_CUTS}
"""Parameters that take one of a few names."""

STEERING_RATIO = "steering_ratio"
"""A number or a table, checked by ``dynamics.steering_ratio.check_steering_ratio``; None (not
stated) by default: only a kit steering by the steering wheel (PACMod 3) needs it."""

OPTIONAL_IN_FILE = frozenset({"start_failures", "start_failure_prob", *SENSOR_CHECKS,
                              *SECONDARY_BRAKING, *SAFETY_DEVICES, STEERING_RATIO})
"""Simulation knobs (failed crank attempts, 0 unless stated), the sensor cross-checks'
thresholds, the parking brake and the safety devices (defaults unless stated): every other field
is required."""

_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")
_FIELD_TYPES: dict[str, Any] = {f.name: f.type for f in msgspec.structs.fields(VehicleParams)}
PARAMETERS: tuple[str, ...] = tuple(f for f in _FIELD_TYPES if f not in ("preset", "gears"))
"""The parameters a scenario may override: every field but the name and the gear table."""
FILE_FIELDS: tuple[str, ...] = tuple("name" if f == "preset" else f for f in _FIELD_TYPES)
"""The fields of a vehicle file (``name`` is ``VehicleParams.preset``), in the shipped files'
order."""
_GEAR_TYPES: dict[str, Any] = {f.name: f.type for f in msgspec.structs.fields(Gear)}
_GEAR_REQUIRED = tuple(f.name for f in msgspec.structs.fields(Gear) if f.required)

_UNITS = {"m": "m", "m2": "m²", "kg": "kg", "w": "W", "n": "N", "rpm": "rev/min", "s": "s",
          "mps": "m/s", "mps2": "m/s²", "rad": "rad", "rps": "rad/s", "g": "g"}
"""Unit suffixes of the field names, for "did you mean" on a field given in another unit."""


class VehicleSpecError(ValueError):
    """An invalid vehicle: ``field`` is the path to the value ("" for the whole vehicle)."""

    def __init__(self, field: str, reason: str) -> None:
        self.field, self.reason = field, reason
        super().__init__(f"{field}: {reason}" if field else reason)


def did_you_mean(key: str, known: Iterable[str]) -> str:
    """``"; did you mean mass_kg? (the unit is kg)"`` for ``mass_lb`` or ``mass``: a known field
    of the same quantity in another unit, else a close spelling, else ``""``."""
    known = list(known)
    stem = key.rsplit("_", 1)[0]
    for name in known:
        base, _, unit = name.rpartition("_")
        if base and unit in _UNITS and base in (stem, key):
            return f"; did you mean {name}? (the unit is {_UNITS[unit]})"
    close = difflib.get_close_matches(key, known, n=1, cutoff=0.75)
    return f"; did you mean {close[0]}?" if close else ""


def _check_value(field: str, value: Any, expected: Any,
                 bounds: tuple[float, float, str] | None) -> None:
    """``value`` has the ``expected`` type (YAML numbers: a quoted number is a string; a whole
    number is a number, a fraction no whole number) and, for a number, is finite and in range."""
    if expected in (int, float):
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or (expected is int and not isinstance(value, int))):
            raise VehicleSpecError(field, f"must be a {_TYPE_WORDS[expected]}, got {_show(value)}")
        if isinstance(value, float) and not math.isfinite(value):
            raise VehicleSpecError(field, f"must be a finite number, got {value}")
        if bounds is not None:
            low, high, why = bounds
            if not low <= value <= high:    # a huge int compares exactly
                raise VehicleSpecError(field, f"must be within {low:g}..{high:g} ({why}), "
                                              f"got {_show(value)}")
    elif type(value) is not expected:
        raise VehicleSpecError(field, f"must be a {_TYPE_WORDS[expected]}, got {_show(value)}")
    elif field in CHOICES and value not in CHOICES[field]:
        raise VehicleSpecError(field, f"must be one of {', '.join(CHOICES[field])}, got "
                                      f"{_show(value)}")


_TYPE_WORDS = {float: "number", int: "whole number", bool: "boolean (true/false)", str: "string"}


def _show(value: Any) -> str:
    """A value as the file spelled it, cut short: ``null``, ``true``, ``the string '-1700'``."""
    if value is None or isinstance(value, bool):
        return {None: "null", True: "true", False: "false"}[value]
    text = repr(value)
    text = text if len(text) <= 24 else f"{text[:20]}... ({len(text)} characters)"
    return f"the string {text}" if isinstance(value, str) else text


def _check_name(field: str, value: Any) -> None:
    if not isinstance(value, str) or not _NAME.fullmatch(value):
        raise VehicleSpecError(field, "must be a name of letters, digits, '.', '_' and '-' "
                                      f"(at most 64 characters), got {_show(value)}")


def _check_field(key: str, value: Any) -> None:
    """One parameter's value: the steering ratio by its own rules, the rest by type and range."""
    if key == STEERING_RATIO:
        try:
            check_steering_ratio(value)
        except SteeringRatioError as e:
            raise VehicleSpecError(key, str(e)) from None
    else:
        _check_value(key, value, _FIELD_TYPES[key], PLAUSIBLE_RANGES.get(key))


def _check_roles(params: VehicleParams) -> None:
    """Each gear role names a gear of the vehicle, one that moves the way the role needs."""
    by_name = {g.name: g for g in params.gears}
    for role, (direction, what) in GEAR_ROLES.items():
        name = getattr(params, role)
        gear = by_name.get(name)
        if gear is None:
            raise VehicleSpecError(role, f"{name!r:.40} names no gear of {params.preset} "
                                         f"(gears: {', '.join(params.gear_names)})")
        if gear.direction != direction:
            raise VehicleSpecError(role, f"{name!r} has direction {gear.direction}; the "
                                         f"{role} must be {what}")


def _check_consistent(params: VehicleParams, given: set[str]) -> None:
    """Cross-field checks: the geometry adds up and the engine's speed range is not empty."""
    if params.wheelbase_m + params.rear_overhang_m > params.length_m:
        field = next((f for f in ("wheelbase_m", "rear_overhang_m") if f in given), "length_m")
        raise VehicleSpecError(field, f"wheelbase_m {params.wheelbase_m:g} + rear_overhang_m "
                                      f"{params.rear_overhang_m:g} is longer than length_m "
                                      f"{params.length_m:g} (the axles must fit in the vehicle)")
    if params.track_width_m > params.width_m:
        field = "track_width_m" if "track_width_m" in given else "width_m"
        raise VehicleSpecError(field, f"track_width_m {params.track_width_m:g} is wider than "
                                      f"width_m {params.width_m:g} (the tyres are inside the "
                                      f"vehicle)")
    if params.idle_rpm >= params.redline_rpm:
        field = "idle_rpm" if "idle_rpm" in given else "redline_rpm"
        raise VehicleSpecError(field, f"idle_rpm {params.idle_rpm:g} must be below redline_rpm "
                                      f"{params.redline_rpm:g}")
    tyres_mps2 = min(params.max_brake_decel_mps2, params.max_decel_mps2)
    if params.pause_decel_mps2 > tyres_mps2:
        field = next((f for f in ("pause_decel_mps2", "max_brake_decel_mps2",
                                  "stopping_distance_60mph_m") if f in given), "pause_decel_mps2")
        raise VehicleSpecError(field, f"pause_decel_mps2 {params.pause_decel_mps2:g} is more than "
                                      f"the tyres hold: the full brake's {tyres_mps2:.3g} m/s^2 "
                                      f"(max_brake_decel_mps2, and the 60-0 mph stop's "
                                      f"v^2 / 2d from stopping_distance_60mph_m)")
    for i, gear in enumerate(params.gears):
        if gear.direction == 0 and gear.engine_brake_decel_mps2 > 0.0:
            raise VehicleSpecError(f"gears[{i}].engine_brake_decel_mps2",
                                   f"{gear.name!r} does not drive (direction 0): it has no "
                                   f"engine braking")


def with_overrides(base: VehicleParams, overrides: Mapping[Any, Any]) -> VehicleParams:
    """``base`` with some parameters replaced (a scenario's ``vehicle: {preset: NAME, ...}``).

    Raises ``VehicleSpecError`` naming the field on an unknown field (saying which field is
    meant when only the unit is wrong), a wrong type (a quoted number is a string), a value
    outside ``PLAUSIBLE_RANGES``, a gear role naming no gear or the wrong kind of gear, or an
    inconsistent combination (axles longer than the vehicle).
    """
    for key, value in overrides.items():
        if key not in PARAMETERS:
            raise VehicleSpecError(str(key), "not a vehicle parameter"
                                             + did_you_mean(str(key), PARAMETERS))
        _check_field(key, value)
    merged = msgspec.to_builtins(base)
    merged.update(overrides)
    params = msgspec.convert(merged, VehicleParams)
    _check_roles(params)
    _check_consistent(params, set(overrides))
    return params


def vehicle_from_data(data: Any) -> VehicleParams:
    """A whole vehicle from plain data (a vehicle file as loaded): ``name``, every parameter
    (``OPTIONAL_IN_FILE`` may be left out) and the ``gears`` list.

    Raises ``VehicleSpecError`` with the field path (``mass_kg``, ``gears[2].direction``) on
    everything ``with_overrides`` refuses, and on a missing field or a malformed gear table.
    """
    if not isinstance(data, dict):
        raise VehicleSpecError("", "a vehicle must be a mapping of its fields to values, got "
                                   + _show(data))
    for key in data:
        if key not in FILE_FIELDS:
            hint = ("; a vehicle names itself with name:" if key == "preset"
                    else did_you_mean(str(key), FILE_FIELDS))
            raise VehicleSpecError(str(key), "not a vehicle parameter" + hint)
    for key in FILE_FIELDS:
        if key not in data and key not in OPTIONAL_IN_FILE:
            raise VehicleSpecError(key, "required field missing")
    _check_name("name", data["name"])
    values = {k: data[k] for k in PARAMETERS if k in data}
    for key, value in values.items():
        _check_field(key, value)
    if (values.get("park_brake_decel_mps2", 0.0) > 0.0
            and values.get("park_brake_max_apply_mps", 0.0) > 0.0
            and "park_brake_apply_s" not in values):
        raise VehicleSpecError("park_brake_apply_s", "required for a parking brake that may brake "
                                                     "a moving vehicle (it sets the ramp the "
                                                     "stop and the judge's distance use)")
    gears = _gears_from_data(data["gears"])
    params = msgspec.convert({"preset": data["name"], **values, "gears": gears}, VehicleParams)
    _check_roles(params)
    _check_consistent(params, set(data))
    return params


def _gears_from_data(value: Any) -> list[dict[str, Any]]:
    """The gear table: a list of ``{name, direction, max_speed_mps, max_force_n}`` (``holds``
    and ``all_wheel`` false, ``engine_brake_decel_mps2`` 0 unless given), names unique, a
    driving gear able to drive."""
    if not isinstance(value, list) or not value:
        raise VehicleSpecError("gears", "must be a list of gears, each {name, direction, "
                                        f"max_speed_mps, max_force_n}}, got {_show(value)}")
    if len(value) > MAX_GEARS:
        raise VehicleSpecError("gears", f"{len(value)} gears (at most {MAX_GEARS})")
    seen: dict[str, int] = {}
    for i, gear in enumerate(value):
        where = f"gears[{i}]"
        if not isinstance(gear, dict):
            raise VehicleSpecError(where, "must be a mapping {name, direction, max_speed_mps, "
                                          f"max_force_n}}, got {_show(gear)}")
        for key in gear:
            if key not in _GEAR_TYPES:
                raise VehicleSpecError(f"{where}.{key}", "not a gear field"
                                                         + did_you_mean(str(key), _GEAR_TYPES))
        for key in _GEAR_REQUIRED:
            if key not in gear:
                raise VehicleSpecError(f"{where}.{key}", "required field missing")
        _check_name(f"{where}.name", gear["name"])
        if gear["name"] in seen:
            raise VehicleSpecError(f"{where}.name", f"{gear['name']!r} is already the name of "
                                                    f"gears[{seen[gear['name']]}]")
        seen[gear["name"]] = i
        for key, value_ in gear.items():
            if key != "name":
                _check_value(f"{where}.{key}", value_, _GEAR_TYPES[key], GEAR_RANGES.get(key))
        if gear["direction"] not in (-1, 0, 1):
            raise VehicleSpecError(f"{where}.direction", "must be 1 (forward), -1 (reverse) or 0 "
                                                         f"(neutral/park), got {gear['direction']}")
        if gear["direction"] != 0 and not (gear["max_speed_mps"] > 0 and gear["max_force_n"] > 0):
            field = "max_speed_mps" if gear["max_speed_mps"] <= 0 else "max_force_n"
            raise VehicleSpecError(f"{where}.{field}", "a gear that drives (direction 1 or -1) "
                                                       "needs a top speed and a force above 0")
    return value


def vehicle_to_data(params: VehicleParams) -> dict[str, Any]:
    """``params`` as ``vehicle_from_data`` reads them: a vehicle file's fields, in its order."""
    data = msgspec.to_builtins(params)
    data["name"] = data.pop("preset")
    data["gears"] = list(data["gears"])     # a list, as YAML and JSON hold it
    return {key: data[key] for key in FILE_FIELDS}
