"""``overdrive node``, ``launch``, ``pub`` and ``echo``: the stack as processes over Zenoh.

Standalone click commands, registered on the main group with ``main.add_command(...)``; also
runnable as ``python -m overdrive.cli.bus COMMAND`` (the launcher starts nodes that way).
Endpoints are loopback-only unless ``--allow-remote``; see docs/multiprocess.md.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

import click
import msgspec

from overdrive.bus.access import read_tool_credentials
from overdrive.bus.tool_gate import run_tool_gate
from overdrive.bus.wire import WireError
from overdrive.bus.zenoh_bus import (
    ALIVE,
    DEFAULT_ENDPOINT,
    DEFAULT_VEHICLE,
    _check_endpoint,
    check_topic,
    open_bus,
)
from overdrive.cli.summary import print_summary

EXIT_OK, EXIT_VIOLATION, EXIT_USAGE = 0, 1, 2
NODE_CHOICES = ("move", "driving", "speed", "vehicle-sim", "xgv-client")
PASSWORD_ENV = "OVERDRIVE_ZENOH_PASSWORD"
CONNECT_WAIT_S = 5.0     # pub/echo retry this long for a launch that is still starting
NO_LINK_HINT = " (a locked-down launch admits tools only with --run RUN_DIR, its credentials)"
RUN_OPTION = click.option(
    "--run", "run_dir", type=click.Path(file_okay=False, path_type=Path),
    help="The run folder of a running `overdrive launch`: join it with that run's tool "
         "credentials (endpoint and vehicle from there too).")


def _usage(message: str) -> None:
    click.echo(f"error: {message}", err=True)
    raise SystemExit(EXIT_USAGE)


def _load(path: Path) -> Any:
    from overdrive.scenario.schema import ScenarioError, load_scenario

    try:
        return load_scenario(path)
    except ScenarioError as exc:
        _usage(str(exc))


def _zenoh_options(fn: Any) -> Any:
    fn = click.option("--zenoh-config", "zenoh_config", type=click.Path(dir_okay=False, exists=True),
                      help="JSON5 Zenoh config loaded first (TLS, auth, access control); "
                           "endpoints and scouting are set by overdrive.")(fn)
    fn = click.option("--user", help=f"Zenoh user name (password from ${PASSWORD_ENV}).")(fn)
    fn = click.option("--allow-remote", is_flag=True,
                      help="Allow endpoints outside 127.0.0.0/8.")(fn)
    fn = click.option("--vehicle", default=DEFAULT_VEHICLE, show_default=True,
                      help="Key prefix: overdrive/<vehicle>/<topic>.")(fn)
    return fn


@click.command()
@click.argument("name", type=click.Choice(NODE_CHOICES))
@click.option("--scenario", "scenario_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Build the node as this scenario needs it (vehicle, world, start state).")
@click.option("--preset", default="escape-hybrid", show_default=True,
              help="Vehicle preset when no --scenario is given.")
@click.option("--start", type=click.Choice(["parked", "ready"]), default="parked", show_default=True,
              help="Initial state when no --scenario is given.")
@click.option("--listen", multiple=True, help="Endpoint to listen on, e.g. tcp/127.0.0.1:7448.")
@click.option("--connect", multiple=True, help=f"Endpoint to dial, e.g. {DEFAULT_ENDPOINT} (repeat).")
@click.option("--mode", type=click.Choice(["peer", "client"]), default="peer", show_default=True)
@click.option("--wait-clock", is_flag=True, help="Wait for a launcher's clock and share its epoch.")
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path),
              help="Write timing and bus statistics here (JSON) on exit.")
@click.option("--duration-s", type=click.FloatRange(min=0.0, min_open=True),
              help="Stop after this long (default: until SIGINT/SIGTERM).")
@click.option("--rt-priority/--no-rt-priority", default=True, show_default=True,
              help="Run SCHED_FIFO (priority 10) where the OS permits it, else at niceness -10.")
@click.option("--clock-offset", "clock_offset", metavar="OFFSET_S[:DRIFT_PPM]", hidden=True,
              help="Test hook: this process's clock is CLOCK_MONOTONIC + OFFSET_S, drifting "
                   "DRIFT_PPM (docs/multiprocess.md, \"Clocks across machines\").")
@_zenoh_options
def node(name: str, scenario_path: Path | None, preset: str, start: str, listen: tuple[str, ...],
         connect: tuple[str, ...], mode: str, wait_clock: bool, report: Path | None,
         duration_s: float | None, rt_priority: bool, clock_offset: str | None,
         zenoh_config: str | None, user: str | None, allow_remote: bool, vehicle: str) -> None:
    """Run one server NAME in this process, on the wall clock, over Zenoh."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.launch import UNAVAILABLE, preset_scenario, run_node
    from overdrive.scenario.schema import ScenarioError

    if name in UNAVAILABLE:
        _usage(f"node {name}: {UNAVAILABLE[name]}")
    if not listen and not connect:
        _usage("give --listen and/or --connect (e.g. --connect tcp/127.0.0.1:7447)")
    try:
        if report is not None:   # written at exit: a folder that cannot be made fails now
            make_out_dir(report.parent, f"--report {report}: its folder")
        scenario = _load(scenario_path) if scenario_path else preset_scenario(name, preset, start)
        code = run_node(name, scenario, listen=listen, connect=connect, mode=mode, vehicle=vehicle,
                        wait_clock=wait_clock, report_path=report, base_file=zenoh_config,
                        user=user, password=os.environ.get(PASSWORD_ENV),
                        allow_remote=allow_remote, duration_s=duration_s, rt_priority=rt_priority,
                        clock_offset=_parse_clock(clock_offset) if clock_offset else None)
    except (ScenarioError, OutDirError) as exc:
        _usage(str(exc))
        return
    except ValueError as exc:           # bad endpoint
        _usage(str(exc))
        return
    raise SystemExit(code)


