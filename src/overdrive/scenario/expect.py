"""Scenario expectations: each entry of ``expect`` checked against a finished run.

Every failed expectation becomes one violation string; the reference is docs/scenarios.md.
"""

from __future__ import annotations

import math
from typing import Any

from overdrive.scenario.schema import ExpectSpec, Window


def _matches(event: dict[str, Any], window: Window) -> bool:
    if event["kind"] != window.kind:
        return False
    if window.within_s is not None and not window.within_s[0] <= event["t_s"] <= window.within_s[1]:
        return False
    return all(str(event.get(k)) == str(v) for k, v in window.match.items())


def _describe(window: Window) -> str:
    where = f" within {window.within_s[0]}..{window.within_s[1]} s" if window.within_s else ""
    match = "".join(f" {k}={v}" for k, v in window.match.items())
    return f"{window.kind}{match}{where}"


def check(expect: ExpectSpec, summary: dict[str, Any], states_seen: set[str],
          modes_seen: set[str]) -> str | None:
    """Return a violation message, or None when the expectation holds."""
    final, peaks = summary["final"], summary["peaks"]
    kind = expect.kind
    value = getattr(expect, kind)
    if kind == "final_speed_below_mps":
        ok = abs(final["speed_mps"]) < value
        got = f"final speed {abs(final['speed_mps']):.3f} m/s"
    elif kind == "odometer_between_m":
        ok = value[0] <= summary["odometer_m"] <= value[1]
        got = f"odometer {summary['odometer_m']:.3f} m"
    elif kind == "final_position":
        err = math.hypot(final["x_m"] - value.x_m, final["y_m"] - value.y_m)
        ok = err <= value.tolerance_m
        got = f"final position ({final['x_m']:.2f}, {final['y_m']:.2f}), {err:.2f} m away"
    elif kind in ("peak_speed_below_mps", "peak_accel_below_mps2", "peak_decel_below_mps2",
                  "peak_lat_accel_below_mps2"):
        key = {"peak_speed_below_mps": "max_speed_mps", "peak_accel_below_mps2": "max_accel_mps2",
               "peak_decel_below_mps2": "max_decel_mps2",
               "peak_lat_accel_below_mps2": "max_lateral_accel_mps2"}[kind]
        ok = peaks[key] < value
        got = f"{key} {peaks[key]:.3f}"
    elif kind == "event":
        ok = any(_matches(e, value) for e in summary["events"])
        got = f"no event {_describe(value)}"
    elif kind == "no_event":
        hits = [e for e in summary["events"] if _matches(e, value)]
        ok = not hits
        got = f"event {_describe(value)} at t={hits[0]['t_s']} s" if hits else ""
    elif kind == "speed_state_reached":
        ok, got = value in states_seen, f"states seen: {', '.join(sorted(states_seen)) or 'none'}"
    elif kind == "safety_mode_reached":
        ok, got = value in modes_seen, f"modes seen: {', '.join(sorted(modes_seen)) or 'none'}"
    elif kind == "final_speed_state":
        ok, got = final["speed_state"] == value, f"final speed state {final['speed_state']!r}"
    elif kind == "final_safety_mode":
        ok, got = final["safety_mode"] == value, f"final safety mode {final['safety_mode']!r}"
    elif kind == "no_contact":
        contact = any(e["kind"] == "contact" for e in summary["events"])
        ok = contact != value
        got = "contact with an obstacle" if contact else "no contact"
    else:  # pragma: no cover - the schema admits only the kinds above
        raise ValueError(kind)
    if ok:
        return None
    return f"expect {kind}: {value if not hasattr(value, '__struct_fields__') else _struct(value)} failed: {got}"


def _struct(value: Any) -> str:
    return "{" + ", ".join(f"{f}: {getattr(value, f)}" for f in value.__struct_fields__) + "}"
