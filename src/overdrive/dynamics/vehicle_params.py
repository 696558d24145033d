"""Vehicle presets: every physical parameter the plant, the dynamics model and the servers use.

Two presets come from the seeds: ``escape-hybrid`` (the ByWire XGV base vehicle, a 2005-2008
Ford Escape Hybrid, gears P/R/N/D/L) and ``ranger-6x6`` (Team Overbot's Polaris Ranger 6x6,
gears neutral/low6wd/low/high/reverse). A scenario may override any field by name.
Numbers come from manufacturer data where it exists; the rest are stated engineering estimates.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec

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
    # envelope (seed 003)
    skidpad_lat_g: float = 0.8          # lateral g on the skid pad
    stopping_distance_60mph_m: float = 40.0  # 60-0 mph stopping distance (26.82 m/s)
    max_pitch_rad: float = 0.35         # steepest grade the vehicle is allowed to drive
    # sensors
    radar_range_m: float = 100.0        # Eaton VORAD EVT-300: ~107 m (350 ft)
    radar_half_angle_rad: float = 0.105  # VORAD beam: 12 deg wide (6 deg either side)
    gps_noise_m: float = 0.02           # RTK-grade GPS/INS position noise (1 sigma)
    speed_noise_mps: float = 0.02
    accel_noise_mps2: float = 0.05

    @property
    def front_overhang_m(self) -> float:
        return self.length_m - self.wheelbase_m - self.rear_overhang_m

    @property
    def max_curvature_1pm(self) -> float:
        """Tightest curvature the steering can reach (minimum turning radius)."""
        return math.tan(self.max_steer_rad) / self.wheelbase_m

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


MPH = 0.44704  # m/s per mph

ESCAPE_HYBRID = VehicleParams(
    preset="escape-hybrid",
    # Ford Escape Hybrid 2005: 174.9 in long, 70.1 in wide, 103.1 in wheelbase
    length_m=4.44, width_m=1.78, wheelbase_m=2.62, rear_overhang_m=0.92,
    mass_kg=1700.0,                  # 1,660 kg curb + XGV equipment
    drag_area_m2=0.42 * 2.4,         # Cd 0.42, frontal area 2.4 m^2
    rolling_resistance=0.012,
    driven_weight_fraction=0.6,      # front-wheel drive, ~60 % of the weight on the front axle
    max_power_w=115_000.0,           # 155 hp combined system output
    idle_rpm=800.0, redline_rpm=5500.0,
    gears=(
        Gear("park", 0, 0.0, 0.0, holds=True),
        Gear("reverse", -1, 9.0, 5000.0),
        Gear("neutral", 0, 0.0, 0.0),
        Gear("drive", 1, 45.0, 5200.0),
        Gear("low", 1, 20.0, 6000.0),   # eCVT "L": engine braking, capped for the stack
    ),
    park_gear="park", drive_gear="drive", low_gear="low", reverse_gear="reverse",
    shift_time_s=0.5, shift_only_stopped=False, crank_time_s=1.2,
    max_brake_decel_mps2=9.0,
    max_steer_rad=math.atan(2.62 / 5.6),   # 11.6 m curb-to-curb turning circle
    steer_rate_rps=0.5,
    skidpad_lat_g=0.74,              # published skid-pad figure for the 2005 Escape
    stopping_distance_60mph_m=41.0,  # published 60-0 mph: 134 ft
    max_pitch_rad=math.atan(0.30),   # 30 % grade
)

RANGER_6X6 = VehicleParams(
    preset="ranger-6x6",
    # Polaris Ranger 6x6 (2004): 143.5 in long, 60 in wide; wheelbase to the middle axle pair
    length_m=3.65, width_m=1.52, wheelbase_m=2.45, rear_overhang_m=0.55,
    mass_kg=1050.0,                  # 590 kg dry + Overbot computers, sensors, fuel
    drag_area_m2=1.1 * 1.9,          # boxy utility vehicle with roll cage
    rolling_resistance=0.03,         # knobby off-road tyres
    driven_weight_fraction=0.67,     # 4 of 6 wheels (rear tandem) driven outside low6wd
    max_power_w=15_000.0,            # 20 hp Polaris engine
    idle_rpm=1200.0, redline_rpm=4500.0,
    gears=(
        Gear("neutral", 0, 0.0, 0.0),
        Gear("low6wd", 1, 10.0 * MPH, 6500.0, all_wheel=True),   # seed 001: stay below 10 mph
        Gear("low", 1, 17.0 * MPH, 4500.0),      # seed 001: low limited to about 17 mph
        Gear("high", 1, 25.0 * MPH, 2600.0),     # Ranger 6x6 top speed ~25 mph
        Gear("reverse", -1, 8.0 * MPH, 4000.0),
    ),
    park_gear="neutral", drive_gear="high", low_gear="low6wd", reverse_gear="reverse",
    shift_time_s=1.5, shift_only_stopped=True, crank_time_s=2.0,
    max_brake_decel_mps2=6.5,
    max_steer_rad=math.atan(2.45 / 6.1),   # ~12 m turning circle
    steer_rate_rps=0.35,             # Overbot's steering motor, slower than a production EPS
    skidpad_lat_g=0.55,              # high centre of gravity
    stopping_distance_60mph_m=60.0,  # extrapolated from 25-0 mph tests on dirt
    max_pitch_rad=math.atan(0.35),
)

PRESETS: dict[str, VehicleParams] = {p.preset: p for p in (ESCAPE_HYBRID, RANGER_6X6)}


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
    "radar_range_m": (1.0, 500.0, "automotive long-range radars reach ~250 m"),
    "radar_half_angle_rad": (0.005, 1.6, "half the beam width: up to +-90 deg"),
    "gps_noise_m": (0.0, 50.0, "1 sigma: RTK ~0.02 m, standalone GPS ~5 m"),
    "speed_noise_mps": (0.0, 5.0, "1 sigma of the wheel-speed reading"),
    "accel_noise_mps2": (0.0, 5.0, "1 sigma of the accelerometer reading"),
}
"""Physically plausible range of every number a scenario may override (docs/scenarios.md)."""


class VehicleSpecError(ValueError):
    def __init__(self, field: str, reason: str) -> None:
        self.field, self.reason = field, reason
        super().__init__(f"{field}: {reason}")


def _check_override(key: str, value: Any, base: VehicleParams) -> None:
    """One override has the base value's type (YAML numbers: no quoted numbers) and, for a
    number, lies within ``PLAUSIBLE_RANGES``."""
    expected = type(getattr(base, key))
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if type(value) is not expected:
            raise VehicleSpecError(key, f"must be a {_TYPE_WORDS[expected]}, got {_show(value)}")
        return
    if expected is bool or expected is str or (expected is int and not isinstance(value, int)):
        raise VehicleSpecError(key, f"must be a {_TYPE_WORDS[expected]}, got {_show(value)}")
    low, high, why = PLAUSIBLE_RANGES[key]
    if not low <= value <= high:    # NaN fails this too; a huge int compares exactly
        raise VehicleSpecError(key, f"must be within {low:g}..{high:g} ({why}), got {_show(value)}")


_TYPE_WORDS = {float: "number", int: "whole number", bool: "boolean (true/false)", str: "string"}


def _show(value: Any) -> str:
    """A value as the file spelled it, cut short: ``null``, ``true``, ``the string '-1700'``."""
    if value is None or isinstance(value, bool):
        return {None: "null", True: "true", False: "false"}[value]
    text = repr(value)
    text = text if len(text) <= 24 else f"{text[:20]}... ({len(text)} characters)"
    return f"the string {text}" if isinstance(value, str) else text


def _check_consistent(params: VehicleParams, overridden: set[str]) -> None:
    """Cross-field checks: the geometry adds up and the engine's speed range is not empty."""
    if params.wheelbase_m + params.rear_overhang_m > params.length_m:
        field = next((f for f in ("wheelbase_m", "rear_overhang_m") if f in overridden), "length_m")
        raise VehicleSpecError(field, f"wheelbase_m {params.wheelbase_m:g} + rear_overhang_m "
                                      f"{params.rear_overhang_m:g} is longer than length_m "
                                      f"{params.length_m:g} (the axles must fit in the vehicle)")
    if params.idle_rpm >= params.redline_rpm:
        field = "idle_rpm" if "idle_rpm" in overridden else "redline_rpm"
        raise VehicleSpecError(field, f"idle_rpm {params.idle_rpm:g} must be below redline_rpm "
                                      f"{params.redline_rpm:g}")


