"""The simulated vehicle: longitudinal and lateral dynamics, actuators, powertrain, world.

A pure model stepped with an explicit ``dt_s``; it owns no clock and no bus. Randomness
(engine starts) comes from a ``random.Random`` the caller seeds.

Model (SI units, x forward along the heading):

- Drive force ``F_d = throttle * min(F_gear, P_max / max(|v|, 0.5 m/s))``, tapering to zero over
  the last 10 % below the gear's top speed (redline); none while shifting or with the engine off.
- Brake force ``F_b = brake * m * a_brake_max``, opposing motion; the park pawl or parking
  brake holds a stopped vehicle with ``m * a_brake_max``.
- Secondary braking (issue 30 item 4; ``dynamics.secondary_braking``): engine braking
  ``m * a_engine(gear) * f(throttle, v)`` with the engine running, in gear, not shifting, at
  closed throttle (``engine_brake_factor``); the parking brake on a moving vehicle
  ``level * m * a_park``, ``level`` ramping 0..1 over ``park_brake_apply_s`` while applied
  (0 at once when released). Both join the brake force inside the friction ellipse. A
  scenario may fail the parking brake (``park_brake_failed``); a stuck service-brake actuator
  or weak service hydraulics take it with them unless the vehicle file says it survives them.
- Rolling resistance ``C_rr * m * g * cos(pitch)``; drag ``0.5 * rho * CdA * v * |v|``;
  grade ``-m * g * sin(pitch)``.
- Combined slip, friction ellipse: ``(F_x / X)^2 + (F_y / Y)^2 <= 1`` with ``X = mu N``
  (``N = m g cos(pitch)``; drive force also only up to the driven share of it) and
  ``Y = N * skidpad_lat_g * min(mu / DRY_MU, 1)`` (the skid-pad figure, scaled by friction:
  the judge's physical ellipse). A demand beyond it saturates along its own direction: both
  components are divided by ``sqrt((F_x/X)^2 + (F_y/Y)^2)``. This is the brush tyre model at full sliding (Pacejka, Tyre and Vehicle
  Dynamics, 3rd ed. 2012, sec. 3.3; Svendenius and Gaefvert, Lund TFRT-7606, 2003, sec. 2.2):
  the sliding force is ``mu Fz`` opposing the sliding velocity, collinear with the slip vector,
  which the unsaturated demand stands in for. Braking in a curve beyond grip therefore costs
  cornering force and the vehicle runs wide (understeer); neither direction has priority.
  Saturated, the wheel speed departs from ground speed and the traction-control signal rises
  (wheel spin or a slide) or, braking straight, the ABS signal (issue 31: reported apart).
- Kinematic bicycle: curvature ``k = tan(delta) / L`` (positive right), heading rate ``-v * k``.
  The steering actuator has a rate limit and a first-order lag. The curvature driven is the
  lateral force the circle leaves over ``m v^2`` (understeer).
- Actuators: first-order lags on throttle and brake (preset time constants).
- Engine: cranking takes ``crank_time_s`` on a rising edge of the engine request; the first
  ``start_failures`` attempts fail, later ones fail with ``start_failure_prob``. A new attempt
  needs the request to go off and on again (like a key).
- Gearbox: a shift takes ``shift_time_s``; refused while moving on a ``shift_only_stopped``
  gearbox, and into park or reverse above 1 m/s on any.
"""

from __future__ import annotations

import bisect
import math
import random

import msgspec

from overdrive.dynamics.secondary_braking import engine_brake_factor
from overdrive.dynamics.vehicle_params import (
    AIR_DENSITY_KGPM3,
    DRY_MU,
    G_MPS2,
    Gear,
    GearTable,
    VehicleParams,
)

STOPPED_MPS = 1e-3             # below this the vehicle is treated as at rest
SHIFT_STOPPED_MPS = 0.05       # "stopped" for a gearbox that only shifts at a standstill
PARK_REVERSE_MAX_MPS = 1.0     # no gearbox engages park or reverse faster than this