def _parse_clock(text: str) -> tuple[float, float]:
    """``OFFSET_S[:DRIFT_PPM]`` -> ``(offset_s, drift_ppm)``."""
    offset, _, drift = text.partition(":")
    try:
        parsed = float(offset), float(drift or 0.0)
    except ValueError:
        raise click.BadParameter(f"{text!r}: expected OFFSET_S[:DRIFT_PPM], e.g. 0.1:300") from None
    if not all(map(math.isfinite, parsed)):
        raise click.BadParameter(f"{text!r}: not a finite offset and drift")
    return parsed


def _parse_action(text: str, what: str, flag: str, end_s: float) -> tuple[float, str, str]:
    """``NODE@AT_S`` (of option ``flag``) -> ``(at_s, what, node)``; AT_S within the run
    (0 to ``end_s``)."""
    name, sep, at = text.partition("@")
    try:
        at_s = float(at)
    except ValueError:
        at_s = math.nan
    if not sep or not name or not math.isfinite(at_s) or at_s < 0.0:
        raise click.BadParameter(f"{flag} {text!r}: expected NODE@AT_S with AT_S a time in "
                                 f"seconds >= 0, e.g. move@12")
    if at_s > end_s:
        raise click.BadParameter(f"{flag} {text!r}: AT_S {at_s:g} s is not a time in the run "
                                 f"(0 to {end_s:g} s)")
    return at_s, what, name


def _parse_stall(text: str, end_s: float) -> list[tuple[float, str, str]]:
    """``NODE@AT_S[:FOR_S]`` -> ``launch.stall_actions``: a SIGSTOP and, after FOR_S, a SIGCONT
    (none: hung to the end, as is a FOR_S that ends past the run's ``end_s``)."""
    from overdrive.run.launch import stall_actions

    head, _, for_text = text.partition(":")
    at_s, _, name = _parse_action(head, "stop", "--stall", end_s)
    for_s = math.inf
    if for_text:
        try:
            for_s = float(for_text)
        except ValueError:
            for_s = math.nan
        if not (math.isfinite(for_s) and for_s > 0.0):
            raise click.BadParameter(f"--stall {text!r}: FOR_S must be a positive number of "
                                     f"seconds, e.g. move@12:0.5")
    return stall_actions(name, at_s, for_s, end_s=end_s)


