"""Multi-process runs over Zenoh: one node per process, a launcher that supervises and records.

``overdrive node NAME`` runs one server (``run_node``); ``overdrive launch SCENARIO`` (``Launch``)
starts the nodes a scenario needs as processes on this machine, plays the scenario in wall-clock
time from its own process, records the run from the bus and writes the same run folder as
``overdrive sim``. See docs/multiprocess.md.

Topology: Zenoh 1.x peers do not forward between other peers, and scouting is off, so the
processes form an explicit full mesh on loopback. Each node listens on its own port and connects
to the nodes before it in ``MESH_ORDER``; the launcher comes last, connects to every node, and
listens on the public endpoint (default ``tcp/127.0.0.1:7447``) where ``overdrive pub``/``echo``
attach as clients. The later process always dials the earlier one, so each link's listener is
the side receiving commands and can authenticate the dialler (Zenoh user/password identifies
the connecting side only).

Time: the launcher publishes a ``LaunchClock`` (the run's epoch on CLOCK_MONOTONIC, which is one
clock for every process on the machine) at 10 Hz. Nodes wait for it, then step on
``now_s = monotonic() - epoch``: every process shares the scenario's time axis (sensor-fault
windows, channel-fault windows and recorded events line up), and a restarted node rejoins on
the same axis. Channel faults are applied by the process that publishes the faulted topic.
"""

from __future__ import annotations

import contextlib
import faulthandler
import json
import math
import os
import random
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import msgspec

from overdrive.bus.access import (
    GATE_USER,
    LAUNCHER_USER,
    LOG_FILTER,
    TOOL_TOPICS,
    RunAccess,
    count_refused_links,
)
from overdrive.bus.wire import Registry
from overdrive.bus.zenoh_bus import DEFAULT_ENDPOINT, DEFAULT_VEHICLE, ZenohBus, open_bus
from overdrive.observe.judge import DELIVERED_TOPICS
from overdrive.observe.recorder import Recorder
from overdrive.observe.run_files import finite_json
from overdrive.run.compose import build_nodes
from overdrive.run.sim import add_judgement, make_monitor, make_summary
from overdrive.runtime.lockstep import DEFAULT_PERIOD_S, Node
from overdrive.runtime.wall import WallRuntime
from overdrive.scenario.player import ScenarioPlayer, channel_faults, world_from_spec
from overdrive.scenario.schema import Scenario, ScenarioError, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.plant import ActuatorFaults, World
from overdrive.vehicle.sim_node import (
    COMMAND_TIMEOUT_S,
    WORLD_TOPIC,
    EngineStall,
    SensorFault,
    VehicleSim,
)

CLOCK_TOPIC = "launch/clock"
CLOCK_PERIOD_S = 0.1            # a (re)started node waits at most this long for the epoch
START_LEAD_S = 0.3              # epoch this far ahead of the first clock message: all nodes start at t=0
READY_TIMEOUT_S = 20.0          # nodes must be up (liveliness) within this
STOP_GRACE_S = 10.0             # SIGTERM -> SIGKILL of the process group (a loaded host needs time)
DUMP_SIGNAL = signal.SIGUSR1    # a node still up after the grace dumps every thread's stack first
DUMP_WAIT_S = 0.5               # (faulthandler: needs no GIL, so it works in a wedged process)
JUDGE_LAG_S = 1.0
"""The monitor judges a multi-process run by the frames' send stamps, this far behind the wall
clock: evidence still in flight on a loaded host has arrived by then, so a late delivery to the
launcher is never taken for a late emergency stop (the last second of a run is not judged)."""
RUN_NICE = -10
"""Niceness of a run's processes where the OS permits raising it (root or CAP_SYS_NICE): on a
busy host the CFS scheduler then gives a 10 ms control loop ~10x the share of a default-priority
busy loop, so nodes are not starved into watchdog stops; without the permission, unchanged."""
NODE_RT_PRIORITY = 10
"""``SCHED_FIFO`` priority of a node's process (every thread) where the OS permits it (root,
``CAP_SYS_NICE``, or ``RLIMIT_RTPRIO`` >= 10), as openpilot runs its control processes: a node that
wakes for its step or a command runs at once instead of waiting for the CFS to pick it among busy
processes (at nice -10, launches under two busy loops still saw nodes stalled 65-87 ms and watchdog
stops). Low among real-time priorities, below the kernel's threaded interrupts (50). Set after the
imports (start-up is a CPU burst that must not hold running nodes back: FIFO has no time slice)."""
NODE_RT_CPU_LIMIT_S = (0.5, 1.0)
"""``RLIMIT_RTTIME`` (soft, hard) of a real-time node: a thread that runs this long without
blocking gets SIGXCPU, which ends the process (then SIGKILL at the hard limit); a node steps every
10 ms for well under a millisecond and sleeps between steps, so only a runaway hits it. The
kernel's real-time throttling alone would leave the rest of the host 5 % of a CPU meanwhile, and a
dead node is what the watchdogs are for."""
NODE_SPIN_S = 0.0                # no busy-wait in node processes: on a loaded host the CPU is
                                 # better left to the others (sleep overshoot ~0.1 ms << 10 ms)
