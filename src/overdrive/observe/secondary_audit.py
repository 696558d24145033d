"""The judge's audit of a stop on a lost service brake (issue 30 item 4).

Fed by the judge (``observe.judge.Monitor``) with ground truth, the powertrain commands as the
speed server issued them, its notices and the faults injected into the simulated vehicle. From
the speed server's first "brake lost" fault (1133 BRAKE_NOT_APPLYING or 1136 BRAKE_FAILED) it
checks that everything the vehicle has was used:

- **engine braking**: the engine not cut while moving when a gear it may reach brakes (unless
  a throttle fault came too: then the engine must be cut within ``RESPONSE_S``); the engine
  cut at rest;
- **downshift**: on a gearbox that may shift while moving, the gear command is the
  ``secondary_gear`` of the current speed within ``RESPONSE_S`` (at the fault, and again
  once the vehicle has slowed under a braking gear's top speed);
- **parking brake**: commanded within ``RESPONSE_S`` of the true speed falling to the vehicle's
  ``park_brake_max_apply_mps`` (when it has one);

and states the distance allowed from that moment (``secondary_stop_m`` from the true speed, the
grade, the friction, with the parking brake left out when the vehicle's has failed) against the
distance the vehicle travelled to rest. A run judged "all used" and "within" is one whose
overrun the sweep may count as unavoidable (``run.sweep.unavoidable_cause``).
"""

from __future__ import annotations

import math
from typing import Any

from overdrive.dynamics.secondary_braking import (
    has_engine_braking,
    secondary_gear,
    secondary_stop_m,
)
from overdrive.dynamics.vehicle_params import Gear, GearTable, VehicleParams

BRAKE_LOST_CODES = frozenset({"1133", "1136"})
"""``safety.actuators.BRAKE_LOST`` (BRAKE_NOT_APPLYING, BRAKE_FAILED) as notice codes."""
THROTTLE_FAULT_CODES = frozenset({"1131", "1132"})
"""``safety.actuators`` THROTTLE_STUCK_OPEN / THROTTLE_STUCK_CLOSED as notice codes."""
RESPONSE_S = 0.2
"""Time the stack has to act on what it knows: two 10 Hz vehicle-status periods (the speed
server acts on a new status; its command reaches the vehicle within the next period)."""
PARK_SPEED_MARGIN_MPS = 0.1
"""The parking brake is owed once the true speed is this far below its limit: the speed
server's filtered speed (0.1 s) lags a decelerating vehicle by ~0.03-0.3 m/s at 0.3-3 m/s^2."""
DISTANCE_TOLERANCE_M = 0.5
"""Allowed beyond ``secondary_stop_m``: the plant's first-order lags (throttle 0.15 s closing),
the integration of the two models at 10 ms, and a stop decided by the filtered speed
(engineering bound; the tests show the margin used)."""
STOPPED_MPS = 0.01
ENGINE_OWED_MPS = 0.2
"""Engine braking (and the downshift for it) is owed above this true speed: the speed server cuts the engine once its
filtered speed is under 0.1 m/s (standstill), which a stopping vehicle's true speed leads by
up to ~0.1 m/s; below it engine braking gives under a fifth of its figure (it fades below
1 m/s) anyway."""