def vehicle_from_spec(spec: str | dict) -> VehicleParams:
    """Build parameters from a preset name or ``{preset: NAME, field: value, ...}``.

    Raises ``VehicleSpecError`` naming the field on an unknown preset or field, a wrong type
    (a quoted number is a string), a value outside ``PLAUSIBLE_RANGES`` or an inconsistent
    combination (axles longer than the vehicle).
    """
    if isinstance(spec, str):
        spec = {"preset": spec}
    overrides = dict(spec)
    name = overrides.pop("preset", None)
    if not isinstance(name, str) or name not in PRESETS:
        raise VehicleSpecError("preset", f"unknown vehicle preset {name!r:.40} "
                                         f"(known: {', '.join(PRESETS)})")
    base = PRESETS[name]
    fields = set(base.__struct_fields__) - {"preset", "gears"}
    for key, value in overrides.items():
        if key not in fields:
            raise VehicleSpecError(str(key), "not a vehicle parameter")
        _check_override(key, value, base)
    merged = msgspec.to_builtins(base)
    merged.update(overrides)
    params = msgspec.convert(merged, VehicleParams)
    for role in ("park_gear", "drive_gear", "low_gear", "reverse_gear"):
        if getattr(params, role) not in params.gear_names:
            raise VehicleSpecError(role, f"{getattr(params, role)!r:.40} is not one of the "
                                         f"preset's gears {params.gear_names}")
    _check_consistent(params, set(overrides))
    return params
