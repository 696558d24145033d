"""XGV vehicle modes (seed 000): every safety-mode value, every PD/MPD configuration, precedence."""

from __future__ import annotations

import itertools

import msgspec
import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.messages import SafetyDevices
from overdrive.vehicle.modes import (
    MPD_ID,
    SAFETY_MODE_CODE,
    SAFETY_MODES,
    ModeInputs,
    compute_modes,
    computer_axes,
    control_mode,
    partial_override_bits,
    ready_mode,
    safety_device_bits,
    safety_mode,
)

CLIENT, OTHER = "2.2.4.1", "3.1.4.1"

CONTROL_CASES = [
    # (pd controller, mpd controller) -> control mode
    ((None, None), "software-pause"),
    ((CLIENT, None), "wrench-efforts"),
    ((MPD_ID, CLIENT), "motion-profiles"),
    ((CLIENT, CLIENT), "software-pause"),     # MPD controlled but could not take the PD
    ((OTHER, CLIENT), "software-pause"),
    ((None, CLIENT), "software-pause"),       # MPD has not (yet) got the PD
    ((MPD_ID, None), "software-pause"),
]


@pytest.mark.parametrize(("controllers", "expected"), CONTROL_CASES)
def test_control_mode_per_configuration(controllers, expected) -> None:
    assert control_mode(*controllers) == expected


STATUSES = ("initialize", "ready", "standby", "shutdown", "failure", "emergency")


@pytest.mark.parametrize(("pd", "mpd"), list(itertools.product(STATUSES, STATUSES)))
@pytest.mark.parametrize("control", ["software-pause", "wrench-efforts", "motion-profiles"])
def test_ready_mode_for_every_status_combination(control, pd, mpd) -> None:
    expected = (control == "wrench-efforts" and pd == "ready") or (
        control == "motion-profiles" and pd == "ready" and mpd == "ready")
    assert (ready_mode(control, pd, mpd) == "ready") == expected


SAFETY_CASES = {
    "drive-by-wire": SafetyDevices(),
    "software-pause": SafetyDevices(door_open=True),
    "estop-pause": SafetyDevices(safestop="pause"),
    "manual-override": SafetyDevices(manual_override=True),
    "emergency-manual-override": SafetyDevices(emergency_manual_override=True),
    "estop-disable": SafetyDevices(safestop="stop"),
}


@pytest.mark.parametrize("mode", SAFETY_MODES)
def test_every_safety_mode_value(mode) -> None:
    if mode == "inactive":
        assert safety_mode(SafetyDevices(safestop="stop"), active=False) == "inactive"
    else:
        assert safety_mode(SAFETY_CASES[mode]) == mode


@pytest.mark.parametrize("devices", [
    SafetyDevices(internal_error=True), SafetyDevices(steering_needs_init=True),
    SafetyDevices(door_open=True)])
def test_software_pause_causes(devices) -> None:
    assert safety_mode(devices) == "software-pause"


def test_estop_button_disables_and_lost_link_pauses() -> None:
    assert safety_mode(SafetyDevices(estop_button=True)) == "estop-disable"
    assert safety_mode(SafetyDevices(safestop_link="none")) == "estop-pause"
    assert safety_mode(SafetyDevices(safestop_link="bypass")) == "drive-by-wire"


def test_no_control_or_not_ready_is_software_pause() -> None:
    assert compute_modes(ModeInputs()).safety_mode == "software-pause"
    assert compute_modes(ModeInputs(pd_controller=CLIENT)).safety_mode == "software-pause"
    ok = compute_modes(ModeInputs(pd_controller=CLIENT, pd_status="ready"))
    assert (ok.control_mode, ok.ready_mode, ok.safety_mode) == ("wrench-efforts", "ready", "drive-by-wire")
    mp = compute_modes(ModeInputs(pd_controller=MPD_ID, mpd_controller=CLIENT, pd_status="ready",
                                  mpd_status="ready"))
    assert (mp.control_mode, mp.safety_mode) == ("motion-profiles", "drive-by-wire")
    half = compute_modes(ModeInputs(pd_controller=MPD_ID, mpd_controller=CLIENT, pd_status="ready"))
    assert half.ready_mode == "software-pause" and half.safety_mode == "software-pause"


