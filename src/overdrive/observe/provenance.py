"""Where a result came from, recorded in every ``summary.json`` and ``sweep.json``.

A figure is only worth what can be traced back: the code (git commit, and whether the tree had
uncommitted changes), the installed packages (the lock file's hash and whether the environment
matches it), the interpreter, and the vehicle parameters and scenario as validated. Two runs of
one scenario on one checkout give the same record but for ``created_utc``.

The lock (``requirements.lock``, written by ``make lock``) pins every direct and transitive
dependency with hashes; ``lock_entries`` and ``lock_drift`` are the pure half of the check that
``scripts/check_env.py`` runs before ``make test``.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import platform
import re
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import msgspec
from packaging.markers import InvalidMarker, Marker
from packaging.requirements import InvalidRequirement, Requirement
from packaging.version import InvalidVersion, Version

import overdrive

LOCK_NAME = "requirements.lock"
"""The lock file at the checkout's root (``make lock`` writes it)."""
GIT_TIMEOUT_S = 5.0
"""A git that does not answer within this (a network file system) leaves the commit unknown."""

_LOCK_LINE = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;\\]+)\s*(?:;\s*([^\\]+?))?\s*\\?$")


class LockEntry(NamedTuple):
    """One pinned distribution: its normalized name, version and environment marker ("")."""

    name: str
    version: str
    marker: str


def normalize(name: str) -> str:
    """A distribution name as PEP 503 compares them (``PyYAML`` == ``pyyaml``)."""
    return re.sub(r"[-_.]+", "-", name).lower()


def lock_entries(text: str) -> list[LockEntry]:
    """The pins of a requirements-format lock (``name==version [; marker]`` lines; hashes,
    comments and continuation lines skipped). A line that pins nothing is a ``ValueError``."""
    entries = []
    for number, line in enumerate(text.splitlines(), 1):
        if not line or line[0] in " \t#":
            continue
        match = _LOCK_LINE.match(line)
        if match is None:
            raise ValueError(f"{LOCK_NAME} line {number}: not a 'name==version' pin: {line!r}")
        name, version, marker = match.groups()
        entries.append(LockEntry(normalize(name), version, (marker or "").strip()))
    return entries


def applies(entry: LockEntry, environment: Mapping[str, str] | None = None) -> bool:
    """Whether ``entry``'s marker holds here (or in ``environment``, PEP 508 variables)."""
    if not entry.marker:
        return True
    try:
        return Marker(entry.marker).evaluate(dict(environment) if environment else None)
    except InvalidMarker as exc:
        raise ValueError(f"{LOCK_NAME}: {entry.name}: bad marker {entry.marker!r}: {exc}") from None


def installed_versions() -> dict[str, str]:
    """Every distribution this interpreter sees, by normalized name."""
    out: dict[str, str] = {}
    for dist in importlib.metadata.distributions():
        name = dist.metadata["Name"]
        if name:
            out.setdefault(normalize(name), dist.version)
    return out


def lock_drift(entries: list[LockEntry], installed: Mapping[str, str],
               environment: Mapping[str, str] | None = None) -> list[str]:
    """One line per pin that does not hold: a version other than the lock's, or missing."""
    drift = []
    for entry in entries:
        if not applies(entry, environment):
            continue
        have = installed.get(entry.name)
        if have is None:
            drift.append(f"{entry.name}: not installed (the lock pins {entry.version})")
        elif not same_version(have, entry.version):
            drift.append(f"{entry.name}: {have} installed, the lock pins {entry.version}")
    return drift


def same_version(a: str, b: str) -> bool:
    """Equal as PEP 440 versions (``1.0`` == ``1.0.0``), or as strings when either is not one."""
    try:
        return Version(a) == Version(b)
    except InvalidVersion:
        return a == b


def unlocked_requirements(entries: list[LockEntry]) -> list[str]:
    """Requirements of the installed overdrive (its test extra included) that the lock does not
    pin: a dependency added to pyproject.toml without ``make lock``."""
    try:
        requires = importlib.metadata.requires("overdrive") or []
    except importlib.metadata.PackageNotFoundError:
        return []
    locked = {e.name for e in entries}
    missing = set()
    for text in requires:
        try:
            req = Requirement(text)
        except InvalidRequirement:
            continue
        env_ok = req.marker is None or req.marker.evaluate({"extra": "test"})
        if env_ok and normalize(req.name) not in locked:
            missing.add(normalize(req.name))
    return sorted(missing)


def unlocked(entries: list[LockEntry], installed: Mapping[str, str]) -> list[str]:
    """Installed distributions the lock does not name (besides overdrive itself)."""
    locked = {e.name for e in entries} | {"overdrive"}
    return sorted(f"{name} {version}" for name, version in installed.items()
                  if name not in locked)


def checkout_root() -> Path | None:
    """The source checkout this package is imported from (editable install), else None."""
    root = Path(overdrive.__file__).resolve().parent.parent.parent
    return root if (root / "pyproject.toml").is_file() else None


def _git(root: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                              timeout=GIT_TIMEOUT_S, check=False)
    except (OSError, subprocess.TimeoutExpired):
        return None
    return done.stdout if done.returncode == 0 else None


@functools.cache
def code_provenance() -> dict[str, Any]:
    """The code and environment half, once per process (git and the package list are read;
    runners call it before they write anything, so a run folder inside the checkout does not
    make the tree read as dirty). ``git_commit`` is null unless the package is imported from the
    top of a git checkout (not a wheel, not a copy inside another repository)."""
    root = checkout_root()
    commit = dirty = None
    top = _git(root, "rev-parse", "--show-toplevel") if root is not None else None
    in_own_repo = top is not None and Path(top.strip()).resolve() == root
    if in_own_repo and (head := _git(root, "rev-parse", "HEAD")) is not None:
        commit = head.strip()
        status = _git(root, "--no-optional-locks", "status", "--porcelain",
                      "--untracked-files=normal")
        dirty = None if status is None else bool(status.strip())
    lock_sha256 = drift = None
    lock_path = root / LOCK_NAME if root is not None else None
    if lock_path is not None and lock_path.is_file():
        data = lock_path.read_bytes()
        lock_sha256 = hashlib.sha256(data).hexdigest()
        try:
            drift = lock_drift(lock_entries(data.decode("utf-8")), installed_versions())
        except (UnicodeDecodeError, ValueError) as exc:
            drift = [f"unreadable: {exc}"]
    return {
        "overdrive_version": overdrive.__version__,
        "git_commit": commit,
        "git_dirty": dirty,
        "lock_sha256": lock_sha256,
        "lock_drift": drift,
        "python": platform.python_version(),
        "python_implementation": platform.python_implementation(),
        "platform": f"{sys.platform}-{platform.machine()}",
    }


def run_provenance(spec: msgspec.Struct, vehicle: msgspec.Struct) -> dict[str, Any]:
    """The whole record for a run of ``spec`` (a validated scenario file) on ``vehicle``."""
    scenario = msgspec.to_builtins(spec)
    encoded = msgspec.json.encode(scenario, order="sorted")
    return {
        **code_provenance(),
        "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "scenario_sha256": hashlib.sha256(encoded).hexdigest(),
        "scenario": scenario,
        "vehicle": msgspec.to_builtins(vehicle),
    }
