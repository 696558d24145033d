"""Test bench for the driving module: synthetic sensors and an ideal speed server + vehicle.

``IdealLoop`` steps a ``DrivingModule`` every 10 ms. Its "speed server" adopts every request at
once (state and gear), and its vehicle's speed follows the SPSS ramp exactly, ``delay_s`` after
the SPSS was sent: the simple longitudinal model the property tests check the module against.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.messages import (
    GpsIns,
    SetSpeed,
    SpeedState,
    SteerCommand,
    Topic,
    VehicleStatus,
)
from overdrive.servers.driving import DrivingConfig, DrivingModule

DT_S = 0.01


def outputs(out: list[tuple[str, Any]], topic: str) -> list[Any]:
    return [m for t, m in out if t == topic]


def sensors(params: VehicleParams, *, speed_mps: float = 0.0, odometer_m: float = 0.0,
            pitch_rad: float = 0.0, roll_rad: float = 0.0, state: str = "run",
            gear: str | None = None, traction: bool = False,
            steer_pct: float = 0.0) -> list[tuple[str, Any]]:
    gear = gear or params.drive_gear
    return [
        (Topic.VEHICLE_STATUS, VehicleStatus(
            gear=gear, shifting=False, engine="running", engine_rpm=1000.0, start_failed=False,
            traction_control=traction, steer_pct=steer_pct, throttle_pct=0.0, brake_pct=0.0,
            safety_mode="drive-by-wire")),
        (Topic.GPS_INS, GpsIns(x_m=odometer_m, y_m=0.0, heading_rad=0.0, speed_mps=speed_mps,
                               pitch_rad=pitch_rad, roll_rad=roll_rad, odometer_m=odometer_m)),
        (Topic.SPEED_STATE, SpeedState(speed_mps=speed_mps, accel_mps2=0.0, gear=gear,
                                       state=state)),
    ]


class IdealLoop:
    """Driving module + ideal speed server and vehicle (see the module docstring)."""

    def __init__(self, params: VehicleParams, *, friction: float = 0.8, pitch_rad: float = 0.0,
                 delay_s: float = 0.3, config: DrivingConfig | None = None) -> None:
        self.params = params
        self.node = DrivingModule(params, friction=friction, config=config)
        self.pitch_rad = pitch_rad
        self.delay_s = delay_s
        self.t_s = 0.0
        self.tick = 0
        self.speed_mps = 0.0
        self.odometer_m = 0.0
        self.state = "run"
        self.gear = params.drive_gear
        self.pending: deque[tuple[float, SetSpeed]] = deque()
        self.active: SetSpeed | None = None
        self.last_spss: SetSpeed | None = None
        self.curvature_1pm = 0.0
        self.steer_pct = 0.0

    def step(self, extra: list[tuple[str, Any]] | None = None) -> list[tuple[str, Any]]:
        inbox = sensors(self.params, speed_mps=self.speed_mps, odometer_m=self.odometer_m,
                        pitch_rad=self.pitch_rad, state=self.state, gear=self.gear,
                        steer_pct=self.steer_pct)   # ideal wheels: where they were commanded
        inbox += extra or []
        out = self.node.step(self.t_s, inbox)
        for spss in outputs(out, Topic.SET_SPEED):
            self.last_spss = spss
            self.pending.append((self.t_s + self.delay_s, spss))
            self.state, self.gear = spss.state, spss.gear   # the ideal server obeys at once
        for steer in outputs(out, Topic.STEER):
            assert isinstance(steer, SteerCommand)
            self.steer_pct = steer.steer_pct
            angle = steer.steer_pct / 100.0 * self.params.max_steer_rad
            self.curvature_1pm = math.tan(angle) / self.params.wheelbase_m
        self._vehicle()
        self.tick += 1
        self.t_s = self.tick * DT_S
        return out

    def _vehicle(self) -> None:
        while self.pending and self.pending[0][0] <= self.t_s + 1e-9:
            self.active = self.pending.popleft()[1]
        target = 0.0
        rate = 10.0
        if self.active is not None and self.state == "run":
            target, rate = self.active.speed_mps, self.active.accel_mps2
        if self.state != "run":
            target, rate = 0.0, 10.0
        step = rate * DT_S
        v0 = self.speed_mps
        v1 = min(v0 + step, target) if target > v0 else max(v0 - step, target)
        self.speed_mps = v1
        self.odometer_m += 0.5 * (v0 + v1) * DT_S

    def run(self, seconds: float, extra_at: dict[int, list] | None = None) -> list:
        outs = []
        for _ in range(round(seconds / DT_S)):
            outs.append(self.step((extra_at or {}).get(self.tick)))
        return outs
