"""The hazard log (docs/safety-case.md) points at tests, scenarios and rules that exist."""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

from overdrive.observe import judge as monitor_module
from overdrive.observe.judge import RULES

ROOT = Path(__file__).resolve().parents[2]
LOG = ROOT / "docs" / "safety-case.md"
REQUIRED = ("overrun", "runaway", "rollback", "collision ahead", "collision while reversing",
            "after a SafeStop pause", "after a manual override", "after an e-stop disable",
            "loss of the command stream", "throttle stuck", "throttle weak", "brakes weak",
            "brakes stuck released", "steering stuck", "steering slow", "GPS/INS frozen",
            "GPS/INS jumping", "GPS/INS lost", "wheel speed", "radar lost", "reordering",
            "duplication", "rogue publisher", "malformed input")


def rows() -> list[list[str]]:
    lines = [ln for ln in LOG.read_text(encoding="utf-8").splitlines() if re.match(r"\| H\d+ ", ln)]
    return [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines]


@functools.cache     # many rows name the same test files: parse each once
def functions_in(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}


def test_every_required_hazard_has_a_row() -> None:
    hazards = " ".join(row[1] for row in rows())
    assert [h for h in REQUIRED if h not in hazards] == []


def test_every_row_points_at_tests_and_scenarios_that_exist() -> None:
    missing = []
    for row in rows():
        refs = re.findall(r"`([^`]+)`", row[6])
        tests = [r for r in refs if r.startswith("tests/")]
        assert tests, f"{row[0]} names no test"
        for ref in refs:
            path, _, name = ref.partition("::")
            name = name.split("[")[0]
            if not (ROOT / path).is_file():
                missing.append(f"{row[0]}: {path}")
            elif name and name not in functions_in(ROOT / path):
                missing.append(f"{row[0]}: {ref}")
    assert missing == []


def test_every_rule_named_is_a_rule_of_the_judge() -> None:
    for row in rows():
        for rule in row[5].split(","):
            assert rule.strip() in RULES, f"{row[0]}: {rule!r}"


def test_the_rule_list_is_what_the_monitor_can_report() -> None:
    source = Path(monitor_module.__file__).read_text(encoding="utf-8")
    reported = set(re.findall(r'self\._violate\(\s*"(\w+)"', source))
    assert reported == set(RULES)
    reliability = (ROOT / "docs" / "reliability.md").read_text(encoding="utf-8")
    assert [r for r in RULES if f"`{r}" not in reliability] == []
    assert [r for r in RULES if f"``{r}``" not in (monitor_module.__doc__ or "")
            and f"**{r}**" not in (monitor_module.__doc__ or "")] == []
