"""A vehicle file's steering_ratio: a constant or a table [[wheel_rad, ratio], ...] whose
road-wheel angle rises with the wheel angle; NaN, infinities, zero, negative, a table not
starting at 0, wheel angles not increasing and a ratio rising so fast the road angle falls are
refused naming the field; the inverse the stack uses is exact over the whole range."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.dynamics.steering_ratio import (
    RATIO_MAX,
    RATIO_MIN,
    check_steering_ratio,
    ratio_at,
    road_wheel_rad,
    steering_wheel_rad,
)
from overdrive.dynamics.vehicle_params import VehicleSpecError, vehicle_from_data, vehicle_to_data
from overdrive.scenario.vehicles import KIT_VEHICLES, PRESETS
from overdrive.vehicle.pacmod3_kit import Pacmod3Kit

LEXUS = KIT_VEHICLES["lexus-rx450h"]


def with_ratio(value: object) -> dict:
    data = vehicle_to_data(LEXUS)
    data["steering_ratio"] = value
    return data


@pytest.mark.parametrize("value, words", [
    (float("nan"), "finite"), (float("inf"), "finite"), (0, "within"), (0.0, "within"),
    (-15.0, "within"), (RATIO_MIN - 1e-9, "within"), (RATIO_MAX + 1e-9, "within"),
    (True, "number or a table"), ("15.7", "number or a"), ([], "non-empty"),
    ([[0.0, 15.0], [float("nan"), 14.0]], "finite"), ([[0.0, 15.0], [5.0, float("nan")]], "finite"),
    ([[0.0, 0.0]], "within"), ([[1.0, 15.0], [5.0, 14.0]], "starts at the centre"),
    ([[0.0, 15.0], [5.0, 14.0], [4.0, 13.0]], "strictly increase"),
    ([[0.0, 15.0], [5.0, 14.0], [5.0, 13.0]], "strictly increase"),
    ([[0.0, 15.0], [5.0, 14.0], [6.0, 17.0]], "no inverse"),     # 6/17 < 5/14: road angle falls
    ([[0.0, 15.0], [-1.0, 14.0]], "within"), ([[0.0, 15.0, 1.0]], "pair"), ([[0.0]], "pair"),
])
def test_a_bad_steering_ratio_is_refused_naming_the_field(value: object, words: str) -> None:
    with pytest.raises(VehicleSpecError) as err:
        vehicle_from_data(with_ratio(value))
    assert err.value.field == "steering_ratio" and words in err.value.reason


@pytest.mark.parametrize("last_ratio, ok", [(5.0 / (4.0 / 15.0) - 1e-6, True),
                                            (5.0 / (4.0 / 15.0), False)])
def test_the_road_angle_rising_is_the_limit_of_a_rising_ratio(last_ratio: float, ok: bool) -> None:
    """From (4 rad, 15) the next point at 5 rad may rise to just under 18.75 (same road angle)."""
    table = [[0.0, 15.0], [4.0, 15.0], [5.0, last_ratio]]
    if ok:
        assert check_steering_ratio(table) is not None
    else:
        with pytest.raises(ValueError, match="no inverse"):
            check_steering_ratio(table)


@pytest.mark.parametrize("value", [1, 16, 15.713, RATIO_MAX, [[0, 15.713], [7, 15.419]],
                                   [[0.0, 12.0], [2.0, 14.0], [8.0, 17.0]]])
def test_a_good_steering_ratio_is_taken(value: object) -> None:
    params = vehicle_from_data(with_ratio(value))
    assert params.steering_ratio is not None


def test_presets_without_a_wheel_interface_state_none_and_the_kit_refuses_them() -> None:
    for name in ("escape-hybrid", "ranger-6x6"):
        assert PRESETS[name].steering_ratio is None
        with pytest.raises(ValueError, match="steering_ratio"):
            Pacmod3Kit(PRESETS[name])


def test_the_lexus_ratio_is_variable_and_full_lock_within_the_pacmod_range() -> None:
    spec = LEXUS.steering_ratio
    assert ratio_at(spec, 0.0) == 15.713 and ratio_at(spec, 7.0) == pytest.approx(15.419)
    assert ratio_at(spec, 3.5) == pytest.approx(15.713 - 0.042 * 3.5)
    lock = steering_wheel_rad(spec, LEXUS.max_steer_rad)
    assert 6.0 < lock < 7.5      # ~390 deg of steering wheel either side


tables = st.one_of(
    st.floats(RATIO_MIN, RATIO_MAX),
    st.lists(st.tuples(st.floats(0.1, 3.0), st.floats(RATIO_MIN, RATIO_MAX)), min_size=1,
             max_size=6).map(lambda steps: [[0.0, steps[0][1]]] + [
                 [sum(s for s, _ in steps[: i + 1]), r] for i, (_, r) in enumerate(steps)]))


@given(tables, st.floats(-30.0, 30.0))
def test_the_inverse_is_exact_wherever_the_table_is_accepted(table: object, wheel: float) -> None:
    try:
        spec = check_steering_ratio(table)
    except ValueError:
        return
    road = road_wheel_rad(spec, wheel)
    assert math.copysign(1.0, road) == math.copysign(1.0, wheel) or road == 0.0
    assert steering_wheel_rad(spec, road) == pytest.approx(wheel, abs=1e-9, rel=1e-9)
