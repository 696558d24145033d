"""Reproducible installs and traceable results: the lock is what is installed, a drifted package
stops the suite naming it, and every run folder and sweep says what produced it."""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.observe.provenance import (
    LOCK_NAME,
    LockEntry,
    applies,
    code_provenance,
    installed_versions,
    lock_drift,
    lock_entries,
)
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import scenario_dict

ROOT = Path(__file__).resolve().parent.parent
LOCK = ROOT / LOCK_NAME
CHECK_ENV = ROOT / "scripts" / "check_env.py"
WALL_CLOCK_FIELDS = ("wall_time_s", "real_time_factor")


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True,
                          check=True).stdout


def test_lock_pins_every_dependency_with_hashes() -> None:
    text = LOCK.read_text(encoding="utf-8")
    entries = lock_entries(text)
    names = {e.name for e in entries}
    # direct (pyproject.toml), test extras, the installer and the build backend
    assert {"msgspec", "pyyaml", "eclipse-zenoh", "pytest", "hypothesis", "packaging", "pip",
            "setuptools"} <= names
    pins = re.split(r"\n(?=[A-Za-z])", text[text.index("\n", text.index("make lock")) + 1:])
    assert len(pins) == len(entries)
    for pin in pins:
        assert pin.split("\n")[0].rstrip().endswith("\\"), pin
        assert re.search(r"--hash=sha256:[0-9a-f]{64}", pin), f"no hash: {pin.splitlines()[0]}"


def test_installed_environment_is_the_lock() -> None:
    """What `make test` runs on is exactly what the lock pins (the suite's own install)."""
    assert lock_drift(lock_entries(LOCK.read_text(encoding="utf-8")), installed_versions()) == []


def test_a_version_spelled_differently_is_not_drift() -> None:
    assert lock_drift([LockEntry("tzdata", "2026.6", "")], {"tzdata": "2026.6.0"}) == []


def test_drift_names_each_package_whose_version_differs() -> None:
    entries = [LockEntry("pyyaml", "6.0.4", ""), LockEntry("numpy", "2.4.6", ""),
               LockEntry("click", "8.5.1", "")]
    drift = lock_drift(entries, {"pyyaml": "6.0.2", "click": "8.5.1"})
    assert drift == ["pyyaml: 6.0.2 installed, the lock pins 6.0.4",
                     "numpy: not installed (the lock pins 2.4.6)"]


def test_a_pin_for_another_python_or_platform_is_not_drift() -> None:
    win = LockEntry("colorama", "0.4.6", "sys_platform == 'win32'")
    new = LockEntry("numpy", "2.5.5", "python_full_version >= '3.12'")
    env311 = {"sys_platform": "linux", "python_full_version": "3.11.7", "python_version": "3.11"}
    assert not applies(win, env311) and not applies(new, env311)
    assert lock_drift([win, new], {}, env311) == []
    assert lock_drift([new], {"numpy": "2.4.6"}, env311 | {"python_full_version": "3.12.1"}) \
        == ["numpy: 2.4.6 installed, the lock pins 2.5.5"]


@pytest.mark.parametrize("line", ["pyyaml>=6.0", "-e .", "pyyaml==", "git+https://x/y"])
def test_a_lock_line_that_pins_nothing_is_refused(line: str) -> None:
    with pytest.raises(ValueError, match="not a 'name==version' pin"):
        lock_entries(f"click==8.5.1 \\\n    --hash=sha256:00\n{line}\n")


def test_a_dependency_missing_from_the_lock_stops_the_suite(tmp_path: Path) -> None:
    text = LOCK.read_text(encoding="utf-8")
    rich = re.search(r"^rich==.*?(?=^[a-z])", text, re.S | re.M).group(0)
    without = tmp_path / LOCK_NAME
    without.write_text(text.replace(rich, ""), encoding="utf-8")
    done = subprocess.run([sys.executable, str(CHECK_ENV), str(without)], capture_output=True,
                          text=True, check=False)
    assert done.returncode == 3
    assert "rich: required by pyproject.toml, not in requirements.lock (run make lock)" in done.stderr


def test_changed_version_stops_the_suite_naming_the_package(tmp_path: Path) -> None:
    """scripts/check_env.py (the first step of `make test`) against a lock whose pyyaml pin is
    not what is installed: the same comparison as an installed version that moved."""
    text = LOCK.read_text(encoding="utf-8")
    pinned = next(e for e in lock_entries(text) if e.name == "pyyaml")
    moved = tmp_path / LOCK_NAME
    moved.write_text(text.replace(f"pyyaml=={pinned.version}", "pyyaml==6.0.1"), encoding="utf-8")
    done = subprocess.run([sys.executable, str(CHECK_ENV), str(moved)], capture_output=True,
                          text=True, check=False)
    assert done.returncode == 3
    assert f"pyyaml: {pinned.version} installed, the lock pins 6.0.1" in done.stderr
    ok = subprocess.run([sys.executable, str(CHECK_ENV), str(LOCK)], capture_output=True,
                        text=True, check=False)
    assert ok.returncode == 0, ok.stderr


def test_summary_traces_the_run_to_code_lock_interpreter_vehicle_and_scenario(
        tmp_path: Path) -> None:
    data = scenario_dict(duration_s=2, seed=7)
    code_provenance.cache_clear()    # git state now, not when this worker first ran a scenario
    for name in ("a", "b"):
        run_scenario(parse_scenario(data), tmp_path / name, plot=False)
    a, b = (json.loads((tmp_path / n / "summary.json").read_text()) for n in ("a", "b"))
    prov = a["provenance"]
    assert prov["git_commit"] == _git("rev-parse", "HEAD").strip()
    assert prov["git_dirty"] == bool(_git("status", "--porcelain").strip())
    assert prov["lock_sha256"] == hashlib.sha256(LOCK.read_bytes()).hexdigest()
    assert prov["lock_drift"] == []
    assert prov["python"] == ".".join(map(str, sys.version_info[:3]))
    assert prov["scenario"]["seed"] == 7 and prov["scenario"]["duration_s"] == 2
    assert prov["vehicle"]["preset"] == "escape-hybrid" and prov["vehicle"]["mass_kg"] > 0
    # two runs differ only in wall-clock fields
    for summary in (a, b):
        for key in WALL_CLOCK_FIELDS:
            summary.pop(key)
        summary["provenance"].pop("created_utc")
    assert a == b


@pytest.mark.parametrize("change", [{"seed": 2}, {"duration_s": 1.5},
                                    {"vehicle": {"preset": "escape-hybrid", "mass_kg": 1800}},
                                    {"world": {"friction": 0.5}}])
def test_scenario_hash_changes_with_the_scenario(change: dict) -> None:
    base = scenario_dict(duration_s=1)
    one = run_scenario(parse_scenario(base), None).summary["provenance"]
    two = run_scenario(parse_scenario(base | change), None).summary["provenance"]
    assert one["scenario_sha256"] != two["scenario_sha256"]
    if "vehicle" in change:
        assert two["vehicle"]["mass_kg"] == 1800


def test_sweep_report_carries_provenance_and_base_seed(tmp_path: Path) -> None:
    scenario = ROOT / "scenarios" / "move-straight.yaml"
    result = CliRunner().invoke(main, ["sweep", str(scenario), "--runs", "2", "--jobs", "1",
                                       "--out", str(tmp_path / "sw")])
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    assert report["provenance"]["git_commit"] == _git("rev-parse", "HEAD").strip()
    assert report["provenance"]["scenario"]["name"] == "move-straight"
    assert report["base_seed"] == report["provenance"]["scenario"]["seed"]
