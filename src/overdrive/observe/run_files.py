"""Writing run files: the output folder made before anything runs, JSON without NaN.

Every command that takes ``--out`` calls ``make_out_dir`` first, so a folder that cannot be
created (``/dev/null/x``, a path under a regular file, no permission) is a usage error (exit 2,
one line) instead of a traceback after the run. ``finite_json`` writes ``summary.json`` and
``sweep.json``: a non-finite number becomes ``null``, as the CSV files leave such cells empty.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from pathlib import Path
from typing import Any, TextIO

from overdrive.observe.plot import plot_run
from overdrive.scenario.safe_yaml import one_line


class OutDirError(ValueError):
    """The output folder cannot be created or written; ``str()`` is the one-line message."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))


def make_out_dir(path: Path, option: str = "--out") -> Path:
    """Create ``path`` (and its parents) and check it is a writable folder."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutDirError(f"{option} {path}: exists and is not a folder") from None
    except OSError as exc:
        raise OutDirError(f"{option} {path}: cannot create the folder: "
                          f"{exc.strerror or exc}") from None
    except ValueError as exc:    # an embedded NUL byte
        raise OutDirError(f"{option} {path!r}: not a usable path: {exc}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise OutDirError(f"{option} {path}: folder is not writable")
    return path


def finite_only(value: Any) -> Any:
    """``value`` with every NaN or infinity (in dicts, lists and tuples) replaced by None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: finite_only(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_only(v) for v in value]
    return value


def finite_json(value: Any) -> str:
    """Indented JSON text of ``value`` (ends in a newline); non-finite numbers become null."""
    return json.dumps(finite_only(value), indent=2, allow_nan=False) + "\n"


def open_trace(stack: contextlib.ExitStack, out_path: Path | None) -> TextIO | None:
    """Create the run folder ``out_path`` and open its ``trace.csv`` on ``stack`` (None when the
    run keeps no folder): the first half of every runner's folder (sim, drive, launch)."""
    if out_path is None:
        return None
    out_path.mkdir(parents=True, exist_ok=True)
    return stack.enter_context(open(out_path / "trace.csv", "w", encoding="utf-8", newline=""))


def write_summary(out_path: Path | None, summary: dict[str, Any], *, plot: bool) -> None:
    """The second half: ``summary.json`` and, when asked, ``plot.png`` from ``trace.csv``."""
    if out_path is None:
        return
    (out_path / "summary.json").write_text(finite_json(summary), encoding="utf-8")
    if plot:
        plot_run(out_path / "trace.csv", out_path / "plot.png", summary)
