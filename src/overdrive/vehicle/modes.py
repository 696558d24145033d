"""ByWire XGV vehicle modes (seed 000) as pure functions.

Four aspects, computed from the controlling entities and component statuses of the Primitive
Driver (PD) and Motion Profile Driver (MPD), the safety devices and the LCD partial-mode setting:

- **control mode**: which commands execute. ``wrench-efforts`` when a client controls the PD
  and nobody controls the MPD; ``motion-profiles`` when a client controls the MPD and the MPD
  controls the PD (it requests PD control itself when it is controlled); ``software-pause`` in
  every other configuration (seed: "In all other configurations, the control mode defaults to
  Software Pause").
- **ready mode**: ``ready`` when the components of the control mode are all in status
  ``ready`` (PD for wrench efforts; PD and MPD for motion profiles); else ``software-pause``.
- **safety mode**, highest precedence first: inactive > e-stop disable > emergency manual
  override > manual override > e-stop pause > software pause > drive-by-wire.
- **partial overrides**: which axes the human keeps, in drive-by-wire and the pauses only.

Decisions where the seed is silent (docs/xgv.md): a SafeStop with no link pauses (fail-safe,
like a dead transmitter); steering that still needs initialization is a software pause.
"""

from __future__ import annotations

from typing import Literal

import msgspec

from overdrive.messages import SafetyDevices

ControlMode = Literal["software-pause", "wrench-efforts", "motion-profiles"]
ReadyMode = Literal["software-pause", "ready"]
ComponentStatus = Literal["initialize", "ready", "standby", "shutdown", "failure", "emergency"]

SAFETY_MODES = (
    "drive-by-wire", "software-pause", "estop-pause", "manual-override",
    "emergency-manual-override", "estop-disable", "inactive",
)
"""In increasing order of precedence (seed 000, "The possible values for the safety mode")."""

SAFETY_MODE_CODE = {
    "drive-by-wire": 1, "software-pause": 2, "estop-pause": 8, "manual-override": 9,
    "emergency-manual-override": 10, "estop-disable": 11, "inactive": 0,
}
"""Report Vehicle Mode field 4 (seed 000); an inactive XGV reports nothing, 0 is "unknown"."""

CONTROL_MODE_CODE = {"software-pause": 1, "wrench-efforts": 2, "motion-profiles": 3}
"""Report Vehicle Mode field 2 (seed 000)."""

READY_MODE_CODE = {"software-pause": 1, "ready": 2}
"""Report Vehicle Mode field 3 (seed 000)."""

PAUSE_MODES = frozenset({"software-pause", "estop-pause"})
MANUAL_MODES = frozenset({"manual-override", "emergency-manual-override", "estop-disable", "inactive"})
PARTIAL_MODE_APPLIES = frozenset({"drive-by-wire", "software-pause", "estop-pause"})


class ModeInputs(msgspec.Struct, frozen=True, kw_only=True):
    """Everything the modes depend on. Controllers are opaque ids (JAUS ids as strings)."""

    pd_controller: str | None = None     # who controls the Primitive Driver
    mpd_controller: str | None = None    # who controls the Motion Profile Driver
    pd_status: ComponentStatus = "standby"
    mpd_status: ComponentStatus = "standby"
    devices: SafetyDevices = SafetyDevices()
    active: bool = True                  # XGV system activated (controller booted)


MPD_ID = "mpd"
"""The controller id the PD sees when the MPD holds it (the MPD requests PD control itself)."""


class VehicleMode(msgspec.Struct, frozen=True):
    control_mode: ControlMode
    ready_mode: ReadyMode
    safety_mode: str
    manual_steering: bool      # partial-mode override bit 0
    manual_speed: bool         # partial-mode override bit 1


def control_mode(pd_controller: str | None, mpd_controller: str | None) -> ControlMode:
    if mpd_controller is None and pd_controller not in (None, MPD_ID):
        return "wrench-efforts"
    if mpd_controller is not None and mpd_controller != MPD_ID and pd_controller == MPD_ID:
        return "motion-profiles"
    return "software-pause"


def ready_mode(control: ControlMode, pd_status: str, mpd_status: str) -> ReadyMode:
    if control == "wrench-efforts" and pd_status == "ready":
        return "ready"
    if control == "motion-profiles" and pd_status == "ready" and mpd_status == "ready":
        return "ready"
    return "software-pause"


def safety_mode(devices: SafetyDevices, *, active: bool = True, software_ready: bool = True) -> str:
    """Safety mode from the devices; ``software_ready`` False is the control/ready-mode pause."""
    if not active:
        return "inactive"
    if devices.safestop == "stop" or devices.estop_button:
        return "estop-disable"
    if devices.emergency_manual_override:
        return "emergency-manual-override"
    if devices.manual_override:
        return "manual-override"
    if devices.safestop == "pause" or devices.safestop_link == "none":
        return "estop-pause"
    if (devices.door_open or devices.internal_error or devices.steering_needs_init
            or not software_ready):
        return "software-pause"
    return "drive-by-wire"


def compute_modes(inputs: ModeInputs) -> VehicleMode:
    control = control_mode(inputs.pd_controller, inputs.mpd_controller)
    ready = ready_mode(control, inputs.pd_status, inputs.mpd_status)
    safety = safety_mode(inputs.devices, active=inputs.active,
                         software_ready=control != "software-pause" and ready == "ready")
    partial = inputs.devices.partial_mode if safety in PARTIAL_MODE_APPLIES else "full"
    return VehicleMode(control_mode=control, ready_mode=ready, safety_mode=safety,
                       manual_steering=partial == "manual-steering",
                       manual_speed=partial == "manual-speed")


def computer_axes(mode: str, partial_mode: str) -> tuple[bool, bool]:
    """(computer steers, computer controls throttle/brake) in safety ``mode``.

    In a pause the computer still steers (seed 000: "steering will continue to execute JAUS
    commands") but throttle and brake belong to the pause logic.
    """
    if mode in MANUAL_MODES:
        return False, False
    steering = partial_mode != "manual-steering"
    speed = partial_mode != "manual-speed" and mode == "drive-by-wire"
    return steering, speed


LINK_CODE = {"none": 0, "bypass": 1, "good": 2}


def safety_device_bits(devices: SafetyDevices) -> int:
    """Report Vehicle Mode field 6 (seed 000): the safety devices as a u16 bit field."""
    return (
        int(devices.manual_override)
        | int(devices.safestop == "pause") << 1
        | int(devices.safestop == "stop") << 2
        | LINK_CODE[devices.safestop_link] << 3
        | int(devices.estop_button) << 5
        | int(devices.door_open) << 6
        | int(devices.internal_error) << 7
        | int(devices.emergency_manual_override) << 8
        | int(devices.steering_needs_init) << 9
        | int(devices.steering_awaiting_user) << 10
    )


def partial_override_bits(mode: VehicleMode) -> int:
    """Report Vehicle Mode field 5 (seed 000)."""
    return int(mode.manual_steering) | int(mode.manual_speed) << 1
