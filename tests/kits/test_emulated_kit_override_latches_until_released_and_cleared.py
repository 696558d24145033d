"""Operator override on the emulated PACMod 3 kit: an input beyond its threshold (swept either
side) latches override_active on that system and disables it; the latch clears only once the
operator has let go AND the stream sends clear_override with a DISABLE -> ENABLE edge. Judged
from the kit's reports and the vehicle's ground truth."""

from __future__ import annotations

import pytest

from overdrive.kits.pacmod3 import BrakeRpt, Gear, GlobalRpt, SteeringRpt
from overdrive.messages import SafetyDevices
from overdrive.vehicle.pacmod3_kit import (
    ACCEL_OVERRIDE_RATIO,
    BRAKE_OVERRIDE_RATIO,
    STEERING_OVERRIDE_NM,
    KitFault,
)
from tests.kits.kit_driver import KitDriver, command, drive_stream, lexus_kit

THRESHOLDS = {"accel": ACCEL_OVERRIDE_RATIO, "brake": BRAKE_OVERRIDE_RATIO,
              "steering": STEERING_OVERRIDE_NM}


def engaged(faults: tuple[KitFault, ...] = ()) -> KitDriver:
    d = KitDriver(lexus_kit(faults=faults))
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5))
    return d


@pytest.mark.parametrize("system", sorted(THRESHOLDS))
@pytest.mark.parametrize("scale, latches", [(0.9, False), (0.99, False), (1.0, True), (1.1, True)])
def test_an_operator_input_latches_an_override_at_its_threshold(system: str, scale: float,
                                                                latches: bool) -> None:
    value = THRESHOLDS[system] * scale
    d = engaged((KitFault(kind="override", system=system, start_s=1.0, end_s=1.5, value=value),))
    d.advance(2.5, drive_stream(brake=0.5))
    st = d.kit.systems[system]
    assert st.override is latches
    assert st.enabled is not latches
    assert d.last_report(GlobalRpt).override_active is latches
    others = [s for s in THRESHOLDS if s != system]
    assert all(d.kit.systems[s].enabled for s in others)   # per system


def test_the_brake_pedal_pressed_shows_as_manual_input_and_override() -> None:
    d = engaged((KitFault(kind="override", system="brake", start_s=1.0, end_s=2.0, value=0.4),))
    d.advance(1.5, drive_stream(brake=0.5))
    rpt = d.last_report(BrakeRpt)
    assert rpt.override_active and not rpt.enabled and rpt.manual_input == pytest.approx(0.4,
                                                                                         abs=1e-3)


def brake_override_then(clear: list, *, release_s: float = 1.5) -> KitDriver:
    """Brake override 1.0 .. release_s, then the commands ``clear`` (each a stream, 0.2 s)."""
    d = engaged((KitFault(kind="override", system="brake", start_s=1.0, end_s=release_s,
                          value=0.5),))
    d.advance(2.0, drive_stream(brake=0.5))
    assert d.kit.systems["brake"].override
    for stream in clear:
        d.advance(d.now_s + 0.2, stream)
    return d


def brake_only(enable: bool, clear_override: bool = False):
    return lambda t: [command("brake", enable, 0.5, clear_override=clear_override)]


def test_the_stream_still_enabled_after_an_override_does_not_re_enable() -> None:
    d = brake_override_then([brake_only(True)])
    assert d.kit.systems["brake"].override and not d.kit.systems["brake"].enabled


def test_an_edge_without_clear_override_leaves_it_latched() -> None:
    d = brake_override_then([brake_only(False), brake_only(True)])
    assert d.kit.systems["brake"].override and not d.kit.systems["brake"].enabled
    assert d.kit.events.refused_edges[-1][0] == "brake"


def test_clear_override_without_an_edge_leaves_it_latched() -> None:
    d = brake_override_then([brake_only(True, clear_override=True)])
    assert d.kit.systems["brake"].override and not d.kit.systems["brake"].enabled


def test_clear_override_with_the_edge_while_the_pedal_is_still_pressed_is_refused() -> None:
    d = brake_override_then([brake_only(False), brake_only(True, clear_override=True)],
                            release_s=5.0)
    assert d.kit.systems["brake"].override and not d.kit.systems["brake"].enabled
    assert d.last_report(GlobalRpt).override_active


def test_released_then_clear_override_with_the_edge_re_enables() -> None:
    d = brake_override_then([brake_only(False), brake_only(True, clear_override=True)])
    st = d.kit.systems["brake"]
    assert not st.override and st.enabled
    assert [s for s, _ in d.kit.events.override_clears] == ["brake"]
    assert not d.last_report(GlobalRpt).override_active


def test_a_scenario_manual_override_takes_brake_and_wheel_and_stops_the_vehicle() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5, gear=Gear.FORWARD))
    d.advance(4.0, drive_stream(accel=0.5, gear=Gear.FORWARD))
    assert d.kit.truth(d.now_s).speed_mps > 2.0
    d.kit.set_devices(SafetyDevices(manual_override=True))
    d.advance(15.0, drive_stream(accel=0.5, gear=Gear.FORWARD))   # the planner keeps asking
    truth = d.kit.truth(d.now_s)
    assert truth.speed_mps == 0.0
    assert set(truth.enabled) == {"accel", "shift"}
    assert d.last_report(SteeringRpt).override_active and d.last_report(BrakeRpt).override_active


def test_an_accelerator_override_with_ignore_overrides_is_ignored_and_counted() -> None:
    d = KitDriver(lexus_kit(faults=(KitFault(kind="override", system="accel", start_s=1.0,
                                             end_s=2.0, value=0.5),)))
    d.engage()
    d.advance(3.0, drive_stream(brake=0.5, ignore_overrides=True))
    assert not d.kit.systems["accel"].override and d.kit.systems["accel"].enabled
    assert d.kit.ignore_overrides_frames > 0
