"""``overdrive kit-sim pacmod3``: an emulated drive-by-wire kit on a CAN bus (run/kit_sim.py)."""

from __future__ import annotations

import contextlib
import math
import signal
from pathlib import Path

import click

from overdrive.cli.can import EXIT_USAGE, can_options, resolve_from_flags


def _usage(message: str) -> None:
    click.echo(f"error: {message}", err=True)
    raise SystemExit(EXIT_USAGE)


@click.group("kit-sim")
def kit_sim() -> None:
    """An emulated CAN drive-by-wire kit with overdrive's simulated vehicle behind it."""


@kit_sim.command("pacmod3")
@can_options
@click.option("--dialect", type=click.Choice(["v3", "v14"]), default="v3", show_default=True,
              help="PACMod 3 protocol: v3 (the shipped DBC) or v14 (GLOBAL_CMD counters, "
                   "supervisory enable).")
@click.option("--scenario", type=click.Path(dir_okay=False, path_type=Path),
              help="Vehicle, seed, world, safety-device and actuator-fault events to play (from "
                   "the first frame received).")
@click.option("--vehicle", help="A vehicle file (or preset name) with a steering_ratio; default "
                                "lexus-rx450h, or the scenario's vehicle.")
@click.option("--fault", "faults", multiple=True, metavar="KIND:SYSTEM:START[:END[:VALUE]]",
              help="Inject a kit fault on the scenario clock: override:brake:5:7:0.4 (pedal "
                   "ratio; steering: N.m; shift: a gear number), silence::3:4 (no reports), "
                   "stuck:steering:2. Repeatable.")
@click.option("--duration", "duration_s", type=click.FloatRange(0.0, 86_400.0, min_open=True),
              help="Stop after this many seconds (default: until SIGINT / SIGTERM).")
@click.option("--summary", "summary_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the kit's JSON summary here on exit (truth, odometer, frames, enable "
                   "edges, timeouts, overrides, bad frames).")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the vehicle's own state every 10 ms to this CSV.")
def pacmod3(can_interface: str | None, can_channel: str | None, can_bitrate: int | None,
            can_context: str | None, can_option: tuple[str, ...], dialect: str,
            scenario: Path | None, vehicle: str | None, faults: tuple[str, ...],
            duration_s: float | None, summary_path: Path | None, truth_path: Path | None) -> None:
    """An emulated PACMod 3 on a CAN bus, in wall-clock time."""
    from overdrive.run.kit_sim import (
        TRUTH_HEADER,
        CanConfigError,
        KitSimServer,
        parse_fault,
        write_summary,
    )
    from overdrive.scenario.schema import ScenarioError, load_scenario
    from overdrive.scenario.vehicles import VehicleFileError, VehicleSpecError, vehicle_from_spec

    if duration_s is not None and not math.isfinite(duration_s):
        _usage("--duration: a finite number of seconds")
    try:
        kit_faults = tuple(parse_fault(f) for f in faults)
    except ValueError as e:
        _usage(f"--fault {e}")
        return
    loaded = None
    if scenario is not None:
        try:
            loaded = load_scenario(scenario)
        except ScenarioError as exc:
            _usage(str(exc))
    params = None
    if vehicle is not None:
        try:
            params = vehicle_from_spec(vehicle)
        except (VehicleSpecError, VehicleFileError) as exc:
            _usage(f"--vehicle {exc}")
    config = resolve_from_flags(can_interface, can_channel, can_bitrate, can_context, can_option)
    try:
        server = KitSimServer(config, scenario=loaded, vehicle=params,
                              dialect=dialect, faults=kit_faults)  # type: ignore[arg-type]
    except CanConfigError as exc:
        click.echo(f"error: {exc}", err=True)
        raise SystemExit(1) from None
    except ValueError as exc:     # a vehicle without a steering ratio
        _usage(str(exc))
        return
    try:
        truth = truth_path.open("w", encoding="utf-8", buffering=1) if truth_path else None
    except OSError as exc:
        server.close()
        _usage(f"--truth {truth_path}: {exc.strerror or exc}")
        return
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    kit = server.kit
    click.echo(f"kit-sim: PACMod 3 ({kit.dialect}, {kit.codec.dbc_version}) on "
               f"{config.interface} {config.channel}, vehicle {kit.params.preset}", err=True)
    for line in config.describe().splitlines():
        click.echo(f"  {line}", err=True)
    with server, truth or contextlib.nullcontext():
        if truth is not None:
            truth.write(TRUTH_HEADER + "\n")
        with contextlib.suppress(KeyboardInterrupt):
            server.serve(duration_s, truth=truth)
        summary = server.summary()
    if summary_path is not None:
        write_summary(summary_path, summary)
    click.echo(f"kit-sim: {summary['frames_received']} frames received, "
               f"{summary['reports_sent']} reports sent, enable edges "
               f"{len(summary['enable_edges'])}, timeouts {len(summary['timeouts'])}, bad frames "
               f"{sum(summary['bad_frames'].values())}, odometer {summary['odometer_m']:.3f} m",
               err=True)
