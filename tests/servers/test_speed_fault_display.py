"""The fault display (seed 001: "Sending a nonzero fault code will result in a message being
displayed in the LED sign"): the speed server's ``display`` output, stepped directly.

Judged against the server's own replies: after every period the last ``Display`` sent shows
the fault the replies carry (its code and message), blank when they carry none; a text is
sent the period it changes and re-sent every ``DISPLAY_REFRESH_S``, never more often."""

from __future__ import annotations

from itertools import pairwise

import pytest

from overdrive.messages import DISPLAY_CHANGE_MIN_S, DISPLAY_REFRESH_S, Display, Topic, sign_text
from overdrive.servers.speed_table import FaultCode, fault_message
from tests.servers.test_speed_server import PERIOD_S, PRESET_NAMES, Rig, drive_gear, spss


class DisplayRig(Rig):
    """The speed-server rig, keeping every ``Display`` sent with its time."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.displays: list[tuple[float, Display]] = []
        self.expected: tuple[int, str] | None = None   # the server's fault, and since when
        self.expected_since_s = 0.0

    def tick(self, *requests):
        now = self.now_s
        out = super().tick(*requests)
        sent = [m for t, m in out if t == Topic.DISPLAY]
        assert len(sent) <= 1, "one Display per period at most"
        self.displays.extend((now, m) for m in sent)
        shown = self.displays[-1][1]
        server = self.server
        # the sign shows the server's current fault (what its next status carries), the same
        # period: the latest one when a request's rejection and a timeout come together; a
        # change within DISPLAY_CHANGE_MIN_S of the last change sent is held back that long
        expected = (server.fault, sign_text(server.fault_message)) if server.fault else (0, "")
        if expected != self.expected:
            self.expected, self.expected_since_s = expected, now
        changes_s = [t for (t, d), (_, d0) in zip(self.displays[1:], self.displays, strict=False)
                     if d != d0]
        held_back = (now - self.expected_since_s < DISPLAY_CHANGE_MIN_S - 1e-9
                     and bool(changes_s) and now - changes_s[-1] < DISPLAY_CHANGE_MIN_S - 1e-9)
        assert (shown.code, shown.text) == expected or held_back, (now, shown)
        return out

    def shown(self) -> Display:
        return self.displays[-1][1]


def refresh_gaps_s(displays: list[tuple[float, Display]]) -> list[float]:
    """Gaps between consecutive sends of an unchanged text."""
    return [t1 - t0 for (t0, d0), (t1, d1) in pairwise(displays) if d0 == d1]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("code", [1, 7, 42, 999])
def test_a_client_fault_shows_its_message_until_cleared_then_blank(preset, code):
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(2.0, spss("run", 4.0, 2.0, gear=gear))
    assert rig.shown() == Display(text="")                  # blank before any fault
    sent_before = len(rig.displays)
    rig.run(3.0, spss("run", 4.0, 2.0, gear=gear, fault=code), every_s=0.1)
    onset_s, first = rig.displays[sent_before]
    assert first == Display(text=fault_message(code), code=code)
    assert onset_s == pytest.approx(2.0)                     # the period the fault came
    assert rig.shown() == first                              # held while the client sends it
    rig.run(4.0, spss("idle", 0.0, 2.0, gear=gear))         # stopped, fault 0: cleared
    assert rig.shown() == Display(text="") and not rig.server.latched
    blank_s = next(t for t, d in rig.displays if t > onset_s and d.text == "")
    assert blank_s >= onset_s + rig.server.config.fault_hold_s - 1e-9


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_the_servers_own_fault_shows_and_clears(preset):
    """The SPSS watchdog's e-stop (fault 1001): shown while latched, blank once a request for
    a state that does not move clears it."""
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(2.0, spss("run", 4.0, 2.0, gear=gear))
    rig.run(3.0)                                             # the client goes quiet
    assert rig.shown().code == FaultCode.SPSS_TIMEOUT
    assert rig.shown().text == fault_message(FaultCode.SPSS_TIMEOUT,
                                             timeout_s=rig.server.config.spss_timeout_s)
    rig.run(3.0, spss("idle", 0.0, 2.0, gear=gear))
    assert rig.shown() == Display(text="") and not rig.server.latched


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_invalid_request_shows_its_rejection(preset):
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(2.0, spss("run", 4.0, 2.0, gear=gear))
    rig.tick(spss("run", float("nan"), 2.0, gear=gear))
    assert rig.shown().code == FaultCode.NOT_FINITE and "speed_mps" in rig.shown().text
    assert rig.replies[-1].fault == FaultCode.NOT_FINITE
    rig.run(3.0, spss("run", 4.0, 2.0, gear=gear))
    assert rig.shown() == Display(text="")


@pytest.mark.parametrize("preset", PRESET_NAMES)
def test_an_unchanged_text_is_resent_once_a_refresh_period_and_no_more(preset):
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(3.0, spss("run", 4.0, 2.0, gear=gear))
    rig.run(5.0, spss("run", 4.0, 2.0, gear=gear, fault=9))
    gaps = refresh_gaps_s(rig.displays)
    assert gaps, "the refresh resends the unchanged text"
    for gap in gaps:   # within one period of the refresh, never sooner
        assert DISPLAY_REFRESH_S - 1e-9 <= gap <= DISPLAY_REFRESH_S + PERIOD_S + 1e-9
    assert len(rig.displays) <= 8.0 / DISPLAY_REFRESH_S + 3     # changes + refreshes, not 800
