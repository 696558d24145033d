"""A pause stops at the vehicle's pause rate (issue 31 item 2). Seed 000: a SafeStop pause
"brings the vehicle to a stop using a constant (user set) acceleration"; a software pause (a
door open) is "identical" in every other respect. The rate is the vehicle file's
``pause_decel_mps2``; the stack brakes harder only when the authorization needs it (the least
that keeps it), and a STOP, an authorization cut or an e-stop disable stays "stop now". Judged
from the plant's own speed and x (ground truth), through the move server and through the
driving module alone, on both presets."""

from __future__ import annotations

import math

import pytest

from overdrive.dynamics.vehicle_params import VehicleSpecError, with_overrides
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from tests.conftest import PRESET_NAMES

ON_S = 9.0          # at cruise: the 8 m/s reached, the end far ahead
CRUISE_MPS = 8.0    # the acceptance speed
RATE_TOLERANCE = 0.10   # the acceptance: the set rate within 10 %
STOPPED_MPS = 0.05
END_TOLERANCE_M = 0.05  # the judge's position noise allowance at an authorization's end
INTERRUPTIONS = {"pause": {"safestop": "pause"}, "door": {"door": "open"}}

EDGE = pytest.mark.variant_edge   # `make test` runs 1 in 4 of the sweep plus these (tests/conftest.py)


def drive(preset: str, via: str, distance_m: float, events: list[dict],
          overrides: dict | None = None, duration_s: float = 18.0):
    vehicle = {"preset": preset, **overrides} if overrides else preset
    if via == "move":
        start = [{"at_s": 0.5, "move": {"distance_m": distance_m, "maxspeed_mps": CRUISE_MPS,
                                        "curvature_1pm": 0}}]
    else:
        start = [{"at_s": 0.5, "advance": {"source": "lidar", "distance_m": distance_m}},
                 {"at_s": 0.5, "max_speed": {"source": "map", "speed_mps": CRUISE_MPS}}]
    data = {"name": "pause-rate", "vehicle": vehicle, "start": "ready", "seed": 1,
            "duration_s": duration_s, "events": [*start, *events]}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def stop_after(result, t0_s: float) -> tuple[float, float, float]:
    """(speed at ``t0_s``, seconds to a standstill, metres to it), from the plant's trace."""
    rows = [r for r in result.trace if float(r["t_s"]) >= t0_s - 1e-9]
    v0, x0 = float(rows[0]["speed_mps"]), float(rows[0]["x_m"])
    stop = next(r for r in rows if abs(float(r["speed_mps"])) < STOPPED_MPS)
    return v0, float(stop["t_s"]) - t0_s, float(stop["x_m"]) - x0


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("via", ["move", "driving"])
@pytest.mark.parametrize("kind", sorted(INTERRUPTIONS))
@pytest.mark.parametrize("rate_mps2", [1.5, pytest.param(2.5, marks=EDGE), 4.0])
def test_a_pause_at_8_mps_stops_at_the_set_rate(preset: str, via: str, kind: str,
                                                rate_mps2: float) -> None:
    result = drive(preset, via, 120.0, [{"at_s": ON_S, **INTERRUPTIONS[kind]}],
                   {"pause_decel_mps2": rate_mps2}, duration_s=ON_S + 8.0)
    v0, stop_s, stop_m = stop_after(result, ON_S)
    assert v0 == pytest.approx(CRUISE_MPS, abs=0.3)
    mean_mps2 = v0 / stop_s
    assert mean_mps2 == pytest.approx(rate_mps2, rel=RATE_TOLERANCE), (mean_mps2, stop_m)
    # the distance too: no harder than the rate (no full-brake stop hidden in the mean)
    assert stop_m >= v0 * v0 / (2.0 * rate_mps2 * (1.0 + RATE_TOLERANCE))
    assert result.summary["violations"] == []


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("via", ["move", "driving"])
@pytest.mark.parametrize("on_s", [pytest.param(7.4, marks=EDGE), 7.8, 8.2, 8.6,
                                  pytest.param(9.0, marks=EDGE)])
def test_a_pause_with_a_short_authorization_still_stops_inside_it(preset: str, via: str,
                                                                  on_s: float) -> None:
    """A 40 m authorization: paused from 15 m before its end (harder than the pause rate is
    needed) to the last metres (the normal stop already under way)."""
    result = drive(preset, via, 40.0, [{"at_s": on_s, "safestop": "pause"}])
    x0 = float(result.trace[0]["x_m"])
    final_m = float(result.trace[-1]["x_m"]) - x0
    assert final_m <= 40.0 + END_TOLERANCE_M
    assert abs(float(result.trace[-1]["speed_mps"])) < STOPPED_MPS
    assert result.summary["violations"] == []


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("ahead_m", [pytest.param(12.0, marks=EDGE), 13.0, 14.0, 15.0,
                                     pytest.param(16.0, marks=EDGE)])
