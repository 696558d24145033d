"""Simulation mode of the move server (seed 004 "-s"): a fake command generator.

``FakePlanner`` stands in for the map server: it draws a random but seeded route (straight and
curved legs, planned stops, an occasional short reverse), and streams MOVE commands every
``command_period_s`` that always reach ahead of the vehicle to the next planned stop, so the
vehicle moves continuously between stops. Every command is feasible by construction (curvature
within the turning radius, speed within the gear and a gentle share of the lateral ellipse).
It reads only ``GpsIns`` (progress), ``MoveReply`` and ``MoveStatus``.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from typing import Any

import msgspec

from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.messages import GpsIns, MoveCommand, MoveReply, MoveStatus, Topic


class PlannerConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    command_period_s: float = 0.2       # the acceptance's stream rate ("every 200 ms")
    leg_length_m: tuple[float, float] = (15.0, 50.0)
    curved_share: float = 0.5           # share of the legs that are curves
    curvature_share: tuple[float, float] = (0.15, 0.6)   # of the vehicle's tightest curvature
    speed_mps: tuple[float, float] = (2.0, 10.0)
    lateral_share: float = 0.3          # of the skid-pad lateral g: a gentle, comfortable curve
    stop_chance: float = 0.2            # after a leg, a planned stop ...
    hold_s: tuple[float, float] = (2.0, 5.0)   # ... standing this long
    reverse_chance: float = 0.3         # at a stop, back up a little
    reverse_m: tuple[float, float] = (3.0, 8.0)
    reverse_speed_mps: float = 1.5
    lookahead_m: float = 60.0           # no command reaches further than this
    slow_ahead_m: float = 15.0          # the next leg's (lower) speed applies this far before it
    standstill_mps: float = 0.05


class Leg(msgspec.Struct, frozen=True):
    length_m: float
    curvature_1pm: float
    speed_mps: float


class FakePlanner:
    """Seeded stream of feasible MOVE commands (see the module docstring)."""

    name = "planner"
    period_s = 0.01
    subscriptions = (Topic.GPS_INS, Topic.MOVE_REPLY, Topic.MOVE_STATUS)

    def __init__(self, params: VehicleParams, seed: int, *,
                 config: PlannerConfig | None = None) -> None:
        self.params = params
        self.config = config or PlannerConfig()
        self.rng = random.Random(f"{seed}/planner")
        self.command_id = 0
        self.legs: list[Leg] = []
        self.progress_m = 0.0
        self.last_odometer_m: float | None = None
        self.speed_mps = 0.0
        self.mode = "forward"           # forward | hold | reverse
        self.hold_until_s = 0.0
        self.reverse_id: int | None = None
        self.reverse_accepted = False
        self.status: MoveStatus | None = None
        self.next_send_s = 0.0
        self.sent: list[MoveCommand] = []
        self.rejected: list[MoveReply] = []
        self._new_route()

    # ------------------------------------------------------------------ route

    def _leg(self) -> Leg:
        cfg, p, rng = self.config, self.params, self.rng
        top = max(g.max_speed_mps for g in p.gears if g.direction > 0) * 0.9
        length = rng.uniform(*cfg.leg_length_m)
        k = 0.0
        if rng.random() < cfg.curved_share:
            k = rng.choice((-1.0, 1.0)) * rng.uniform(*cfg.curvature_share) * p.max_curvature_1pm
        v = min(rng.uniform(*cfg.speed_mps), top)
        if k:
            v = min(v, math.sqrt(cfg.lateral_share * p.skidpad_lat_g * G_MPS2 / abs(k)))
        return Leg(length, k, round(v, 2))

    def _new_route(self) -> None:
        """Legs up to the next planned stop (at least one)."""
        self.legs = [self._leg()]
        while self.rng.random() >= self.config.stop_chance and len(self.legs) < 8:
            self.legs.append(self._leg())
        self.progress_m = 0.0

    def _where(self) -> tuple[int, float]:
        """Index of the current leg and distance left in it."""
        s = self.progress_m
        for i, leg in enumerate(self.legs):
            if s < leg.length_m:
                return i, leg.length_m - s
            s -= leg.length_m
        return len(self.legs) - 1, 0.0

    # ------------------------------------------------------------------ node

    def step(self, now_s: float, inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        cfg = self.config
        for _topic, msg in inbox:
            if isinstance(msg, GpsIns):
                if self.last_odometer_m is not None and self.mode == "forward":
                    self.progress_m += msg.odometer_m - self.last_odometer_m
                self.last_odometer_m = msg.odometer_m
                self.speed_mps = msg.speed_mps
            elif isinstance(msg, MoveReply):
                if not msg.accepted:
                    self.rejected.append(msg)
                elif msg.command_id == self.reverse_id:
                    self.reverse_accepted = True
            elif isinstance(msg, MoveStatus):
                self.status = msg
        out: list[tuple[str, Any]] = []
        stopped = abs(self.speed_mps) < cfg.standstill_mps
        total = sum(leg.length_m for leg in self.legs)
        if self.mode == "forward" and total - self.progress_m < 0.5 and stopped:
            self.mode = "hold"
            self.hold_until_s = now_s + self.rng.uniform(*cfg.hold_s)
        if self.mode == "hold" and now_s >= self.hold_until_s:
            if self.rng.random() < cfg.reverse_chance:
                self.mode = "reverse"
                self.reverse_id = None
                self.reverse_accepted = False
            else:
                self.mode = "forward"
                self._new_route()
        if self.mode == "reverse":
            status = self.status
            done = (self.reverse_accepted and status is not None
                    and status.command_id == self.reverse_id and status.phase == "idle")
            if done:
                self.mode = "forward"
                self._new_route()
            elif not self.reverse_accepted and now_s >= self.next_send_s:
                cmd = self._command("reverse", round(self.rng.uniform(*cfg.reverse_m), 2),
                                    cfg.reverse_speed_mps, 0.0)
                self.reverse_id = cmd.command_id
                out.append((Topic.MOVE_COMMAND, cmd))
                self.next_send_s = now_s + cfg.command_period_s
        if self.mode == "forward" and now_s >= self.next_send_s:
            i, left_in_leg = self._where()
            leg = self.legs[i]
            speed = leg.speed_mps
            if i + 1 < len(self.legs) and left_in_leg < cfg.slow_ahead_m:
                speed = min(speed, self.legs[i + 1].speed_mps)
            distance = min(max(total - self.progress_m, 0.0), cfg.lookahead_m)
            out.append((Topic.MOVE_COMMAND, self._command("move", round(distance, 3), speed,
                                                          leg.curvature_1pm)))
            self.next_send_s = now_s + cfg.command_period_s
        return out

    def _command(self, kind: str, distance_m: float, speed_mps: float,
                 curvature_1pm: float) -> MoveCommand:
        self.command_id += 1
        cmd = MoveCommand(kind=kind, command_id=self.command_id,  # type: ignore[arg-type]
                          distance_m=distance_m, maxspeed_mps=speed_mps,
                          curvature_1pm=curvature_1pm)
        self.sent.append(cmd)
        return cmd


__all__ = ["FakePlanner", "Leg", "PlannerConfig"]
