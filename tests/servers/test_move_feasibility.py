"""Reply codes of the move server's command check: every rejection reason, swept at its limit."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.dynamics.ellipse import ellipse_for
from overdrive.messages import MoveCommand
from overdrive.servers.move_feasibility import (
    Situation,
    check_command,
    direction_change_note,
    top_speed_mps,
)

OK = Situation()


def move(kind: str = "move", distance: float = 10.0, speed: float = 3.0,
         curvature: float = 0.0) -> MoveCommand:
    return MoveCommand(kind=kind, command_id=1, distance_m=distance, maxspeed_mps=speed,  # type: ignore[arg-type]
                       curvature_1pm=curvature)


def code(cmd: object, preset, situation: Situation = OK) -> str:
    verdict = check_command(cmd, situation, preset)
    return "ok" if verdict is None else verdict.code


def test_plain_commands_accepted(preset) -> None:
    for kind in ("move", "reverse"):
        assert code(move(kind, speed=1.0), preset) == "ok"
    assert code(MoveCommand(kind="stop"), preset) == "ok"
    assert code(move(distance=0.0, speed=0.0), preset) == "ok"


# ----------------------------------------------------------------------------- invalid

@pytest.mark.parametrize("field", ["distance", "speed", "curvature"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_is_invalid(preset, field: str, value: float) -> None:
    verdict = check_command(move(**{field: value}), OK, preset)
    assert verdict is not None and verdict.code == "invalid"
    assert {"distance": "distance_m", "speed": "maxspeed_mps",
            "curvature": "curvature_1pm"}[field] in verdict.message


@pytest.mark.parametrize("field", ["distance", "speed"])
@pytest.mark.parametrize("value", [-1e-9, -0.5, -1e6])
def test_negative_is_invalid(preset, field: str, value: float) -> None:
    assert code(move(**{field: value}), preset) == "invalid"


def test_malformed_messages_are_invalid(preset) -> None:
    assert code("MOVE 10", preset) == "invalid"
    assert code(MoveCommand(kind="jump"), preset) == "invalid"  # type: ignore[arg-type]
    assert code(MoveCommand(kind="move", distance_m="10"), preset) == "invalid"  # type: ignore[arg-type]
    assert code(MoveCommand(kind="move", maxspeed_mps=True), preset) == "invalid"  # type: ignore[arg-type]


@given(st.floats(allow_nan=True, allow_infinity=True), st.floats(allow_nan=True, allow_infinity=True),
       st.floats(allow_nan=True, allow_infinity=True))
def test_property_no_crash_and_non_finite_never_accepted(d: float, v: float, k: float) -> None:
    from overdrive.scenario.vehicles import PRESETS
    verdict = check_command(move(distance=d, speed=v, curvature=k), OK, PRESETS["escape-hybrid"])
    if not all(math.isfinite(x) for x in (d, v, k)) or d < 0 or v < 0:
        assert verdict is not None and verdict.code == "invalid"
    else:
        assert verdict is None or verdict.code == "infeasible"


# ----------------------------------------------------------------------------- infeasible

@pytest.mark.parametrize("kind", ["move", "reverse"])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_curvature_limit_swept(preset, kind: str, sign: float) -> None:
    k_max = preset.max_curvature_1pm
    for factor in (0.0, 0.5, 0.99, 0.999999, 1.0):
        assert code(move(kind, speed=1.0, curvature=sign * factor * k_max), preset) == "ok"
    for factor in (1.000001, 1.01, 1.5, 10.0):
        verdict = check_command(move(kind, speed=1.0, curvature=sign * factor * k_max), OK, preset)
        assert verdict is not None and verdict.code == "infeasible"
        assert "turning radius" in verdict.message


@pytest.mark.parametrize("kind", ["move", "reverse"])
def test_speed_limit_of_the_gear_swept(preset, kind: str) -> None:
    top = top_speed_mps(preset, "reverse" if kind == "reverse" else "forward", 0.9)
    assert 0.0 < top < 70.0
    for v in (0.0, 0.5 * top, 0.999 * top, top):
        assert code(move(kind, speed=v), preset) == "ok"
    for v in (top * 1.001, top + 0.01, 2 * top, 70.0):
        verdict = check_command(move(kind, speed=v), OK, preset)
        assert verdict is not None and verdict.code == "infeasible"
        assert "reaches" in verdict.message


def test_reverse_is_slower_than_forward(preset) -> None:
    assert top_speed_mps(preset, "reverse", 0.9) < top_speed_mps(preset, "forward", 0.9)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_grade_limit_swept(preset, sign: float) -> None:
    limit = preset.max_pitch_rad
    for factor in (0.0, 0.5, 0.999, 1.0):
        assert code(move(), preset, Situation(pitch_rad=sign * factor * limit)) == "ok"
    for factor in (1.001, 1.2):
        verdict = check_command(move(), Situation(pitch_rad=sign * factor * limit), preset)
        assert verdict is not None and verdict.code == "infeasible" and "grade" in verdict.message


def test_stop_is_accepted_even_when_nothing_else_is(preset) -> None:
    bad = Situation(have_position=False, safety_mode="estop-pause", pitch_rad=2.0,
                    estop_braking=True, latched_estop=True)
    assert code(MoveCommand(kind="stop"), preset, bad) == "ok"


# ----------------------------------------------------------------------------- not_ready

@pytest.mark.parametrize("situation, words", [
    (Situation(have_position=False), "no position"),
    (Situation(safety_mode="software-pause"), "software-pause"),
    (Situation(safety_mode="manual-override"), "manual-override"),
    (Situation(computer_speed=False), "computer does not control speed"),
    (Situation(speed_server_estop=True, speed_server_fault="no SPSS"), "speed server e-stop"),
])
def test_not_ready(preset, situation: Situation, words: str) -> None:
    verdict = check_command(move(), situation, preset)
    assert verdict is not None and verdict.code == "not_ready" and words in verdict.message


def test_latched_estop_obstacle_reach(preset) -> None:
    ell = ellipse_for(preset, 0.8)
    latched = dict(latched_estop=True, radar_target=True, ellipse=ell, obstacle_margin_m=2.0)
    cmd = move(distance=10.0, speed=3.0)
    reach = 10.0 + 3.0**2 / (2 * ell.lon_mps2) + 2.0
    assert code(cmd, preset, Situation(radar_range_m=reach - 0.05, **latched)) == "not_ready"
    assert code(cmd, preset, Situation(radar_range_m=reach + 0.05, **latched)) == "ok"
    assert code(cmd, preset, Situation(**{**latched, "radar_target": False})) == "ok"
    # backing away from the obstacle is allowed: the radar looks forward
    assert code(move("reverse", speed=1.0), preset, Situation(radar_range_m=1.0, **latched)) == "ok"


def test_infeasible_is_reported_before_not_ready(preset) -> None:
    cmd = move(curvature=2 * preset.max_curvature_1pm)
    assert code(cmd, preset, Situation(have_position=False)) == "infeasible"


# ----------------------------------------------------------------------------- busy

@pytest.mark.parametrize("speed_mps", [0.11, 2.0, 20.0])
def test_a_change_of_direction_while_moving_replaces_and_says_it_stops_first(preset,
                                                                            speed_mps) -> None:
    """Seed 004: "the new command replaces the current one and gets immediately executed"
    (issue 31 item 9: it was ``busy``); the reply says the vehicle stops first."""
    fwd = Situation(moving_direction="forward", speed_mps=speed_mps)
    back = Situation(moving_direction="reverse", speed_mps=-speed_mps)
    for cmd, situation, turn in ((move("reverse", speed=1.0), fwd, True),
                                 (move("move"), back, True), (move("move"), fwd, False),
                                 (move("reverse", speed=1.0), back, False)):
        assert code(cmd, preset, situation) == "ok"
        note = direction_change_note(cmd, situation)
        assert ("stopping now" in note and f"{speed_mps:.2f} m/s" in note) if turn else note == ""


def test_a_change_of_direction_during_another_waits_for_its_shift(preset) -> None:
    shifting = Situation(shifting_to="reverse")
    assert code(move("move"), preset, shifting) == "ok"
    assert "shift to reverse under way ends first" in direction_change_note(move("move"), shifting)
    assert code(move("reverse", speed=1.0), preset, shifting) == "ok"
    assert direction_change_note(move("reverse", speed=1.0), shifting) == ""


def test_busy_while_estop_brakes(preset) -> None:
    verdict = check_command(move("reverse", speed=1.0), Situation(estop_braking=True), preset)
    assert verdict is not None and verdict.code == "busy" and "emergency stop" in verdict.message
