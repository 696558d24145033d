"""Unit tests of the direction hold (hill-start hold, rollback catch and faults): its table, each
threshold swept just inside and just outside, faults once per onset, on both presets."""

from __future__ import annotations

import math

import pytest

from overdrive.dynamics.control import MAX_CONTROL_STEP_S
from overdrive.dynamics.speed_control import drive_authority_mps2, resistance_mps2
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.direction_hold import (
    EVENTS,
    SOURCES_AGREE_MPS,
    STATES,
    TRANSITIONS,
    DirectionFault,
    DirectionHold,
    DirectionHoldConfig,
    agreed_speed_mps,
    mermaid_diagram,
    next_state,
)
from tests.conftest import PRESET_NAMES

DT_S = 0.01
CFG = DirectionHoldConfig()


def sin_of(grade_pct: float) -> float:
    return math.sin(math.atan(grade_pct / 100.0))


class Driver:
    """Steps a hold with one set of inputs at a time; collects the faults."""

    def __init__(self, preset: str = "escape-hybrid", gear: str | None = None) -> None:
        self.params = PRESETS[preset]
        self.gear = self.params.gear(gear or self.params.drive_gear)
        self.hold = DirectionHold(self.params)
        self.faults: list[int] = []
        self.messages: list[str] = []
        self.caught: list[str] = []
        self.last = None

    def step(self, n: int = 1, *, target: float = 2.0, speed: float = 0.0, stopped: bool = True,
             grade_pct: float = 15.0, throttle: float = 0.0,
             agreed: list[float] | None = None, dt_s: float = DT_S) -> str:
        for _ in range(n):
            self.last = cmd = self.hold.step(
                dt_s, target_mps=target, speed_mps=speed, stopped=stopped,
                sin_pitch=sin_of(grade_pct), throttle_pct=throttle, gear=self.gear,
                source_speeds_mps=agreed)
            if cmd.fault is not None:
                self.faults.append(cmd.fault[0])
                self.messages.append(cmd.fault[1])
            if cmd.caught:
                self.caught.append(cmd.caught)
        return self.hold.state

    def release_throttle_pct(self, grade_pct: float) -> float:
        """The throttle position at which the model's drive beats the pull with the margin."""
        full = drive_authority_mps2(self.params, self.gear, 0.0)
        pull = resistance_mps2(self.params, 0.0, sin_of(grade_pct))
        return 100.0 * pull * (1.0 + CFG.release_margin) / full


# --------------------------------------------------------------------------- the table

def test_the_table_names_only_known_states_and_events() -> None:
    assert set(TRANSITIONS) == set(STATES)
    for row in TRANSITIONS.values():
        assert set(row) <= set(EVENTS)
        assert set(row.values()) <= set(STATES)
    assert {e for row in TRANSITIONS.values() for e in row} == set(EVENTS)
    assert next_state("free", None) == "free"
    assert next_state("failed", "launch") == "failed"    # not listed: stays
    assert "free --> holding : launch" in mermaid_diagram()


def test_direction_hold_fault_codes_stay_in_their_block_1121_to_1129() -> None:
    assert all(1121 <= int(code) <= 1129 for code in DirectionFault)


# --------------------------------------------------------------------------- hill-start hold

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_pct", [0.0, -5.0, -15.0])
def test_no_hold_on_flat_or_downhill(preset: str, grade_pct: float) -> None:
    d = Driver(preset)
    d.step(target=0.0, grade_pct=grade_pct)
    assert d.step(target=2.0, grade_pct=grade_pct) == "free"
    assert d.last.mode == "free"


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_pct", [1.0, 5.0, 15.0])
def test_an_uphill_start_holds_on_the_parking_brake(preset: str, grade_pct: float) -> None:
    d = Driver(preset)
    d.step(target=0.0, grade_pct=grade_pct)
    assert d.step(target=2.0, grade_pct=grade_pct) == "holding"
    assert d.last.mode == "park"


