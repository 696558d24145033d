"""A test's hands on the emulated PACMod 3 kit: command frames from the project's codec, the
kit stepped every 10 ms, reports decoded. No clock: times are passed in."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from overdrive.kits.pacmod3 import (
    AccelCmd,
    BrakeCmd,
    Gear,
    Pacmod3Codec,
    ShiftCmd,
    SteeringCmd,
)
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_kit import COMMAND_PERIOD_S, KitFault, Pacmod3Kit

STEP_S = 0.01


CODECS = {dialect: Pacmod3Codec(dialect) for dialect in ("v3", "v14")}   # a DBC load is ~50 ms


def lexus_kit(dialect: str = "v3", faults: tuple[KitFault, ...] = ()) -> Pacmod3Kit:
    return Pacmod3Kit(KIT_VEHICLES["lexus-rx450h"], codec=CODECS[dialect], faults=faults)


def command(system: str, enable: bool, value: float | Gear = 0.0, **flags: Any) -> Any:
    """One system's command message."""
    if system == "accel":
        return AccelCmd(enable=enable, accel_ratio=float(value), **flags)
    if system == "brake":
        return BrakeCmd(enable=enable, brake_ratio=float(value), **flags)
    if system == "steering":
        return SteeringCmd(enable=enable, position_rad=float(value),
                           rotation_rate_radps=flags.pop("rate", 6.0), **flags)
    return ShiftCmd(enable=enable, gear=Gear(value) if value else Gear.NONE, **flags)


class KitDriver:
    """Sends commands at 30 Hz and steps the kit every 10 ms in between."""

    def __init__(self, kit: Pacmod3Kit) -> None:
        self.kit = kit
        self.codec: Pacmod3Codec = kit.codec
        self.now_s = 0.0
        self.next_command_s = 0.0
        self.reports: list[tuple[float, Any]] = []

    def send(self, msg: Any) -> None:
        self.kit.receive(self.codec.encode(msg), self.now_s)

    def advance(self, until_s: float,
                commands: Callable[[float], list[Any]] | None = None) -> None:
        """Step to ``until_s``; every command period, send ``commands(t)``."""
        while self.now_s < until_s - 1e-9:
            if commands is not None and self.now_s >= self.next_command_s - 1e-9:
                for msg in commands(self.now_s):
                    self.send(msg)
                self.next_command_s += COMMAND_PERIOD_S
            self.now_s = round(self.now_s + STEP_S, 9)
            self.kit.step(self.now_s)
            for frame in self.kit.report_frames(self.now_s):
                self.reports.append((self.now_s, self.codec.decode(frame)))

    def engage(self, systems: tuple[str, ...] = ("accel", "brake", "steering", "shift"),
               brake_ratio: float = 0.5) -> None:
        """enable=0 for two periods, then enable=1 (the edge), brake held, in park."""
        def zeros(t: float) -> list[Any]:
            return [command(s, False, brake_ratio if s == "brake" else 0.0) for s in systems]
        self.advance(self.now_s + 2 * COMMAND_PERIOD_S, zeros)
        for s in systems:
            self.send(command(s, True, brake_ratio if s == "brake" else 0.0))

    def last_report(self, cls: type) -> Any:
        return next(r for _, r in reversed(self.reports) if isinstance(r, cls))


def drive_stream(accel: float = 0.0, brake: float = 0.0, steer_rad: float = 0.0,
                 gear: Gear = Gear.NONE, enable: bool = True, **flags: Any) -> Callable[[float],
                                                                                        list[Any]]:
    """Every period the same four commands."""
    def stream(t: float) -> list[Any]:
        return [command("accel", enable, accel, **flags), command("brake", enable, brake, **flags),
                command("steering", enable, steer_rad, **flags),
                command("shift", enable, gear, **flags)]
    return stream
