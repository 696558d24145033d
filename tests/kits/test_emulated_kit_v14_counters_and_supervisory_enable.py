"""The v14 dialect of the emulated PACMod 3 kit: GLOBAL_CMD and SUPERVISORY_CTRL counters must
advance by one (mod 16, wrapping 15 -> 0); a repeated or skipped counter or a bad complement is
counted and the frame ignored; supervisory_enable_required is reported; no system enables
without a current SUPERVISORY_CTRL enable=1, and enable=0 disables every system."""

from __future__ import annotations

import pytest

from overdrive.kits.frames import CanFrame
from overdrive.kits.pacmod3 import GlobalCmd, GlobalRpt, SupervisoryCtrl
from overdrive.vehicle.pacmod3_kit import SYSTEMS
from tests.kits.kit_driver import KitDriver, drive_stream, lexus_kit


class Supervisor:
    """A SUPERVISORY_CTRL stream with a proper counter."""

    def __init__(self, start: int = 0) -> None:
        self.counter = start

    def __call__(self, enable: bool = True) -> SupervisoryCtrl:
        msg = SupervisoryCtrl(counter=self.counter, enable=enable)
        self.counter = (self.counter + 1) % 16
        return msg


def v14_engaged() -> tuple[KitDriver, Supervisor]:
    d, sup = KitDriver(lexus_kit("v14")), Supervisor()
    base = drive_stream(brake=0.5, enable=False)
    d.advance(0.1, lambda t: [sup(), *base(t)])
    on = drive_stream(brake=0.5)
    d.advance(0.5, lambda t: [sup(), *on(t)])
    return d, sup


def test_supervisory_enable_required_is_reported_in_v14_only() -> None:
    for dialect, required in (("v3", False), ("v14", True)):
        d = KitDriver(lexus_kit(dialect))
        d.advance(0.1)
        assert d.last_report(GlobalRpt).supervisory_enable_required is required


def test_without_supervisory_enable_no_system_enables() -> None:
    d = KitDriver(lexus_kit("v14"))
    d.engage()
    d.advance(0.5, drive_stream(brake=0.5))
    assert d.kit.truth(d.now_s).enabled == ()
    assert {why for _, _, why in d.kit.events.refused_edges} == {"supervisory enable required"}


def test_with_supervisory_enable_the_edge_enables() -> None:
    d, _ = v14_engaged()
    assert d.kit.truth(d.now_s).enabled == SYSTEMS


def test_supervisory_enable_0_disables_every_system() -> None:
    d, sup = v14_engaged()
    on = drive_stream(brake=0.5)
    d.advance(d.now_s + 0.2, lambda t: [sup(enable=False), *on(t)])
    assert d.kit.truth(d.now_s).enabled == ()
    d.advance(d.now_s + 0.2, lambda t: [sup(), *on(t)])   # enable=1 again: still needs the edge
    assert d.kit.truth(d.now_s).enabled == ()


def test_the_supervisory_stream_going_quiet_disables_every_system() -> None:
    d, _ = v14_engaged()
    d.advance(d.now_s + 0.5, drive_stream(brake=0.5))
    assert d.kit.truth(d.now_s).enabled == ()
    assert ("supervisory" in {s for s, _ in d.kit.events.timeouts})


@pytest.mark.parametrize("first", [0, 7, 14, 15])
def test_consecutive_counters_wrap_and_are_accepted(first: int) -> None:
    d = KitDriver(lexus_kit("v14"))
    for i in range(40):
        d.send(GlobalCmd(counter=(first + i) % 16))
    assert d.kit.bad_frames == {}
    assert d.kit.frames_seen["GlobalCmd"] == 40


@pytest.mark.parametrize("second, reason", [(5, "repeated_counter"), (7, "bad_counter"),
                                            (4, "bad_counter"), (0, "bad_counter")])
def test_a_repeated_or_skipped_counter_is_counted_and_ignored(second: int, reason: str) -> None:
    """A GLOBAL_CMD clear_overrides with a bad counter does not clear a released override."""
    d = KitDriver(lexus_kit("v14"))
    d.kit.systems["brake"].override = True
    d.send(GlobalCmd(counter=5))
    d.send(GlobalCmd(counter=second, clear_overrides=True))
    assert d.kit.bad_frames == {reason: 1}
    assert d.kit.systems["brake"].override
    d.send(GlobalCmd(counter=(second + 1) % 16, clear_overrides=True))   # back in turn
    assert not d.kit.systems["brake"].override


def test_a_bad_complement_is_counted_and_ignored() -> None:
    d = KitDriver(lexus_kit("v14"))
    d.kit.systems["brake"].override = True
    good = d.codec.encode(GlobalCmd(counter=3, clear_overrides=True))
    data = bytearray(good.data)
    for i in range(len(data)):          # flip the complement's bits wherever they are
        trial = bytearray(good.data)
        trial[i] ^= 0xF0
        try:
            d.codec.decode(CanFrame(arbitration_id=good.arbitration_id, data=bytes(trial)))
        except ValueError:
            data = trial
            break
    d.kit.receive(CanFrame(arbitration_id=good.arbitration_id, data=bytes(data)), 0.0)
    assert d.kit.bad_frames == {"bad_complement": 1}
    assert d.kit.systems["brake"].override


def test_v14_frames_on_a_v3_kit_are_unknown_ids() -> None:
    d = KitDriver(lexus_kit("v3"))
    v14 = KitDriver(lexus_kit("v14"))
    d.kit.receive(v14.codec.encode(SupervisoryCtrl(counter=0, enable=True)), 0.0)
    d.kit.receive(v14.codec.encode(GlobalCmd(counter=0)), 0.0)
    assert d.kit.bad_frames == {"unknown_id": 2}