def test_a_start_while_still_moving_is_not_a_launch() -> None:
    d = Driver()
    d.step(target=0.0, stopped=False, speed=0.5)
    assert d.step(target=2.0, stopped=False, speed=0.5) == "free"


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("grade_pct", [5.0, 10.0, 15.0])
@pytest.mark.parametrize(("offset_pct", "released"), [(-0.5, False), (0.5, True)])
def test_released_just_above_the_drive_that_beats_the_pull(preset: str, grade_pct: float,
                                                           offset_pct: float,
                                                           released: bool) -> None:
    d = Driver(preset)
    d.step(target=0.0, grade_pct=grade_pct)
    d.step(target=2.0, grade_pct=grade_pct)
    need = d.release_throttle_pct(grade_pct)
    assert need < 100.0
    state = d.step(target=2.0, grade_pct=grade_pct, throttle=need + offset_pct)
    assert state == ("free" if released else "holding")


def test_the_client_asking_for_zero_cancels_the_hold() -> None:
    d = Driver()
    d.step(target=0.0)
    d.step(target=2.0)
    assert d.step(target=0.0) == "free"
    assert d.faults == []


@pytest.mark.parametrize(("held_s", "fault"), [(2.95, False), (3.05, True)])
def test_a_gear_that_cannot_beat_the_pull_is_held_then_a_fault(held_s: float, fault: bool) -> None:
    """Ranger in high on 30 %: the model's full drive is below the pull: no throttle, held; a
    fault only after the timeout (the driving module's downshift had its turn)."""
    d = Driver("ranger-6x6", "high")
    d.step(target=0.0, grade_pct=30.0)
    d.step(target=2.0, grade_pct=30.0)
    assert d.last.mode == "brake"     # no throttle against the parking brake
    d.step(round(held_s / DT_S), target=2.0, grade_pct=30.0, throttle=100.0)
    assert d.faults == ([DirectionFault.CANNOT_HOLD_GRADE] if fault else [])
    assert d.hold.state == ("failed" if fault else "holding")
    d.step(50, target=2.0, grade_pct=30.0, throttle=100.0)
    assert d.faults == [DirectionFault.CANNOT_HOLD_GRADE]    # once per onset
    assert d.step(target=0.0, grade_pct=30.0) == "free"


# --------------------------------------------------------------------------- rollback catch

def released(d: Driver, grade_pct: float = 15.0) -> None:
    d.step(target=0.0, grade_pct=grade_pct)
    d.step(target=2.0, grade_pct=grade_pct)
    d.step(target=2.0, grade_pct=grade_pct, throttle=d.release_throttle_pct(grade_pct) + 1.0)
    assert d.hold.state == "free"


@pytest.mark.parametrize(("speed_mps", "caught"), [(-0.099, False), (-0.101, True)])
def test_rolling_back_faster_than_the_threshold_brakes_at_once(speed_mps: float,
                                                               caught: bool) -> None:
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=speed_mps, stopped=True, throttle=60.0,
           agreed=[0.0])
    assert d.hold.state == ("caught" if caught else "free")
    assert d.last.mode == ("brake" if caught else "free")
    assert bool(d.caught) == caught


@pytest.mark.parametrize(("back_m", "caught"), [(0.029, False), (0.031, True)])
def test_creeping_back_further_than_the_threshold_brakes(back_m: float, caught: bool) -> None:
    d = Driver()
    released(d)
    creep = -0.05
    d.step(round(back_m / -creep / DT_S), target=2.0, speed=creep, throttle=60.0)
    assert d.hold.state == ("caught" if caught else "free")


def test_one_source_frozen_backwards_is_not_a_creep() -> None:
    """The creep rule integrates what the sources agree on: GPS frozen at -0.04 m/s while the
    wheels say the vehicle moves on is no rollback."""
    assert agreed_speed_mps([-0.04, 0.4]) == 0.4
    assert agreed_speed_mps([-0.04, 0.0]) == pytest.approx(-0.02)
    assert agreed_speed_mps([0.5]) == 0.5
    assert agreed_speed_mps([]) is None
    assert agreed_speed_mps([0.0, SOURCES_AGREE_MPS]) == pytest.approx(SOURCES_AGREE_MPS / 2)
    d = Driver()
    released(d)
    d.step(300, target=2.0, speed=-0.04, stopped=False, throttle=60.0, agreed=[-0.04, 0.4])
    assert d.hold.state == "free"
    d.step(300, target=0.0, speed=-0.07, agreed=[-0.07, 0.0])   # frozen backwards at rest
    assert d.hold.state == "free" and d.caught == []


