"""The fault display (seed 001's LED sign; docs/speed-server.md, "The fault display") under a
hostile or broken client: what the sign shows stays readable and bounded. Stepped directly (the
speed-server rig); the printed line is ``observe.display.DisplayLines``' own output.

A request's rejection names the client's own strings (``state {state!r}``, ``no gear
{gear!r}``): quoted with ``repr``, so control characters and lone surrogates arrive escaped
(holds). Their length is not bounded: a 1 MB gear name becomes a 1 MB sign text, re-sent every
second on ``display``, written to ``run.mcap`` each time and printed as one 1 MB console line.
And a client whose rejection changes every period (10 ms) makes a new ``Display`` every
period, 100 a second, where the doc promises about one a second (10 with one per SPSS)."""

from __future__ import annotations

import pytest

from overdrive.messages import Topic
from overdrive.observe.display import DisplayLines
from overdrive.servers.speed_table import FAULT_MESSAGES
from tests.servers.test_speed_fault_display import DisplayRig
from tests.servers.test_speed_server import PRESET_NAMES, drive_gear, spss

LONGEST_TEMPLATE = max(len(text) for text in FAULT_MESSAGES.values())   # 80 chars (2026-11-26)
SIGN_CHARS = 4 * LONGEST_TEMPLATE + 200   # generous: a template with numbers and a short name
HOSTILE = "\x1b[2J\x1b[31mall clear\n\r\udcff"


def rejected_rig(preset: str, **bad):
    """A running server, then one request with ``bad`` fields (state / gear) in it."""
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(1.0, spss("run", 4.0, 2.0, gear=gear))
    request = {"state": "run", "gear": gear, **bad}
    rig.tick(spss(request["state"], 4.0, 2.0, gear=request["gear"]))
    return rig


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("field", ["state", "gear"])
def test_control_characters_of_a_client_reach_the_console_escaped(preset, field) -> None:
    """Holds: the sign's text and the printed line carry no ESC, CR, LF or lone surrogate."""
    rig = rejected_rig(preset, **{field: HOSTILE})
    lines: list[str] = []
    DisplayLines(lines.append).observe(Topic.DISPLAY, rig.shown())
    assert rig.shown().code != 0 and len(lines) == 1
    assert not any(c in lines[0] for c in "\x1b\n\r\udcff")


@pytest.mark.xfail(strict=True, reason="the rejection quotes the client's string whole: a 1 MB "
                                       "gear or state name is a 1 MB sign text, re-sent every "
                                       "second and printed as one line")
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("field", ["state", "gear"])
@pytest.mark.parametrize("length", [1_000, 1_000_000])
def test_the_sign_text_of_a_hostile_request_is_bounded(preset, field, length) -> None:
    """Measured 2026-11-26 (this file): a 1,000,000-char state gave a 1,000,113-char Display
    text (gear: 1,000,085) and a 1,000,117-char printed line; the longest template is 80
    chars, the bound asserted ``SIGN_CHARS`` (520)."""
    rig = rejected_rig(preset, **{field: "A" * length})
    lines: list[str] = []
    DisplayLines(lines.append).observe(Topic.DISPLAY, rig.shown())
    assert rig.shown().code != 0
    assert len(rig.shown().text) <= SIGN_CHARS
    assert len(lines[0]) <= SIGN_CHARS + 40


@pytest.mark.xfail(strict=True, reason="every change of the fault is sent at once: a client "
                                       "changing its rejection or its fault code every 10 ms "
                                       "makes 100 Display messages a second")
@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", ["bad_state", "fault_code"])
def test_a_client_changing_its_fault_every_period_does_not_flood_the_sign(preset, kind) -> None:
    """Measured 2026-11-26 (this file): 100 Display messages in 1 s (one per 10 ms period) for
    a new invalid state every period, and for client fault 1 / 2 alternating; the doc's figure
    is about 1 a second, 10 with one per SPSS (an SPSS every 100 ms)."""
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(1.0, spss("run", 4.0, 2.0, gear=gear))
    before = len(rig.displays)
    for i in range(100):   # 1 s of periods
        rig.tick(spss(f"bogus{i}", 4.0, 2.0, gear=gear) if kind == "bad_state"
                 else spss("run", 4.0, 2.0, gear=gear, fault=1 + i % 2))
    assert len(rig.displays) - before <= 10
