"""The steering ratio: steering-WHEEL angle <-> road-wheel angle, constant or variable.

A kit that steers by the steering wheel (PACMod 3's ``STEERING_CMD`` is a steering-wheel angle)
needs the vehicle's ratio to turn the stack's road-wheel angle into a wheel angle and back. A
vehicle file's ``steering_ratio`` is one of:

- a number: a constant ratio (steering-wheel angle / road-wheel angle), e.g. ``16.0``;
- a table ``[[wheel_rad, ratio], ...]``: the ratio at each steering-wheel angle (magnitude,
  the same left and right), linear between the points and held beyond the last one. The first
  point is at 0 rad; wheel angles strictly increase; the road-wheel angle ``wheel / ratio`` must
  strictly increase too (a ratio rising faster than the wheel angle would make two wheel angles
  give one road angle: the inverse the stack needs would not exist);
- ``null``: not stated (a vehicle steered by road-wheel effort, like the XGV's).

Within one segment ``ratio = r_i + s (w - w_i)`` the road angle ``w / ratio`` has a derivative of
constant sign (``(r_i - s w_i) / ratio^2``), so checking it at the points proves it everywhere,
and the inverse is exact: ``w = road (r_i - s w_i) / (1 - road s)``.

Pure functions, no state: the kit (``vehicle.pacmod3_kit``) and the stack's client use the same.
"""

from __future__ import annotations

import math
from typing import Any, Final

SteeringRatio = float | tuple[tuple[float, float], ...] | None

RATIO_MIN: Final = 1.0
"""Lowest ratio: a go-kart's direct steering is ~1:1."""
RATIO_MAX: Final = 40.0
"""Highest ratio: heavy trucks ~20-26:1; 40 leaves room for a slow robot's gearing."""
WHEEL_ANGLE_MAX_RAD: Final = 32.767
"""Largest steering-wheel angle a table may name: PACMod 3's STEERING_CMD range (16 bits of
0.001 rad); road cars turn ~1.5-2 turns (~10-13 rad) from centre to lock."""
MAX_POINTS: Final = 32
"""Points in a table: a measured ratio curve needs a handful."""


class SteeringRatioError(ValueError):
    """A ``steering_ratio`` that is not a usable ratio; ``str()`` says why."""


def check_steering_ratio(value: Any) -> SteeringRatio:
    """``value`` as read from a vehicle file, checked (module docstring); the table as tuples.

    Raises ``SteeringRatioError``: NaN, infinities, a ratio outside ``RATIO_MIN..RATIO_MAX``
    (zero, negative), a malformed or non-monotonic table.
    """
    if value is None:
        return None
    if isinstance(value, bool):
        raise SteeringRatioError(f"must be a number or a table [[wheel_rad, ratio], ...], "
                                 f"got {value!r}")
    if isinstance(value, (int, float)):
        return _check_ratio(float(value), "")
    if not isinstance(value, (list, tuple)) or not value:
        raise SteeringRatioError("must be a number or a non-empty table [[wheel_rad, ratio], "
                                 f"...], got {value!r:.40}")
    if len(value) > MAX_POINTS:
        raise SteeringRatioError(f"{len(value)} points (at most {MAX_POINTS})")
    points: list[tuple[float, float]] = []
    for i, point in enumerate(value):
        if (not isinstance(point, (list, tuple)) or len(point) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in point)):
            raise SteeringRatioError(f"[{i}] must be a pair [wheel_rad, ratio] of numbers, "
                                     f"got {point!r:.40}")
        wheel, ratio = float(point[0]), float(point[1])
        if not math.isfinite(wheel) or not 0.0 <= wheel <= WHEEL_ANGLE_MAX_RAD:
            raise SteeringRatioError(f"[{i}] wheel angle {wheel} must be a finite number within "
                                     f"0..{WHEEL_ANGLE_MAX_RAD} rad")
        _check_ratio(ratio, f"[{i}] ")
        points.append((wheel, ratio))
    if points[0][0] != 0.0:
        raise SteeringRatioError(f"[0] the table starts at the centre (0 rad), got "
                                 f"{points[0][0]} rad")
    for i in range(1, len(points)):
        (w0, r0), (w1, r1) = points[i - 1], points[i]
        if not w1 > w0:
            raise SteeringRatioError(f"[{i}] wheel angles must strictly increase: {w1} rad after "
                                     f"{w0} rad")
        if not w1 / r1 > w0 / r0:
            raise SteeringRatioError(f"[{i}] the road-wheel angle must increase with the wheel "
                                     f"angle: {w1} rad / {r1} = {w1 / r1:.6g} rad is not above "
                                     f"{w0} rad / {r0} = {w0 / r0:.6g} rad (the ratio rises too "
                                     f"fast: no inverse)")
    return tuple(points)


def _check_ratio(ratio: float, where: str) -> float:
    if not math.isfinite(ratio) or not RATIO_MIN <= ratio <= RATIO_MAX:
        raise SteeringRatioError(f"{where}ratio {ratio} must be a finite number within "
                                 f"{RATIO_MIN:g}..{RATIO_MAX:g} (a go-kart ~1, cars ~12-18, "
                                 f"trucks ~20-26)")
    return ratio


def _segment(table: tuple[tuple[float, float], ...], wheel_abs_rad: float) -> tuple[float, float,
                                                                                   float]:
    """(w_i, r_i, slope) of the segment holding ``wheel_abs_rad`` (held beyond the last)."""
    for i in range(len(table) - 1, -1, -1):
        w0, r0 = table[i]
        if wheel_abs_rad >= w0 or i == 0:
            if i == len(table) - 1:
                return w0, r0, 0.0
            w1, r1 = table[i + 1]
            return w0, r0, (r1 - r0) / (w1 - w0)
    raise AssertionError("unreachable")


def ratio_at(spec: SteeringRatio, wheel_rad: float) -> float:
    """The ratio at the steering-wheel angle ``wheel_rad`` (either sign)."""
    if spec is None:
        raise SteeringRatioError("this vehicle states no steering_ratio")
    if isinstance(spec, float):
        return spec
    w0, r0, slope = _segment(spec, abs(wheel_rad))
    return r0 + slope * (abs(wheel_rad) - w0)


def road_wheel_rad(spec: SteeringRatio, wheel_rad: float) -> float:
    """The road-wheel angle the steering-wheel angle ``wheel_rad`` gives (same sign)."""
    return wheel_rad / ratio_at(spec, wheel_rad)


def steering_wheel_rad(spec: SteeringRatio, road_rad: float) -> float:
    """The steering-wheel angle that gives the road-wheel angle ``road_rad`` (the exact
    inverse of ``road_wheel_rad``; same sign)."""
    if spec is None:
        raise SteeringRatioError("this vehicle states no steering_ratio")
    if isinstance(spec, float):
        return road_rad * spec
    road = abs(road_rad)
    for i in range(len(spec) - 1, -1, -1):
        w0, r0 = spec[i]
        if road >= w0 / r0 or i == 0:
            slope = 0.0 if i == len(spec) - 1 else (spec[i + 1][1] - r0) / (spec[i + 1][0] - w0)
            return math.copysign(road * (r0 - slope * w0) / (1.0 - road * slope), road_rad)
    raise AssertionError("unreachable")


__all__ = ["SteeringRatio", "SteeringRatioError", "check_steering_ratio", "ratio_at",
           "road_wheel_rad", "steering_wheel_rad"]