VEHICLE_COMMAND_TIMEOUT_S = COMMAND_TIMEOUT_S  # the vehicle brakes on pedal-command silence (VehicleSim)

NODE_CLASSES = {             # CLI name -> node name (the bus sender) as built by sim.build_nodes
    "vehicle-sim": "vehicle",
    "speed": "speed",
    "driving": "driving",
    "move": "move",
}
UNAVAILABLE = {"xgv-client": "the XGV client (JAUS) is not available in this build yet (issue 9)"}
MESH_ORDER = ("vehicle-sim", "speed", "driving", "move")
"""Command receivers first: each process dials those before it (see module doc)."""

_PULL_IN = {  # a minimal event that makes sim.build_nodes include the node, for --preset runs
    "vehicle-sim": {"at_s": 0, "engine": "off"},
    "speed": {"at_s": 0, "set_speed": {"speed_mps": 0, "accel_mps2": 1, "gear": "__park__",
                                       "state": "paused"}},
    "driving": {"at_s": 0, "max_speed": {"source": "cli", "speed_mps": 1}},
    "move": {"at_s": 0, "stop": {}},
}


class LaunchClock(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The run's epoch: ``now_s = CLOCK_MONOTONIC - epoch_monotonic_s`` in every process."""

    epoch_monotonic_s: float
    scenario: str
    duration_s: float


def stack_registry() -> Registry:
    """Stack messages plus the simulator's control types and the launch clock."""
    registry = Registry()
    registry.register(World, WORLD_TOPIC)
    for cls in (ActuatorFaults, SensorFault, EngineStall):
        registry.register(cls)
    registry.register(LaunchClock, CLOCK_TOPIC)
    return registry


LISTEN_PORTS: Final = (20000, 32768)
"""Where listening ports are picked: below Linux's default ephemeral range (32768-60999), from
which the kernel takes both ``bind(port 0)`` answers and the source ports of outgoing
connections. A port picked there could be handed out twice, or taken by a peer's dial before
the node binds it (seen under load: the speed node could not listen and the run failed)."""


def _ephemeral_range() -> tuple[int, int]:
    try:
        lo, hi = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
        return int(lo), int(hi)
    except (OSError, ValueError):
        return 32768, 60999


WINDOW_TRIES: Final = 500   # random picks in LISTEN_PORTS before falling back to bind(0)


def free_ports(count: int, taken: frozenset[int] = frozenset()) -> list[int]:
    """``count`` distinct TCP ports free on 127.0.0.1 now: in ``LISTEN_PORTS`` outside the
    ephemeral range, and where too few of those are free (a host whose ephemeral range covers
    the window), distinct ports from ``bind(port 0)``."""
    eph_lo, eph_hi = _ephemeral_range()
    pick = random.SystemRandom()   # not the scenario's seeded RNG: ports never reach a trace
    ports: list[int] = []
    for attempt in range(WINDOW_TRIES + 2000):
        in_window = attempt < WINDOW_TRIES
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("127.0.0.1", pick.randrange(*LISTEN_PORTS) if in_window else 0))
            except OSError:
                continue
            port = s.getsockname()[1]
        if port in ports or port in taken or (in_window and eph_lo <= port <= eph_hi):
            continue
        ports.append(port)
        if len(ports) == count:
            return ports
    raise RuntimeError(f"could not find {count} free TCP ports on 127.0.0.1")


