"""The simulated vehicle as a node: command gate, safety modes, plant, sensors.

Stands where a real drive-by-wire vehicle would: it accepts actuator commands only from the
sources allowed to command it, passes them through the command gate, lets the safety devices
override them (seed 000 behaviour), integrates the plant, and publishes sensor readings with
seeded noise. It is the first node of every tick, so it integrates the 10 ms that just passed
under the commands received before it.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from typing import Any, Literal

import msgspec

from overdrive.dynamics.speed_control import resistance_mps2
from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.messages import (
    SIM_FAULTS_TOPIC,
    SIM_WORLD_TOPIC,
    GpsIns,
    Imu,
    Notice,
    PedalCommand,
    PowertrainCommand,
    Radar,
    SafetyDevices,
    SteerCommand,
    Topic,
    Truth,
    VehicleStatus,
    WheelSpeed,
)
from overdrive.safety.gate import GateLimits, gate_pedals, gate_steer
from overdrive.safety.watchdog import Watchdog
from overdrive.vehicle.modes import PAUSE_MODES, computer_axes, safety_mode
from overdrive.vehicle.plant import STOPPED_MPS, ActuatorFaults, Plant, World

PAUSE_HOLD_BRAKE_PCT = 50.0  # seed 000: once stopped in a pause, 50 % braking effort
DRIVER_BRAKE_PCT = 30.0      # simulated safety driver under manual override: firm, controlled stop
COMMAND_TIMEOUT_S = 0.2     # seed 001's 200 ms SPSS budget, applied by the vehicle to pedal commands
ESTOP_THROTTLE_OPEN = 0.1     # e-stop disable, estop_engine_cut "standstill": a throttle still
ESTOP_THROTTLE_CLOSE_S = 0.5  # open beyond this share this long (3 throttle lags of 0.15 s: a
                              # closing one is below 5 %) does not close: the engine is cut at once
WATCHED_SOURCES = frozenset({"speed"})   # periodic controllers; one-shot scenario commands are not
WORLD_TOPIC = SIM_WORLD_TOPIC    # scenario -> simulator: replace the World (obstacles, friction)
FAULTS_TOPIC = SIM_FAULTS_TOPIC  # scenario -> simulator: ActuatorFaults, SensorFault, EngineStall

SENSOR_TOPICS = {"gps": Topic.GPS_INS, "imu": Topic.IMU, "wheel_speed": Topic.WHEEL_SPEED,
                 "radar": Topic.RADAR}
NOISY_FIELDS = {Topic.GPS_INS: ("x_m", "y_m", "speed_mps"),
                Topic.IMU: ("accel_x_mps2", "accel_y_mps2"),
                Topic.WHEEL_SPEED: ("speed_mps",),
                Topic.RADAR: ("range_m",)}


class SensorFault(msgspec.Struct, frozen=True):
    """A sensor freezes (repeats its last reading), gets noisy, or drops out, for a window."""

    name: Literal["gps", "imu", "wheel_speed", "radar"]
    fault: Literal["freeze", "noise", "dropout"]
    start_s: float
    end_s: float
    sigma: float = 1.0


class SensorError(msgspec.Struct, frozen=True):
    """A sensor quantity reads ``scale x true + bias + drift_per_s x (t - start_s)`` from
    ``start_s`` until ``end_s`` (None: the end of the run); a position error lies along
    ``direction_rad`` from the vehicle's heading at ``start_s`` (scenario ``sensor_error``)."""

    quantity: Literal["gps_position", "gps_heading", "gps_speed", "wheel_speed", "imu_accel",
                      "imu_yaw_rate"]
    start_s: float
    end_s: float | None = None
    bias: float = 0.0
    drift_per_s: float = 0.0
    scale: float = 1.0
    direction_rad: float = 0.0


class GpsStatus(msgspec.Struct, frozen=True):
    """The receiver's solution status and position sigma from now on (scenario ``gps_status``):
    the sigma is also the position noise the simulated receiver then has."""

    solution: Literal["rtk_fixed", "rtk_float", "dgps", "single", "dead_reckoning", "none"]
    position_sigma_m: float


class EngineStall(msgspec.Struct, frozen=True):
    """The engine dies now."""


