"""A minimal PACMod 3 kit double for the client's sans-IO tests: the enable edge per system,
override latching and clearing, the command timeout, reports at 30 Hz, and a point-mass plant
(speed from the pedal ratios, yaw from the steering-wheel angle). The emulated kit
(``overdrive.vehicle.pacmod3_kit``) is the full one; this double only holds the kit facts of
docs/pacmod3.md that the client's tests judge against."""

from __future__ import annotations

import math

from overdrive.dynamics.steering_ratio import road_wheel_rad
from overdrive.kits.frames import CanFrame
from overdrive.kits.pacmod3 import (
    AccelCmd,
    AccelRpt,
    BrakeCmd,
    BrakeRpt,
    Gear,
    GlobalRpt,
    Pacmod3Codec,
    ShiftCmd,
    ShiftRpt,
    SteeringCmd,
    SteeringRpt,
    VehicleSpeedRpt,
    YawRateRpt,
)

SYSTEM_OF = {AccelCmd: "accel", BrakeCmd: "brake", SteeringCmd: "steering", ShiftCmd: "shift"}
ACCEL_GAIN_MPS2 = 3.0     # full throttle's acceleration (the client does not know it)
BRAKE_GAIN_MPS2 = 9.0     # full brake's deceleration
TIMEOUT_S = 0.1           # 3 command periods


class KitDouble:
    def __init__(self, params, codec: Pacmod3Codec | None = None, gear: Gear = Gear.FORWARD):
        self.params = params
        self.codec = codec or Pacmod3Codec()
        self.enabled = dict.fromkeys(SYSTEM_OF.values(), False)
        self.last_enable = dict.fromkeys(SYSTEM_OF.values(), True)   # a stream starting at 1
        self.override = dict.fromkeys(SYSTEM_OF.values(), False)     # does not enable
        self.operator = dict.fromkeys(SYSTEM_OF.values(), False)     # operator input present
        self.cmd: dict[str, object] = {}
        self.cmd_s: dict[str, float] = {}
        self.timed_out = False
        self.speed_mps = 0.0
        self.x_m = self.y_m = self.heading_rad = 0.0
        self.odometer_m = 0.0
        self.wheel_rad = 0.0
        self.gear = gear
        self.accel_ratio = 0.0
        self.brake_ratio = 0.0
        self.log: list[tuple[float, object]] = []   # every command taken, in order
        self.next_report_s = 0.0
        self.silent: set[type] = set()              # report types not sent (fault injection)
        self.sent: list[tuple[float, type]] = []    # (time, report type) of every report sent
        self.now_s = 0.0

    def take(self, frame: CanFrame, now_s: float) -> None:
        msg = self.codec.decode(frame)
        self.log.append((now_s, msg))
        system = SYSTEM_OF.get(type(msg))
        if system is None:
            return
        self.cmd[system], self.cmd_s[system] = msg, now_s
        if msg.enable and not self.last_enable[system]:   # the DISABLE -> ENABLE edge
            if self.override[system] and msg.clear_override and not self.operator[system]:
                self.override[system] = False
            if not self.override[system]:
                self.enabled[system] = True
                self.timed_out = False
        if not msg.enable:
            self.enabled[system] = False
        self.last_enable[system] = msg.enable

    def press(self, system: str, on: bool = True) -> None:
        """The operator's input on ``system`` (latches an override, disables it)."""
        self.operator[system] = on
        if on:
            self.override[system] = True
            self.enabled[system] = False

    def step(self, now_s: float, dt_s: float) -> list[CanFrame]:
        for system, t in self.cmd_s.items():
            if self.enabled[system] and now_s - t > TIMEOUT_S:
                self.timed_out = True
                for s in self.enabled:
                    self.enabled[s] = False
        a = self.cmd.get("accel")
        b = self.cmd.get("brake")
        s = self.cmd.get("steering")
        g = self.cmd.get("shift")
        self.accel_ratio = a.accel_ratio if a is not None and self.enabled["accel"] else 0.0
        self.brake_ratio = b.brake_ratio if b is not None and self.enabled["brake"] else 0.0
        if s is not None and self.enabled["steering"]:
            step = s.rotation_rate_radps * dt_s
            self.wheel_rad += max(-step, min(step, s.position_rad - self.wheel_rad))
        if g is not None and self.enabled["shift"] and g.gear != Gear.NONE:
            self.gear = g.gear
        direction = {Gear.FORWARD: 1.0, Gear.LOW: 1.0, Gear.REVERSE: -1.0}.get(self.gear, 0.0)
        drive = direction * ACCEL_GAIN_MPS2 * self.accel_ratio
        brake = BRAKE_GAIN_MPS2 * self.brake_ratio + 0.2   # and rolling resistance
        v = self.speed_mps + drive * dt_s
        if abs(v) <= brake * dt_s:
            v = 0.0
        else:
            v -= math.copysign(brake * dt_s, v)
        road = road_wheel_rad(self.params.steering_ratio, self.wheel_rad)   # left positive
        yaw = v * math.tan(road) / self.params.wheelbase_m
        self.heading_rad += yaw * dt_s
        self.x_m += v * math.cos(self.heading_rad) * dt_s
        self.y_m += v * math.sin(self.heading_rad) * dt_s
        self.odometer_m += abs(v) * dt_s
        self.speed_mps, self.yaw_radps = v, yaw
        if now_s + 1e-9 < self.next_report_s:
            return []
        self.next_report_s = max(self.next_report_s + 1.0 / 30.0, now_s)
        self.now_s = now_s
        return self.reports()

    def reports(self) -> list[CanFrame]:
        def rpt(cls, system, **values):
            return cls(enabled=self.enabled[system], override_active=self.override[system],
                       **values)

        msgs = [
            GlobalRpt(enabled=any(self.enabled.values()), override_active=any(self.override.values()),
                      usr_can_timeout=self.timed_out, str_can_timeout=False,
                      brk_can_timeout=False, subsystem_timeout=False, veh_can_timeout=False,
                      fault_active=False, config_fault_active=False, usr_can_read_errors=0),
            rpt(AccelRpt, "accel", manual_input=0.0, commanded_value=self.accel_ratio,
                output_value=self.accel_ratio),
            rpt(BrakeRpt, "brake", manual_input=0.0, commanded_value=self.brake_ratio,
                output_value=self.brake_ratio),
            rpt(SteeringRpt, "steering", manual_input=0.0, commanded_value=self.wheel_rad,
                output_value=self.wheel_rad),
            rpt(ShiftRpt, "shift", manual_input=int(self.gear), commanded_value=int(self.gear),
                output_value=int(self.gear)),
            VehicleSpeedRpt(speed_mps=self.speed_mps, valid=True),
            YawRateRpt(yaw_rate_radps=self.yaw_radps if hasattr(self, "yaw_radps") else 0.0),
        ]
        msgs = [m for m in msgs if type(m) not in self.silent]
        self.sent.extend((self.now_s, type(m)) for m in msgs)
        return [self.codec.encode(m) for m in msgs]
