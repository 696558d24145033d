"""A service brake lost above the top speed of every gear with engine braking (the Escape's L
tops out at 20 m/s, D has none) must keep the engine for L once the vehicle has slowed below
it, and the judge's allowed distance must count that downshift. Judged from ground truth."""

from __future__ import annotations

import math
from typing import Any

import msgspec
import pytest

from overdrive.dynamics.secondary_braking import secondary_stop_m
from overdrive.dynamics.vehicle_params import AIR_DENSITY_KGPM3, G_MPS2
from overdrive.run.sim import run_scenario
from overdrive.run.sweep import unavoidable_cause
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers import speed as speed_module

PRESET = "escape-hybrid"
MOVE_M = 400.0
CRUISE_MPS = 22.0


def coast_m(params: Any, from_mps: float, to_mps: float, pitch_rad: float = 0.0) -> float:
    """Hand integration (1 ms) of a coast in a gear without engine braking: rolling resistance,
    drag and grade only, from ``from_mps`` down to ``to_mps``; infinite if it never gets there."""
    v, x, dt = from_mps, 0.0, 0.001
    for _ in range(2_000_000):
        if v <= to_mps:
            return x
        a = (params.rolling_resistance * G_MPS2 * math.cos(pitch_rad)
             + 0.5 * AIR_DENSITY_KGPM3 * params.drag_area_m2 * v * v / params.mass_kg
             + G_MPS2 * math.sin(pitch_rad))
        x += v * dt
        v -= a * dt
    return math.inf


def best_possible_m(params: Any, v0_mps: float, pitch_rad: float = 0.0) -> float:
    """Coast in D to just under L's top speed, then what ``secondary_stop_m`` allows from there
    (the downshift, L's engine braking, the parking brake at or below its speed)."""
    low = params.gear(params.low_gear)
    v_shift = low.max_speed_mps - 0.01
    return (coast_m(params, v0_mps, v_shift, pitch_rad)
            + secondary_stop_m(params, v_shift, params.gear(params.drive_gear),
                               pitch_rad=pitch_rad, reaction_s=0.2))


def run(grade_percent: float) -> Any:
    data = {"name": "brake-stuck-fast", "vehicle": PRESET, "start": "ready", "duration_s": 120,
            "world": {"grade_percent": grade_percent},
            "events": [
                {"at_s": 0.5, "move": {"distance_m": MOVE_M, "maxspeed_mps": CRUISE_MPS,
                                       "curvature_1pm": 0}},
                {"at_s": 5.0, "actuator": {"brake": {"stuck": True}}}]}
    return run_scenario(parse_scenario(data), None)


@pytest.mark.parametrize("grade_percent", [0.0, 5.0])
def test_a_brake_lost_above_the_low_gears_top_speed_stops_with_low_once_below_it(
        grade_percent: float) -> None:
    """Measured (2026-11-26, this file): flat, lost at 21.94 m/s: engine cut at the detection,
    never downshifted; stopped 905 m after it (829 m past the 400 m MOVE) where coasting to
    19.99 m/s then L and the parking brake need 300 m (``best_possible_m``). +5 %: 285 m (161 m
    possible), 218 m
    past. The judge flags it (``missing: engine braking``). Suspected cause:
    ``SpeedServer._brake_lost`` cuts the engine when ``has_engine_braking`` is false at the
    detection speed, and ``engine_cut`` latches."""
    p = PRESETS[PRESET]
    result = run(grade_percent)
    audit = result.summary["secondary_braking"]
    assert audit is not None and audit["distance_m"] is not None, audit
    pitch = math.atan(grade_percent / 100.0)
    best = best_possible_m(p, audit["speed_mps"], pitch)
    assert audit["distance_m"] <= best + audit["tolerance_m"] + 5.0, (audit, best)
    assert audit["all_used"], audit["missing"]


@pytest.mark.parametrize("speed_mps", [20.0, 20.5, 22.0, 25.0])
def test_secondary_stop_counts_a_downshift_once_the_vehicle_has_slowed_into_low(
        speed_mps: float) -> None:
    """The allowed distance can be no longer than coasting to L's top speed and stopping from
    there. Measured (2026-11-26): ``secondary_stop_m`` (reaction 0.2 s) from 19.99 m/s 152 m,
    from 20.0 m/s 761 m, 22 m/s 912 m, 25 m/s 1133 m; the coast-then-L bound from 22 m/s is
    ~304 m. The judge's ``allowed_m`` (``observe.secondary_audit``) inherits it: a stack that
    kept the engine and never used L would still be "within"."""
    p = PRESETS[PRESET]
    got = secondary_stop_m(p, speed_mps, p.gear(p.drive_gear), reaction_s=0.2)
    assert got <= best_possible_m(p, speed_mps) + 1.0


@pytest.mark.parametrize("speed_mps", [12.0, 19.5, 19.99])
def test_secondary_stop_below_the_low_gears_top_speed_meets_the_hand_bound(
        speed_mps: float) -> None:
    """The reference for the defect above: below L's top speed the bound holds (the coast part
    is then 0 or a few metres)."""
    p = PRESETS[PRESET]
    got = secondary_stop_m(p, speed_mps, p.gear(p.drive_gear), reaction_s=0.2)
    assert got <= best_possible_m(p, speed_mps) + 1.0


@pytest.mark.parametrize("grade_percent", [0.0, 5.0])
def test_a_stack_that_keeps_the_engine_but_never_downshifts_is_judged_avoidable(
        grade_percent: float, monkeypatch: pytest.MonkeyPatch) -> None:
    """The judge can fail: the speed server patched to keep the engine running (as for engine
    braking) but never to shift into L. Measured (2026-11-26, this file): flat, 906 m to rest
    (830 m past the 400 m MOVE), audit ``all_used`` and ``within`` (allowed 907 m),
    ``unavoidable_cause`` "every secondary means used"; +5 %: 285 m of 285 m allowed, the same.
    Suspected cause: ``SecondaryBrakingAudit`` fixes ``target`` (``secondary_gear`` at the
    detection speed, D above 20 m/s) and owes the downshift only when it differs from the
    start gear; ``secondary_stop_m`` (above) allows the distance of a stop without L."""
    original_brake_lost = speed_module.SpeedServer._brake_lost
    original_actuators = speed_module.SpeedServer._actuators

    def keep_engine(self: Any, *args: Any) -> None:
        original_brake_lost(self, *args)
        self.engine_cut = False

    def never_low(self: Any, dt_s: float, elapsed_s: float) -> Any:
        pedals, powertrain = original_actuators(self, dt_s, elapsed_s)
        if self.brake_lost and powertrain.gear == self.params.low_gear:
            powertrain = msgspec.structs.replace(powertrain, gear=self.params.drive_gear)
        return pedals, powertrain

    monkeypatch.setattr(speed_module.SpeedServer, "_brake_lost", keep_engine)
    monkeypatch.setattr(speed_module.SpeedServer, "_actuators", never_low)
    result = run(grade_percent)
    audit = result.summary["secondary_braking"]
    assert audit["speed_mps"] > PRESETS[PRESET].gear("low").max_speed_mps, audit
    assert not audit["all_used"], audit
    assert unavoidable_cause("brake_stuck", ["authorization"], result.summary) is None
