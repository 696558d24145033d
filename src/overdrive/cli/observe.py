"""Observability commands: ``overdrive replay`` and ``overdrive plot``, and the ``--live`` hook.

Registered in ``overdrive.cli.main`` with ``main.add_command``. Exit codes follow the contract:
0 ran and held (replay: no difference), 1 ran and something differed, 2 bad usage or an
invalid file, with a one-line message naming the file.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

EXIT_OK, EXIT_DIFFERENT, EXIT_USAGE = 0, 1, 2


def _fail(message: str) -> None:
    click.echo(f"error: {message}", err=True)
    raise SystemExit(EXIT_USAGE)


def _mcap_error(path: Path, exc: Exception) -> str:
    return f"{path}: not a readable run.mcap ({type(exc).__name__}: {exc})"


@click.command()
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
def replay(recording: Path, as_json: bool) -> None:
    """Feed RECORDING's inputs (a run.mcap or its run folder) back through the control stack
    and report every server decision that differs from the recording.

    Exit 0 when every decision matches, 1 when one differs, 2 when the file cannot be replayed.
    """
    from overdrive.run.replay import ReplayError
    from overdrive.run.replay import replay as run_replay
    from overdrive.scenario.schema import ScenarioError
    path = recording / "run.mcap" if recording.is_dir() else recording
    if not path.is_file():
        _fail(f"{path}: no such file")
    try:
        report = run_replay(path)
    except (ReplayError, ScenarioError) as exc:
        _fail(str(exc))
        return
    except Exception as exc:   # a corrupt or foreign file: the mcap reader's own errors
        _fail(_mcap_error(path, exc))
        return
    click.echo(json.dumps(report.to_dict(), indent=2) if as_json else report.format())
    raise SystemExit(EXIT_OK if report.ok else EXIT_DIFFERENT)


@click.command()
@click.argument("run", type=click.Path(exists=True, path_type=Path))
@click.option("--out", "out_png", type=click.Path(dir_okay=False, path_type=Path),
              help="Output PNG (default: plot.png next to the run).")
def plot(run: Path, out_png: Path | None) -> None:
    """Plot RUN (a run folder, its run.mcap or its trace.csv): speed and goal speed,
    acceleration against the ellipse limits, pedals, speed states, safety modes and gears,
    and the path with obstacles and authorizations."""
    from overdrive.observe.plot import plot_source
    from overdrive.observe.run_files import OutDirError, make_out_dir
    try:
        if out_png is not None:
            make_out_dir(out_png.parent, f"--out {out_png}: its folder")
        written = plot_source(run, out_png)
    except OutDirError as exc:
        _fail(str(exc))
        return
    except FileNotFoundError as exc:
        _fail(str(exc))
        return
    except (KeyError, ValueError) as exc:
        _fail(f"{run}: cannot plot: {exc}")
        return
    except Exception as exc:
        if run.suffix == ".mcap" or (run / "run.mcap").exists():
            _fail(_mcap_error(run, exc))
        raise
    click.echo(str(written))


def start_live(port: int, host: str = "127.0.0.1") -> Any:
    """The ``--live`` hook: a started ``LiveView`` (close it after the run); exit 2 when it
    cannot start (foxglove-sdk missing, port taken)."""
    from overdrive.observe.live import LiveView, LiveViewError

    try:
        view = LiveView(host=host, port=port)
    except LiveViewError as exc:
        _fail(str(exc))
        raise AssertionError("unreachable") from exc
    click.echo(f"live view: open {view.url} in Foxglove (Open connection > Foxglove WebSocket)",
               err=True)
    return view


COMMANDS = (replay, plot)
"""What ``overdrive.cli.main`` registers: ``for c in COMMANDS: main.add_command(c)``."""

__all__ = ["COMMANDS", "plot", "replay", "start_live"]
