"""The ``overdrive`` command line.

Exit codes (contract): 0 ran and every expectation held; 1 ran and something was violated;
2 bad usage or an invalid file, with a message naming the file, the field and the problem.
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from typing import Any

import click
import msgspec

from overdrive import __version__
from overdrive.cli.bus import echo, launch, node, pub
from overdrive.cli.can import can_hub, can_monitor, can_options, resolve_from_flags
from overdrive.cli.can_log import can_log
from overdrive.cli.jaus import jaus
from overdrive.cli.kit_sim import kit_sim
from overdrive.cli.link import link_proxy
from overdrive.cli.observe import COMMANDS, start_live
from overdrive.cli.summary import print_summary
from overdrive.runtime.udp import parse_address

EXIT_OK, EXIT_VIOLATION, EXIT_USAGE = 0, 1, 2


def fail_usage(message: str) -> None:
    click.echo(f"error: {message}", err=True)
    raise SystemExit(EXIT_USAGE)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="overdrive")
def main() -> None:
    """overdrive: drive-by-wire motion control (move server, driving module, speed server,
    JAUS 3.3 / ByWire XGV)."""


@main.command()
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Run folder (default runs/NAME-TIMESTAMP/).")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), help="Override the scenario's seed.")
@click.option("--realtime", is_flag=True, help="Pace the simulation to the wall clock.")
@click.option("--quiet", is_flag=True, help="No progress bar and no summary table.")
@click.option("--live", is_flag=True,
              help="Serve the run to the Foxglove app (WebSocket on localhost); use with --realtime.")
@click.option("--live-port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Port of the --live WebSocket.")
def sim(scenario: Path, out_dir: Path | None, seed: int | None, realtime: bool, quiet: bool,
        live: bool, live_port: int) -> None:
    """Run SCENARIO against the simulated vehicle and write the run folder."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.sim import default_out_dir, run_scenario
    from overdrive.scenario.schema import ScenarioError, load_scenario

    observers = []
    if live:
        observers.append(start_live(live_port))
    try:
        loaded = load_scenario(scenario)
        if seed is not None:
            loaded = msgspec.structs.replace(
                loaded, spec=msgspec.structs.replace(loaded.spec, seed=seed))
        out = make_out_dir(out_dir or default_out_dir(loaded))
        show_progress = not quiet and sys.stdout.isatty()
        if show_progress:
            from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

            with Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                          TextColumn("{task.completed:.1f}/{task.total:.0f} s"),
                          TimeRemainingColumn(), transient=True) as bar:
                task = bar.add_task(loaded.name, total=loaded.spec.duration_s)
                result = run_scenario(loaded, out, keep_trace=False, realtime=realtime,
                                      progress=lambda now, _t: bar.update(task, completed=now),
                                      observers=observers)
        else:
            result = run_scenario(loaded, out, keep_trace=False, realtime=realtime,
                                  observers=observers)
    except (ScenarioError, OutDirError) as exc:
        fail_usage(str(exc))
        return
    finally:
        for observer in observers:
            observer.close()
    if not quiet:
        print_summary(result.summary, out)
    else:
        click.echo(str(out))
    raise SystemExit(result.exit_code)


@main.command("sweep")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--runs", type=click.IntRange(1, 1_000_000), default=100, show_default=True)
@click.option("--jobs", type=click.IntRange(1, 256), default=None,
              help="Worker processes (default: one per core).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Sweep folder (default runs/sweep-NAME-TIMESTAMP/).")
@click.option("--seed", type=click.IntRange(0, 2**62), help="Seed of run 0 (default: the scenario's).")
def sweep_command(scenario: Path, runs: int, jobs: int | None, out_dir: Path | None,
                  seed: int | None) -> None:
    """Monte Carlo validation: run SCENARIO N times with sampled conditions; exit 1 on any
    safety-invariant violation."""
    import time

    from overdrive.observe.run_files import OutDirError
    from overdrive.run.sweep import default_jobs, sweep
    from overdrive.scenario.schema import ScenarioError

    out = out_dir or Path("runs") / f"sweep-{scenario.stem}-{time.strftime('%Y%m%d-%H%M%S')}"
    try:
        report = sweep(scenario, runs, jobs or default_jobs(), out, seed)
    except (ScenarioError, OutDirError, OSError) as exc:
        fail_usage(str(exc))
        return
    print_sweep(report, out)
    raise SystemExit(EXIT_VIOLATION if report["violations"] else EXIT_OK)


