"""ByWire XGV vehicle modes (seed 000) as pure functions.

The safety mode follows the seed's precedence, highest first: inactive > e-stop disable >
emergency manual override > manual override > e-stop pause > software pause > drive-by-wire.
"""

from __future__ import annotations

from overdrive.messages import SafetyDevices

SAFETY_MODES = (
    "drive-by-wire", "software-pause", "estop-pause", "manual-override",
    "emergency-manual-override", "estop-disable", "inactive",
)
"""In increasing order of precedence (seed 000, "The possible values for the safety mode")."""

SAFETY_MODE_CODE = {
    "drive-by-wire": 1, "software-pause": 2, "estop-pause": 8, "manual-override": 9,
    "emergency-manual-override": 10, "estop-disable": 11, "inactive": 0,
}
"""Report Vehicle Mode field 4 values (seed 000); inactive is not reported (0 = unknown)."""

PAUSE_MODES = frozenset({"software-pause", "estop-pause"})
MANUAL_MODES = frozenset({"manual-override", "emergency-manual-override", "estop-disable", "inactive"})


def safety_mode(devices: SafetyDevices, *, active: bool = True, software_ready: bool = True) -> str:
    """Safety mode from the safety devices; ``software_ready`` False is the control/ready pause."""
    if not active:
        return "inactive"
    if devices.safestop == "stop" or devices.estop_button:
        return "estop-disable"
    if devices.emergency_manual_override:
        return "emergency-manual-override"
    if devices.manual_override:
        return "manual-override"
    if devices.safestop == "pause":
        return "estop-pause"
    if devices.door_open or devices.internal_error or not software_ready:
        return "software-pause"
    return "drive-by-wire"


def computer_axes(mode: str, partial_mode: str) -> tuple[bool, bool]:
    """(computer steers, computer controls speed) in ``mode`` with the LCD partial-mode setting.

    Partial mode applies in drive-by-wire and the pauses only (seed 000); in a pause the
    computer still steers but throttle and brake belong to the pause logic.
    """
    if mode in MANUAL_MODES:
        return False, False
    steering = partial_mode != "manual-steering"
    speed = partial_mode != "manual-speed" and mode == "drive-by-wire"
    return steering, speed
