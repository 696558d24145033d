"""The independent safety-invariant monitor, checked on every run.

It is a bus tap: it watches what the stack publishes and the simulator's ground truth, keeps
its own bookkeeping (it never asks the code under test), and lists each violated invariant:

1. **authorization**: the vehicle never passes the end of an authorization to advance. An
   authorization shorter than the distance the vehicle physically needs to stop when it
   arrives (command latency and brake lag, then the brake/tyre limit with gravity along the
   slope) is judged from that shortest possible stop instead.
2. **throttle while braking**: no pedal command has throttle and brake both above zero.
3. **watchdog**: once an SPSS client exists, a gap of more than 200 ms is followed by an
   emergency stop (full brake, zero throttle from the speed server) within one control period.
4. **control**: no actuator command from a source that does not hold control reaches the
   vehicle (the vehicle must reject it).
5. **acceleration**: achieved acceleration stays inside the vehicle's physical acceleration
   ellipse (not derated) with a stated plant tolerance, outside emergency stops.
6. **e-stop precedence**: in e-stop disable the vehicle applies full brake within its
   actuator lag, whatever the stack commands.
7. **contact**: the vehicle never touches an obstacle.
"""

from __future__ import annotations

import math
from typing import Any

from overdrive.messages import Topic
from overdrive.vehicle.plant import DRY_MU
from overdrive.vehicle.presets import G_MPS2, VehicleParams
from overdrive.vehicle.sim_node import WORLD_TOPIC

WATCHDOG_S = 0.200            # seed 001: "Failure to send one for 200ms will result in an emergency stop"
ESTOP_BRAKE_PCT = 99.0        # what counts as "brakes full on"
AUTHORIZATION_TOLERANCE_M = 0.0  # issue 4: "0 m overrun"
ELLIPSE_TOLERANCE = 0.15      # plant tolerance: actuator lags and tyre-model transients
ESTOP_DISABLE_BRAKE_S = 0.5   # brake actuator reaches full effort within ~5 time constants
EPS_S = 1e-6
MOVING_MPS = 0.05             # a stop is recorded when the speed falls from above this ...
STOPPED_MPS = 0.001           # ... to below this


