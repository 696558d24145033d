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


ZERO_ALLOWED = frozenset({"rolling_resistance", "drag_area_m2", "start_failures",
                          "start_failure_prob", "gps_noise_m", "speed_noise_mps",
                          "accel_noise_mps2"})
"""Parameters that may be zero; every other number must be strictly positive."""


class VehicleSpecError(ValueError):
    def __init__(self, field: str, reason: str) -> None:
        self.field, self.reason = field, reason
        super().__init__(f"{field}: {reason}")


def vehicle_from_spec(spec: str | dict) -> VehicleParams:
    """Build parameters from a preset name or ``{preset: NAME, field: value, ...}``.

    Raises ``VehicleSpecError`` naming the field on an unknown preset or field, a wrong type,
    or a value out of range.
    """
    if isinstance(spec, str):
        spec = {"preset": spec}
    overrides = dict(spec)
    name = overrides.pop("preset", None)
    if name not in PRESETS:
        raise VehicleSpecError("preset", f"unknown vehicle preset {name!r} (known: {', '.join(PRESETS)})")
    base = PRESETS[name]
    fields = set(base.__struct_fields__) - {"preset", "gears"}
    for key, value in overrides.items():
        if key not in fields:
            raise VehicleSpecError(str(key), "not a vehicle parameter")
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            continue
        if isinstance(value, (int, float)):
            if not math.isfinite(value):
                raise VehicleSpecError(key, f"must be a finite number, got {value}")
            if value < 0 or (value == 0 and key not in ZERO_ALLOWED):
                raise VehicleSpecError(key, f"must be {'>= 0' if key in ZERO_ALLOWED else '> 0'}, got {value}")
            if key == "start_failure_prob" and value > 1:
                raise VehicleSpecError(key, f"is a probability, must be <= 1, got {value}")
    merged = msgspec.to_builtins(base)
    merged.update(overrides)
    try:
        params = msgspec.convert(merged, VehicleParams, strict=False)
    except msgspec.ValidationError as exc:
        raise VehicleSpecError("", str(exc).replace("`$.", "`")) from None
    for gear_name in (params.park_gear, params.drive_gear, params.low_gear, params.reverse_gear):
        if gear_name not in params.gear_names:
            raise VehicleSpecError("gears", f"{gear_name!r} is not one of {params.gear_names}")
    return params
