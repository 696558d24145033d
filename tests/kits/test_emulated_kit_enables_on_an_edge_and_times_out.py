"""The emulated PACMod 3 kit enables a system only on a DISABLE -> ENABLE edge of its own
command stream, and disables it after 3 command periods (100 ms) without a command: swept around
the limit (2.9 vs 3.1 periods), judged from the kit's own state and the vehicle's ground truth."""

from __future__ import annotations

import pytest

from overdrive.kits.pacmod3 import AccelRpt, Gear, GlobalRpt
from overdrive.vehicle.pacmod3_kit import COMMAND_PERIOD_S, COMMAND_TIMEOUT_S, SYSTEMS
from tests.kits.kit_driver import KitDriver, command, drive_stream, lexus_kit


@pytest.mark.parametrize("system", SYSTEMS)
def test_a_stream_that_starts_with_enable_never_enables(system: str) -> None:
    d = KitDriver(lexus_kit())
    d.advance(1.0, lambda t: [command(system, True, 0.2 if system != "shift" else Gear.FORWARD)])
    assert not d.kit.systems[system].enabled
    assert d.kit.events.enable_edges == []
    assert d.kit.truth(d.now_s).enabled == ()


@pytest.mark.parametrize("system", SYSTEMS)
def test_the_edge_enables_only_its_own_system(system: str) -> None:
    d = KitDriver(lexus_kit())
    d.advance(0.1, lambda t: [command(s, False) for s in SYSTEMS])
    d.send(command(system, True))
    d.advance(0.2, lambda t: [command(s, s == system) for s in SYSTEMS])
    assert d.kit.truth(d.now_s).enabled == (system,)
    assert [s for s, _ in d.kit.events.enable_edges] == [system]


def test_without_an_edge_the_throttle_never_moves_the_vehicle() -> None:
    """enable=1 at 50 % accelerator from the first frame, in drive: no edge, no motion."""
    d = KitDriver(lexus_kit())
    d.engage(("shift", "brake"), brake_ratio=0.5)
    d.advance(1.0, lambda t: [command("shift", True, Gear.FORWARD), command("brake", True, 0.5)])
    assert d.kit.plant.gear == "drive"
    d.advance(4.0, lambda t: [command("shift", True, Gear.FORWARD), command("brake", True, 0.0),
                              command("accel", True, 0.5)])
    truth = d.kit.truth(d.now_s)
    assert "accel" not in truth.enabled and truth.throttle == 0.0
    assert truth.odometer_m == 0.0


@pytest.mark.parametrize("gap_periods, times_out", [(2.0, False), (2.9, False), (3.0, False),
                                                     (3.1, True), (4.0, True), (30.0, True)])
def test_the_command_timeout_is_three_periods(gap_periods: float, times_out: bool) -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(1.0, drive_stream(brake=0.5))
    last_s = d.now_s
    for msg in drive_stream(brake=0.5)(last_s):   # the last frames, at last_s
        d.send(msg)
    d.kit.step(last_s + gap_periods * COMMAND_PERIOD_S)
    st = d.kit.systems["brake"]
    assert st.enabled is not times_out
    assert st.timed_out is times_out
    assert (d.kit.events.timeouts != []) is times_out
    if times_out:
        assert d.kit.events.timeouts[0][1] - last_s > COMMAND_TIMEOUT_S


def test_a_late_frame_after_the_timeout_is_not_a_continuation() -> None:
    """The frame arriving 3.1 periods late finds the system already timed out: still enable=1,
    it does not re-enable (a stalled sender resuming with stale intent)."""
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(1.0, drive_stream(brake=0.5))
    for msg in drive_stream(brake=0.5)(d.now_s):
        d.send(msg)
    t = d.now_s + 3.1 * COMMAND_PERIOD_S
    d.kit.receive(d.codec.encode(command("brake", True, 0.5)), t)
    assert not d.kit.systems["brake"].enabled
    assert sorted(s for s, _ in d.kit.events.timeouts) == sorted(SYSTEMS)


def test_after_a_timeout_the_stale_stream_never_re_enables_and_the_vehicle_is_not_driven() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5, gear=Gear.FORWARD))
    d.advance(3.0, drive_stream(accel=0.4, gear=Gear.FORWARD))
    moving_mps = d.kit.truth(d.now_s).speed_mps
    assert moving_mps > 1.0
    d.advance(d.now_s + 0.2)                       # silence: every system times out
    assert d.kit.truth(d.now_s).enabled == ()
    assert d.last_report(GlobalRpt).usr_can_timeout
    assert not d.last_report(AccelRpt).enabled
    d.advance(d.now_s + 3.0, drive_stream(accel=0.4, gear=Gear.FORWARD))   # the stale stream
    truth = d.kit.truth(d.now_s)
    assert truth.enabled == () and truth.throttle < 1e-6
    assert truth.speed_mps < moving_mps             # nobody drives: it rolls down
    assert not d.last_report(GlobalRpt).usr_can_timeout   # frames flow again, still disabled


def test_a_new_edge_after_a_timeout_enables_again() -> None:
    d = KitDriver(lexus_kit())
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5))
    d.advance(d.now_s + 0.2)
    assert d.kit.truth(d.now_s).enabled == ()
    d.engage()
    assert d.kit.truth(d.now_s).enabled == SYSTEMS
    assert [s for s, _ in d.kit.events.enable_edges].count("accel") == 2


def test_the_summary_says_the_brake_held_at_each_edge_and_when_throttle_first_came() -> None:
    """What a stack's engage is judged by: brake enabled and held before accel enables, and no
    throttle before that (the edges' brake ratio, the first throttle's time)."""
    d = KitDriver(lexus_kit())
    d.engage(("brake",), brake_ratio=0.6)
    d.advance(0.3, lambda t: [command("brake", True, 0.6)])
    d.engage(("accel", "steering", "shift"))
    assert d.kit.events.first_throttle_s is None
    d.advance(1.0, lambda t: [command("brake", True, 0.6), command("shift", True, Gear.FORWARD),
                              command("steering", True), command("accel", True, 0.0)])
    throttle_from_s = d.now_s
    d.advance(2.0, drive_stream(accel=0.3, gear=Gear.FORWARD))
    summary = d.kit.summary(d.now_s)
    edges = {e["system"]: e for e in summary["enable_edges"]}
    assert edges["brake"]["brake_ratio"] == 0.0         # the brake itself: none before it
    assert edges["accel"]["brake_ratio"] == pytest.approx(0.6, abs=1e-3)
    assert edges["brake"]["t_s"] < edges["accel"]["t_s"]
    assert throttle_from_s <= summary["first_throttle_s"] <= throttle_from_s + 0.05
