"""Figures of issue 31's adaptation and ABS rules, for docs/driving-module.md and move-server.md.

Prints, per preset: a hard stop with ABS on dry road (gear changes and runwaits after it, time
from the next MOVE to motion); friction rising 0.25 -> 0.8 at 4 s in a 0.05 1/m curve
(friction_max 0.8: when the planned speed first reaches 95 % of a run planned at 0.8 from the
start); friction falling 0.8 -> 0.25 at 3 s, a STOP at 6 s (the estimate after the first ABS /
traction report); a hard stop in a 0.02 1/m curve; a 0.05 1/m curve on 0.4 with friction_max
1.0 (its slides); state lost (90 % of the speed state for 5 s: top speed with and without).

Usage: ``.venv/bin/python scripts/adaptation_figures.py``
"""

from __future__ import annotations

import itertools
from typing import Any

from overdrive.messages import Topic
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS


class Tap:
    def __init__(self) -> None:
        self.now_s = 0.0
        self.rows: list[tuple[float, str, Any]] = []

    def set_time(self, now_s: float) -> None:
        self.now_s = now_s

    def observe(self, topic: str, msg: Any) -> None:
        if topic in (Topic.SPEED_STATE, Topic.DRIVING_STATUS, Topic.VEHICLE_STATUS):
            self.rows.append((self.now_s, topic, msg))


def run(preset: str, friction: float, events: list[dict], duration_s: float,
        friction_max: float | None = None) -> tuple[Any, Tap]:
    tap = Tap()
    data = {"name": "fig", "vehicle": preset, "start": "ready", "duration_s": duration_s,
            "seed": 7, "world": {"friction": friction}, "friction_max": friction_max,
            "events": events}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False,
                        observers=[tap]), tap


def hard_stop(preset: str, curvature_1pm: float = 0.0) -> str:
    friction = 0.8 if preset == "escape-hybrid" else 0.6
    _, tap = run(preset, friction, [{"at_s": 0.5, "move": {"distance_m": 300.0,
                                                          "maxspeed_mps": 10.0,
                                                          "curvature_1pm": curvature_1pm}},
                                    {"at_s": 8.0, "stop": {}},
                                    {"at_s": 14.0, "move": {"distance_m": 20.0,
                                                            "maxspeed_mps": 5.0}}], 18.0)
    states = [m for t, k, m in tap.rows if k == Topic.SPEED_STATE and t >= 8.0]
    gears = sorted({m.gear for m in states})
    waits = sum(1 for a, b in itertools.pairwise(states)
                if b.state == "runwait" and a.state != "runwait")
    abs_n = sum(1 for _, k, m in tap.rows if k == Topic.VEHICLE_STATUS and m.abs_active)
    moving = min(t for t, k, m in tap.rows
                 if k == Topic.SPEED_STATE and t >= 14.0 and m.speed_mps > 0.5)
    tc_n = sum(1 for _, k, m in tap.rows if k == Topic.VEHICLE_STATUS and m.traction_control)
    return (f"hard stop at mu {friction}, curvature {curvature_1pm} 1/m: ABS reports {abs_n} "
            f"(traction control {tc_n}), gears after {gears}, runwaits "
            f"after {waits}, next MOVE to 0.5 m/s {moving - 14.0:.2f} s")


def curve_goal(preset: str, f0: float, events: list[dict]) -> list[tuple[float, float]]:
    _, tap = run(preset, f0, [{"at_s": 0.5, "move": {"distance_m": 400.0, "maxspeed_mps": 10.0,
                                                     "curvature_1pm": 0.05}}, *events], 30.0, 0.8)
    return [(t, m.goal_speed_mps) for t, k, m in tap.rows if k == Topic.DRIVING_STATUS]


def rising(preset: str) -> str:
    steady = curve_goal(preset, 0.8, [])[-1][1]
    goal = curve_goal(preset, 0.25, [{"at_s": 4.0, "world": {"friction": 0.8}}])
    before = max(g for t, g in goal if t < 4.0)
    reach = next(t for t, g in goal if t >= 4.0 and g >= 0.95 * steady)
    return (f"rise 0.25 -> 0.8 at 4 s: planned {before:.2f} m/s before, 95 % of {steady:.2f} "
            f"m/s {reach - 4.0:.1f} s after the rise")


def falling(preset: str) -> str:
    result, tap = run(preset, 0.8, [{"at_s": 0.5, "move": {"distance_m": 300.0,
                                                           "maxspeed_mps": 8.0}},
                                    {"at_s": 3.0, "world": {"friction": 0.25}},
                                    {"at_s": 6.0, "stop": {}}], 10.0)
    first = min(t for t, k, m in tap.rows if k == Topic.VEHICLE_STATUS
                and (m.traction_control or m.abs_active))
    return (f"drop 0.8 -> 0.25 at 3 s: first ABS / traction report {first:.2f} s, estimate "
            f"at the end {result.nodes['driving'].grip.estimate:.3f} (driving), "
            f"{result.nodes['move'].grip.estimate:.3f} (move)")


def curve_hard_stop(preset: str) -> str:
    return hard_stop(preset, 0.02)


def curve_slides(preset: str) -> str:
    """friction 0.4, friction_max 1.0, a 0.05 1/m curve for 30 s: traction-control episodes
    (onsets more than 1 s apart) and the estimate at the end."""
    result, tap = run(preset, 0.4, [{"at_s": 0.5, "move": {"distance_m": 400.0,
                                                           "maxspeed_mps": 10.0,
                                                           "curvature_1pm": 0.05}}], 30.0, 1.0)
    onsets, active, last = [], False, -1e9
    for t, k, m in tap.rows:
        if k == Topic.VEHICLE_STATUS:
            if m.traction_control and not active and t - last > 1.0:
                onsets.append(t)
            if m.traction_control:
                last = t
            active = bool(m.traction_control)
    return (f"curve on 0.4, friction_max 1.0, 30 s: slides at {[round(t, 2) for t in onsets]}, "
            f"estimate at the end {result.nodes['driving'].grip.estimate:.3f}")


def lost_state(preset: str) -> str:
    def top(events: list[dict]) -> float:
        result, _ = run(preset, 0.8, [{"at_s": 0.5, "move": {"distance_m": 120.0,
                                                             "maxspeed_mps": 8.0}}, *events], 12.0)
        return max(float(r["speed_mps"]) for r in result.trace if 6.0 <= float(r["t_s"]) <= 10.0)
    lost = top([{"at_s": 5.0, "loss": {"channel": "speed_state", "for_s": 5.0, "fraction": 0.9}}])
    return f"speed state 90 % lost 5-10 s: top speed 6-10 s {lost:.2f} m/s (healthy {top([]):.2f})"


def main() -> None:
    for preset in PRESETS:
        print(preset)
        for figure in (hard_stop, curve_hard_stop, rising, falling, curve_slides, lost_state):
            print("  " + figure(preset))


if __name__ == "__main__":
    main()