class SecondaryBrakingAudit:
    """State of the audit (see the module docstring); ``result`` is the summary's record."""

    def __init__(self, params: VehicleParams) -> None:
        self.params = params
        self.gears = GearTable(params)
        self.park_failed = False
        self.throttle_failed = False
        self.throttle_failed_s = math.inf
        self.gear_cmd: Gear | None = None
        self.park_cmd = False
        self.engine_cmd = True
        self.now_s = 0.0
        self.odometer_m = 0.0
        self.speed_mps = 0.0
        self.pitch_rad = 0.0
        self.friction = 0.8
        self.start: dict[str, Any] | None = None   # at the brake-lost fault
        self.target: Gear | None = None            # the gear secondary braking should be in
        self.missing: dict[str, str] = {}          # means not used -> when and how
        self._owed_since: dict[str, float] = {}
        self.stop_m: float | None = None
        self.rest_s: float | None = None             # when the vehicle came to rest

    # ------------------------------------------------------------------ inputs

    def fault_injected(self, msg: Any) -> None:
        """The simulated vehicle's actuator faults (``ActuatorFaults``)."""
        failed = getattr(msg, "park_brake_failed", None)
        if failed is not None:
            self.park_failed = bool(failed)

    def powertrain(self, msg: Any) -> None:
        if msg.source != "speed":
            return
        self.gear_cmd = self.gears.get(msg.gear)
        self.park_cmd, self.engine_cmd = bool(msg.park_brake), bool(msg.engine_on)

    def notice(self, msg: Any, now_s: float) -> None:
        if msg.source != "speed" or msg.kind != "fault":
            return
        if msg.code in THROTTLE_FAULT_CODES:
            self.throttle_failed_s = min(self.throttle_failed_s, now_s)   # the first one
            self.throttle_failed = True
        elif msg.code in BRAKE_LOST_CODES and self.start is None:
            gear = self.gear_cmd or self.gears.get(self.params.drive_gear)
            assert gear is not None
            speed = abs(self.speed_mps)
            self.target = secondary_gear(self.params, gear, speed)
            self.start = {"at_s": round(now_s, 3), "speed_mps": round(speed, 3),
                          "odometer_m": self.odometer_m, "pitch_rad": self.pitch_rad,
                          "friction": self.friction, "gear": gear.name}

    def truth(self, now_s: float, speed_mps: float, pitch_rad: float, ds_m: float,
              friction: float) -> None:
        self.now_s = now_s
        self.odometer_m += abs(ds_m)
        self.speed_mps, self.pitch_rad, self.friction = speed_mps, pitch_rad, friction
        if self.start is None or self.stop_m is not None:
            return
        speed = abs(speed_mps)
        if speed < STOPPED_MPS:
            self.stop_m = self.odometer_m - self.start["odometer_m"]
            self.rest_s = now_s
            return
        self._check_means(now_s, speed)

    # ------------------------------------------------------------------ checks

    def _owe(self, means: str, owed: bool, used: bool, now_s: float, how: str) -> None:
        """``means`` is owed (and not used) for longer than ``RESPONSE_S``: missing."""
        if not owed or used:
            self._owed_since.pop(means, None)
            return
        since = self._owed_since.setdefault(means, now_s)
        if now_s - since > RESPONSE_S + 1e-9 and means not in self.missing:
            self.missing[means] = f"{how} at {now_s:.2f} s"

    def _check_means(self, now_s: float, speed: float) -> None:
        p = self.params
        assert self.target is not None and self.start is not None
        gear = self.gear_cmd or self.target
        engine_brakes = (has_engine_braking(p, gear, speed) and not self.throttle_failed
                         and speed > ENGINE_OWED_MPS)
        self._owe("engine braking", engine_brakes, self.engine_cmd, now_s,
                  f"engine cut while moving at {speed:.2f} m/s")
        self._owe("engine cut", self.throttle_failed, not self.engine_cmd, now_s,
                  f"engine running {now_s - self.throttle_failed_s:.2f} s after a throttle fault")
        want = secondary_gear(p, gear, speed)
        downshift = want is not gear and not self.throttle_failed and speed > ENGINE_OWED_MPS
        self._owe("downshift", downshift, False, now_s,
                  f"gear {gear.name} instead of {want.name} at {speed:.2f} m/s")
        park = (p.park_brake_decel_mps2 > 0.0
                and speed <= p.park_brake_max_apply_mps - PARK_SPEED_MARGIN_MPS)
        self._owe("parking brake", park, self.park_cmd, now_s,
                  f"parking brake not applied at {speed:.2f} m/s")

    # ------------------------------------------------------------------ result

    def result(self) -> dict[str, Any] | None:
        """The summary's ``secondary_braking`` record; None when the brake was never lost."""
        start = self.start
        if start is None:
            return None
        gear = self.gears.get(start["gear"])
        assert gear is not None
        allowed = secondary_stop_m(
            self.params, start["speed_mps"], gear, pitch_rad=gear.direction * start["pitch_rad"],
            friction=start["friction"], reaction_s=RESPONSE_S,
            engine_braking=not self.throttle_failed, park_brake=not self.park_failed,
            downshift=not self.throttle_failed)
        distance = self.stop_m
        if self.rest_s is not None and self.engine_cmd and self.now_s > self.rest_s + 1.0:
            self.missing.setdefault("engine cut", "engine still running 1 s after the vehicle "
                                                  "came to rest")
        within = distance is not None and distance <= allowed + DISTANCE_TOLERANCE_M
        return {"at_s": start["at_s"], "speed_mps": start["speed_mps"], "gear": start["gear"],
                "park_brake_failed": self.park_failed, "throttle_failed": self.throttle_failed,
                "allowed_m": round(allowed, 3) if math.isfinite(allowed) else None,
                "tolerance_m": DISTANCE_TOLERANCE_M,
                "distance_m": None if distance is None else round(distance, 3),
                "missing": dict(self.missing), "all_used": not self.missing,
                "within": within}


__all__ = ["BRAKE_LOST_CODES", "SecondaryBrakingAudit"]