def print_sweep(report: dict, out: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"overdrive sweep: {report['scenario']}")
    for column in ("figure", "min", "median", "p95", "max"):
        table.add_column(column, justify="left" if column == "figure" else "right")
    for key in ("authorization_margin_m", "max_decel_mps2", "max_accel_mps2",
                "max_lateral_accel_mps2"):
        stats = report[key]
        if stats:
            table.add_row(key, *(f"{stats[k]:.3f}" for k in ("min", "median", "p95", "max")))
    Console().print(table)
    for worst in report["worst"][:3]:
        click.echo(f"worst: run {worst['run']} (seed {worst['seed']}), margin "
                   f"{worst['authorization_margin_m']} m: {worst['replay']}")
    for rule, runs in report["violations_by_rule"].items():
        click.echo(f"rule {rule}: broken in {runs} runs")
    faults = {k: v for k, v in report["runs_by_fault"].items() if k != "none" or len(report["runs_by_fault"]) > 1}
    for fault, row in faults.items():
        rules = ", ".join(f"{k} {n}" for k, n in row["rules"].items()) or "-"
        click.echo(f"fault {fault}: {row['violating']} of {row['runs']} runs violating ({rules})")
    click.echo(f"{report['violations']} violations in {report['runs']} runs")
    click.echo(f"results: {out}")


@main.command("move-server")
@click.option("-s", "--simulate", is_flag=True,
              help="Simulation mode (seed 004): a seeded fake planner drives the simulated vehicle.")
