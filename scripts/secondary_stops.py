"""The secondary stopping distances of the shipped vehicles (issue 30 item 4), as a Markdown
table for docs/drive-your-own-vehicle.md: from the first brake command at cruise, the detection
(``DETECT_S``) then ``observe.secondary_audit.RESPONSE_S``, then what the vehicle file gives
(``dynamics.secondary_braking.secondary_stop_m``), on dry ground (friction 0.8).

Usage: ``python scripts/secondary_stops.py``
"""

from __future__ import annotations

import math

from overdrive.dynamics.secondary_braking import secondary_stop_m
from overdrive.observe.secondary_audit import RESPONSE_S
from overdrive.safety.actuators import ActuatorMonitorConfig
from overdrive.scenario.vehicles import PRESETS

STATUS_PERIOD_S = 0.1
"""The simulated vehicle's status period (10 Hz): the stuck check needs a new status."""
DETECT_S = ActuatorMonitorConfig().hold_s + 2 * STATUS_PERIOD_S
"""A brake stuck released is found this long after a brake command (still for ``hold_s`` on new
statuses, plus one period each side)."""


def main() -> None:
    print("| vehicle | speed (m/s) | grade | all means (m) | parking brake failed (m) |")
    print("|---|---|---|---|---|")
    for name, p in PRESETS.items():
        gear = p.gear(p.drive_gear)
        for speed in (8.0, 11.0 if name == "escape-hybrid" else 10.0):
            for grade in (0.0, -5.0):
                pitch = math.atan(grade / 100.0)
                full, no_park = (secondary_stop_m(p, speed, gear, pitch_rad=pitch,
                                                  reaction_s=DETECT_S + RESPONSE_S,
                                                  park_brake=park) for park in (True, False))
                print(f"| {name} | {speed:g} | {grade:g} % | {full:.1f} | "
                      f"{'no stop' if math.isinf(no_park) else f'{no_park:.1f}'} |")


if __name__ == "__main__":
    main()
