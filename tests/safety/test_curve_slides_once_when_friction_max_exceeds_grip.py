"""A curve driven with ``friction_max`` above the true grip slides once, not again and again.

``dynamics.grip_estimate``: "a curve's cap can exceed the truth once the estimate passes 1.48
times it: that slide is the measurement". After the measurement (traction control in the curve)
the estimate is the grip measured; the tyres then work at the curve's cap (0.675 of the
estimate), which is no evidence of more grip, yet after ``quiet_s`` the estimate loosened again to
``headroom`` x that work (1.35 x the grip measured) and the vehicle slid again: a slide every
5.5-7.4 s for as long as the curve lasted, on unchanged ground. Now a measured slide or ABS
episode is a ceiling: no loosening above it until grip above it is used without slip.

Measured before the fix (2026-11-26, seed 7, ``friction`` 0.4, ``friction_max`` 1.0, MOVE 400 m at 10 m/s on
curvature 0.05 1/m, 60 s): traction-control onsets at 7.35, 13.94, 20.6, 27.09, 33.59, 40.11,
46.57, 53.2, 59.7 s (escape-hybrid) and 6.57, 13.16, 19.73, 27.12, 34.53, 41.93, 48.45, 55.83 s
(ranger-6x6); each slide small (at most 0.04 m off the arc, ground truth), the judge silent.
"""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.messages import Topic, VehicleStatus
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES

DURATION_S = 30.0


class SlideTap:
    """Onsets of traction control reported by the vehicle (the plant's own slide signal)."""

    def __init__(self) -> None:
        self.now_s = 0.0
        self.active = False
        self.onsets: list[float] = []

    def set_time(self, now_s: float) -> None:
        self.now_s = now_s

    def observe(self, topic: str, msg: Any) -> None:
        if topic == Topic.VEHICLE_STATUS and isinstance(msg, VehicleStatus):
            if msg.traction_control and not self.active:
                self.onsets.append(self.now_s)
            self.active = bool(msg.traction_control)


def curve_run(preset: str, friction_max: float) -> tuple[Any, SlideTap]:
    tap = SlideTap()
    data = {"name": "curve-slides", "vehicle": preset, "start": "ready", "seed": 7,
            "duration_s": DURATION_S, "world": {"friction": 0.4}, "friction_max": friction_max,
            "events": [{"at_s": 0.5, "move": {"distance_m": 400.0, "maxspeed_mps": 10.0,
                                              "curvature_1pm": 0.05}}]}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False,
                          observers=[tap])
    return result, tap


def episodes(onsets: list[float], gap_s: float = 1.0) -> int:
    """Slides separated by more than ``gap_s`` (ABS-like flicker within one slide counts once)."""
    count, last = 0, -1e9
    for t in onsets:
        if t - last > gap_s:
            count += 1
        last = t
    return count


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_friction_max_at_the_grip_never_slides(preset: str) -> None:
    """Reference: configured with the true grip as its maximum, the curve never slides."""
    result, tap = curve_run(preset, 0.4)
    assert episodes(tap.onsets) <= 1
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_friction_max_above_the_grip_slides_at_most_once(preset: str) -> None:
    result, tap = curve_run(preset, 1.0)
    assert result.nodes["vehicle"].plant.odometer_m > 100.0     # it drove the curve
    assert episodes(tap.onsets) <= 1, tap.onsets


@pytest.mark.xfail(strict=True, reason="residual: the start's 2WD wheel spin reads the driven "
                   "share only and sets no ceiling, so the curve slides once more to measure "
                   "(onsets 0.9, 12.03 s escape-hybrid; 1.13, 11.72 s ranger-6x6; was 6 in 30 s)")
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_ground_below_the_start_friction_slides_at_most_once_in_a_curve(preset: str) -> None:
    """No misconfiguration needed: the ground turns 0.3 before a curve MOVE at 10 m/s, the
    maximum left at its default (the start's 0.8). Measured 2026-11-26, 40 s: onsets 0.9, 6.5,
    12.0, 17.5, 23.0, 28.5, 34.0, 39.5 s (escape-hybrid), 1.1 ... 39.9 s every 5.5 s
    (ranger-6x6); be389f6 (no online estimate) slid 12 / 8 times: the estimate takes the first
    slide's grip within one period but then loosens above it again."""
    tap = SlideTap()
    data = {"name": "ice-curve", "vehicle": preset, "start": "ready", "seed": 7,
            "duration_s": DURATION_S, "world": {"friction": 0.8},
            "events": [{"at_s": 0.3, "world": {"friction": 0.3}},
                       {"at_s": 0.5, "move": {"distance_m": 1000.0, "maxspeed_mps": 10.0,
                                              "curvature_1pm": 0.05}}]}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False,
                          observers=[tap])
    assert result.nodes["vehicle"].plant.odometer_m > 100.0
    assert episodes(tap.onsets) <= 1, tap.onsets