@click.command()
@click.argument("scenario", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--out", "out_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Run folder (default runs/NAME-TIMESTAMP/).")
@click.option("--listen", default=DEFAULT_ENDPOINT, show_default=True,
              help="The launcher's endpoint, where pub/echo connect.")
@click.option("--restart", is_flag=True,
              help="Restart a process (a node or the tool gate) that dies, 0.5 s after.")
@click.option("--kill", "kills", multiple=True, metavar="NODE@AT_S",
              help="Fault injection: SIGKILL a process (a node or `gate`) at scenario time AT_S "
                   "(repeat).")
@click.option("--stall", "stalls", multiple=True, metavar="NODE@AT_S[:FOR_S]",
              help="Fault injection: SIGSTOP a process at AT_S, SIGCONT it FOR_S later (without "
                   "FOR_S, or with one ending past the run, it stays hung to the end of the run) "
                   "(repeat).")
@click.option("--restart-node", "restart_nodes", multiple=True, metavar="NODE@AT_S",
              help="Fault injection: restart a process at AT_S (SIGTERM, then start it again) "
                   "(repeat).")
@click.option("--credentials", type=click.Path(dir_okay=False, exists=True),
              help="user:password lines; each process authenticates as its node name.")
@click.option("--no-plot", is_flag=True, help="Skip plot.png.")
@click.option("--rt-priority/--no-rt-priority", default=True, show_default=True,
              help="Nodes run SCHED_FIFO (priority 10) where the OS permits it, else niceness -10.")
@click.option("--quiet", is_flag=True, help="Print only the run folder.")
@click.option("--open-bus", is_flag=True,
              help="No authentication or access rules (any local process can join and command "
                   "the run). Default: per-run credentials and rules, locked down.")
@click.option("--clock-offset", "clock_offsets", multiple=True, hidden=True,
              metavar="NODE=OFFSET_S[:DRIFT_PPM]",
              help="Test hook: NODE's process runs on CLOCK_MONOTONIC + OFFSET_S, drifting "
                   "DRIFT_PPM (repeat; docs/multiprocess.md, \"Clocks across machines\").")
@_zenoh_options
def launch(scenario: Path, out_dir: Path | None, listen: str, restart: bool, kills: tuple[str, ...],
           stalls: tuple[str, ...], restart_nodes: tuple[str, ...], credentials: str | None, no_plot: bool, rt_priority: bool, quiet: bool, open_bus: bool,
           clock_offsets: tuple[str, ...], zenoh_config: str | None, user: str | None,
           allow_remote: bool, vehicle: str) -> None:
    """Run SCENARIO with every server in its own process, in wall-clock time."""
    from overdrive.observe.run_files import OutDirError, make_out_dir
    from overdrive.run.launch import Launch, check_launchable
    from overdrive.run.sim import default_out_dir
    from overdrive.scenario.schema import ScenarioError

    del user  # each process uses its node name
    loaded = _load(scenario)
    end_s = loaded.spec.duration_s
    actions = [*(_parse_action(k, "kill", "--kill", end_s) for k in kills),
               *(a for text in stalls for a in _parse_stall(text, end_s)),
               *(_parse_action(r, "restart", "--restart-node", end_s) for r in restart_nodes)]
    offsets: dict[str, tuple[float, float]] = {}
    for text in clock_offsets:
        name, sep, value = text.partition("=")
        if not sep:
            raise click.BadParameter(f"{text!r}: expected NODE=OFFSET_S[:DRIFT_PPM], e.g. speed=0.1")
        offsets[name] = _parse_clock(value)
    out = out_dir or default_out_dir(loaded)
    try:
        check_launchable(loaded)
        make_out_dir(out)
        run = Launch(loaded, out, listen=listen, vehicle=vehicle, restart=restart, actions=actions,
                     base_file=zenoh_config, credentials=credentials, allow_remote=allow_remote,
                     plot=not no_plot, node_log=True, secure=not open_bus, rt_priority=rt_priority,
                     clock_offsets=offsets,
                     display=None if quiet else (lambda line: click.echo(line, err=True)))
    except (ScenarioError, OutDirError, ValueError) as exc:
        _usage(str(exc))
        return
    except RuntimeError as exc:   # no free ports for the nodes
        click.echo(f"error: {exc}", err=True)
        raise SystemExit(EXIT_VIOLATION) from None
    interrupted = threading.Event()

    def on_signal(_signum: int, _frame: Any) -> None:
        interrupted.set()
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_signal)
    try:
        run.start()
        if not quiet:
            click.echo(f"launched {', '.join(run.names)} on {listen}; playing {loaded.name} "
                       f"({loaded.spec.duration_s:g} s)", err=True)
        result = run.run()
    except KeyboardInterrupt:
        click.echo("interrupted: stopping nodes", err=True)
        raise SystemExit(130) from None
    except RuntimeError as exc:
        click.echo(f"error: {exc}", err=True)
        raise SystemExit(EXIT_VIOLATION) from None
    finally:
        run.close()
    for line in result.summary["launch"].get("refused_to_engage", ()):
        click.echo(f"refused to engage: {line}", err=True)
    if quiet:
        click.echo(str(out))
    else:
        print_summary(result.summary, out)
    raise SystemExit(result.exit_code)


