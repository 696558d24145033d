"""The scenario player: a node that turns timed scenario events into bus messages.

It plays the planner (MOVE/REVERSE/STOP), the other sources of seed 003 (advance, max_speed,
steer), an SPSS client (set_speed, repeated every 100 ms as seed 001 requires), the safety
devices (SafeStop, overrides, door), world changes, actuator faults, and open-loop actuator
commands. Channel faults (``drop``) are not messages: ``ChannelFaults`` applies them on the bus.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import msgspec

from overdrive.bus.faults import ChannelFaults
from overdrive.messages import (
    SIM_FAULTS_TOPIC,
    SIM_WORLD_TOPIC,
    AdvanceAuthorization,
    MaxSpeed,
    MoveCommand,
    PedalCommand,
    PowertrainCommand,
    SafetyDevices,
    SetSpeed,
    SteerCommand,
    SteeringRequest,
    Topic,
)
from overdrive.scenario.schema import EventSpec, Scenario
from overdrive.vehicle.plant import ActuatorFaults, World
from overdrive.vehicle.sim_node import EngineStall, GpsStatus, SensorError, SensorFault

SPSS_PERIOD_S = 0.1        # seed 001: "An SPSS message should be sent to the speed server every 100ms"
REFRESH_PERIOD_S = 0.1     # max_speed limits are refreshed at the same rate, so they never expire
EPS_S = 1e-9


def world_from_spec(spec: Any) -> World:
    grade = spec.grade_percent
    if isinstance(grade, list):
        segments = tuple(sorted((s.from_m, s.grade_percent) for s in grade))
        if not segments or segments[0][0] > 0.0:
            segments = ((float("-inf"), 0.0), *segments)
    else:
        segments = ((float("-inf"), float(grade)),)
    return World(grade_segments=segments, friction=spec.friction,
                 obstacles=tuple((o.x_m, o.y_m) for o in spec.obstacles),
                 roughness_mps2=spec.roughness_mps2)


def channel_faults(scenario: Scenario) -> ChannelFaults:
    """The bus channel model for the scenario's drop/loss/delay/duplicate/reorder events
    (loss drawn from the scenario's seed)."""
    faults = ChannelFaults(seed=scenario.spec.seed)
    for event in scenario.events:
        if event.kind in ("drop", "duplicate", "reorder"):
            faults.add(event.body.channel, event.kind, event.at_s, event.body.for_s)
        elif event.kind == "loss":
            faults.add(event.body.channel, "loss", event.at_s, event.body.for_s,
                       fraction=event.body.fraction)
        elif event.kind == "delay":
            faults.add(event.body.channel, "delay", event.at_s, event.body.for_s, event.body.delay_s)
    return faults


def stall_windows(scenario: Scenario) -> list[tuple[str, float, float]]:
    """The scenario's ``stall`` events as (node, start, end) for the lock-step runtime."""
    return [(e.body.node, e.at_s, e.at_s + e.body.for_s) for e in scenario.events
            if e.kind == "stall"]


class ScenarioPlayer:
    """Plays the scenario's events. As the planner it stamps commands on its own clock (the
    stack's unless a ``planner_clock`` event offsets it) and, on another machine
    (``planner_machine: separate`` or a ``planner_clock`` event), echoes the newest MoveStatus
    in each command so the move server can measure the offset."""

    name = "scenario"
    period_s = 0.01

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self.params = scenario.vehicle
        self.pending = list(scenario.events)
        self.next_index = 0
        self.devices = SafetyDevices()
        self.faults = ActuatorFaults()
        self.world = world_from_spec(scenario.spec.world)
        ready = scenario.spec.start == "ready"
        self.gear = self.params.drive_gear if ready else self.params.park_gear
        self.engine_on = ready
        self.spss: SetSpeed | None = None
        self.next_spss_s = 0.0
        self.limits: dict[str, MaxSpeed] = {}
        self.next_refresh_s = 0.0
        self.command_id = 0
        self.session = 1        # the planner's run: a real planner picks a random 63-bit number
        self.started = False
        # the planner's clock: now + offset + drift * (now - since)
        self.clock_offset_s, self.clock_drift, self.clock_since_s = 0.0, 0.0, 0.0
        self.echo = scenario.spec.planner_machine == "separate" or "planner_clock" in {
            e.kind for e in scenario.events}
        self.subscriptions: tuple[str, ...] = (Topic.MOVE_STATUS,) if self.echo else ()
        self.status_echo: tuple[float, float] | None = None   # (its sent_s, received: our clock)

    def planner_time(self, now_s: float) -> float:
        """``now_s`` (the run's clock) read on the planner's clock."""
        return now_s + self.clock_offset_s + self.clock_drift * (now_s - self.clock_since_s)

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        out: list[tuple[str, Any]] = []
        if not self.started:
            self.started = True
            out.append((Topic.SAFETY, self.devices))
        for topic, msg in inbox:
            if topic == Topic.MOVE_STATUS and msg.sent_s is not None:
                self.status_echo = (msg.sent_s, self.planner_time(now_s))
        while self.next_index < len(self.pending) and self.pending[self.next_index].at_s <= now_s + EPS_S:
            self._apply(self.pending[self.next_index], now_s, out)
            self.next_index += 1
        if self.spss is not None and now_s + EPS_S >= self.next_spss_s:
            out.append((Topic.SET_SPEED, self.spss))
            self.next_spss_s += SPSS_PERIOD_S
        if self.limits and now_s + EPS_S >= self.next_refresh_s:
            self.limits = {k: msgspec.structs.replace(m, issued_s=now_s)
                           for k, m in self.limits.items()}
            out.extend((Topic.MAX_SPEED, m) for m in self.limits.values())
            self.next_refresh_s = now_s + REFRESH_PERIOD_S
        return out

    def _powertrain(self) -> PowertrainCommand:
        return PowertrainCommand(gear=self.gear, engine_on=self.engine_on,
                                 park_brake=self.gear == self.params.park_gear, source="scenario")

    def _apply(self, event: EventSpec, now_s: float, out: list[tuple[str, Any]]) -> None:
        kind, body = event.kind, event.body
        if kind == "planner_restart":
            if body.new_session:
                self.session += 1   # a new run of the planner: its ids start again
            self.command_id = 0
            self.status_echo = None     # a new process has received no status yet
        elif kind == "planner_clock":
            self.clock_offset_s, self.clock_drift = body.offset_s, body.drift_ppm * 1e-6
            self.clock_since_s = now_s
            self.echo = body.echo
        elif kind in ("move", "reverse", "stop"):
            self.command_id += 1
            echo = self.status_echo if self.echo else None
            sent_s, received_s = echo if echo is not None else (None, None)
            stamps: dict[str, Any] = {"issued_s": self.planner_time(now_s),
                                      "status_sent_s": sent_s, "status_received_s": received_s}
            if kind == "stop":
                out.append((Topic.MOVE_COMMAND, MoveCommand(
                    kind="stop", command_id=self.command_id, session=self.session, **stamps)))
            else:
                out.append((Topic.MOVE_COMMAND, MoveCommand(
                    kind=kind, command_id=self.command_id, session=self.session,
                    distance_m=body.distance_m, maxspeed_mps=body.maxspeed_mps,
                    curvature_1pm=body.curvature_1pm, **stamps)))
        elif kind == "advance":
            out.append((Topic.ADVANCE, AdvanceAuthorization(
                source=body.source, distance_m=body.distance_m, reverse=body.reverse,
                issued_s=now_s)))
        elif kind == "max_speed":
            self.limits[body.source] = MaxSpeed(source=body.source, speed_mps=body.speed_mps,
                                                issued_s=now_s)
            out.append((Topic.MAX_SPEED, self.limits[body.source]))
            self.next_refresh_s = now_s + REFRESH_PERIOD_S
        elif kind == "steer":
            out.append((Topic.STEERING, SteeringRequest(curvature_1pm=body.curvature_1pm)))
        elif kind == "set_speed":
            self.spss = SetSpeed(speed_mps=body.speed_mps, accel_mps2=body.accel_mps2,
                                 gear=body.gear, state=body.state, fault=body.fault)
            self.next_spss_s = now_s
            out.append((Topic.SET_SPEED, self.spss))
            self.next_spss_s = now_s + SPSS_PERIOD_S
        elif kind == "actuators":
            out.append((Topic.PEDALS, PedalCommand(throttle_pct=body.throttle_pct,
                                                   brake_pct=body.brake_pct, source="scenario")))
            out.append((Topic.STEER, SteerCommand(steer_pct=body.steer_pct, source="scenario")))
        elif kind == "gear":
            self.gear = body
            out.append((Topic.POWERTRAIN, self._powertrain()))
        elif kind == "engine":
            self.engine_on = body == "on"
            out.append((Topic.POWERTRAIN, self._powertrain()))
        elif kind in ("safestop", "manual_override", "emergency_manual_override", "estop_button",
                      "internal_error", "door", "partial_mode"):
            field, value = kind, body
            if kind == "door":
                field, value = "door_open", body == "open"
            self.devices = msgspec.structs.replace(self.devices, **{field: value})
            out.append((Topic.SAFETY, self.devices))
        elif kind == "actuator":
            changes: dict[str, float] = {}
            for pedal in ("throttle", "brake"):
                spec = getattr(body, pedal)
                if spec is not None:
                    changes[f"{pedal}_effectiveness"] = spec.effectiveness
                    changes[f"{pedal}_lag_scale"] = spec.lag_scale
                    changes[f"{pedal}_stuck"] = spec.stuck
            if body.steering is not None:
                changes["steering_rate_scale"] = body.steering.rate_scale
                changes["steering_stuck"] = body.steering.stuck
            if body.park_brake is not None:
                changes["park_brake_failed"] = body.park_brake.failed
            self.faults = msgspec.structs.replace(self.faults, **changes)
            out.append((SIM_FAULTS_TOPIC, self.faults))
        elif kind == "sensor":
            out.append((SIM_FAULTS_TOPIC, SensorFault(name=body.name, fault=body.fault, start_s=now_s,
                                                  end_s=now_s + body.for_s, sigma=body.sigma)))
        elif kind == "sensor_error":
            out.append((SIM_FAULTS_TOPIC, SensorError(
                quantity=body.quantity, start_s=now_s,
                end_s=None if body.for_s is None else now_s + body.for_s, bias=body.bias,
                drift_per_s=body.drift_per_s, scale=body.scale, direction_rad=body.direction_rad)))
        elif kind == "gps_status":
            out.append((SIM_FAULTS_TOPIC, GpsStatus(solution=body.solution,
                                                    position_sigma_m=body.position_sigma_m)))
        elif kind == "engine_stall":
            out.append((SIM_FAULTS_TOPIC, EngineStall()))
        elif kind == "world":
            changes_w: dict[str, Any] = {}
            if body.friction is not None:
                changes_w["friction"] = body.friction
            if body.obstacles is not None:
                changes_w["obstacles"] = tuple((o.x_m, o.y_m) for o in body.obstacles)
            self.world = msgspec.structs.replace(self.world, **changes_w)
            out.append((SIM_WORLD_TOPIC, self.world))
        # drop, loss, delay, duplicate and reorder are applied by ChannelFaults on the bus; stall by
        # the runtime (stall_windows)