@pytest.mark.parametrize(("filtered_mps", "caught"), [(-0.029, False), (-0.031, True)])
def test_standing_without_a_command_creeping_back_is_caught(filtered_mps: float,
                                                           caught: bool) -> None:
    """Target 0: the parking brake is on (auto-hold); a creep back (a service brake too weak
    for the grade) is caught with full brake, without a fault (no command failed)."""
    d = Driver()
    d.step(target=0.0)
    assert d.last.mode == "park"
    d.step(100, target=0.0, speed=filtered_mps, agreed=[filtered_mps, filtered_mps])
    assert d.hold.state == ("caught" if caught else "free")
    d.step(100, target=0.0)
    assert d.hold.state == "free" and d.faults == [] and d.last.mode == "park"


def test_the_auto_hold_goes_on_before_the_vehicle_stands_and_off_for_a_command() -> None:
    d = Driver()
    d.step(target=0.0, speed=0.3, stopped=False, grade_pct=0.0)
    assert d.last.mode == "free"                     # still rolling to a stop
    d.step(target=0.0, speed=0.04, stopped=False, grade_pct=0.0)
    assert d.last.mode == "park"
    d.step(target=0.0, speed=0.06, stopped=False, grade_pct=0.0)
    assert d.last.mode == "park"                     # latched: noise cannot flicker it off
    d.step(target=2.0, grade_pct=0.0)
    assert d.last.mode == "free"                     # flat: released at once


def test_a_catch_then_a_retry_at_full_drive_then_a_fault_once() -> None:
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, stopped=True, throttle=60.0)
    assert d.hold.state == "caught"
    settle = round(CFG.settle_s / DT_S)
    d.step(settle - 2, target=2.0, throttle=0.0)
    assert d.hold.state == "caught"
    d.step(3, target=2.0, throttle=0.0)
    assert d.hold.state == "holding" and d.faults == []
    d.step(target=2.0, throttle=CFG.full_drive_pct - 0.1)
    assert d.hold.state == "holding"          # a retry waits for full drive
    d.step(target=2.0, throttle=CFG.full_drive_pct)
    assert d.hold.state == "free"
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=100.0)
    assert d.hold.state == "caught" and d.faults == []
    d.step(settle + 1, target=2.0, throttle=0.0)
    assert d.hold.state == "failed"
    assert d.faults == [DirectionFault.ROLLBACK_AT_FULL_DRIVE]
    d.step(200, target=2.0)
    assert d.faults == [DirectionFault.ROLLBACK_AT_FULL_DRIVE]    # once per onset
    assert d.last.mode == "brake"
    assert d.step(target=0.0) == "free"


def test_a_catch_at_full_throttle_is_a_fault_without_a_retry() -> None:
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=99.0)
    d.step(round(CFG.settle_s / DT_S) + 1, target=2.0)
    assert d.faults == [DirectionFault.ROLLBACK_AT_FULL_DRIVE]


def test_a_grade_a_gear_failed_on_is_not_tried_again() -> None:
    """After a fault, a new command in the same gear on the same grade waits held (timeout fault)
    instead of rolling back again: repeated commands never add up to a rollback."""
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=99.0)
    d.step(round(CFG.settle_s / DT_S) + 1, target=2.0)
    d.step(target=0.0)
    d.step(target=2.0)
    assert d.hold.state == "holding" and d.last.mode == "brake"
    d.step(target=2.0, throttle=100.0)
    assert d.hold.state == "holding"          # never released
    d.step(round(CFG.hold_timeout_s / DT_S), target=2.0, throttle=100.0)
    assert d.faults == [DirectionFault.ROLLBACK_AT_FULL_DRIVE, DirectionFault.CANNOT_HOLD_GRADE]
    # a gentler grade (beyond the margin) is tried again
    d.step(target=0.0, grade_pct=10.0)
    d.step(target=2.0, grade_pct=10.0)
    assert d.last.mode == "park"