def _run_access(run_dir: Path | None, connect: tuple[str, ...], vehicle: str, user: str | None,
                wait_s: float = CONNECT_WAIT_S) -> tuple[tuple[str, ...], str, str | None, str | None]:
    """``(connect, vehicle, user, password)``: from ``--run`` (a locked-down launch's tool
    credentials, waited for ``wait_s``: the run may be starting) when given, else from the
    options and ``$OVERDRIVE_ZENOH_PASSWORD``."""
    if run_dir is None:
        return connect, vehicle, user, os.environ.get(PASSWORD_ENV)
    deadline = time.monotonic() + wait_s
    while True:
        try:
            creds = read_tool_credentials(run_dir)
            break
        except FileNotFoundError as exc:
            if time.monotonic() > deadline:
                click.echo(f"error: --run {run_dir}: {exc}", err=True)
                raise SystemExit(EXIT_VIOLATION) from None
            time.sleep(0.1)
        except (OSError, ValueError, KeyError) as exc:
            _usage(f"--run {run_dir}: {exc}")
            raise AssertionError from exc   # unreachable: _usage exits
    return connect or (creds["endpoint"],), creds["vehicle"], creds["user"], creds["password"]


def _client(connect: tuple[str, ...], sender: str, vehicle: str, zenoh_config: str | None,
            user: str | None, allow_remote: bool, wait_s: float = CONNECT_WAIT_S,
            password: str | None = None) -> Any:
    """A client session to a running launch; retries for ``wait_s`` (it may be starting)."""
    from overdrive.run.launch import stack_registry

    deadline = time.monotonic() + wait_s
    while True:
        try:
            return open_bus(sender=sender, mode="client", connect=connect or (DEFAULT_ENDPOINT,),
                            vehicle=vehicle, registry=stack_registry(), base_file=zenoh_config,
                            user=user, password=password, allow_remote=allow_remote,
                            publishers=None)
        except ValueError:
            raise
        except Exception:               # ZError: nothing listening yet
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