def test_a_short_authorization_gets_the_least_rate_that_keeps_it(preset: str,
                                                                 ahead_m: float) -> None:
    """Through the driving module alone: the end a few metres ahead when the pause comes at
    up to 8 m/s (the normal stop may already have begun). Where the pause rate could not keep
    the end (its v^2 / 2a plus the 0.3 s a stop loses at speed), harder than it, far gentler
    than the full brake; always inside the end."""
    params = PRESETS[preset]
    probe = drive(preset, "driving", 200.0, [], duration_s=ON_S + 0.005)
    x_on_m = float(probe.trace[-1]["x_m"]) - float(probe.trace[0]["x_m"])
    result = drive(preset, "driving", x_on_m + ahead_m, [{"at_s": ON_S, "safestop": "pause"}])
    v0, stop_s, stop_m = stop_after(result, ON_S)
    assert stop_m <= ahead_m + END_TOLERANCE_M
    pause_m = v0 * v0 / (2.0 * params.pause_decel_mps2) + 0.3 * v0
    if pause_m > ahead_m:
        assert params.pause_decel_mps2 < v0 / stop_s < 0.6 * params.max_brake_decel_mps2
    assert result.summary["violations"] == []


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("stop", ["estop", "stop_command", "authorization_cut"])
def test_a_stop_an_authorization_cut_and_an_estop_stay_stop_now(preset: str, stop: str) -> None:
    """Not a pause: e-stop disable (seed 000: "100% braking effort"), the planner's STOP, an
    authorization cut to 0 (driving module alone): at least twice the pause rate."""
    via = "driving" if stop == "authorization_cut" else "move"
    event = {"estop": {"safestop": "stop"}, "stop_command": {"stop": {}},
             "authorization_cut": {"advance": {"source": "lidar", "distance_m": 0.0}}}[stop]
    result = drive(preset, via, 120.0, [{"at_s": ON_S, **event}], duration_s=ON_S + 5.0)
    v0, stop_s, _ = stop_after(result, ON_S)
    assert v0 / stop_s >= 2.0 * PRESETS[preset].pause_decel_mps2


def tyres_mps2(preset: str) -> float:
    """What the tyres hold: the full brake's deceleration and the 60-0 mph stop's v^2 / 2d."""
    p = PRESETS[preset]
    return min(p.max_brake_decel_mps2, 26.8224 ** 2 / (2.0 * p.stopping_distance_60mph_m))


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("factor", [0.999, 1.0, "floor"])
def test_a_pause_rate_up_to_what_the_tyres_hold_is_taken(preset: str, factor) -> None:
    rate = 1.0 if factor == "floor" else tyres_mps2(preset) * factor
    assert with_overrides(PRESETS[preset], {"pause_decel_mps2": rate}).pause_decel_mps2 == rate


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, -2.5, 0.0, 0.1, 0.999, "2.5",
                                   None, True, "tyres+"])
def test_a_pause_rate_not_finite_not_above_0_or_beyond_the_tyres_is_refused(preset: str,
                                                                          value) -> None:
    if value == "tyres+":
        value = tyres_mps2(preset) * 1.001
    with pytest.raises(VehicleSpecError) as err:
        with_overrides(PRESETS[preset], {"pause_decel_mps2": value})
    assert err.value.field == "pause_decel_mps2"


def test_brakes_weakened_below_the_pause_rate_are_refused_naming_the_brakes() -> None:
    with pytest.raises(VehicleSpecError) as err:
        with_overrides(PRESETS["escape-hybrid"], {"max_brake_decel_mps2": 2.4})
    assert err.value.field == "max_brake_decel_mps2" and "pause_decel_mps2" in err.value.reason


@pytest.mark.variants
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("via", ["move", "driving"])
@pytest.mark.parametrize("pause_s", [pytest.param(0.3, marks=EDGE), 1.0, 2.0])
def test_a_pause_released_before_the_vehicle_stands_stops_it_now(preset: str, via: str,
                                                                  pause_s: float) -> None:
    """Back in drive-by-wire while still stopping, the stack has no command in force: it stops
    now (the judge's unintended_motion: no further than the shortest stop from the release),
    and nothing moves after."""
    result = drive(preset, via, 120.0, [{"at_s": ON_S, "safestop": "pause"},
                                        {"at_s": ON_S + pause_s, "safestop": "run"}])
    v_release, _, _ = stop_after(result, ON_S + pause_s)
    assert v_release > 1.0                       # still moving at the release
    assert abs(float(result.trace[-1]["speed_mps"])) < STOPPED_MPS
    assert result.summary["violations"] == []
