"""The speed server's downshift hint and the direction hold together (issue 16, cases 2 and 7):
a start the hold keeps on the brakes because the gear cannot beat the grade is lugging; a gear
that beats the grade by less than the hold's margin is released at full throttle; a fault in
one gear never blocks a lower one. Thresholds swept just inside and just outside, both presets."""

from __future__ import annotations

import math

import msgspec
import pytest

from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.direction_hold import DirectionFault, DirectionHold, DirectionHoldConfig
from overdrive.servers.speed_hints import HintConfig, HintMonitor
from tests.conftest import PRESET_NAMES
from tests.servers.test_speed_hints import CAP, hint_after, lugging_view

DT_S = 0.01
CFG = DirectionHoldConfig()
HINTS = HintConfig()


def sin_of(grade_pct: float) -> float:
    return math.sin(math.atan(grade_pct / 100.0))


def grade_for_margin(params, gear_name: str, margin: float) -> float:
    """The grade (%) on which ``gear_name``'s full drive beats the pull by exactly ``margin``."""
    full = drive_authority_mps2(params, params.gear(gear_name), 0.0)
    lo, hi = 0.0, 200.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        pull = resistance_mps2(params, 0.0, sin_of(mid))
        lo, hi = (mid, hi) if full >= pull * (1.0 + margin) else (lo, mid)
    return lo


def loaded(preset: str, mass_kg: float):
    return msgspec.structs.replace(PRESETS[preset], mass_kg=mass_kg)


def hold_start(params, gear_name: str, grade_pct: float, throttle_pct: float,
               seconds: float, hold: DirectionHold | None = None) -> tuple[DirectionHold, list]:
    """A standstill, then a command to move at ``throttle_pct`` for ``seconds``."""
    hold = hold or DirectionHold(params)
    gear = params.gear(gear_name)
    faults = []
    for target, n in ((0.0, 1), (2.0, round(seconds / DT_S))):
        for _ in range(n):
            cmd = hold.step(DT_S, target_mps=target, speed_mps=0.0, stopped=True,
                            sin_pitch=sin_of(grade_pct), throttle_pct=throttle_pct, gear=gear)
            if cmd.fault is not None:
                faults.append(cmd.fault[0])
    return hold, faults


# --------------------------------------------------------------------------- the hold's side

def full_throttle_threshold_pct(params, gear_name: str) -> float:
    """The grade on which the gear's drive at the hold's full throttle just equals the pull."""
    return grade_for_margin(params, gear_name, 100.0 / CFG.full_drive_pct - 1.0)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("offset_pct", "climbs"), [(-0.05, True), (0.05, False)])
def test_cannot_climb_is_the_drive_at_full_throttle_against_the_pull(preset, offset_pct, climbs):
    p = PRESETS[preset]
    grade = full_throttle_threshold_pct(p, p.drive_gear) + offset_pct
    hold, faults = hold_start(p, p.drive_gear, grade, 100.0, 0.1)
    assert hold.cannot_climb is not climbs
    assert hold.state == ("free" if climbs else "holding")   # full throttle: released
    assert faults == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("throttle_pct", "released"), [
    (CFG.full_drive_pct - 0.1, False), (CFG.full_drive_pct, True), (100.0, True)])
def test_a_gear_inside_the_margin_is_released_only_at_full_throttle(preset, throttle_pct,
                                                                     released):
    """Full drive 5 % above the pull (inside the 10 % margin, above the 5.3 % that 95 %
    throttle needs): the hold lets go only at full throttle; never cannot_climb."""
    p = PRESETS[preset]
    grade = grade_for_margin(p, p.drive_gear, 0.06)
    hold, faults = hold_start(p, p.drive_gear, grade, throttle_pct, 0.1)
    assert hold.state == ("free" if released else "holding")
    assert not hold.cannot_climb
    assert faults == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_fault_in_the_drive_gear_does_not_block_the_low_gear(preset):
    """CANNOT_HOLD_GRADE remembers the grade for the gear that failed; a start in the low gear
    on the same grade is released as usual."""
    p = PRESETS[preset]
    grade = full_throttle_threshold_pct(p, p.drive_gear) + 1.0
    hold, faults = hold_start(p, p.drive_gear, grade, 100.0, CFG.hold_timeout_s + 0.1)
    assert faults == [DirectionFault.CANNOT_HOLD_GRADE]
    assert hold.state == "failed"
    hold, faults = hold_start(p, p.drive_gear, grade, 100.0, 0.2, hold)   # cancel, then again
    assert hold.state == "holding" and hold.cannot_climb
    hold, faults = hold_start(p, p.low_gear, grade, 100.0, 0.2, hold)
    assert hold.state == "free" and not hold.cannot_climb
    assert faults == []


# --------------------------------------------------------------------------- the hint's side

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize(("seconds", "fires"), [(HINTS.lug_time_s - 0.02, False),
                                                (HINTS.lug_time_s, True)])
def test_held_because_the_gear_cannot_climb_is_lugging(preset, seconds, fires):
    """Standing, throttle closed (the hold brakes), target ahead: the hint after lug_time_s."""
    m = HintMonitor(PRESETS[preset], HINTS, CAP)
    view = lugging_view(preset, speed_mps=0.0, wheel_mps=0.0, throttle_pct=0.0,
                        target_mps=2.0, held_cannot_climb=True)
    assert hint_after(m, view, seconds) == ("suggest_downshift" if fires else "none")
    assert HINTS.lug_time_s < CFG.hold_timeout_s - 1.0   # a second left for the client to act


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("over", [
    {"held_cannot_climb": False},                  # held for the throttle to build up: no
    {"target_mps": 0.0},                           # not asked to move
    {"low": True},                                 # already in the low gear
])
def test_no_downshift_when_held_for_another_reason(preset, over):
    p = PRESETS[preset]
    fields = dict(speed_mps=0.0, wheel_mps=0.0, throttle_pct=0.0, target_mps=2.0,
                  held_cannot_climb=True)
    over = dict(over)   # parametrised: shared between the presets
    if over.pop("low", False):
        fields["gear"] = p.gear(p.low_gear)
    fields.update(over)
    m = HintMonitor(p, HINTS, CAP)
    assert hint_after(m, lugging_view(preset, **fields), 2.0) == "none"
