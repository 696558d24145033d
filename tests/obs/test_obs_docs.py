"""The generated docs are up to date, and the hand-written ones link what exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from overdrive.messages import ALL_MESSAGES
from overdrive.run import docs
from overdrive.servers.speed_table import TRANSITIONS

DOCS = Path(__file__).resolve().parents[2] / "docs"


@pytest.fixture(scope="module")
def generated() -> dict[Path, str]:
    return docs.generated(DOCS)


def test_generated_docs_are_up_to_date(generated: dict[Path, str]) -> None:
    assert set(generated) == {DOCS / "messages.md", DOCS / "state-machines.md",
                              DOCS / "architecture.md", DOCS / "scenarios.md"}
    for path, content in generated.items():
        assert path.read_text(encoding="utf-8") == content, (
            f"{path.name} is stale: run `python -m overdrive.run.docs` and commit the result")


def test_message_reference_covers_every_field(generated: dict[Path, str]) -> None:
    text = generated[DOCS / "messages.md"]
    for cls in ALL_MESSAGES:
        assert f"## {cls.__name__}\n" in text
        for name in cls.__struct_fields__:
            assert f"| `{name}` |" in text, f"{cls.__name__}.{name}"
    assert "| `speed_mps` | float | m/s |" in text


def test_state_diagram_has_every_transition(generated: dict[Path, str]) -> None:
    text = generated[DOCS / "state-machines.md"]
    for state, events in TRANSITIONS.items():
        for event, target in events.items():
            assert f"{state} --> {target} : {event}" in text
    assert text.index("`estop-disable`") < text.index("`manual-override`") < text.index(
        "`drive-by-wire`"), "modes listed in precedence order"
    from overdrive.servers import move

    for phase, events in move.TRANSITIONS.items():   # the move server's, interruptions included
        for event, target in events.items():
            assert f"{phase} --> {target} : {event}" in text


def test_topic_table_lists_every_periodic_sensor(generated: dict[Path, str]) -> None:
    table = generated[DOCS / "architecture.md"]
    for topic in ("vehicle/status", "sensors/gps_ins", "sensors/imu", "sim/truth"):
        assert re.search(rf"\| `{topic}` \| \w+ \| vehicle: 100 Hz \|", table), topic
    assert re.search(r"\| `speed/set_speed` \| SetSpeed \| [^|]*scenario: 10 Hz", table)


def test_relative_links_resolve() -> None:
    for page in ("architecture.md", "drive-your-own-vehicle.md"):
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", (DOCS / page).read_text()):
            assert (DOCS / target).exists(), f"{page} links to missing {target}"