@pytest.mark.parametrize(("stand_s", "fault"), [(2.9, False), (3.1, True)])
def test_standing_uphill_at_full_throttle_is_a_fault(stand_s: float, fault: bool) -> None:
    d = Driver()
    released(d)
    d.step(round(stand_s / DT_S), target=2.0, throttle=100.0)
    assert d.faults == ([DirectionFault.STALLED_ON_GRADE] if fault else [])


def test_standing_at_full_throttle_on_flat_ground_is_not_a_stall() -> None:
    d = Driver()
    d.step(500, target=2.0, grade_pct=0.0, throttle=100.0)
    assert d.faults == [] and d.hold.state == "free"


def test_rolling_back_beyond_the_judges_limit_is_reported_once() -> None:
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=50.0)
    d.step(60, target=2.0, speed=-0.2, stopped=False)    # 0.12 m more: the brakes do not hold
    assert d.faults == [DirectionFault.ROLLBACK_BEYOND_LIMIT]


def test_reset_forgets_the_state_but_not_the_failed_grades() -> None:
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=99.0)
    d.step(round(CFG.settle_s / DT_S) + 1, target=2.0)
    d.hold.reset()
    assert d.hold.state == "free" and d.hold.back_m == 0.0
    assert d.gear.name in d.hold.failed_pull_mps2


# --------------------------------------------------------------------------- noisy readings near a standstill

@pytest.mark.parametrize(("periods", "caught"), [(CFG.rollback_periods - 1, False),
                                                 (CFG.rollback_periods, True)])
def test_one_noisy_backward_sample_is_not_a_rollback(periods: int, caught: bool) -> None:
    """A real GNSS at low speed reads below -rollback_mps now and then (~2 sigma): only
    ``rollback_periods`` in a row are a rollback; a lone sample between forward ones is not."""
    d = Driver()
    released(d)
    for _ in range(20):   # isolated outliers: never caught
        d.step(target=2.0, speed=-0.15, stopped=False, throttle=60.0, agreed=[0.3])
        d.step(2, target=2.0, speed=0.3, stopped=False, throttle=60.0, agreed=[0.3])
    assert d.hold.state == "free" and d.caught == []
    d.step(periods, target=2.0, speed=-0.15, stopped=False, throttle=60.0, agreed=[0.3])
    assert (d.hold.state == "caught") is caught


@pytest.mark.parametrize(("grade_pct", "needs_full"), [(0.0, False), (0.5, True), (5.0, True)])
def test_a_retry_waits_for_full_drive_only_uphill(grade_pct: float, needs_full: bool) -> None:
    d = Driver()
    d.step(target=2.0, grade_pct=grade_pct, throttle=30.0)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, grade_pct=grade_pct, throttle=30.0)
    assert d.hold.state == "caught"
    d.step(round(CFG.settle_s / DT_S) + 2, target=2.0, grade_pct=grade_pct)
    assert d.hold.state == "holding" and d.faults == []
    d.step(target=2.0, grade_pct=grade_pct, throttle=60.0)
    assert (d.hold.state == "holding") is needs_full


# --------------------------------------------------------------------------- timeouts and the hold that never releases

@pytest.mark.parametrize(("periods", "fault"), [(round(CFG.hold_timeout_s / DT_S) - 1, False),
                                                (round(CFG.hold_timeout_s / DT_S), True)])
def test_a_throttle_that_stays_short_of_the_release_times_out(periods: int, fault: bool) -> None:
    """A gear that could climb, a throttle that never opens enough: held, then a fault naming
    the throttle (not the gear) after hold_timeout_s."""
    d = Driver()
    d.step(target=0.0)
    d.step(target=2.0)                                   # launch: holding from here
    short = d.release_throttle_pct(15.0) - 0.5
    d.step(periods, target=2.0, throttle=short)
    assert d.hold.state == ("failed" if fault else "holding")
    assert d.faults == ([DirectionFault.CANNOT_HOLD_GRADE] if fault else [])
    if fault:
        assert f"the throttle stayed at {short:.0f} %" in d.messages[0]
        assert "cannot beat the pull" not in d.messages[0]


