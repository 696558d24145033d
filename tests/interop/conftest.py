"""OpenJAUS 3.3 for the interop tests: located, built once per session into a cache keyed by
the hash of the kit (tarball, Makefile, test tools), or the tests skip saying why.

The kit is ``../shared/interop/openjaus`` seen from the project root (its README), or
``$OVERDRIVE_OPENJAUS_KIT``. The build goes to ``$OVERDRIVE_CACHE`` (default
``$XDG_CACHE_HOME/overdrive``, else ``~/.cache/overdrive``, else the temporary directory)
under ``openjaus-<hash>``; a lock
file makes concurrent sessions build it once. Nothing is written into the kit or the project.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

PROJECT = Path(__file__).resolve().parents[2]
BUILD_TIMEOUT_S = 600  # ~20 s on 2 idle cores (kit README); generous for a loaded CI machine
KIT_FILES = ("openjaus-3.3-b3722c1.tar.gz", "Makefile", "ojcodec.c", "ojpeer.c", "ojcmpt.c")


def kit_dir() -> Path:
    return Path(os.environ.get("OVERDRIVE_OPENJAUS_KIT", PROJECT.parent / "shared/interop/openjaus"))


def cache_root() -> Path:
    if "OVERDRIVE_CACHE" in os.environ:
        return Path(os.environ["OVERDRIVE_CACHE"])
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "overdrive"


def kit_hash(kit: Path) -> str:
    digest = hashlib.sha256()
    for name in KIT_FILES:
        digest.update(name.encode() + b"\0" + (kit / name).read_bytes())
    return digest.hexdigest()[:16]


def build(target: str = "all") -> Path:
    """The build directory holding OpenJAUS's products for ``target`` (``all`` or ``vsim``)."""
    kit = kit_dir()
    missing = [name for name in KIT_FILES if not (kit / name).is_file()]
    if missing:
        pytest.skip(f"OpenJAUS interop kit not found at {kit} (missing {', '.join(missing)}); "
                    "set OVERDRIVE_OPENJAUS_KIT or put ../shared beside the project")
    tools = [t for t in ("make", "gcc", "g++", "ar") if shutil.which(t) is None]
    if tools:
        pytest.skip(f"cannot build OpenJAUS: {', '.join(tools)} not installed")
    if target == "vsim" and not _has_header("ncurses.h"):
        pytest.skip("cannot build ojVehicleSim: the ncurses headers are not installed "
                    "(Debian/Ubuntu: apt-get install libncurses-dev)")
    root = cache_root()
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError:   # a read-only home on some CI runners
        root = Path(tempfile.gettempdir()) / "overdrive-cache"
        root.mkdir(parents=True, exist_ok=True)
    out = root / f"openjaus-{kit_hash(kit)}"
    stamp = out / f".built-{target}"
    with open(out.parent / f"{out.name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not stamp.exists():
            result = subprocess.run(
                ["make", "-C", str(kit), f"BUILD={out}", "-j2", target],
                capture_output=True, text=True, timeout=BUILD_TIMEOUT_S, check=False)
            if result.returncode != 0:
                pytest.fail(f"building OpenJAUS ({target}) failed:\n{result.stdout[-3000:]}"
                            f"\n{result.stderr[-3000:]}")
            stamp.touch()
    return out


def _has_header(name: str) -> bool:
    probe = subprocess.run(["gcc", "-E", "-x", "c", "-"], input=f"#include <{name}>\n",
                           capture_output=True, text=True, check=False)
    return probe.returncode == 0


@pytest.fixture(scope="session")
def openjaus_vsim() -> Path:
    """The build directory with ojVehicleSim too (needs the ncurses headers)."""
    return build("vsim")


@pytest.fixture(scope="session")
def openjaus() -> Path:
    """The directory with ojcodec, ojpeer, ojcmpt, ojNodeManager (built once)."""
    return build("all")


@pytest.fixture(scope="session")
def kit() -> Path:
    return kit_dir()
