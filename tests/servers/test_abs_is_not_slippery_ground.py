"""ABS in a hard stop is braking at the grip limit, not slippery ground (issue 31 item 3).

The audit: "ABS activity in a hard stop on dry road counts as traction control: after the move
ends, a shift to low and a 5 s runwait for nothing." The simulated vehicle reports ABS
(``VehicleStatus.abs_active``) apart from traction control (a spin or a slide); the stack takes
only the latter as slippery ground (seed 001: low gear "on slippery or steep ground"). A vehicle
that reports only one (``abs_active`` None) has its ``traction_control`` taken as slip, ABS or
not: the conservative side (docs/driving-module.md, "ABS is not slippery ground").
Judged from ground truth (the plant's speed and gear), both presets.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from overdrive.messages import GpsIns, SpeedState, Topic, VehicleStatus
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import DrivingModule
from tests.conftest import PRESET_NAMES

# frictions at which a full brake from 10 m/s brings the ABS in (the preset's full brake,
# 9.0 / 6.5 m/s^2, exceeds mu g): dry asphalt (0.9) down to a wet road (0.5)
ABS_FRICTIONS = {"escape-hybrid": (0.55, 0.8, 0.9), "ranger-6x6": (0.5, 0.6, 0.65)}
STOP_AT_S = 8.0
NEXT_MOVE_AT_S = 14.0
HARD_STOPS = {
    "stop": {"at_s": STOP_AT_S, "stop": {}},
    "authorization_cut_short": {"at_s": STOP_AT_S, "advance": {"source": "lidar",
                                                                "distance_m": 1.0}},
}


class Tap:
    """The vehicle's reports, the speed server's state and the plant's truth, by time."""

    def __init__(self) -> None:
        self.now_s = 0.0
        self.status: list[tuple[float, VehicleStatus]] = []
        self.speed: list[tuple[float, SpeedState]] = []

    def set_time(self, now_s: float) -> None:
        self.now_s = now_s

    def observe(self, topic: str, msg: Any) -> None:
        if topic == Topic.VEHICLE_STATUS:
            self.status.append((self.now_s, msg))
        elif topic == Topic.SPEED_STATE:
            self.speed.append((self.now_s, msg))


def hard_stop_run(preset: str, friction: float, stop: dict) -> tuple[Any, Tap]:
    tap = Tap()
    events = [{"at_s": 0.5, "move": {"distance_m": 300.0, "maxspeed_mps": 10.0}}, stop]
    if "advance" in stop:   # the lidar's authorization stays short: lift it for the next move
        events.append({"at_s": NEXT_MOVE_AT_S - 0.5,
                       "advance": {"source": "lidar", "distance_m": 500.0}})
    events.append({"at_s": NEXT_MOVE_AT_S, "move": {"distance_m": 20.0, "maxspeed_mps": 5.0}})
    data = {"name": "abs", "vehicle": preset, "start": "ready", "duration_s": NEXT_MOVE_AT_S + 4.0,
            "seed": 5, "world": {"friction": friction}, "events": events}
    result = run_scenario(parse_scenario(data), None, plot=False, record_mcap=False,
                          observers=[tap])
    return result, tap


@pytest.mark.parametrize("stop", sorted(HARD_STOPS))
@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_a_hard_stop_with_abs_changes_no_gear_and_waits_for_nothing(preset: str,
                                                                    stop: str) -> None:
    params = PRESETS[preset]
    for friction in ABS_FRICTIONS[preset]:
        result, tap = hard_stop_run(preset, friction, HARD_STOPS[stop])
        abs_s = [t for t, s in tap.status if s.abs_active]
        assert abs_s and min(abs_s) >= STOP_AT_S, (friction, "the hard stop brought the ABS in")
        assert not any(s.traction_control for _, s in tap.status), friction
        # from the stop on: no gear but the drive gear, never a shift or a runwait
        after = [s for t, s in tap.speed if t >= STOP_AT_S]
        assert {s.gear for s in after} == {params.drive_gear}, friction
        assert not {s.state for s in after} & {"shifting", "runwait", "idle"}, friction
        assert {s.gear for t, s in tap.status if t >= STOP_AT_S} == {params.drive_gear}
        assert not any(s.hint == "slipping" for s in after), friction
        # the vehicle stood, then the next MOVE drives within 1.5 s (no 5 s runwait)
        plant = result.nodes["vehicle"].plant
        assert plant.odometer_m > 0.0
        moving = [t for t, s in tap.speed if t >= NEXT_MOVE_AT_S and s.speed_mps > 0.5]
        assert moving and min(moving) - NEXT_MOVE_AT_S < 1.5, friction
        assert result.summary["violations"] == [], friction