devices_strategy = st.builds(
    SafetyDevices,
    safestop=st.sampled_from(["run", "pause", "stop"]),
    safestop_link=st.sampled_from(["none", "bypass", "good"]),
    manual_override=st.booleans(), emergency_manual_override=st.booleans(),
    door_open=st.booleans(), estop_button=st.booleans(), internal_error=st.booleans(),
    steering_needs_init=st.booleans(), steering_awaiting_user=st.booleans(),
    partial_mode=st.sampled_from(["full", "manual-steering", "manual-speed"]))


@given(devices_strategy, st.booleans(), st.booleans())
def test_precedence_holds_for_any_combination(devices, active, software_ready) -> None:
    mode = safety_mode(devices, active=active, software_ready=software_ready)
    wanted = []
    if not active:
        wanted.append("inactive")
    if devices.safestop == "stop" or devices.estop_button:
        wanted.append("estop-disable")
    if devices.emergency_manual_override:
        wanted.append("emergency-manual-override")
    if devices.manual_override:
        wanted.append("manual-override")
    if devices.safestop == "pause" or devices.safestop_link == "none":
        wanted.append("estop-pause")
    if (devices.door_open or devices.internal_error or devices.steering_needs_init
            or not software_ready):
        wanted.append("software-pause")
    wanted.append("drive-by-wire")
    assert mode == max(wanted, key=SAFETY_MODES.index)
    # raising any device never lowers the precedence
    worse = msgspec.structs.replace(devices, estop_button=True)
    assert SAFETY_MODES.index(safety_mode(worse, active=active)) >= SAFETY_MODES.index("estop-disable") or not active


@given(devices_strategy)
def test_partial_mode_only_in_drive_by_wire_and_pauses(devices) -> None:
    modes = compute_modes(ModeInputs(pd_controller=CLIENT, pd_status="ready", devices=devices))
    if modes.safety_mode in ("drive-by-wire", "software-pause", "estop-pause"):
        assert modes.manual_steering == (devices.partial_mode == "manual-steering")
        assert modes.manual_speed == (devices.partial_mode == "manual-speed")
    else:
        assert not modes.manual_steering and not modes.manual_speed
    assert partial_override_bits(modes) == int(modes.manual_steering) | int(modes.manual_speed) << 1


def test_computer_axes() -> None:
    assert computer_axes("drive-by-wire", "full") == (True, True)
    assert computer_axes("drive-by-wire", "manual-steering") == (False, True)
    assert computer_axes("drive-by-wire", "manual-speed") == (True, False)
    assert computer_axes("estop-pause", "full") == (True, False)
    for mode in ("manual-override", "emergency-manual-override", "estop-disable", "inactive"):
        assert computer_axes(mode, "full") == (False, False)


def test_safety_device_bits_layout() -> None:
    assert safety_device_bits(SafetyDevices()) == 2 << 3
    assert safety_device_bits(SafetyDevices(manual_override=True, safestop_link="none")) == 1
    assert safety_device_bits(SafetyDevices(safestop="pause", safestop_link="none")) == 2
    assert safety_device_bits(SafetyDevices(safestop="stop", safestop_link="none")) == 4
    assert safety_device_bits(SafetyDevices(estop_button=True, safestop_link="none")) == 32
    assert safety_device_bits(SafetyDevices(door_open=True, safestop_link="none")) == 64
    assert safety_device_bits(SafetyDevices(internal_error=True, safestop_link="none")) == 128
    assert safety_device_bits(SafetyDevices(emergency_manual_override=True, safestop_link="none")) == 256
    assert safety_device_bits(SafetyDevices(steering_needs_init=True, safestop_link="none")) == 512
    assert safety_device_bits(SafetyDevices(steering_awaiting_user=True, safestop_link="none")) == 1024
    assert SAFETY_MODE_CODE["estop-pause"] == 8 and SAFETY_MODE_CODE["estop-disable"] == 11