class Monitor:
    def __init__(self, params: VehicleParams, friction: float, period_s: float,
                 pedal_sources: frozenset[str] = frozenset({"speed", "scenario"}),
                 steer_sources: frozenset[str] = frozenset({"driving", "scenario"})) -> None:
        self.params = params
        self.period_s = period_s
        self.pedal_sources = pedal_sources
        self.steer_sources = steer_sources
        self.friction = friction
        self.violations: list[str] = []
        self._seen: set[str] = set()
        self.now_s = 0.0
        self.position_m = 0.0            # signed path position: forward +, reverse -
        self._last_odometer: float | None = None
        self.speed_mps = 0.0
        self.pitch_rad = 0.0
        self.auth_ends: dict[str, tuple[float, bool]] = {}   # source -> (end position, reverse)
        self.last_spss_s: float | None = None
        self.estop_at_s: float | None = None   # first emergency stop since the last SPSS
        self.estop_active = False
        self.rejected_expected = 0
        self.rejected_seen = 0
        self.estop_disable_since: float | None = None
        self.stop_margins_m: list[float] = []   # authorization left each time the vehicle stopped
        self.moving = False
        self._handlers = {Topic.TRUTH: self._truth, Topic.ADVANCE: self._authorization,
                          Topic.PEDALS: self._pedals, Topic.STEER: self._steer,
                          Topic.POWERTRAIN: self._powertrain, Topic.SET_SPEED: self._set_speed,
                          Topic.NOTICE: self._notice, Topic.VEHICLE_STATUS: self._estop_disable,
                          WORLD_TOPIC: self._world}
        # the ellipse's semi-axes before the friction scale (params are immutable)
        self._ax_full_mps2 = max(params.max_decel_mps2, params.max_brake_decel_mps2)
        self._ay_full_mps2 = params.skidpad_lat_g * G_MPS2

    # ------------------------------------------------------------------ helpers

    def _violate(self, key: str, message: str) -> None:
        """Record a violation once per key (the first occurrence, with its time)."""
        if key not in self._seen:
            self._seen.add(key)
            self.violations.append(f"{key}: {message} (t={self.now_s:.2f} s)")

    def _physical_decel_mps2(self) -> float:
        """Hardest possible braking now: brakes or tyres, with gravity along the slope."""
        pitch = self.pitch_rad if self.speed_mps >= 0.0 else -self.pitch_rad
        tyre = min(self.params.max_brake_decel_mps2, self.friction * G_MPS2 * math.cos(pitch))
        return max(tyre + G_MPS2 * math.sin(pitch), 0.1)

    # ------------------------------------------------------------------ bus tap

    def observe(self, topic: str, msg: Any) -> None:
        handler = self._handlers.get(topic)
        if handler is not None:
            handler(msg)

    def _pedals(self, msg: Any) -> None:
        if msg.throttle_pct > 0.0 and msg.brake_pct > 0.0:
            self._violate("throttle_while_braking",
                          f"{msg.source} commanded throttle {msg.throttle_pct:.1f} % with brake "
                          f"{msg.brake_pct:.1f} %")
        if msg.source not in self.pedal_sources:
            self.rejected_expected += 1
        if msg.source == "speed":
            self.estop_active = msg.throttle_pct == 0.0 and msg.brake_pct >= ESTOP_BRAKE_PCT
            if self.estop_active and self.estop_at_s is None:
                self.estop_at_s = self.now_s

    def _steer(self, msg: Any) -> None:
        if msg.source not in self.steer_sources:
            self.rejected_expected += 1

    def _powertrain(self, msg: Any) -> None:
        if msg.source not in self.pedal_sources:
            self.rejected_expected += 1

    def _set_speed(self, msg: Any) -> None:
        self.last_spss_s = self.now_s
        self.estop_at_s = None

    def _notice(self, msg: Any) -> None:
        if msg.kind == "rejected" and msg.code == "no_control":
            self.rejected_seen += 1

    def _world(self, msg: Any) -> None:
        self.friction = msg.friction

    def _authorization(self, msg: Any) -> None:
        if not (math.isfinite(msg.distance_m) and msg.distance_m >= 0.0):
            return  # invalid input: the driving module must reject it; nothing to hold it to
        speed = abs(self.speed_mps)
        reaction_s = 2.0 * self.period_s + self.params.brake_lag_s   # command latency + brake lag
        shortest_stop_m = speed * reaction_s + speed * speed / (2.0 * self._physical_decel_mps2())
        length = max(msg.distance_m, shortest_stop_m)
        end = self.position_m - length if msg.reverse else self.position_m + length
        self.auth_ends[msg.source] = (end, msg.reverse)

    def _truth(self, truth: Any) -> None:
        if self._last_odometer is not None:
            step = truth.odometer_m - self._last_odometer
            self.position_m += step if truth.speed_mps >= 0.0 else -step
        self._last_odometer = truth.odometer_m
        self.speed_mps = truth.speed_mps
        self.pitch_rad = truth.pitch_rad
        if abs(truth.speed_mps) > MOVING_MPS:
            self.moving = True
        elif self.moving and abs(truth.speed_mps) < STOPPED_MPS:
            self.moving = False
            margin = self.authorization_margin_m()
            if margin is not None:
                self.stop_margins_m.append(margin)
        for source, (end, reverse) in self.auth_ends.items():
            overrun = (end - self.position_m) if reverse else (self.position_m - end)
            if overrun > AUTHORIZATION_TOLERANCE_M + 1e-9:
                self._violate(f"authorization[{source}]",
                              f"passed the end of the authorization from {source!r} by {overrun:.3f} m")
        if truth.contact:
            self._violate("contact", "the vehicle touched an obstacle")
        self._ellipse(truth)

    def _ellipse(self, truth: Any) -> None:
        if self.estop_active or abs(truth.speed_mps) < 0.05:
            return
        scale = min(self.friction / DRY_MU, 1.0)
        ax_max = self._ax_full_mps2 * scale
        ay_max = self._ay_full_mps2 * scale
        ax = truth.accel_mps2 + G_MPS2 * math.sin(truth.pitch_rad)   # tyre force, gravity removed
        ay = truth.lat_accel_mps2
        usage = math.hypot(ax / ax_max, ay / ay_max)
        if usage > 1.0 + ELLIPSE_TOLERANCE:
            self._violate("acceleration_ellipse",
                          f"achieved acceleration ({ax:.2f}, {ay:.2f}) m/s^2 uses {usage:.0%} of the "
                          f"ellipse ({ax_max:.2f}, {ay_max:.2f})")

    def _estop_disable(self, status: Any) -> None:
        if status.safety_mode == "estop-disable":
            if self.estop_disable_since is None:
                self.estop_disable_since = self.now_s
            elif (self.now_s - self.estop_disable_since > ESTOP_DISABLE_BRAKE_S
                  and status.brake_pct < 95.0):
                self._violate("estop_precedence",
                              f"e-stop disable but brake only {status.brake_pct:.0f} %")
        else:
            self.estop_disable_since = None

    # ------------------------------------------------------------------ per tick

    def tick(self, now_s: float) -> None:
        """Time-based checks, after every node has stepped at ``now_s``."""
        if self.last_spss_s is not None:
            deadline_s = self.last_spss_s + WATCHDOG_S + self.period_s
            late = self.estop_at_s is None or self.estop_at_s > deadline_s + EPS_S
            if now_s > deadline_s + EPS_S and late:
                gap = now_s - self.last_spss_s
                self._violate("watchdog",
                              f"no SPSS for {gap * 1000:.0f} ms and no emergency stop by "
                              f"{(WATCHDOG_S + self.period_s) * 1000:.0f} ms")

    def authorization_margin_m(self) -> float | None:
        """Distance still authorized ahead of the vehicle by the most restrictive source, now."""
        if not self.auth_ends:
            return None
        return min((self.position_m - end) if reverse else (end - self.position_m)
                   for end, reverse in self.auth_ends.values())

    def finish(self) -> list[str]:
        if self.rejected_seen < self.rejected_expected:
            self._violate("control", f"{self.rejected_expected} actuator commands from sources "
                                     f"without control, only {self.rejected_seen} rejected")
        return self.violations