@click.command()
@click.argument("topic")
@click.argument("data")
@click.option("--type", "type_name", help="Message type (default: the topic's type).")
@click.option("--as", "sender", default="cli", show_default=True,
              help="Sender name in the envelope (the receivers' publisher policy applies).")
@click.option("--count", type=click.IntRange(min=1), default=1, show_default=True)
@click.option("--rate", "rate_hz", type=click.FloatRange(min=0.0, min_open=True), default=10.0,
              show_default=True, help="Publications per second when --count > 1.")
@click.option("--wait-s", type=click.FloatRange(min=0.0), default=3.0, show_default=True,
              help="Wait this long for a subscriber before publishing.")
@click.option("--connect", multiple=True, help=f"Endpoint (default {DEFAULT_ENDPOINT}).")
@RUN_OPTION
@_zenoh_options
def pub(topic: str, data: str, type_name: str | None, sender: str, count: int, rate_hz: float,
        wait_s: float, connect: tuple[str, ...], run_dir: Path | None, zenoh_config: str | None,
        user: str | None, allow_remote: bool, vehicle: str) -> None:
    """Publish DATA (a JSON object) on TOPIC, like ``ros2 topic pub``.

    A locked-down launch (the default) admits a tool only with ``--run RUN_DIR`` and lets it
    write only ``events``; everything else is denied and counted in the run's summary."""
    from overdrive.run.launch import stack_registry

    registry = stack_registry()
    try:
        check_topic(topic)
        cls = registry.type_named(type_name) if type_name else registry.topic_types.get(topic)
    except (ValueError, KeyError):
        _usage(f"unknown topic or type: {topic!r} {type_name or ''}".rstrip())
        return
    if cls is None:
        _usage(f"topic {topic!r} has no fixed type; give --type")
        return
    try:
        msg = msgspec.json.decode(data.encode(), type=cls)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        _usage(f"DATA is not a valid {cls.__name__}: {exc}")
        return
    connect, vehicle, user, password = _run_access(run_dir, connect, vehicle, user,
                                                   max(wait_s, CONNECT_WAIT_S))
    try:
        bus = _client(connect, sender, vehicle, zenoh_config, user, allow_remote, wait_s=wait_s,
                      password=password)
    except Exception as exc:  # Zenoh raises ZError for refused links
        click.echo(f"error: cannot connect: {exc}{NO_LINK_HINT}", err=True)
        raise SystemExit(EXIT_VIOLATION) from None
    try:
        publisher = bus.session.declare_publisher(f"overdrive/{vehicle}/{topic}")
        deadline = time.monotonic() + wait_s
        while not publisher.matching_status and time.monotonic() < deadline:
            time.sleep(0.01)
        matched = publisher.matching_status
        publisher.undeclare()
        for i in range(count):
            bus.publish(topic, msg)
            if i + 1 < count:
                time.sleep(1.0 / rate_hz)
        time.sleep(0.05)   # let the last frame leave before the session closes
    finally:
        bus.close()
    click.echo(f"published {count} x {cls.__name__} on {topic} as {sender!r}"
               + ("" if matched else " (no subscriber was seen)"), err=True)


@click.command()
@click.argument("topic")
@click.option("--count", type=click.IntRange(min=1), help="Exit after this many messages.")
@click.option("--timeout-s", type=click.FloatRange(min=0.0, min_open=True),
              help="Exit (code 1 if nothing came) after this long.")