def test_a_timeout_says_why_the_hold_was_never_released() -> None:
    # the gear's full drive is below the pull
    d = Driver("ranger-6x6", "high")
    d.step(target=0.0, grade_pct=30.0)
    d.step(round(CFG.hold_timeout_s / DT_S) + 1, target=2.0, grade_pct=30.0, throttle=100.0)
    assert d.faults == [DirectionFault.CANNOT_HOLD_GRADE]
    assert "its full drive" in d.messages[0] and "cannot beat the pull" in d.messages[0]
    # the gear already failed on this grade (a rollback at full drive): not tried again
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, throttle=99.0)
    d.step(round(CFG.settle_s / DT_S) + 1, target=2.0)
    d.step(target=0.0)
    d.step(round(CFG.hold_timeout_s / DT_S) + 1, target=2.0, throttle=100.0)
    assert d.faults == [DirectionFault.ROLLBACK_AT_FULL_DRIVE, DirectionFault.CANNOT_HOLD_GRADE]
    assert d.messages[1].endswith("it already failed on this grade in this gear; held, brakes on")


# --------------------------------------------------------------------------- gaps (a stall)

GAP_S = 0.5   # a stalled speed server: one step after half a second


def test_after_a_gap_one_standing_sample_does_not_end_the_settle() -> None:
    """Caught, then the server stalls 0.5 s: the step after the gap is one observed standing
    sample, not settle_s of standing; the retry comes only after settle_s of observed periods."""
    d = Driver()
    released(d)
    d.step(CFG.rollback_periods, target=2.0, speed=-0.2, stopped=True, throttle=60.0)
    assert d.hold.state == "caught"
    d.step(target=2.0, dt_s=GAP_S)
    assert d.hold.state == "caught"
    assert d.hold.standing_s == pytest.approx(MAX_CONTROL_STEP_S)
    d.step(round((CFG.settle_s - MAX_CONTROL_STEP_S) / DT_S) - 2, target=2.0)
    assert d.hold.state == "caught"
    d.step(3, target=2.0)
    assert d.hold.state == "holding"


@pytest.mark.parametrize("gaps", [5, 20])
def test_gaps_do_not_add_towards_the_hold_timeout_or_the_stall(gaps: int) -> None:
    """Holding (a throttle short of the release) or standing uphill at full throttle across
    stalls of 0.5 s: each gap adds one bounded step to the 3 s timers, not 0.5 s (20 gaps
    would be 10 s: both faults, unobserved)."""
    held = Driver()
    held.step(target=0.0)
    held.step(target=2.0)
    short = held.release_throttle_pct(15.0) - 0.5
    held.step(gaps, target=2.0, throttle=short, dt_s=GAP_S)
    assert held.hold.state == "holding" and held.faults == []
    assert held.hold.time_in_state_s == pytest.approx(gaps * MAX_CONTROL_STEP_S)
    stalled = Driver()
    released(stalled)
    stalled.step(gaps, target=2.0, throttle=100.0, dt_s=GAP_S)
    assert stalled.faults == [] and stalled.hold.stalled_s <= gaps * MAX_CONTROL_STEP_S + 1e-9


def test_a_rollback_during_a_gap_is_measured_in_full() -> None:
    """The distance integral takes the real elapsed time: 0.05 m/s back for 0.8 s (a stall) is
    0.04 m, beyond rollback_m (0.03), slower than rollback_mps: caught by the distance rule."""
    d = Driver()
    released(d)
    d.step(target=2.0, speed=-0.05, stopped=False, throttle=60.0, dt_s=0.8)
    assert d.hold.back_m == pytest.approx(0.04)
    assert d.hold.state == "caught" and d.caught


def test_a_negative_elapsed_time_counts_nothing() -> None:
    d = Driver()
    released(d)
    before = d.hold.time_in_state_s
    d.step(target=2.0, throttle=100.0, dt_s=-1.0)
    assert d.hold.time_in_state_s == before and d.hold.stalled_s == 0.0