def _endpoint_port(endpoint: str) -> int | None:
    """The port of a ``tcp/HOST:PORT`` endpoint, else None."""
    _, _, port = (endpoint or "").rpartition(":")
    return int(port) if port.isdigit() else None


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now, outside the ephemeral range (``free_ports``)."""
    return free_ports(1)[0]


# --------------------------------------------------------------------------- nodes

def preset_scenario(cli_name: str, preset: str, start: str = "parked") -> Scenario:
    """A stand-in scenario for running one node without a scenario file."""
    event = json.loads(json.dumps(_PULL_IN[cli_name]))
    if "set_speed" in event:
        event["set_speed"]["gear"] = PRESETS[preset].park_gear if preset in PRESETS else "park"
    return parse_scenario({"name": f"node-{cli_name}", "vehicle": preset, "start": start,
                           "duration_s": 1, "events": [event]}, f"<node {cli_name}>")


def scenario_node_names(scenario: Scenario) -> list[str]:
    """The CLI names of the server processes ``scenario`` needs, in mesh order."""
    built = {n.name for n in build_nodes(scenario)}
    return [cli for cli in MESH_ORDER if NODE_CLASSES[cli] in built]


def build_node(cli_name: str, scenario: Scenario) -> Node:
    """The node ``cli_name`` exactly as ``overdrive sim`` builds it for ``scenario``."""
    if cli_name in UNAVAILABLE:
        raise ScenarioError(scenario.source, "node", UNAVAILABLE[cli_name])
    if cli_name not in NODE_CLASSES:
        raise ScenarioError(scenario.source, "node", f"unknown node {cli_name!r}; one of "
                            + ", ".join([*NODE_CLASSES, *UNAVAILABLE]))
    wanted = NODE_CLASSES[cli_name]
    for node in build_nodes(scenario):
        if node.name == wanted:
            return node
    raise ScenarioError(scenario.source, "events",
                        f"this scenario does not use the {cli_name} node")


# --------------------------------------------------------------------------- one node process

def _channel_faults(scenario: Scenario) -> Any:
    return channel_faults(scenario)


def wait_for_clock(bus: ZenohBus, timeout_s: float | None = None,
                   stop: threading.Event | StopFlag | None = None) -> LaunchClock | None:
    """Block until a ``LaunchClock`` arrives (None on timeout or ``stop``)."""
    inbox = bus.subscribe([CLOCK_TOPIC])
    deadline = math.inf if timeout_s is None else time.monotonic() + timeout_s
    while time.monotonic() < deadline and not (stop and stop.is_set()):
        if bus.pull:
            bus.pump()
        for _topic, msg in inbox.drain():
            if isinstance(msg, LaunchClock):
                return msg
        time.sleep(0.005)
    return None


class StopFlag:
    """Set by a signal handler: a plain attribute, no lock. A ``threading.Event`` deadlocked a
    node at stop: the launcher's second SIGTERM arrived while the first handler held the Event's
    lock in ``set()``, and the second handler waited on it forever (faulthandler dump)."""

    def __init__(self) -> None:
        self.flag = False

    def set(self) -> None:
        self.flag = True

    def is_set(self) -> bool:
        return self.flag


def run_node(cli_name: str, scenario: Scenario, *, listen: Sequence[str] = (),
             connect: Sequence[str] = (), mode: str = "peer", vehicle: str = DEFAULT_VEHICLE,
             wait_clock: bool = False, report_path: Path | None = None,
             base_file: str | Path | None = None, user: str | None = None,
             password: str | None = None, allow_remote: bool = False,
             duration_s: float | None = None, rt_priority: bool = True) -> int:
    """Run one node until SIGTERM/SIGINT (or ``duration_s``); write a JSON report. Returns 0.
    ``rt_priority``: ``SCHED_FIFO`` (``NODE_RT_PRIORITY``) where permitted, else ``RUN_NICE``."""
    node = build_node(cli_name, scenario)
    stop = StopFlag()
    runtime_box: list[WallRuntime] = []

    def on_signal(_signum: int, _frame: Any) -> None:
        stop.set()
        if runtime_box:
            runtime_box[0].stop()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    faulthandler.register(DUMP_SIGNAL, all_threads=True)   # the launcher asks before it kills
    if user is not None:        # an authenticated run: log refused links (counted by the launcher)
        import zenoh

        zenoh.init_log_from_env_or(LOG_FILTER)
    node_priority(rt_priority)                   # before the session: its threads inherit it
    bus = open_bus(sender=node.name, mode=mode, listen=listen, connect=connect, vehicle=vehicle,
                   registry=stack_registry(), base_file=base_file, user=user, password=password,
                   allow_remote=allow_remote)
    faults = _channel_faults(scenario)
    bus.channel = faults
    # the plant integrates at its fixed period; servers step at once on a command (issue 20)
    runtime = WallRuntime([node], bus, event_driven=not isinstance(node, VehicleSim),
                          spin_s=NODE_SPIN_S)
    runtime_box.append(runtime)
    bus.announce(node.name)
    started = time.monotonic()
    clock: LaunchClock | None = None
    try:
        if wait_clock:
            clock = wait_for_clock(bus, stop=stop)
            if clock is None:
                return 0
            runtime.start_s = clock.epoch_monotonic_s
        if not stop.is_set():
            runtime.run(duration_s, on_tick=lambda t: setattr(faults, "now_s", t))
    finally:
        report = {
            "node": cli_name, "name": node.name, "pid": os.getpid(),
            "uptime_s": round(time.monotonic() - started, 3),
            "scheduling": scheduling(),
            "epoch_monotonic_s": clock.epoch_monotonic_s if clock else None,
            "runtime": runtime.stats().get(node.name, {}),
            "bus": bus.stats.as_dict(),
            "channel_faults": {k: v for k, v in faults.counts.items() if v},
        }
        if isinstance(node, VehicleSim):
            report["gate_interventions"] = dict(sorted(node.gate_interventions.items()))
            report["command_timeouts"] = node.command_timeouts
        if report_path is not None:    # before closing: a slow session close may be killed
            report_path.parent.mkdir(parents=True, exist_ok=True)
            tmp = report_path.with_suffix(".tmp")
            tmp.write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
            tmp.replace(report_path)
        bus.close()
    return 0


# --------------------------------------------------------------------------- the launcher

def raise_priority() -> int | None:
    """Run this thread (and the threads it starts later) at ``RUN_NICE`` when the OS allows it;
    the previous niceness, else None. On Linux niceness is per thread."""
    try:
        before = os.getpriority(os.PRIO_PROCESS, 0)
        if before > RUN_NICE:
            os.setpriority(os.PRIO_PROCESS, 0, RUN_NICE)
        return before
    except (OSError, AttributeError):   # not permitted (no CAP_SYS_NICE) or not POSIX: as is
        return None


def realtime_priority(priority: int = NODE_RT_PRIORITY) -> bool:
    """Run this thread (and the threads it starts later: call it before any) ``SCHED_FIFO`` at
    ``priority``, with ``NODE_RT_CPU_LIMIT_S``, where the OS permits it; True if it does."""
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_RTTIME,
                           tuple(round(s * 1e6) for s in NODE_RT_CPU_LIMIT_S))
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, ValueError, AttributeError, ImportError):  # not permitted, or not Linux: as is
        return False
    return True


def node_priority(rt_priority: bool = True) -> None:
    """A node's priority: ``SCHED_FIFO`` if ``rt_priority`` and permitted, else ``RUN_NICE`` if
    permitted, else as started."""
    if not (rt_priority and realtime_priority()):
        raise_priority()


def scheduling() -> str:
    """How the OS schedules this process's threads, for reports: ``fifo:10``,
    ``other:nice=-10``, or several joined by ``,`` when the threads differ."""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = [0]
    seen = set()
    for tid in tids:
        try:
            policy = os.sched_getscheduler(tid)
            if policy in (os.SCHED_FIFO, os.SCHED_RR):
                name = "fifo" if policy == os.SCHED_FIFO else "rr"
                seen.add(f"{name}:{os.sched_getparam(tid).sched_priority}")
            else:
                seen.add(f"other:nice={os.getpriority(os.PRIO_PROCESS, tid)}")
        except ProcessLookupError:    # a thread that ended meanwhile
            continue
        except (OSError, AttributeError):
            seen.add("unknown")
    return ",".join(sorted(seen))


def _node_child() -> None:
    """In a node's child process: ``RUN_NICE`` where permitted (the node goes real-time itself,
    after its imports), die with the launcher."""
    raise_priority()
    _die_with_parent()


def _die_with_parent() -> None:
    """In the child: get SIGTERM when the launcher dies, even by SIGKILL (Linux)."""
    if sys.platform.startswith("linux"):
        import ctypes

        PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


class _ClockNode:
    """Launcher node: publishes the run's epoch every 100 ms and supervises the processes."""

    name = "launch"
    period_s = CLOCK_PERIOD_S
    subscriptions: tuple[str, ...] = ()

    def __init__(self, clock: LaunchClock, supervise: Callable[[float], None]) -> None:
        self.clock, self.supervise = clock, supervise

    def step(self, now_s: float, _inbox: Sequence[tuple[str, Any]]) -> list[tuple[str, Any]]:
        self.supervise(now_s)
        return [(CLOCK_TOPIC, self.clock)]