@click.option("--vehicle", type=click.Choice(["escape-hybrid", "ranger-6x6"]), default="escape-hybrid",
              show_default=True)
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=1, show_default=True)
@click.option("--duration-s", type=click.FloatRange(1.0, 86_400.0), default=120.0, show_default=True)
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path))
@click.option("--quiet", is_flag=True)
def move_server(simulate: bool, vehicle: str, seed: int, duration_s: float, out_dir: Path | None,
                quiet: bool) -> None:
    """Run the move server. With -s: offline, against the simulated vehicle and a fake planner."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.move_sim import simulation_nodes
    from overdrive.run.sim import default_out_dir, run_scenario
    from overdrive.scenario.schema import parse_scenario
    from overdrive.vehicle.plant import World

    if not simulate:
        fail_usage("move-server runs offline with -s; on a vehicle run `overdrive node move`")
    scenario = parse_scenario({"name": f"move-server-sim-{vehicle}", "vehicle": vehicle,
                               "seed": seed, "duration_s": duration_s,
                               "description": "overdrive move-server -s"}, "<move-server -s>")
    try:
        out = make_out_dir(out_dir or default_out_dir(scenario))
    except OutDirError as exc:
        fail_usage(str(exc))
        return
    nodes = simulation_nodes(scenario.vehicle, seed, world=World())
    result = run_scenario(scenario, out, keep_trace=False, nodes=nodes)
    if quiet:
        click.echo(str(out))
    else:
        print_summary(result.summary, out)
    raise SystemExit(result.exit_code)


def _host_port(text: str, default_port: int, what: str, *, bind: bool) -> tuple[str, int]:
    try:
        return parse_address(text, what, bind=bind, default_port=default_port)
    except ValueError as exc:
        fail_usage(str(exc))
        raise   # unreachable: fail_usage exits


@main.command("xgv-sim")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to bind.")
@click.option("--port", type=click.IntRange(0, 65535), default=3794, show_default=True,
              help="UDP port (JUDP 3794; 0 picks a free one).")
@click.option("--scenario", type=click.Path(dir_okay=False, path_type=Path),
              help="Vehicle, start, world and safety-device events to play (from the first "
                   "datagram received).")
@click.option("--duration-s", type=click.FloatRange(0.0, 86_400.0, min_open=True),
              help="Stop after this long (default: run until interrupted).")
@click.option("--truth", "truth_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Write the simulated vehicle's own state after every 10 ms step to this CSV "
                   "(t_s, scenario_s, x_m, y_m, speed_mps): ground truth to judge a run by.")
def xgv_sim(host: str, port: int, scenario: Path | None, duration_s: float | None,
            truth_path: Path | None) -> None:
    """A simulated ByWire XGV speaking JAUS 3.3 over JUDP/UDP, in wall-clock time."""
    from overdrive.run.xgv_sim import TRUTH_HEADER, XgvServer
    from overdrive.scenario.schema import ScenarioError, load_scenario

    loaded = None
    if scenario is not None:
        try:
            loaded = load_scenario(scenario)
        except ScenarioError as exc:
            fail_usage(str(exc))
    try:
        server = XgvServer(host, port, loaded)
    except OSError as exc:
        fail_usage(f"cannot bind {host}:{port}: {exc.strerror or exc}")
        return
    try:
        truth = truth_path.open("w", encoding="utf-8", buffering=1) if truth_path is not None else None
    except OSError as exc:
        server.close()
        fail_usage(f"--truth {truth_path}: {exc.strerror or exc}")
        return
    with server, truth or contextlib.nullcontext():
        if truth is not None:
            truth.write(TRUTH_HEADER + "\n")
        bound = server.address
        click.echo(f"xgv-sim: JAUS/JUDP on {bound[0]}:{bound[1]} (subsystem 1, node 1)", err=True)
        with contextlib.suppress(KeyboardInterrupt):
            server.serve(duration_s, truth=truth)
    click.echo(f"xgv-sim: {server.simulator.stats}, dropped over input bounds "
               f"{server.admission.dropped}", err=True)


@main.command()
@click.option("--xgv", "xgv", metavar="HOST[:PORT]",
              help="The XGV's address (port 3794 by default); or --can.")
@click.option("--can", "can_kit", type=click.Choice(["pacmod3"]),
              help="A CAN drive-by-wire kit instead of an XGV (docs/pacmod3-stack.md).")
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--bind", default="0.0.0.0:0", show_default=True, metavar="HOST:PORT",
              help="Local address; a real XGV answers on port 3794: use 0.0.0.0:3794.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Run folder (default runs/NAME-TIMESTAMP/).")
@click.option("--quiet", is_flag=True, help="No summary table.")
@click.option("--profile", type=click.Choice(["xgv", "plain"]), default="xgv", show_default=True,
              help="The vehicle's JAUS profile: xgv (a ByWire XGV or xgv-sim) or plain (a JAUS "
                   "3.3 vehicle without the XGV's reports, e.g. OpenJAUS's ojVehicleSim: "
                   "needs control: wrench and start: ready).")
@click.option("--vehicle", "vehicle_file", type=click.Path(dir_okay=False, path_type=Path),
              help="--can: the vehicle file (default: the Lexus RX 450h, lexus-rx450h).")
@click.option("--engage", is_flag=True,
              help="--can: engage at start (the operator's act); without it the drive waits "
                   "disengaged for `overdrive engage --run RUN_DIR`.")
@click.option("--dialect", type=click.Choice(["v3", "v14"]), default="v3", show_default=True,
              help="--can pacmod3: v3 (the shipped DBC) or v14 (GLOBAL_CMD, supervisory).")
@click.option("--dbc", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="--can pacmod3: your own DBC instead of the shipped one.")
@click.option("--bring-up", "bring_up", type=click.Choice(["throttle", "brake", "steering"]),
              help="--can: enable one axis (with the brake) at low caps (docs/drive-your-own-"
                   "vehicle.md, \"Bring-up over CAN\").")
@can_options
def drive(xgv: str | None, can_kit: str | None, scenario: Path, bind: str, out_dir: Path | None,
          quiet: bool, profile: str, vehicle_file: Path | None, engage: bool, dialect: str,
          dbc: Path | None, bring_up: str | None, can_interface: str | None,
          can_channel: str | None, can_bitrate: int | None, can_context: str | None,
          can_option: tuple[str, ...]) -> None:
    """Run the control stack against a real or simulated XGV over JAUS, or a CAN drive-by-wire
    kit (--can pacmod3), in wall-clock time."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.compose import plain_profile_problem
    from overdrive.run.drive import run_drive
    from overdrive.run.sim import default_out_dir
    from overdrive.scenario.schema import ScenarioError, load_scenario

    if (xgv is None) == (can_kit is None):
        fail_usage("give one of --xgv HOST[:PORT] or --can pacmod3")
    if can_kit is not None:
        _drive_can(scenario, out_dir, quiet, vehicle_file, engage, dialect, dbc, bring_up,
                   (can_interface, can_channel, can_bitrate, can_context, can_option))
        return
    if vehicle_file or engage or bring_up or dbc or dialect != "v3":
        fail_usage("--vehicle, --engage, --dialect, --dbc and --bring-up go with --can")
    assert xgv is not None
    remote = _host_port(xgv, 3794, "--xgv", bind=False)
    local = _host_port(bind, 0, "--bind", bind=True)
    try:
        loaded = load_scenario(scenario)
        problem = plain_profile_problem(loaded) if profile == "plain" else None
        if problem is not None:
            fail_usage(f"{scenario}: {problem} (--profile plain)")
        out = make_out_dir(out_dir or default_out_dir(loaded))
        result = run_drive(loaded, remote, out, bind=local,
                           profile="plain" if profile == "plain" else "xgv",
                           display=lambda line: click.echo(line, err=True))
    except (ScenarioError, OutDirError) as exc:
        fail_usage(str(exc))
        return
    except OSError as exc:
        fail_usage(f"JAUS link to {remote[0]}:{remote[1]}: {exc.strerror or exc}")
        return
    if quiet:
        click.echo(str(out))
    else:
        print_summary(result.summary, out)
    raise SystemExit(result.exit_code)


