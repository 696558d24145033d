"""``overdrive can-log``: a run's CAN frames as candump / ASC, and a CAN log replayed through the
PACMod 3 decoder (``overdrive.observe.can_log``).

Exit codes follow the contract: 0 done, 1 replay found malformed frames, 2 bad usage or a file
that cannot be read, with a one-line message naming it.
"""

from __future__ import annotations

from pathlib import Path

import click

EXIT_OK, EXIT_MALFORMED, EXIT_USAGE = 0, 1, 2


def _fail(message: str) -> None:
    click.echo(f"error: {message}", err=True)
    raise SystemExit(EXIT_USAGE)


@click.group("can-log")
def can_log() -> None:
    """CAN logs: export a run's raw frames, replay a log through the PACMod 3 decoder."""


@can_log.command("export")
@click.argument("run", type=click.Path(path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["candump", "asc"]), default="candump",
              show_default=True, help="candump -L lines (.log) or Vector ASC (.asc).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path),
              help="Output file (default: can.log or can.asc in the run folder).")
def export(run: Path, fmt: str, out: Path | None) -> None:
    """Write RUN's CAN frames (RUN: a run folder or its run.mcap) with python-can's writers,
    direction kept (candump T/R, ASC Tx/Rx)."""
    from overdrive.observe.can_log import SUFFIXES, CanLogError, export_can_log, run_mcap_path
    from overdrive.observe.run_files import OutDirError, make_out_dir

    mcap = run_mcap_path(run)
    if not mcap.is_file():
        _fail(f"{mcap}: no such file")
    if out is None:
        out = mcap.parent / f"can{SUFFIXES[fmt]}"
    try:
        make_out_dir(out.parent, f"--out {out}: its folder")
        count = export_can_log(run, out, fmt)  # type: ignore[arg-type]
    except (CanLogError, OutDirError) as exc:
        _fail(str(exc))
        return
    click.echo(f"{out}: {count} frames ({fmt})")


@can_log.command("replay")
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--dialect", type=click.Choice(["v3", "v14"]), default="v3", show_default=True,
              help="PACMod 3 protocol: v3 (the shipped v3.4.0 DBC) or v14 (GLOBAL_CMD, "
                   "SUPERVISORY_CTRL).")
@click.option("--dbc", type=click.Path(dir_okay=False, path_type=Path),
              help="Your own PACMod 3 DBC instead of the shipped one.")
@click.option("--quiet", is_flag=True, help="Print only the counts.")
def replay(log: Path, dialect: str, dbc: Path | None, quiet: bool) -> None:
    """Print each frame of LOG (candump .log, .asc or .blf) decoded by the PACMod 3 codec;
    unknown and malformed frames are shown and counted, never a crash. Exit 1 when a frame
    was malformed."""
    from overdrive.observe.can_log import CanLogError, CanReplay, make_codec, replay_can_log

    summary = CanReplay()
    try:
        codec = make_codec(dialect, dbc)
        for frame in replay_can_log(log, codec, summary):
            if not quiet:
                click.echo(frame.format())
    except CanLogError as exc:
        _fail(str(exc))
        return
    click.echo(summary.format())
    if summary.error:
        raise SystemExit(EXIT_USAGE)
    raise SystemExit(EXIT_MALFORMED if summary.counts["malformed"] else EXIT_OK)


__all__ = ["can_log"]
