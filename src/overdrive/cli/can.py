"""CAN commands (``can-hub``, ``can-monitor``) and the CAN flags every CAN command shares."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

EXIT_USAGE = 2


def can_options(command: Callable[..., Any]) -> Callable[..., Any]:
    """``--can-interface``, ``--can-channel``, ``--can-bitrate``, ``--can-context`` and
    ``--can-option KEY=VALUE``: given ones win; the rest come from python-can's own lookup
    (CAN_INTERFACE / CAN_CHANNEL / CAN_BITRATE / CAN_CONFIG, its config files)."""
    for decorator in reversed((
        click.option("--can-interface", help="python-can interface (socketcan, kvaser, pcan, "
                     "vector, socketcand, virtual, ...)."),
        click.option("--can-channel", help="python-can channel (can0, PCAN_USBBUS1, ...)."),
        click.option("--can-bitrate", type=click.IntRange(1, 8_000_000), help="Bit rate, bit/s."),
        click.option("--can-context", help="Section of python-can's config file to read."),
        click.option("--can-option", "can_option", multiple=True, metavar="KEY=VALUE",
                     help="Any other python-can option (socketcand: host=127.0.0.1, port=29536)."),
    )):
        command = decorator(command)
    return command


def resolve_from_flags(can_interface: str | None, can_channel: str | None,
                       can_bitrate: int | None, can_context: str | None,
                       can_option: tuple[str, ...]) -> Any:
    """The resolved ``CanConfig``, or exit 2 naming what is wrong."""
    from overdrive.run.can_tools import CanConfigError, cast_option, resolve_can_config

    options: dict[str, Any] = {}
    for item in can_option:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise click.UsageError(f"--can-option {item!r}: expected KEY=VALUE")
        cast = cast_option(value)
        if isinstance(cast, float) and not math.isfinite(cast):
            raise click.UsageError(f"--can-option {item!r}: not a finite number")
        options[key.strip()] = cast
    try:
        return resolve_can_config(can_interface, can_channel, can_bitrate, can_context, **options)
    except CanConfigError as e:
        click.echo(f"error: {e}", err=True)
        raise SystemExit(EXIT_USAGE) from None


@click.command("can-hub")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on (a test bus: keep it on loopback).")
@click.option("--port", type=click.IntRange(0, 65535), default=29536, show_default=True,
              help="TCP port (socketcand's default; 0: any free port, printed).")
def can_hub(host: str, port: int) -> None:
    """A CAN bus on loopback: a socketcand-protocol hub python-can's socketcand interface
    connects to (for machines without SocketCAN)."""
    from overdrive.run.can_tools import serve_hub

    raise SystemExit(serve_hub(host, port, lambda line: click.echo(line, err=True)))


@click.command("can-monitor")
@can_options
@click.option("--dialect", type=click.Choice(["v3", "v14"]), default="v3", show_default=True,
              help="PACMod 3 protocol: v3 (the shipped DBC) or v14 (GLOBAL_CMD, supervisory).")
@click.option("--dbc", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="Your own PACMod 3 DBC instead of the shipped one.")
@click.option("--duration", "duration_s", type=click.FloatRange(0.0, min_open=True),
              help="Stop after this many seconds.")
@click.option("--count", type=click.IntRange(1), help="Stop after this many frames.")
def can_monitor(can_interface: str | None, can_channel: str | None, can_bitrate: int | None,
                can_context: str | None, can_option: tuple[str, ...], dialect: str,
                dbc: Path | None, duration_s: float | None, count: int | None) -> None:
    """Decode a live CAN bus as PACMod 3, sending nothing. Exit 1 if no frame arrived."""
    from overdrive.run.can_tools import CanConfigError, KitError, monitor

    if duration_s is not None and not math.isfinite(duration_s):
        raise click.UsageError("--duration: a finite number of seconds")
    config = resolve_from_flags(can_interface, can_channel, can_bitrate, can_context, can_option)
    try:
        code = monitor(config, click.echo, dialect=dialect, dbc=dbc,  # type: ignore[arg-type]
                       duration_s=duration_s, count=count)
    except KitError as e:
        click.echo(f"error: {e}", err=True)
        raise SystemExit(EXIT_USAGE) from None
    except CanConfigError as e:    # the bus could not be opened: nothing was monitored
        click.echo(f"error: {e}", err=True)
        raise SystemExit(1) from None
    raise SystemExit(code)