@click.option("--connect", multiple=True, help=f"Endpoint (default {DEFAULT_ENDPOINT}).")
@RUN_OPTION
@_zenoh_options
def echo(topic: str, count: int | None, timeout_s: float | None, connect: tuple[str, ...],
         run_dir: Path | None, zenoh_config: str | None, user: str | None, allow_remote: bool,
         vehicle: str) -> None:
    """Print messages on TOPIC as JSON lines, like ``ros2 topic echo`` (``**`` matches all).

    A locked-down launch (the default) admits a tool only with ``--run RUN_DIR``."""
    if not topic or "//" in topic or topic.startswith("/"):
        _usage(f"invalid topic {topic!r}")
    connect, vehicle, user, password = _run_access(
        run_dir, connect, vehicle, user, timeout_s if timeout_s is not None else CONNECT_WAIT_S)
    prefix = f"overdrive/{vehicle}/"
    try:
        bus = _client(connect, "echo", vehicle, zenoh_config, user, allow_remote,
                      wait_s=timeout_s if timeout_s is not None else CONNECT_WAIT_S,
                      password=password)
    except Exception as exc:
        click.echo(f"error: cannot connect: {exc}{NO_LINK_HINT}", err=True)
        raise SystemExit(EXIT_VIOLATION) from None
    lines: list[bytes] = []
    lock = threading.Lock()
    got = threading.Event()
    bad = [0]

    def on_sample(sample: Any) -> None:
        key = str(sample.key_expr)
        name = key[len(prefix):]
        if name.startswith(ALIVE + "/"):
            return
        try:
            sender, msg = bus.registry.decode(sample.payload.to_bytes(), name)
        except WireError as exc:
            with lock:
                bad[0] += 1
            click.echo(f"undecodable frame on {name}: {exc}", err=True)
            return
        line = msgspec.json.encode({"topic": name, "type": type(msg).__name__, "sender": sender,
                                    "data": msg})
        with lock:
            lines.append(line)
        got.set()

    subscriber = bus.session.declare_subscriber(prefix + topic, on_sample)
    deadline = None if timeout_s is None else time.monotonic() + timeout_s
    printed = 0
    out = sys.stdout
    try:
        while count is None or printed < count:
            remaining = None if deadline is None else deadline - time.monotonic()
            if remaining is not None and remaining <= 0:
                break
            got.wait(0.1 if remaining is None else min(0.1, remaining))
            with lock:
                batch, lines[:] = lines[:], []
                got.clear()
            for line in batch:
                if count is not None and printed >= count:
                    break
                out.write(line.decode() + "\n")
                printed += 1
            out.flush()
    except KeyboardInterrupt:
        pass
    finally:
        subscriber.undeclare()
        bus.close()
    raise SystemExit(EXIT_OK if printed or timeout_s is None else EXIT_VIOLATION)


@click.command(hidden=True)
@click.option("--public", required=True, help="The run's public endpoint, for tools.")
@click.option("--listen", required=True, help="Private endpoint the launcher dials.")
@click.option("--connect", multiple=True, help="Node endpoints to dial (repeat).")
@click.option("--access", "access_dir", required=True,
              type=click.Path(file_okay=False, exists=True, path_type=Path))
@click.option("--report", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--ready", "ready_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Written once both sessions listen (the launcher waits for it).")
@click.option("--vehicle", default=DEFAULT_VEHICLE, show_default=True)
@click.option("--allow-remote", is_flag=True)
def gate(public: str, listen: str, connect: tuple[str, ...], access_dir: Path,
         report: Path | None, ready_path: Path | None, vehicle: str, allow_remote: bool) -> None:
    """The tool gate of a locked-down launch (started by ``overdrive launch``)."""
    from overdrive.run.launch import stack_registry

    try:
        for endpoint in (public, listen, *connect):
            _check_endpoint(endpoint, allow_remote)
    except ValueError as exc:
        _usage(str(exc))
    raise SystemExit(run_tool_gate(
        public=public, listen=listen, connect=list(connect), vehicle=vehicle,
        access_dir=access_dir, registry=stack_registry(), report_path=report,
        password=os.environ.get(PASSWORD_ENV, ""), ready_path=ready_path))


@click.group()
def _main() -> None:
    """overdrive bus commands (node, launch, pub, echo)."""


for _command in (node, launch, pub, echo, gate):
    _main.add_command(_command)

__all__ = ["echo", "launch", "node", "pub"]

if __name__ == "__main__":
    _main()