def _drive_can(scenario: Path, out_dir: Path | None, quiet: bool, vehicle_file: Path | None,
               engage: bool, dialect: str, dbc: Path | None, bring_up: str | None,
               flags: tuple[Any, ...]) -> None:
    """``overdrive drive --can pacmod3``: resolve the bus the python-can way, print it, run."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.drive_can import CanConfigError, KitError, run_drive_can
    from overdrive.run.sim import default_out_dir
    from overdrive.scenario.schema import ScenarioError, load_scenario
    from overdrive.scenario.vehicles import read_vehicle_file

    config = resolve_from_flags(*flags)
    try:
        loaded = load_scenario(scenario)
        vehicle = read_vehicle_file(vehicle_file) if vehicle_file is not None else None
        out = make_out_dir(out_dir or default_out_dir(loaded))
        click.echo("CAN: " + config.describe().replace("\n", "; "), err=True)
        click.echo(f"run folder: {out} (overdrive engage --run {out})", err=True)
        result = run_drive_can(loaded, config, out, vehicle=vehicle,
                               dialect="v14" if dialect == "v14" else "v3", dbc=dbc,
                               engage=engage, bring_up=bring_up,  # type: ignore[arg-type]
                               display=lambda line: click.echo(line, err=True))
    except CanConfigError as exc:   # the bus did not open: nothing was driven
        click.echo(f"error: {exc}", err=True)
        raise SystemExit(EXIT_VIOLATION) from None
    except (ScenarioError, OutDirError, KitError, ValueError) as exc:
        fail_usage(str(exc))
        return
    if quiet:
        click.echo(str(out))
    else:
        print_summary(result.summary, out)
    raise SystemExit(result.exit_code)


@main.command()
@click.option("--run", "run_dir", required=True,
              type=click.Path(file_okay=False, exists=True, path_type=Path),
              help="The run folder of a running `overdrive drive --can`.")
@click.option("--status", is_flag=True, help="Only ask the engage state.")
@click.option("--wait", "wait_s", type=click.FloatRange(0.0, 60.0), default=3.0,
              show_default=True, help="Wait this long for the kit to report engaged.")
def engage(run_dir: Path, status: bool, wait_s: float) -> None:
    """Engage (or re-engage after an override, a timeout or a fault) a running CAN drive: the
    operator's act. Exit 0 engaged, 1 refused or not engaged in time, 2 no drive there."""
    import time

    from overdrive.run.drive_can import request_engage

    try:
        reply = request_engage(run_dir, "status" if status else "engage")
        if not status and reply.get("ok"):
            deadline = time.monotonic() + wait_s
            while reply.get("state") != "engaged" and time.monotonic() < deadline:
                time.sleep(0.1)
                reply = request_engage(run_dir, "status")
    except (OSError, ValueError) as exc:
        fail_usage(f"{run_dir}: {exc}")
        return
    click.echo(f"state: {reply.get('state')}" + (f" (refused: {reply['reason']})"
                                                  if reply.get("reason") else ""))
    raise SystemExit(EXIT_OK if status or reply.get("state") == "engaged" else EXIT_VIOLATION)


@main.command()
def bench() -> None:
    """Run the benchmark suite (bench/ in a source checkout) and print one table."""
    import runpy

    script = Path.cwd() / "bench" / "run.py"
    if not script.is_file():
        fail_usage("bench/run.py not found: run `overdrive bench` from an overdrive source checkout")
    sys.path.insert(0, str(script.parent))
    runpy.run_path(str(script), run_name="__main__")


def _register() -> None:
    """Subcommands defined next to the code they drive."""
    for command in (*COMMANDS, jaus, link_proxy, node, launch, pub, echo, can_hub, can_monitor,
                    can_log, kit_sim):
        main.add_command(command)


_register()

if __name__ == "__main__":  # pragma: no cover
    main()