class VehicleSim:
    name = "vehicle"
    period_s = 0.01
    subscriptions = (Topic.PEDALS, Topic.STEER, Topic.POWERTRAIN, Topic.SAFETY, WORLD_TOPIC,
                     FAULTS_TOPIC)

    def __init__(self, params: VehicleParams, world: World, seed: int, *, ready: bool = False,
                 limits: GateLimits | None = None,
                 command_timeout_s: float | None = COMMAND_TIMEOUT_S) -> None:
        self.params = params
        self.plant = Plant(params, world, random.Random(f"{seed}/engine"),
                           engine_running=ready, gear=params.drive_gear if ready else None)
        self.noise = random.Random(f"{seed}/sensors")
        self.limits = limits or GateLimits(
            steer_rate_pct_per_s=100.0 * params.steer_rate_rps / params.max_steer_rad)
        self.devices = SafetyDevices()
        self.throttle_pct = 0.0
        self.brake_pct = 0.0 if ready else 100.0
        self.steer_pct = 0.0
        self.applied_steer_pct = 0.0
        self.gear_cmd = self.plant.gear
        self.engine_on = ready
        self.park_brake = not ready
        self.last_now_s: float | None = None
        self.now_s = 0.0
        self.sensor_faults: dict[str, SensorFault] = {}
        # quantity -> (error, the heading at its onset: a position error's frame)
        self.sensor_errors: dict[str, tuple[SensorError, float]] = {}
        self.gps_solution: str = "rtk_fixed"
        self.gps_sigma_m = params.gps_noise_m
        self.gps_odometer_error_m = 0.0   # a GPS/INS speed error, integrated by its odometer
        self.last_readings: dict[str, Any] = {}
        self.rejected_sources = 0
        self.gate_interventions: dict[str, int] = {}
        self.command_watchdog = Watchdog(command_timeout_s) if command_timeout_s else None
        self.command_timeouts = 0
        self.timeout_latched = False   # the command-timeout brake holds until a restart
        self.restart_seen = False      # a runwait (horn) from the watched controller
        self.radar_seq = 0           # the radar's alive counter (a freeze repeats it)
        self.software_ready = True   # False: the XGV's control/ready-mode software pause (xgv.py)
        self.mode = safety_mode(self.devices)
        self.estop_since_s: float | None = None   # e-stop disable since (its engine cut)

    # ------------------------------------------------------------------ inputs

    def _receive(self, inbox: Sequence[tuple[str, Any]], out: list) -> None:
        lim = self.limits
        for topic, msg in inbox:
            if topic == Topic.PEDALS:
                if msg.source in lim.pedal_sources:
                    self.throttle_pct, self.brake_pct = msg.throttle_pct, msg.brake_pct
                    if msg.source in WATCHED_SOURCES and self.command_watchdog is not None:
                        self.command_watchdog.feed(self.now_s)
                else:
                    self._reject(msg, out)
            elif topic == Topic.STEER:
                if msg.source in lim.steer_sources:
                    self.steer_pct = msg.steer_pct
                else:
                    self._reject(msg, out)
            elif topic == Topic.POWERTRAIN:
                if msg.source in lim.powertrain_sources:
                    self.gear_cmd, self.engine_on = msg.gear, msg.engine_on
                    self.park_brake = msg.park_brake
                    if msg.horn and msg.source in WATCHED_SOURCES:
                        self.restart_seen = True
                else:
                    self._reject(msg, out)
            elif topic == Topic.SAFETY:
                self.devices = msg
            elif topic == WORLD_TOPIC:
                self.plant.world = msg
            elif topic == FAULTS_TOPIC:
                if isinstance(msg, SensorFault):
                    self.sensor_faults[SENSOR_TOPICS[msg.name]] = msg
                elif isinstance(msg, SensorError):
                    self.sensor_errors[msg.quantity] = (msg, self.plant.heading_rad)
                elif isinstance(msg, GpsStatus):
                    self.gps_solution, self.gps_sigma_m = msg.solution, msg.position_sigma_m
                elif isinstance(msg, EngineStall):
                    self.plant.stall()
                else:
                    self.plant.faults = msg

    def _reject(self, msg: PedalCommand | SteerCommand | PowertrainCommand, out: list) -> None:
        self.rejected_sources += 1
        out.append((Topic.NOTICE, Notice(kind="rejected", source=self.name,
                                         code="no_control",
                                         reason=f"{type(msg).__name__} from {msg.source!r}")))

    # ------------------------------------------------------------------ step

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        self.now_s = now_s
        self._receive(inbox, out)
        self._command_watchdog(now_s, out)
        dt_s = 0.0 if self.last_now_s is None else now_s - self.last_now_s
        self.last_now_s = now_s
        plant = self.plant

        throttle, brake, reason = gate_pedals(self.throttle_pct, self.brake_pct)
        if reason:
            self._count(reason)
        steer, reason = gate_steer(self.steer_pct, self.applied_steer_pct, self.limits, dt_s)
        if reason and reason != "steer rate":
            self._count(reason)

        self.mode = mode = safety_mode(self.devices, software_ready=self.software_ready)
        computer_steers, computer_speed = computer_axes(mode, self.devices.partial_mode)
        stopped = abs(plant.speed_mps) < STOPPED_MPS
        engine_on = self.engine_on
        gear = self.gear_cmd
        if not computer_steers:
            steer = self.applied_steer_pct          # the human holds the wheel where it is
        if mode != "estop-disable":
            self.estop_since_s = None
        if mode in PAUSE_MODES:
            throttle = 0.0
            brake = PAUSE_HOLD_BRAKE_PCT if stopped else max(brake, self.pause_brake_pct())
        elif mode == "estop-disable":
            if self.estop_since_s is None:
                self.estop_since_s = now_s
            throttle, brake = 0.0, 100.0
            engine_on = self._estop_engine(now_s, stopped)
            gear = plant.gear
        elif not computer_speed:
            # the human drives: pedals, gear and the engine are theirs, whatever the computer
            # asks (a real XGV ignores its engine commands under manual override)
            throttle, brake = 0.0, DRIVER_BRAKE_PCT
            gear = plant.gear
            engine_on = plant.engine != "off"
        self.applied_steer_pct = steer

        if dt_s > 0.0:
            plant.step(dt_s, throttle, brake, steer, gear, engine_on, self.park_brake)
        readings = self._sensors(computer_steers, computer_speed, dt_s)
        if self.sensor_faults:
            readings = self._apply_sensor_faults(now_s, readings)
        else:
            self.last_readings.update(readings)   # a freeze repeats the last real reading
        out.extend(readings)
        return out

    def pause_brake_pct(self) -> float:
        """The pause's brake effort: ``pause_decel_mps2`` (seed 000: "a constant (user set)
        acceleration"), rolling resistance, drag and grade counted as the vehicle's own
        speed controller would (the pause is the vehicle's, not open-loop pedal travel)."""
        p, plant = self.params, self.plant
        v = abs(plant.speed_mps)
        sin_grade = math.sin(plant.pitch_rad) * (1.0 if plant.speed_mps >= 0.0 else -1.0)
        need = p.pause_decel_mps2 - resistance_mps2(p, v, sin_grade)
        return min(max(100.0 * need / p.max_brake_decel_mps2, 0.0), 100.0)

    def _estop_engine(self, now_s: float, stopped: bool) -> bool:
        """The engine request in e-stop disable (seed 000: it "will also shut off the engine (if
        configured to do so)"): ``estop_engine_cut`` never (as it is), always (off), standstill
        (off once stopped, or once the throttle has stayed open ``ESTOP_THROTTLE_CLOSE_S``:
        one that does not close would drive against the brake)."""
        plant, cut = self.plant, self.params.estop_engine_cut
        running = plant.engine != "off"
        if cut == "never" or (cut == "standstill" and running and not stopped):
            since = self.estop_since_s if self.estop_since_s is not None else now_s
            if (cut == "standstill" and plant.throttle > ESTOP_THROTTLE_OPEN
                    and now_s - since >= ESTOP_THROTTLE_CLOSE_S - 1e-9):
                return False
            return running
        return False

    def _apply_sensor_faults(self, now_s: float, readings: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
        result = []
        for topic, msg in readings:
            fault = self.sensor_faults.get(topic)
            if fault is None or not fault.start_s - 1e-9 <= now_s < fault.end_s - 1e-9:
                self.last_readings[topic] = msg
                result.append((topic, msg))
            elif fault.fault == "freeze":
                if topic in self.last_readings:
                    result.append((topic, self.last_readings[topic]))
            elif fault.fault == "noise":
                gauss = self.noise.gauss
                noisy = {f: getattr(msg, f) + gauss(0.0, fault.sigma) for f in NOISY_FIELDS[topic]}
                result.append((topic, msgspec.structs.replace(msg, **noisy)))
            # dropout: nothing published
        return result

    def _command_watchdog(self, now_s: float, out: list) -> None:
        """A drive-by-wire vehicle must not hold the last throttle when its controller dies:
        once a periodic controller has sent pedal commands, silence longer than the timeout
        means throttle 0 and full brake (one ``estop`` notice), reported in
        ``VehicleStatus.command_timeout``. Commands resuming do not release it (a stalled
        controller resumes with stale intent): only the stack's deliberate restart does, the
        speed server's runwait (seed 001's 5 s wait before motion, horn sounding) once commands
        flow again."""
        watchdog = self.command_watchdog
        if watchdog is None:
            return
        if watchdog.check(now_s):
            self.command_timeouts += 1
            self.timeout_latched = True
            out.append((Topic.NOTICE, Notice(
                kind="estop", source=self.name, code="command_timeout",
                reason=f"no pedal command for {watchdog.timeout_s} s: full brake until the "
                       f"stack restarts through a runwait")))
        if self.timeout_latched and not watchdog.lost and self.restart_seen:
            self.timeout_latched = False
        self.restart_seen = False
        if self.timeout_latched:
            self.throttle_pct, self.brake_pct = 0.0, 100.0

    def _count(self, reason: str) -> None:
        self.gate_interventions[reason] = self.gate_interventions.get(reason, 0) + 1

    def _error(self, quantity: str, true_value: float) -> float:
        """``true_value`` as the sensor reads it under its active ``sensor_error`` (if any)."""
        entry = self.sensor_errors.get(quantity)
        if entry is None:
            return true_value
        err = entry[0]
        if self.now_s < err.start_s - 1e-9 or (err.end_s is not None
                                               and self.now_s >= err.end_s - 1e-9):
            return true_value
        return err.scale * true_value + err.bias + err.drift_per_s * (self.now_s - err.start_s)

    def _position_error(self) -> tuple[float, float]:
        """(dx, dy) of an active GPS/INS position error."""
        entry = self.sensor_errors.get("gps_position")
        if entry is None:
            return 0.0, 0.0
        along = self._error("gps_position", 0.0)
        angle = entry[1] + entry[0].direction_rad
        return along * math.cos(angle), along * math.sin(angle)

    def _sensors(self, computer_steers: bool, computer_speed: bool,
                 dt_s: float = 0.0) -> list[tuple[str, Any]]:
        p, plant, rng = self.params, self.plant, self.noise
        gauss = rng.gauss
        c, s = math.cos(plant.pitch_rad), math.sin(plant.pitch_rad)
        target, range_m, closing, bearing = plant.radar_target()
        self.radar_seq += 1
        road_wheel = plant.road_wheel_rad
        status = VehicleStatus(
            gear=plant.gear, shifting=plant.shift_target is not None, engine=plant.engine,
            engine_rpm=plant.engine_rpm, start_failed=plant.start_failed,
            traction_control=plant.traction_slip, abs_active=plant.abs_active,
            steer_pct=100.0 * road_wheel / p.max_steer_rad,
            throttle_pct=100.0 * plant.throttle, brake_pct=100.0 * plant.brake,
            safety_mode=self.mode, computer_speed=computer_speed,
            computer_steering=computer_steers, command_timeout=self.timeout_latched)
        yaw_rate = -plant.speed_mps * plant.curvature_1pm
        gps_speed = self._error("gps_speed", plant.speed_mps)
        self.gps_odometer_error_m += (abs(gps_speed) - abs(plant.speed_mps)) * dt_s
        dx, dy = self._position_error()
        sigma = self.gps_sigma_m
        return [
            (Topic.VEHICLE_STATUS, status),
            (Topic.WHEEL_SPEED, WheelSpeed(
                speed_mps=self._error("wheel_speed", plant.wheel_speed_mps)
                + gauss(0.0, p.speed_noise_mps))),
            (Topic.GPS_INS, GpsIns(
                x_m=plant.x_m + dx + gauss(0.0, sigma),
                y_m=plant.y_m + dy + gauss(0.0, sigma),
                heading_rad=math.remainder(self._error("gps_heading", plant.heading_rad), math.tau),
                speed_mps=gps_speed + gauss(0.0, p.speed_noise_mps),
                pitch_rad=plant.pitch_rad, roll_rad=plant.roll_rad,
                odometer_m=max(plant.odometer_m + self.gps_odometer_error_m, 0.0),
                solution=self.gps_solution, position_sigma_m=sigma)),  # type: ignore[arg-type]
            (Topic.IMU, Imu(
                accel_x_mps2=self._error("imu_accel", plant.accel_mps2 + G_MPS2 * s)
                + gauss(0.0, p.accel_noise_mps2),
                accel_y_mps2=-plant.lat_accel_mps2 + gauss(0.0, p.accel_noise_mps2),
                accel_z_mps2=G_MPS2 * c + gauss(0.0, p.accel_noise_mps2 + plant.world.roughness_mps2),
                yaw_rate_rps=self._error("imu_yaw_rate", yaw_rate))),
            (Topic.RADAR, Radar(target=target, range_m=range_m, closing_speed_mps=closing,
                                bearing_rad=bearing, seq=self.radar_seq)),
            (Topic.TRUTH, Truth(
                x_m=plant.x_m, y_m=plant.y_m, heading_rad=plant.heading_rad,
                speed_mps=plant.speed_mps, accel_mps2=plant.accel_mps2,
                lat_accel_mps2=plant.lat_accel_mps2, curvature_1pm=plant.curvature_1pm,
                pitch_rad=plant.pitch_rad, roll_rad=plant.roll_rad, odometer_m=plant.odometer_m,
                slip=plant.slip, contact=plant.contact())),
        ]


__all__ = ["ActuatorFaults", "GpsStatus", "SensorError", "VehicleSim", "World"]