def _status(traction: bool, abs_active: bool | None, speed_mps: float = 8.0,
            throttle_pct: float = 0.0, brake_pct: float = 80.0) -> list:
    p = PRESETS["escape-hybrid"]
    return [(Topic.VEHICLE_STATUS, VehicleStatus(
                gear=p.drive_gear, shifting=False, engine="running", engine_rpm=2000.0,
                start_failed=False, traction_control=traction, steer_pct=0.0,
                throttle_pct=throttle_pct, brake_pct=brake_pct, safety_mode="drive-by-wire",
                abs_active=abs_active)),
            (Topic.GPS_INS, GpsIns(x_m=0.0, y_m=0.0, heading_rad=0.0, speed_mps=speed_mps,
                                   pitch_rad=0.0, roll_rad=0.0, odometer_m=0.0))]


@pytest.mark.parametrize(("traction", "abs_active", "throttle_pct", "brake_pct", "slippery"), [
    (False, True, 0.0, 80.0, False),   # ABS reported apart, no spin or slide: braking at the limit
    (True, True, 0.0, 80.0, False),    # a hard stop in a curve: ABS with the slide flag, brake on
    (True, True, 12.0, 80.0, False),   # ... while the lagged throttle still closes
    (True, True, 40.0, 30.0, True),    # the throttle outweighs the brake: a spin, slippery
    (True, True, math.nan, 80.0, True),  # an unreadable pedal: slip, the safe side
    (True, False, 0.0, 80.0, True),    # a spin or a slide: slippery
    (True, None, 0.0, 80.0, True),     # a vehicle reporting one flag: taken as slip, ABS or not
    (False, None, 0.0, 80.0, False),
    (False, False, 0.0, 80.0, False),
])
def test_only_traction_control_makes_the_ground_slippery(
        traction: bool, abs_active: bool | None, throttle_pct: float, brake_pct: float,
        slippery: bool) -> None:
    """Slippery ground (low gear, issue 31) is traction control the brakes do not explain; the
    slide checks (traction monitor, issue 30) see every traction-control report."""
    node = DrivingModule(PRESETS["escape-hybrid"])
    node.step(0.0, _status(False, False))
    node.step(0.01, _status(traction, abs_active, throttle_pct=throttle_pct,
                            brake_pct=brake_pct))
    assert (node.slippery_s == 0.01) is slippery
    assert node.traction.active(0.02) is traction


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_wheel_spin_on_slippery_ground_still_wants_the_low_gear(preset: str) -> None:
    """Real slippery ground is still detected: a start on ice spins the driven wheels (traction
    control), and the next standstill shifts to the preset's low gear."""
    params = PRESETS[preset]
    tap = Tap()
    data = {"name": "ice", "vehicle": preset, "start": "ready", "duration_s": 30.0, "seed": 5,
            "world": {"friction": 0.8},
            "events": [{"at_s": 0.2, "world": {"friction": 0.06}},
                       {"at_s": 0.5, "move": {"distance_m": 15.0, "maxspeed_mps": 8.0}}]}
    run_scenario(parse_scenario(data), None, plot=False, record_mcap=False, observers=[tap])
    assert any(s.traction_control for _, s in tap.status)
    assert params.low_gear in {s.gear for _, s in tap.status}