class World(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Road and surroundings. Grade is piecewise constant along the initial heading (+x)."""

    grade_segments: tuple[tuple[float, float], ...] = ((0.0, 0.0),)  # (from_m, grade_percent)
    friction: float = 0.8
    obstacles: tuple[tuple[float, float], ...] = ()                  # (x_m, y_m) points
    roughness_mps2: float = 0.0                                      # vertical accel, 1 sigma

    def grade_percent_at(self, s_m: float) -> float:
        starts = [seg[0] for seg in self.grade_segments]
        i = bisect.bisect_right(starts, s_m) - 1
        return self.grade_segments[max(i, 0)][1]


class ActuatorFaults(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Degradations injected by scenarios (weak, slow, stuck); the defaults are healthy."""

    throttle_effectiveness: float = 1.0
    throttle_lag_scale: float = 1.0
    throttle_stuck: bool = False
    brake_effectiveness: float = 1.0
    brake_lag_scale: float = 1.0
    brake_stuck: bool = False
    steering_rate_scale: float = 1.0
    steering_stuck: bool = False
    park_brake_failed: bool = False   # the parking brake gives nothing (moving or at rest)


class Plant:
    """Mutable vehicle state plus ``step``; attribute names carry units."""

    def __init__(self, params: VehicleParams, world: World, rng: random.Random,
                 engine_running: bool = False, gear: str | None = None) -> None:
        self.params = params
        self.gears = GearTable(params)
        self.world = world
        self._grade_world: World | None = None     # the world _grade_starts belong to
        self._grade_starts: list[float] = []
        self.rng = rng
        self.faults = ActuatorFaults()
        self.x_m = 0.0
        self.y_m = 0.0
        self.heading_rad = 0.0
        self.speed_mps = 0.0
        self.accel_mps2 = 0.0
        self.lat_accel_mps2 = 0.0
        self.curvature_1pm = 0.0
        self.road_wheel_rad = 0.0
        self._steer_rate_limited_rad = 0.0
        self.throttle = 0.0          # actual actuator positions, 0..1
        self.brake = 0.0 if engine_running else 1.0
        self.gear = gear or params.park_gear
        self.shift_target: str | None = None
        self.shift_remaining_s = 0.0
        self.shift_refused = False
        self.engine = "running" if engine_running else "off"
        self.crank_remaining_s = 0.0
        self.start_attempts = 0
        self.start_failed = False
        self._engine_request = engine_running
        self.odometer_m = 0.0
        self.slip = False
        self.traction_slip = False
        self.abs_active = False
        self.wheel_speed_mps = 0.0
        self.pitch_rad = 0.0
        self.roll_rad = 0.0
        self.park_brake = gear is None
        self.park_brake_level = 0.0   # the parking brake's application on a moving vehicle, 0..1
        self._update_attitude()

    # ------------------------------------------------------------------ helpers

    @property
    def engine_rpm(self) -> float:
        p = self.params
        if self.engine != "running":
            return 0.0
        gear = self._gear(self.gear)
        if gear.direction == 0 or gear.max_speed_mps <= 0.0 or self.shift_target is not None:
            return p.idle_rpm + (p.redline_rpm - p.idle_rpm) * 0.1 * self.throttle
        frac = min(abs(self.wheel_speed_mps) / gear.max_speed_mps, 1.0)
        return p.idle_rpm + (p.redline_rpm - p.idle_rpm) * frac

    def _gear(self, name: str) -> Gear:
        gear = self.gears.get(name)
        return gear if gear is not None else self.params.gear(name)   # raises KeyError

    def _grade_percent(self) -> float:
        """``world.grade_percent_at(x_m)``, with the segment starts kept while the world is the same."""
        world = self.world
        if world is not self._grade_world:
            self._grade_world = world
            self._grade_starts = [seg[0] for seg in world.grade_segments]
        i = bisect.bisect_right(self._grade_starts, self.x_m) - 1
        return world.grade_segments[max(i, 0)][1]

    def _park_brake_share(self) -> float:
        """What the parking brake gives (0..1) with the faults injected: nothing failed, or
        with the service brake's failure when the vehicle file says it does not survive it."""
        p, faults = self.params, self.faults
        if faults.park_brake_failed or (faults.brake_stuck and not p.park_brake_survives_actuator):
            return 0.0
        return 1.0 if p.park_brake_survives_hydraulic else min(faults.brake_effectiveness, 1.0)

    def _update_attitude(self) -> None:
        road_pitch = math.atan(self._grade_percent() / 100.0)
        self.pitch_rad = road_pitch * math.cos(self.heading_rad)
        self.roll_rad = -road_pitch * math.sin(self.heading_rad)

    # ------------------------------------------------------------------ commands

    def _powertrain(self, dt_s: float, gear_cmd: str, engine_on: bool) -> None:
        p = self.params
        if engine_on and not self._engine_request and self.engine == "off":
            self.engine = "cranking"
            self.crank_remaining_s = p.crank_time_s
            self.start_failed = False
        if not engine_on:
            self.engine = "off"
        self._engine_request = engine_on
        if self.engine == "cranking":
            self.crank_remaining_s -= dt_s
            if self.crank_remaining_s <= 0.0:
                self.start_attempts += 1
                failed = (self.start_attempts <= p.start_failures
                          or self.rng.random() < p.start_failure_prob)
                self.engine = "off" if failed else "running"
                self.start_failed = failed

        if self.shift_target is not None:
            self.shift_remaining_s -= dt_s
            if self.shift_remaining_s <= 0.0:
                self.gear = self.shift_target
                self.shift_target = None
        wanted = gear_cmd if self.gears.get(gear_cmd) is not None else self.gear
        self.shift_refused = False
        if wanted != self.gear and wanted != self.shift_target:
            target = self._gear(wanted)
            moving = abs(self.speed_mps)
            if ((p.shift_only_stopped and moving > SHIFT_STOPPED_MPS)
                    or ((target.holds or target.direction < 0) and moving > PARK_REVERSE_MAX_MPS)):
                self.shift_refused = True
            else:
                self.shift_target = wanted
                self.shift_remaining_s = p.shift_time_s

    def stall(self) -> None:
        """The engine dies; a restart needs the request to go off and on again."""
        if self.engine != "off":
            self.engine = "off"

    # ------------------------------------------------------------------ step

    def step(self, dt_s: float, throttle_pct: float, brake_pct: float, steer_pct: float,
             gear_cmd: str, engine_on: bool, park_brake: bool = False) -> None:
        """Advance the vehicle by ``dt_s`` under the given (already gated) commands."""
        p = self.params
        faults = self.faults
        self._powertrain(dt_s, gear_cmd, engine_on)
        self.park_brake = park_brake
        # applied: a ramp over park_brake_apply_s; released: at once (a simplification: the
        # direction hold releases it as the drive builds, and a drag on the launch after an
        # auto-hold is not what the vehicle files describe)
        self.park_brake_level = (min(self.park_brake_level + dt_s / p.park_brake_apply_s, 1.0)
                                 if park_brake else 0.0)
        park_share = self._park_brake_share()

        # actuators
        if not faults.throttle_stuck:
            tau_t = p.throttle_lag_s * faults.throttle_lag_scale
            self.throttle += (throttle_pct * 0.01 - self.throttle) * (1.0 - math.exp(-dt_s / tau_t))
        if not faults.brake_stuck:
            tau_b = p.brake_lag_s * faults.brake_lag_scale
            self.brake += (brake_pct * 0.01 - self.brake) * (1.0 - math.exp(-dt_s / tau_b))
        target_rad = steer_pct * 0.01 * p.max_steer_rad
        max_step = 0.0 if faults.steering_stuck else p.steer_rate_rps * faults.steering_rate_scale * dt_s
        last = self._steer_rate_limited_rad
        limited = min(max(target_rad, last - max_step), last + max_step)
        self._steer_rate_limited_rad = limited
        self.road_wheel_rad += (limited - self.road_wheel_rad) * (1.0 - math.exp(-dt_s / p.steer_lag_s))
        geom_k = math.tan(self.road_wheel_rad) / p.wheelbase_m

        # forces
        m = p.mass_kg
        pitch = self.pitch_rad
        normal_n = m * G_MPS2 * math.cos(pitch)
        mu_n = self.world.friction * normal_n
        # lateral semi-axis: the vehicle's skid-pad figure (measured on dry pavement, DRY_MU)
        # scaled by the friction, never above it: the judge's physical ellipse
        lat_max_n = normal_n * p.skidpad_lat_g * min(self.world.friction / DRY_MU, 1.0)
        v = self.speed_mps
        lat_demand_n = m * v * v * geom_k   # + right, what the steered wheels ask of the tyres

        gear = self._gear(self.gear)
        direction = gear.direction
        drive_n = 0.0
        spin_mps = 0.0
        slip = False
        if self.engine == "running" and self.shift_target is None and direction != 0:
            along = v * direction
            available = min(gear.max_force_n, p.max_power_w / max(abs(v), 0.5))
            top = gear.max_speed_mps
            if along > 0.9 * top:
                available *= max(0.0, (top - along) / (0.1 * top))
            drive_n = direction * self.throttle * faults.throttle_effectiveness * available
            driven_cap_n = mu_n * (1.0 if gear.all_wheel else p.driven_weight_fraction)
            if abs(drive_n) > driven_cap_n:
                slip = True
                spin_mps = direction * min((abs(drive_n) - driven_cap_n) / m, 5.0)
                drive_n = math.copysign(driven_cap_n, drive_n)
            # engine braking (closed throttle, in gear, moving the gear's way)
            drive_n -= direction * m * gear.engine_brake_decel_mps2 * engine_brake_factor(
                self.throttle, along)

        brake_n = self.brake * faults.brake_effectiveness * m * p.max_brake_decel_mps2
        brake_n += self.park_brake_level * park_share * m * p.park_brake_decel_mps2
        if (gear.holds or (park_brake and park_share > 0.0)) and abs(v) < STOPPED_MPS:
            # park pawl / parking brake: holds a stopped vehicle; at speed only the service
            # brake (with its lag and faults) decelerates
            brake_n = max(brake_n, m * p.max_brake_decel_mps2)
        abs_active = False
        k = geom_k
        if abs(v) < STOPPED_MPS:
            brake_n = min(brake_n, mu_n)   # holding: no lateral demand at rest
        else:
            # combined slip: the tyre force the wheels ask for, saturated along its direction
            lon_demand_n = drive_n - math.copysign(brake_n, v)
            usage = math.hypot(lon_demand_n / mu_n, lat_demand_n / lat_max_n)
            if usage > 1.0:
                scale = 1.0 / usage
                slip = slip or lat_demand_n != 0.0
                abs_active = brake_n > 0.0
                k = geom_k * scale
                drive_n *= scale
                brake_n *= scale
        grade_n = -m * G_MPS2 * math.sin(pitch)
        roll_n = p.rolling_resistance * normal_n

        if abs(v) < STOPPED_MPS:
            push_n = drive_n + grade_n
            hold_n = brake_n + roll_n
            if abs(push_n) <= hold_n:
                accel = 0.0
                v = 0.0
            else:
                accel = (push_n - math.copysign(hold_n, push_n)) / m
        else:
            drag_n = 0.5 * AIR_DENSITY_KGPM3 * p.drag_area_m2 * v * abs(v)
            accel = (drive_n + grade_n - math.copysign(brake_n + roll_n, v) - drag_n) / m

        v_new = v + accel * dt_s
        if v != 0.0 and v_new * v < 0.0:
            # stopped within the step by brakes or resistance: integrate exactly to rest
            t_stop = -v / accel
            ds = 0.5 * v * t_stop
            v_new = 0.0
        else:
            ds = 0.5 * (v + v_new) * dt_s

        # pose (midpoint heading)
        dh = -ds * k
        h_mid = self.heading_rad + 0.5 * dh
        self.x_m += ds * math.cos(h_mid)
        self.y_m += ds * math.sin(h_mid)
        self.heading_rad = math.remainder(self.heading_rad + dh, math.tau)
        self.odometer_m += abs(ds)
        self.accel_mps2 = (v_new - self.speed_mps) / dt_s if dt_s > 0 else 0.0
        self.speed_mps = v_new
        self.curvature_1pm = k
        self.lat_accel_mps2 = v_new * v_new * k
        self.slip = slip or abs_active
        self.traction_slip = slip       # wheel spin or a slide: the traction-control signal
        self.abs_active = abs_active    # braking beyond grip: the ABS signal (issue 31)
        if abs_active and abs(v_new) > STOPPED_MPS:
            self.wheel_speed_mps = v_new * 0.85
        else:
            self.wheel_speed_mps = v_new + spin_mps
        self._update_attitude()

    # ------------------------------------------------------------------ world queries

    def radar(self) -> tuple[bool, float, float]:
        """(target, range from the front bumper, closing speed) of the nearest obstacle in the cone."""
        return self.radar_target()[:3]

    def radar_target(self) -> tuple[bool, float, float, float]:
        """``radar`` and the target's bearing (counter-clockwise from the heading, 0 if none)."""
        p = self.params
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        front = p.length_m - p.rear_overhang_m
        bx, by = self.x_m + front * c, self.y_m + front * s
        best = p.radar_range_m
        found, bearing = False, 0.0
        for ox, oy in self.world.obstacles:
            dx, dy = ox - bx, oy - by
            along = dx * c + dy * s
            if along <= 0.0:
                continue
            lateral = -dx * s + dy * c
            if abs(math.atan2(lateral, along)) > p.radar_half_angle_rad:
                continue
            dist = math.hypot(dx, dy)
            if dist < best:
                best, found, bearing = dist, True, math.atan2(lateral, along)
        return found, best, (self.speed_mps if found else 0.0), (bearing if found else 0.0)

    def contact(self) -> bool:
        """True when an obstacle lies inside the vehicle's footprint."""
        p = self.params
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        half_w = 0.5 * p.width_m
        front = p.length_m - p.rear_overhang_m
        for ox, oy in self.world.obstacles:
            dx, dy = ox - self.x_m, oy - self.y_m
            along = dx * c + dy * s
            lateral = -dx * s + dy * c
            if -p.rear_overhang_m <= along <= front and abs(lateral) <= half_w:
                return True
        return False
