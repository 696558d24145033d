"""The fault display (seed 001's LED sign; docs/speed-server.md, "The fault display") under a
hostile or broken client: what the sign shows stays readable and bounded. Stepped directly (the
speed-server rig); the printed line is ``observe.display.DisplayLines``' own output.

A request's rejection names the client's own strings (``state {state!r}``, ``no gear
{gear!r}``), quoted with ``repr``. Their length was not bounded: a 1 MB gear name became a 1 MB
sign text, re-sent every second on ``display``, written to ``run.mcap`` each time and printed
as one 1 MB console line; now the sign text is at most ``DISPLAY_TEXT_MAX_CHARS`` (the full text
stays in the fault's notice). And a client whose rejection changed every period (10 ms) made a
new ``Display`` every period, 100 a second; now a change is sent at most once per
``DISPLAY_CHANGE_MIN_S`` (the SPSS period), the newest text."""

from __future__ import annotations

import pytest

from overdrive.messages import DISPLAY_TEXT_MAX_CHARS, Topic, sign_text
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
    rig.shown().text.encode("utf-8")   # strict: what run.mcap's writer does with it
    lines[0].encode("utf-8")


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("field", ["state", "gear"])
@pytest.mark.parametrize("length", [1_000, 1_000_000])
def test_the_sign_text_of_a_hostile_request_is_bounded(preset, field, length) -> None:
    """Was: a 1,000,000-char state gave a 1,000,113-char Display text (gear: 1,000,085) and a
    1,000,117-char printed line (measured 2026-11-26). Holds now: the text is cut to
    ``DISPLAY_TEXT_MAX_CHARS`` (120) with an ellipsis, within ``SIGN_CHARS`` (520, from the
    longest template), and the printed line with it."""
    rig = rejected_rig(preset, **{field: "A" * length})
    lines: list[str] = []
    DisplayLines(lines.append).observe(Topic.DISPLAY, rig.shown())
    assert rig.shown().code != 0
    assert len(rig.shown().text) <= SIGN_CHARS
    assert len(lines[0]) <= SIGN_CHARS + 40


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("kind", ["bad_state", "fault_code"])
def test_a_client_changing_its_fault_every_period_does_not_flood_the_sign(preset, kind) -> None:
    """Was: 100 Display messages in 1 s (one per 10 ms period) for a new invalid state every
    period, and for client fault 1 / 2 alternating (measured 2026-11-26). Holds now: a change
    is sent at most once per ``DISPLAY_CHANGE_MIN_S`` (0.1 s), so at most 10 in that second,
    and the last one sent is the server's current fault or one held back under 0.1 s (the
    rig's check every period)."""
    gear = drive_gear(preset)
    rig = DisplayRig(preset, state="run", gear=gear)
    rig.run(1.0, spss("run", 4.0, 2.0, gear=gear))
    before = len(rig.displays)
    for i in range(100):   # 1 s of periods
        rig.tick(spss(f"bogus{i}", 4.0, 2.0, gear=gear) if kind == "bad_state"
                 else spss("run", 4.0, 2.0, gear=gear, fault=1 + i % 2))
    assert len(rig.displays) - before <= 10


@pytest.mark.parametrize("extra", [-2, -1, 0, 1, 2, 1000])
@pytest.mark.parametrize("filler", ["A", "\x00", "\udcff", "\u00e9"])
def test_sign_text_is_printable_and_cut_at_its_limit(extra, filler) -> None:
    """Swept around ``DISPLAY_TEXT_MAX_CHARS``: a text up to it is kept (each unprintable
    character one "?"), a longer one cut to exactly the limit, ending in an ellipsis; the
    result always encodes as strict UTF-8 and holds no unprintable character."""
    text = filler * (DISPLAY_TEXT_MAX_CHARS + extra)
    shown = sign_text(text)
    assert shown.isprintable()
    shown.encode("utf-8")
    if len(text) <= DISPLAY_TEXT_MAX_CHARS:
        assert len(shown) == len(text) and not shown.endswith("\u2026")
        assert shown == (text if filler.isprintable() else "?" * len(text))
    else:
        assert len(shown) == DISPLAY_TEXT_MAX_CHARS and shown.endswith("\u2026")