@dataclass
class NodeProcess:
    cli_name: str
    listen: str
    connect: list[str]
    report: Path
    popen: subprocess.Popen | None = None
    starts: int = 0
    exits: list[dict[str, Any]] = field(default_factory=list)
    expected_exit: bool = False
    restart_at_s: float | None = None
    killed_at_stop: bool = False


@dataclass
class LaunchResult:
    summary: dict[str, Any]
    exit_code: int
    out_dir: Path | None
    reports: dict[str, dict[str, Any]]


Action = tuple[float, str, str]
"""``(at_s, "kill" | "term" | "restart", node)``: supervisor actions at scenario times."""


class Launch:
    """Start, supervise and stop a scenario's node processes; play and record the scenario."""

    def __init__(self, scenario: Scenario, out_dir: str | Path | None = None, *,
                 listen: str = DEFAULT_ENDPOINT, vehicle: str = DEFAULT_VEHICLE,
                 python: str = sys.executable, restart: bool = False,
                 restart_delay_s: float = 0.5, actions: Sequence[Action] = (),
                 base_file: str | Path | None = None, credentials: str | Path | None = None,
                 allow_remote: bool = False, plot: bool = True,
                 node_log: bool = False, secure: bool = True, rt_priority: bool = True) -> None:
        self.scenario = scenario
        self.rt_priority = rt_priority
        """Nodes run ``SCHED_FIFO`` where permitted (``node_priority``); False: niceness only."""
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.listen, self.vehicle, self.python = listen, vehicle, python
        self.restart, self.restart_delay_s = restart, restart_delay_s
        self.actions = sorted(actions)
        self.base_file, self.credentials, self.allow_remote = base_file, credentials, allow_remote
        self.plot = plot
        self.node_log = node_log
        self.secure = secure and base_file is None and credentials is None
        """Generated per-run credentials and rules (the default; issue 18), unless the caller
        brings its own Zenoh config or credentials, or asks for an open bus."""
        for _at, what, _name in self.actions:
            if what not in ("kill", "term", "restart"):
                raise ValueError(f"unknown action {what!r}")
        check_launchable(scenario)
        self.names = scenario_node_names(scenario)
        for _at, _what, name in self.actions:
            if name not in self.names:
                raise ScenarioError(scenario.source, "node",
                                    f"{name!r} is not a process of this run ({', '.join(self.names)})")
        self._tmp: Any = None
        work = self.out_dir if self.out_dir is not None else Path(self._tmpdir())
        self.work_dir = work
        self.procs: dict[str, NodeProcess] = {}
        endpoints: list[str] = []
        public = _endpoint_port(self.listen)
        ports = free_ports(len(self.names) + 1, frozenset({public} if public else ()))
        for cli, port in zip(self.names, ports[:-1], strict=True):
            endpoint = f"tcp/127.0.0.1:{port}"
            self.procs[cli] = NodeProcess(cli, endpoint, list(endpoints), work / "nodes" / f"{cli}.json")
            endpoints.append(endpoint)
        self.access: RunAccess | None = None
        self.gate_listen = f"tcp/127.0.0.1:{ports[-1]}" if self.secure and self.listen else ""
        self.gate: subprocess.Popen | None = None
        self._niceness: int | None = None    # the launcher's own before start(), to restore
        self._nice_tid = 0                   # ... on the thread that called start()
        if self.secure:
            import secrets

            self.access = RunAccess.generate(work / "nodes" / "access",
                                             [NODE_CLASSES[n] for n in self.names],
                                             lambda: secrets.token_urlsafe(24))
        self.bus: ZenohBus | None = None
        self.alive: dict[str, bool] = {}
        self.events: list[dict[str, Any]] = []
        self.violations: list[str] = []
        self.now_s = 0.0
        self.recorder: Any = None
        """The run's Recorder while ``run`` plays (``on_tick`` may read ``recorder.latest``)."""
        self._scenario_path: Path | None = None

    def _tmpdir(self) -> str:
        import tempfile

        self._tmp = tempfile.TemporaryDirectory(prefix="overdrive-launch-")
        return self._tmp.name

    # ------------------------------------------------------------------ processes

    def _credentials_for(self, name: str) -> str | None:
        if self.access is not None:
            return self.access.password(name)
        if self.credentials is None:
            return None
        for line in Path(self.credentials).read_text(encoding="utf-8").splitlines():
            user, _, password = line.strip().partition(":")
            if user == name:
                return password
        raise ValueError(f"{self.credentials}: no credentials for {name!r}")

    def _spawn(self, proc: NodeProcess) -> None:
        assert self._scenario_path is not None
        cmd = [self.python, "-m", "overdrive.cli.bus", "node", proc.cli_name,
               "--scenario", str(self._scenario_path), "--listen", proc.listen,
               "--vehicle", self.vehicle, "--wait-clock", "--report", str(proc.report)]
        for endpoint in proc.connect:
            cmd += ["--connect", endpoint]
        base_file = self.access.mesh_config if self.access is not None else self.base_file
        if base_file is not None:
            cmd += ["--zenoh-config", str(base_file)]
        if self.allow_remote:
            cmd.append("--allow-remote")
        if not self.rt_priority:
            cmd.append("--no-rt-priority")
        env = dict(os.environ)
        node_name = NODE_CLASSES[proc.cli_name]
        password = self._credentials_for(node_name)
        if password is not None:
            cmd += ["--user", node_name]
            env["OVERDRIVE_ZENOH_PASSWORD"] = password
        with contextlib.suppress(FileNotFoundError):
            proc.report.unlink()
        with contextlib.ExitStack() as stack:
            log: Any = subprocess.DEVNULL
            if self.node_log or self.access is not None:   # refused links are counted from it
                log = stack.enter_context(open(self.work_dir / "nodes" / f"{proc.cli_name}.log", "ab"))
            proc.popen = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                          stderr=subprocess.STDOUT if self.node_log else None,
                                          env=env, start_new_session=True,
                                          preexec_fn=_node_child)
        proc.starts += 1
        proc.expected_exit = False
        proc.restart_at_s = None

    @property
    def _gate_ready(self) -> Path:
        return self.work_dir / "nodes" / "gate.ready"

    def _spawn_gate(self, connect: list[str]) -> None:
        """Start the tool gate: the run's public endpoint for pub/echo (``bus.tool_gate``)."""
        assert self.access is not None
        self._gate_ready.unlink(missing_ok=True)
        cmd = [self.python, "-m", "overdrive.cli.bus", "gate", "--public", self.listen,
               "--listen", self.gate_listen, "--vehicle", self.vehicle,
               "--access", str(self.access.folder),
               "--report", str(self.work_dir / "nodes" / "gate.json"),
               "--ready", str(self._gate_ready)]
        for endpoint in connect:
            cmd += ["--connect", endpoint]
        if self.allow_remote:
            cmd.append("--allow-remote")
        env = {**os.environ, "OVERDRIVE_ZENOH_PASSWORD": self.access.password(GATE_USER)}
        with open(self.work_dir / "nodes" / "gate.log", "ab") as log:
            self.gate = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log,
                                         stderr=subprocess.STDOUT,
                                         env=env, start_new_session=True,
                                         preexec_fn=_die_with_parent)

    def access_report(self) -> dict[str, Any]:
        """What the run's access control refused: links without valid credentials (from the
        processes' logs) and tool publications the gate denied (from its report)."""
        if self.access is None:
            return {"mode": "open" if self.base_file is None and self.credentials is None
                    else "user-supplied config"}
        nodes = self.work_dir / "nodes"
        refused = {}
        for log in sorted(nodes.glob("*.log")):
            with contextlib.suppress(OSError):
                n = count_refused_links(log.read_text(encoding="utf-8", errors="replace"))
                if n:
                    refused[log.stem] = n
        gate: dict[str, Any] = {}
        with contextlib.suppress(FileNotFoundError, json.JSONDecodeError):
            gate = json.loads((nodes / "gate.json").read_text(encoding="utf-8"))
        denied = gate.get("denied", {})
        return {"mode": "locked-down (per-run credentials and access rules)",
                "tool_topics": sorted(TOOL_TOPICS), "refused_links": refused,
                "tool_admitted": gate.get("admitted", 0), "tool_denied": denied,
                "attempts_refused": sum(refused.values()) + sum(denied.values()),
                "gate_report": bool(gate) or not self.gate_listen}

    def _event(self, kind: str, **fields: Any) -> None:
        self.events.append({"t_s": round(self.now_s, 4), "kind": kind, **fields})

    def signal_node(self, name: str, sig: int = signal.SIGKILL) -> None:
        """Send ``sig`` to a node's process group (SIGKILL: the fault-injection kill)."""
        popen = self.procs[name].popen
        if popen is not None and popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(popen.pid, sig)
            self._event("process_signal", node=name, signal=signal.Signals(sig).name.lower())

    def restart_node(self, name: str) -> None:
        proc = self.procs[name]
        if proc.popen is not None and proc.popen.poll() is None:
            self._stop_proc(proc)
        self._spawn(proc)
        self._event("process_restart", node=name, pid=proc.popen.pid if proc.popen else None)

    def _supervise(self, now_s: float) -> None:
        self.now_s = now_s
        while self.actions and self.actions[0][0] <= now_s + 1e-9:
            _at, what, name = self.actions.pop(0)
            if what == "restart":
                self.restart_node(name)
            else:
                self.signal_node(name, signal.SIGKILL if what == "kill" else signal.SIGTERM)
        for name, proc in self.procs.items():
            popen = proc.popen
            if popen is not None and proc.restart_at_s is None:
                code = popen.poll()
                if code is not None:
                    how = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
                    proc.exits.append({"t_s": round(now_s, 4), "code": code})
                    self._event("process_exit", node=name, code=code, reason=how)
                    self.violations.append(f"process: {name} died ({how}) at t={now_s:.2f} s")
                    proc.restart_at_s = now_s + self.restart_delay_s if self.restart else math.inf
            if proc.restart_at_s is not None and now_s >= proc.restart_at_s:
                self._spawn(proc)
                self._event("process_restart", node=name, pid=proc.popen.pid if proc.popen else None)

    def _stop_proc(self, proc: NodeProcess, sig: int = signal.SIGTERM) -> None:
        popen = proc.popen
        if popen is None:
            return
        proc.expected_exit = True
        if popen.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(popen.pid, sig)
        try:
            popen.wait(STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            proc.killed_at_stop = True
            with contextlib.suppress(ProcessLookupError):   # where it hangs, on its stderr
                os.kill(popen.pid, DUMP_SIGNAL)
                time.sleep(DUMP_WAIT_S)
            with contextlib.suppress(ProcessLookupError):
                os.killpg(popen.pid, signal.SIGKILL)
            popen.wait(STOP_GRACE_S)
        with contextlib.suppress(ProcessLookupError):   # stragglers in the group
            os.killpg(popen.pid, signal.SIGKILL)

    # ------------------------------------------------------------------ lifecycle

    def start(self, ready_timeout_s: float = READY_TIMEOUT_S) -> None:
        """Write the scenario for the nodes, spawn them, open the launcher's session, wait ready.
        The launcher runs at ``RUN_NICE`` where permitted until ``close()``: raised before its
        session opens, since a thread's niceness is its own (Linux) and Zenoh's receiving threads
        inherit it; a starved launcher that stops reading its links holds back blocking puts."""
        if self._niceness is None:
            self._niceness, self._nice_tid = raise_priority(), threading.get_native_id()
        (self.work_dir / "nodes").mkdir(parents=True, exist_ok=True)
        self._scenario_path = self.work_dir / "nodes" / "scenario.json"
        self._scenario_path.write_bytes(msgspec.json.encode(msgspec.to_builtins(self.scenario.spec)))
        if self.access is not None:
            self.access.write(self.listen, self.vehicle)
        for proc in self.procs.values():
            self._spawn(proc)
        connect = [p.listen for p in self.procs.values()]
        if self.gate_listen:
            self._spawn_gate(connect)
            connect.append(self.gate_listen)
        password = self._credentials_for(LAUNCHER_USER)
        public = [self.listen] if self.listen and self.access is None else []  # else: the gate's
        try:
            self.bus = open_bus(
                sender=LAUNCHER_USER, listen=public, connect=connect, vehicle=self.vehicle,
                registry=stack_registry(),
                base_file=self.access.mesh_config if self.access is not None else self.base_file,
                user=LAUNCHER_USER if password is not None else None, password=password,
                allow_remote=self.allow_remote, pull=True)
        except ValueError:
            raise
        except Exception as exc:   # zenoh.ZError: e.g. the --listen port is taken
            raise RuntimeError(f"cannot open the launcher's session on {public or connect}: "
                               f"{exc}") from None
        lock = threading.Lock()
        alive: set[str] = set()
        changed = threading.Event()

        def on_alive(name: str, up: bool) -> None:
            with lock:
                (alive.add if up else alive.discard)(name)
            changed.set()

        self.bus.watch_alive(on_alive)
        wanted = {NODE_CLASSES[n] for n in self.names}
        deadline = time.monotonic() + ready_timeout_s
        while True:
            with lock:
                missing = wanted - alive
            if self.gate is not None and not self._gate_ready.exists():
                missing = missing | {"gate"}
            if not missing:
                return
            if self.gate is not None and self.gate.poll() is not None:
                raise RuntimeError(f"the tool gate exited during start-up (code "
                                   f"{self.gate.returncode}): is {self.listen} or "
                                   f"{self.gate_listen} taken? see nodes/gate.log")
            for proc in self.procs.values():
                if proc.popen is not None and proc.popen.poll() is not None:
                    raise RuntimeError(f"node {proc.cli_name} exited during start-up "
                                       f"(code {proc.popen.returncode})")
            if time.monotonic() > deadline:
                raise RuntimeError(f"nodes not up after {ready_timeout_s} s: {', '.join(sorted(missing))}")
            changed.wait(0.05)
            changed.clear()

    def run(self, on_tick: Callable[[float], None] | None = None) -> LaunchResult:
        """Play the scenario in wall-clock time, stop the nodes, write the run folder."""
        assert self.bus is not None, "call start() first"
        scenario, spec = self.scenario, self.scenario.spec
        faults = _channel_faults(scenario)
        self.bus.channel = faults
        out_path = self.out_dir
        with contextlib.ExitStack() as stack:
            trace_file = None
            if out_path is not None:
                out_path.mkdir(parents=True, exist_ok=True)
                trace_file = stack.enter_context(
                    open(out_path / "trace.csv", "w", encoding="utf-8", newline=""))
            recorder = self.recorder = Recorder(trace_file, keep_rows=False)
            monitor = make_monitor(scenario, DEFAULT_PERIOD_S)
            self.bus.tap(recorder.observe)
            epoch = time.monotonic() + START_LEAD_S

            def judge(topic: str, msg: Any, sent_s: float) -> None:
                """The monitor sees each message at its send time on the run's axis."""
                monitor.now_s = sent_s - epoch if math.isfinite(sent_s) else self.now_s
                monitor.observe(topic, msg)
                if topic in DELIVERED_TOPICS:
                    # across processes the launcher receives what crossed each process boundary
                    # after the publisher's channel faults: what the nodes were delivered too
                    monitor.observe_delivered(topic, msg)

            self.bus.tap_stamped(judge)
            clock = LaunchClock(epoch_monotonic_s=epoch, scenario=scenario.name,
                                duration_s=spec.duration_s)
            self.bus.publish(CLOCK_TOPIC, clock)
            player = ScenarioPlayer(scenario)
            runtime = WallRuntime([player, _ClockNode(clock, self._supervise)], self.bus)
            runtime.start_s = epoch

            def before(now_s: float) -> None:
                faults.now_s = recorder.now_s = now_s
                if on_tick is not None:
                    on_tick(now_s)

            def after(node: Node, now_s: float) -> None:
                if node is player:
                    recorder.tick(now_s)
                    monitor.now_s = now_s - JUDGE_LAG_S
                    monitor.tick(now_s - JUDGE_LAG_S)

            wall_start = time.monotonic()
            runtime.run(spec.duration_s, on_tick=before, after_step=after)
            wall_time_s = max(time.monotonic() - wall_start, 1e-9)
            self._supervise(runtime.now_s)
            reports = self.stop()
        stand_in = VehicleSim(scenario.vehicle, world_from_spec(spec.world), spec.seed)
        stand_in.gate_interventions = dict(reports.get("vehicle-sim", {}).get("gate_interventions", {}))
        channel_counts = dict(faults.counts)
        for report in reports.values():
            for kind, n in report.get("channel_faults", {}).items():
                channel_counts[kind] = channel_counts.get(kind, 0) + n
        recorder.events.extend(self.events)
        recorder.events.sort(key=lambda e: e["t_s"])
        summary = make_summary(scenario, recorder, spec.duration_s, wall_time_s, [stand_in],
                               monitor.finish(), channel_counts)
        summary["violations"].extend(self.violations)
        add_judgement(summary, monitor)
        summary["launch"] = {
            "mode": "multi-process (zenoh, wall clock)",
            "endpoint": self.listen,
            "processes": {name: {"listen": p.listen, "starts": p.starts, "exits": p.exits,
                                 "killed_at_stop": p.killed_at_stop,
                                 "report": name in reports}
                          for name, p in self.procs.items()},
            "launcher": {"runtime": runtime.stats(), "bus": self.bus.stats.as_dict()},
            "nodes": reports,
            "access": self.access_report(),
        }
        self.close()
        exit_code = 1 if summary["violations"] else 0
        if out_path is not None:
            (out_path / "summary.json").write_text(finite_json(summary), encoding="utf-8")
            if self.plot:
                from overdrive.observe.plot import plot_run

                plot_run(out_path / "trace.csv", out_path / "plot.png", summary)
        return LaunchResult(summary, exit_code, out_path, reports)

    def stop(self) -> dict[str, dict[str, Any]]:
        """Stop every node (SIGTERM, then SIGKILL) and collect their reports."""
        procs = list(self.procs.values())
        for proc in procs:
            proc.expected_exit = True
            if proc.popen is not None and proc.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.popen.pid, signal.SIGTERM)
        if self.gate is not None and self.gate.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.gate.pid, signal.SIGTERM)
        for proc in procs:
            self._stop_proc(proc)
        self._stop_gate()
        reports: dict[str, dict[str, Any]] = {}
        for name, proc in self.procs.items():
            with contextlib.suppress(FileNotFoundError, json.JSONDecodeError):
                reports[name] = json.loads(proc.report.read_text(encoding="utf-8"))
        return reports

    def _stop_gate(self, sig: int = signal.SIGTERM) -> None:
        gate = self.gate
        if gate is None:
            return
        with contextlib.suppress(ProcessLookupError):
            os.killpg(gate.pid, sig)
        try:
            gate.wait(STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(gate.pid, signal.SIGKILL)
            gate.wait(STOP_GRACE_S)

    def close(self) -> None:
        """Kill anything left, close the session and delete the run's credentials; safe to call
        more than once."""
        for proc in self.procs.values():
            if proc.popen is not None and proc.popen.returncode is None:
                self._stop_proc(proc, signal.SIGKILL)
        if self.gate is not None and self.gate.returncode is None:
            self._stop_gate(signal.SIGKILL)
        if self.bus is not None:
            self.bus.close()
            self.bus = None
        if self.access is not None:       # per-run credentials die with the run
            import shutil

            shutil.rmtree(self.access.folder, ignore_errors=True)
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        if self._niceness is not None and self._niceness != RUN_NICE:
            with contextlib.suppress(OSError):    # niceness is per thread: start()'s, wherever we are
                os.setpriority(os.PRIO_PROCESS, self._nice_tid, self._niceness)
        self._niceness = None

    def __enter__(self) -> Launch:
        return self

    def __exit__(self, *_exc: object) -> None:
        self.close()


def launch_scenario(scenario: Scenario, out_dir: str | Path | None = None, **kwargs: Any) -> LaunchResult:
    """Start, run and tear down a multi-process run of ``scenario``."""
    launch = Launch(scenario, out_dir, **kwargs)
    try:
        launch.start()
        return launch.run()
    finally:
        launch.close()


def check_launchable(scenario: Scenario) -> None:
    """Raise ScenarioError for what a multi-process run cannot do yet."""
    if scenario.spec.interface != "embedded":
        raise ScenarioError(scenario.source, "interface",
                            "overdrive launch runs the simulated vehicle; 'jaus' needs the XGV client")


__all__ = ["CLOCK_TOPIC", "MESH_ORDER", "NODE_CLASSES", "Launch", "LaunchClock", "LaunchResult",
           "build_node", "launch_scenario", "run_node",
           "scenario_node_names", "stack_registry"]
