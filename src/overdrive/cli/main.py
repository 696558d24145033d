"""The ``overdrive`` command line.

Exit codes (contract): 0 ran and every expectation held; 1 ran and something was violated;
2 bad usage or an invalid file, with a message naming the file, the field and the problem.
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path

import click
import msgspec

from overdrive import __version__
from overdrive.cli.bus import echo, launch, node, pub
from overdrive.cli.can import can_hub, can_monitor
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
@click.option("--xgv", "xgv", required=True, metavar="HOST[:PORT]",
              help="The XGV's address (port 3794 by default).")
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
def drive(xgv: str, scenario: Path, bind: str, out_dir: Path | None, quiet: bool,
          profile: str) -> None:
    """Run the control stack against a real or simulated XGV over JAUS, in wall-clock time."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.compose import plain_profile_problem
    from overdrive.run.drive import run_drive
    from overdrive.run.sim import default_out_dir
    from overdrive.scenario.schema import ScenarioError, load_scenario

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
