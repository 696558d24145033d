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

Clocks across machines: every process bounds every other's clock offset from the stamps of the
frames it receives and the ``ClockReport``s they exchange (``servers.clock_offset``); stamps
reach a node converted to its clock (``runtime.wall``). The launcher plays nothing until every
pair of processes has an offset known within tolerance (``MAX_CLOCK_OFFSET_S``,
``MAX_CLOCK_UNCERTAINTY_S``), waiting at most ``CLOCK_SYNC_TIMEOUT_S``: otherwise the run ends,
failed, saying which pair and why. ``clock_offsets`` (``--clock-offset``) gives a node's process
another clock (a test hook: offset and drift).
"""

from __future__ import annotations

import contextlib
import faulthandler
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
from overdrive.messages import NodeTick, Notice, Topic
from overdrive.observe.display import DisplayLines
from overdrive.observe.judge import DELIVERED_TOPICS
from overdrive.observe.recorder import Recorder
from overdrive.observe.run_files import open_trace, write_summary
from overdrive.run.compose import build_nodes
from overdrive.run.sim import add_judgement, make_monitor, make_summary
from overdrive.runtime.lockstep import DEFAULT_PERIOD_S, Node
from overdrive.runtime.ports import endpoint_port, free_ports
from overdrive.runtime.processes import DUMP_SIGNAL, STOP_GRACE_S, StopFlag, stop_process_group
from overdrive.runtime.scheduling import (
    RUN_NICE,
    die_with_parent,
    node_child,
    node_priority,
    raise_priority,
    scheduling,
)
from overdrive.runtime.supervision import HANG_BOUND_S, Hung, Liveness, Resumed, TickNode
from overdrive.runtime.wall import ClockReporter, WallRuntime, skewed_clock
from overdrive.scenario.player import ScenarioPlayer, channel_faults, world_from_spec
from overdrive.scenario.schema import Scenario, ScenarioError, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.clock_offset import (
    CLOCK_REPORT_PERIOD_S,
    CLOCK_REPORT_TOPIC,
    MAX_CLOCK_OFFSET_S,
    MAX_CLOCK_UNCERTAINTY_S,
    ClockReport,
    PeerBound,
    describe_pair,
    pair_table,
)
from overdrive.vehicle.plant import ActuatorFaults, World
from overdrive.vehicle.sim_node import (
    COMMAND_TIMEOUT_S,
    WORLD_TOPIC,
    EngineStall,
    GpsStatus,
    SensorError,
    SensorFault,
    VehicleSim,
)

CLOCK_TOPIC = "launch/clock"
CLOCK_PERIOD_S = 0.1            # a (re)started node waits at most this long for the epoch
START_LEAD_S = 0.3              # epoch this far ahead of the first clock message: all nodes start at t=0
READY_TIMEOUT_S = 20.0          # nodes must be up (liveliness) within this
JUDGE_LAG_S = 1.0
"""The monitor judges a multi-process run by the frames' send stamps, this far behind the wall
clock: evidence still in flight on a loaded host has arrived by then, so a late delivery to the
launcher is never taken for a late emergency stop (the last second of a run is not judged)."""
NODE_SPIN_S = 0.0                # no busy-wait in node processes: on a loaded host the CPU is
                                 # better left to the others (sleep overshoot ~0.1 ms << 10 ms)
VEHICLE_COMMAND_TIMEOUT_S = COMMAND_TIMEOUT_S  # the vehicle brakes on pedal-command silence (VehicleSim)
CLOCK_SYNC_TIMEOUT_S = 5.0
"""The launcher waits this long for every pair of processes to have a clock offset known within
tolerance before it plays anything; then the run ends, failed (a few report periods suffice)."""
CLOCK_CHECK_PERIOD_S = 0.5       # the launcher re-judges the pairs' offsets this often during a run
LAUNCHER_NAME = "launcher"       # the launcher in the clock table (its bus sender: LAUNCHER_USER)

NODE_CLASSES = {             # CLI name -> node name (the bus sender) as built by run.compose.build_nodes
    "vehicle-sim": "vehicle",
    "speed": "speed",
    "driving": "driving",
    "move": "move",
}
UNAVAILABLE = {"xgv-client": "the XGV client (JAUS) is not available in this build yet (issue 9)"}
MESH_ORDER = ("vehicle-sim", "speed", "driving", "move")
"""Command receivers first: each process dials those before it (see module doc)."""

_PULL_IN = {  # a minimal event that makes run.compose.build_nodes include the node, for --preset runs
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
    for cls in (ActuatorFaults, SensorFault, SensorError, GpsStatus, EngineStall):
        registry.register(cls)
    registry.register(LaunchClock, CLOCK_TOPIC)
    registry.register(ClockReport, CLOCK_REPORT_TOPIC)
    return registry


# --------------------------------------------------------------------------- nodes

def preset_scenario(cli_name: str, preset: str, start: str = "parked") -> Scenario:
    """A stand-in scenario for running one node without a scenario file."""
    event = json.loads(json.dumps(_PULL_IN[cli_name]))
    if "set_speed" in event:
        event["set_speed"]["gear"] = PRESETS[preset].park_gear if preset in PRESETS else "park"
    return parse_scenario({"name": f"node-{cli_name}", "vehicle": preset, "start": start,
                           "duration_s": 1, "events": [event]}, f"<node {cli_name}>")


def own_tick(topic: str, msg: Any, sender: str) -> bool:
    """``msg`` is a liveness tick its sender sent in its own name: a tick in another process's
    name is ignored (the access rules keep other users off ``process/tick``; this keeps the
    envelope's sender and the tick's ``process`` the same, so no run process speaks for another)."""
    return topic == Topic.TICK and isinstance(msg, NodeTick) and msg.process == sender


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



def wait_for_clock(bus: ZenohBus, timeout_s: float | None = None,
                   stop: threading.Event | StopFlag | None = None,
                   exchange_clocks: bool = False) -> LaunchClock | None:
    """Block until a ``LaunchClock`` arrives (None on timeout or ``stop``); meanwhile, with
    ``exchange_clocks``, publish this process's ``ClockReport`` every ``CLOCK_REPORT_PERIOD_S``
    (the launcher engages only once every pair's clock offset is known)."""
    inbox = bus.subscribe([CLOCK_TOPIC])
    deadline = math.inf if timeout_s is None else time.monotonic() + timeout_s
    next_report = time.monotonic()
    while time.monotonic() < deadline and not (stop and stop.is_set()):
        if exchange_clocks and time.monotonic() >= next_report:
            bus.exchange_clocks()
            next_report = time.monotonic() + CLOCK_REPORT_PERIOD_S
        if bus.pull:
            bus.pump()
        for _topic, msg in inbox.drain():
            if isinstance(msg, LaunchClock):
                return msg
        time.sleep(0.005)
    return None


def run_node(cli_name: str, scenario: Scenario, *, listen: Sequence[str] = (),
             connect: Sequence[str] = (), mode: str = "peer", vehicle: str = DEFAULT_VEHICLE,
             wait_clock: bool = False, report_path: Path | None = None,
             base_file: str | Path | None = None, user: str | None = None,
             password: str | None = None, allow_remote: bool = False,
             duration_s: float | None = None, rt_priority: bool = True,
             clock_offset: tuple[float, float] | None = None) -> int:
    """Run one node until SIGTERM/SIGINT (or ``duration_s``); write a JSON report. Returns 0.
    ``rt_priority``: ``SCHED_FIFO`` (``NODE_RT_PRIORITY``) where permitted, else ``RUN_NICE``.
    ``clock_offset``: ``(offset_s, drift_ppm)``, a test hook: this process's clock (its ``now_s``
    and every stamp it sends) is CLOCK_MONOTONIC shifted and drifting by that much."""
    clock = time.monotonic if clock_offset is None else skewed_clock(*clock_offset)
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
                   allow_remote=allow_remote, clock=clock)
    faults = channel_faults(scenario)
    bus.channel = faults
    # the plant integrates at its fixed period; servers step at once on a command (issue 20)
    runtime = WallRuntime([node, ClockReporter(bus), TickNode(node.name)], bus, clock=clock,
                          event_driven=not isinstance(node, VehicleSim), spin_s=NODE_SPIN_S)
    runtime_box.append(runtime)
    bus.announce(node.name)
    started = time.monotonic()
    launch_clock: LaunchClock | None = None
    try:
        if wait_clock:
            launch_clock = wait_for_clock(bus, stop=stop, exchange_clocks=True)
            if launch_clock is None:
                return 0
            runtime.start_s = launch_clock.epoch_monotonic_s
        if not stop.is_set():
            runtime.run(duration_s, on_tick=lambda t: setattr(faults, "now_s", t))
    finally:
        offsets = {peer: {"lo_s": round(e.lo_s, 6), "hi_s": round(e.hi_s, 6)}
                   for peer, e in sorted(bus.clock_offsets().items()) if e is not None}
        report = {
            "node": cli_name, "name": node.name, "pid": os.getpid(),
            "uptime_s": round(time.monotonic() - started, 3),
            "scheduling": scheduling(),
            "epoch_monotonic_s": launch_clock.epoch_monotonic_s if launch_clock else None,
            "clock_offset_injected": list(clock_offset) if clock_offset else None,
            "clock_offsets": offsets,
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
"""``(at_s, what, process)``: supervisor actions at scenario times (``ACTIONS``), on a node's CLI
name or ``gate``. ``stall_actions`` makes the pair of a stall."""
ACTIONS = {"kill": signal.SIGKILL, "term": signal.SIGTERM, "stop": signal.SIGSTOP,
           "cont": signal.SIGCONT, "restart": None}
"""Fault injection (docs/multiprocess.md, "Injecting faults"): a signal to the process group, or a
restart (SIGTERM, wait, start again). ``stop`` without a ``cont`` is a hang to the run's end."""
GATE = "gate"                    # the tool gate as an action target and in supervision
RESTART_GRACE_S = READY_TIMEOUT_S
"""A (re)started process's first liveness tick is due within this (Python, imports, session and
the clock: seconds on a loaded host); it is judged by ``HANG_BOUND_S`` from then on."""


def stall_actions(process: str, at_s: float, for_s: float = math.inf,
                  end_s: float = math.inf) -> list[Action]:
    """SIGSTOP ``process`` at ``at_s`` and SIGCONT it ``for_s`` later; never (a hang to the
    end) when ``for_s`` is infinite or ends past ``end_s``, the run's end."""
    stop: list[Action] = [(at_s, "stop", process)]
    cont_s = at_s + for_s
    hang = not (math.isfinite(cont_s) and cont_s <= end_s)
    return stop if hang else [*stop, (cont_s, "cont", process)]


class Launch:
    """Start, supervise and stop a scenario's node processes; play and record the scenario."""

    def __init__(self, scenario: Scenario, out_dir: str | Path | None = None, *,
                 listen: str = DEFAULT_ENDPOINT, vehicle: str = DEFAULT_VEHICLE,
                 python: str = sys.executable, restart: bool = False,
                 restart_delay_s: float = 0.5, actions: Sequence[Action] = (),
                 base_file: str | Path | None = None, credentials: str | Path | None = None,
                 allow_remote: bool = False, plot: bool = True,
                 node_log: bool = False, secure: bool = True, rt_priority: bool = True,
                 clock_offsets: Mapping[str, tuple[float, float]] | None = None,
                 clock_sync_timeout_s: float = CLOCK_SYNC_TIMEOUT_S,
                 display: Callable[[str], Any] | None = None) -> None:
        self.scenario = scenario
        self.display = DisplayLines(display) if display is not None else None
        """One line per change of the fault display's text (``observe.display``)."""
        self.clock_offsets = {name: (float(o), float(d)) for name, (o, d)
                              in (clock_offsets or {}).items()}
        """Test hook: node (CLI name) -> ``(offset_s, drift_ppm)`` of its process's clock."""
        self.clock_sync_timeout_s = clock_sync_timeout_s
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
        for at_s, what, _name in self.actions:
            if what not in ACTIONS:
                raise ValueError(f"unknown action {what!r}; one of {', '.join(ACTIONS)}")
            if not (math.isfinite(at_s) and 0.0 <= at_s <= scenario.spec.duration_s):
                raise ValueError(f"{what} at {at_s} s: not a time in the run "
                                 f"(0 to {scenario.spec.duration_s:g} s)")
        check_launchable(scenario)
        self.names = scenario_node_names(scenario)
        has_gate = self.secure and bool(self.listen)
        targets = [*self.names, GATE] if has_gate else list(self.names)
        for _at, _what, name in self.actions:
            if name not in targets:
                raise ScenarioError(scenario.source, "node",
                                    f"{name!r} is not a process of this run ({', '.join(targets)})")
        for name in self.clock_offsets:
            if name not in self.names:
                raise ScenarioError(scenario.source, "node",
                                    f"{name!r} is not a process of this run ({', '.join(self.names)})")
        self._tmp: Any = None
        work = self.out_dir if self.out_dir is not None else Path(self._tmpdir())
        self.work_dir = work
        self.procs: dict[str, NodeProcess] = {}
        endpoints: list[str] = []
        public = endpoint_port(self.listen)
        ports = free_ports(len(self.names) + 1, frozenset({public} if public else ()))
        for cli, port in zip(self.names, ports[:-1], strict=True):
            endpoint = f"tcp/127.0.0.1:{port}"
            self.procs[cli] = NodeProcess(cli, endpoint, list(endpoints), work / "nodes" / f"{cli}.json")
            endpoints.append(endpoint)
        self.access: RunAccess | None = None
        self.gate_listen = f"tcp/127.0.0.1:{ports[-1]}" if self.secure and self.listen else ""
        self.gate: subprocess.Popen | None = None
        self._gate_connect: list[str] = []
        self._gate_exits: list[dict[str, Any]] = []
        self._gate_restart_at_s: float | None = None
        self._gate_expected_exit = False
        self.liveness: Liveness | None = None
        """Who is hung (``runtime.supervision``): made when the run starts playing."""
        self._epoch = 0.0                    # the run's epoch on CLOCK_MONOTONIC, once it plays
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
        self.clock_rows: list[dict[str, Any]] = []
        """The pairs' clock offsets as last judged (``servers.clock_offset.pair_table``)."""
        self._clock_worst: dict[tuple[str, str], dict[str, float]] = {}
        self._clock_faulted: set[tuple[str, str, str]] = set()
        self._clock_checked_s = -math.inf
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
        if proc.cli_name in self.clock_offsets:
            offset_s, drift_ppm = self.clock_offsets[proc.cli_name]
            cmd.append(f"--clock-offset={offset_s!r}:{drift_ppm!r}")
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
                                          preexec_fn=node_child)
        proc.starts += 1
        proc.expected_exit = False
        proc.restart_at_s = None

    @property
    def _gate_ready(self) -> Path:
        return self.work_dir / "nodes" / "gate.ready"

    def _spawn_gate(self, connect: list[str]) -> None:
        """Start the tool gate: the run's public endpoint for pub/echo (``bus.tool_gate``)."""
        assert self.access is not None
        self._gate_connect = list(connect)
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
                                         preexec_fn=die_with_parent)

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
        self._expect(name)

    def _expect(self, name: str) -> None:
        """``name`` was (re)started just now: supervised again from its first tick. Now is the
        clock's, not the step's: the old process ticked until it was stopped, after the step's
        scheduled time, and a tick of it must not count as the new one's."""
        if self.liveness is not None:
            self.liveness.expect(NODE_CLASSES.get(name, name), time.monotonic() - self._epoch,
                                 RESTART_GRACE_S)

    def _act(self, now_s: float) -> None:
        """Run the fault-injection actions that are due (``ACTIONS``)."""
        self.now_s = now_s
        while self.actions and self.actions[0][0] <= now_s + 1e-9:
            _at, what, name = self.actions.pop(0)
            if what == "restart" and name == GATE:
                self.restart_gate()
            elif what == "restart":
                self.restart_node(name)
            elif name == GATE:
                self.signal_gate(ACTIONS[what])
            else:
                self.signal_node(name, ACTIONS[what])

    def signal_gate(self, sig: int) -> None:
        """Send ``sig`` to the tool gate's process group (fault injection)."""
        if self.gate is not None and self.gate.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.gate.pid, sig)
            self._event("process_signal", node=GATE, signal=signal.Signals(sig).name.lower())

    def restart_gate(self) -> None:
        """Stop the tool gate (SIGTERM, wait) and start it again on the same endpoints."""
        if self.gate is not None and self.gate.poll() is None:
            self._gate_expected_exit = True
            self._stop_gate()
        self._respawn_gate()

    def _respawn_gate(self) -> None:
        self._spawn_gate(self._gate_connect)
        self._gate_restart_at_s, self._gate_expected_exit = None, False
        self._event("process_restart", node=GATE, pid=self.gate.pid if self.gate else None)
        self._expect(GATE)

    def _died(self, name: str, code: int, now_s: float, consequence: str = "") -> None:
        """Report a process's death: an event, a fault notice, a violation."""
        how = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
        self._event("process_exit", node=name, code=code, reason=how)
        self._fault("process_exit", f"{name} died ({how}) at t={now_s:.2f} s{consequence}")
        self.violations.append(f"process: {name} died ({how}) at t={now_s:.2f} s")
        if self.liveness is not None:
            self.liveness.down(NODE_CLASSES.get(name, name))

    def _fault(self, code: str, reason: str) -> None:
        if self.bus is not None:
            self.bus.publish(Topic.NOTICE, Notice(kind="fault", source=LAUNCHER_USER, code=code,
                                                  reason=reason))

    def _supervise(self, now_s: float) -> None:
        self._act(now_s)
        self._watch_clocks(now_s)
        for name, proc in self.procs.items():
            popen = proc.popen
            if popen is not None and proc.restart_at_s is None:
                code = popen.poll()
                if code is not None:
                    proc.exits.append({"t_s": round(now_s, 4), "code": code})
                    self._died(name, code, now_s)
                    proc.restart_at_s = now_s + self.restart_delay_s if self.restart else math.inf
            if proc.restart_at_s is not None and now_s >= proc.restart_at_s:
                self._spawn(proc)
                self._event("process_restart", node=name, pid=proc.popen.pid if proc.popen else None)
                self._expect(name)
        gate = self.gate
        if gate is not None and self._gate_restart_at_s is None and not self._gate_expected_exit:
            code = gate.poll()
            if code is not None:
                self._gate_exits.append({"t_s": round(now_s, 4), "code": code})
                self._died(GATE, code, now_s, f": tools are cut off and its public endpoint "
                           f"{self.listen} is free for any process to take")
                self._gate_restart_at_s = now_s + self.restart_delay_s if self.restart else math.inf
        if self._gate_restart_at_s is not None and now_s >= self._gate_restart_at_s:
            self._respawn_gate()
        if self.liveness is not None:
            for hung in self.liveness.check(now_s):
                self._report_liveness(hung)

    def _report_liveness(self, finding: Hung | Resumed) -> None:
        """A process hung (event, fault, violation: the run fails) or resumed (event, notice)."""
        names = {NODE_CLASSES[n]: n for n in self.names}
        name = names.get(finding.process, finding.process)
        bound = self.liveness.bound_s if self.liveness is not None else HANG_BOUND_S
        if isinstance(finding, Hung):
            self.events.append({"t_s": round(finding.now_s, 4), "kind": "process_hung", "node": name,
                                "last_tick_s": round(finding.last_tick_s, 4),
                                "silent_s": round(finding.silent_s, 4)})
            self._fault("process_hung", f"{name}: no liveness tick for {finding.silent_s:.2f} s "
                        f"(more than {bound:g} s) since t={finding.last_tick_s:.2f} s")
            self.violations.append(f"process: {name} hung: no liveness tick for more than "
                                   f"{bound:g} s from t={finding.last_tick_s:.2f} s")
            return
        cause = (f"{finding.lost} ticks lost on the way" if finding.lost
                 else "the process was not run")
        self.events.append({"t_s": round(finding.to_s, 4), "kind": "process_resumed", "node": name,
                            "silent_s": round(finding.silent_s, 4), "lost_ticks": finding.lost})
        if self.bus is not None:
            self.bus.publish(Topic.NOTICE, Notice(
                kind="resumed", source=LAUNCHER_USER, code="process_hung",
                reason=f"{name}: ticks again at t={finding.to_s:.2f} s after {finding.silent_s:.2f} s "
                       f"silent ({cause})"))

    # ------------------------------------------------------------------ clocks

    def judge_clocks(self) -> list[dict[str, Any]]:
        """Every pair of the run's processes (launcher first, then mesh order): offset bounds
        from both ends (the launcher's own, the nodes' latest ``ClockReport``) and why the pair
        must not drive together ("" when fine). Keeps the worst seen per pair."""
        assert self.bus is not None
        sender_to_name = {LAUNCHER_USER: LAUNCHER_NAME,
                          **{NODE_CLASSES[n]: n for n in self.names}}
        views: dict[str, dict[str, PeerBound]] = {
            LAUNCHER_USER: {peer: PeerBound(peer, e.lo_s, e.hi_s, self.bus.clocks.peers[peer].resets)
                            for peer, e in self.bus.clock_offsets().items() if e is not None}}
        for source, report in self.bus.clock_reports().items():
            views[source] = {b.peer: b for b in report.bounds}
        rows = pair_table(sender_to_name, views)
        for row in rows:
            row["a"], row["b"] = sender_to_name[row["a"]], sender_to_name[row["b"]]
            if row["offset_s"] is not None:
                worst = self._clock_worst.setdefault((row["a"], row["b"]), {
                    "max_abs_offset_s": 0.0, "max_uncertainty_s": 0.0})
                worst["max_abs_offset_s"] = max(worst["max_abs_offset_s"], abs(row["offset_s"]))
                worst["max_uncertainty_s"] = max(worst["max_uncertainty_s"], row["uncertainty_s"])
        self.clock_rows = rows
        return rows

    def _sync_clocks(self) -> list[dict[str, Any]]:
        """Exchange clock reports until every pair is within tolerance (``[]``) or the time is
        up (the pairs that are not). Nothing is played meanwhile: the nodes wait for the epoch."""
        assert self.bus is not None
        deadline = time.monotonic() + self.clock_sync_timeout_s
        next_report = next_judge = time.monotonic()
        while True:
            now = time.monotonic()
            if now >= next_report:
                self.bus.exchange_clocks()
                next_report = now + CLOCK_REPORT_PERIOD_S
            self.bus.pump()
            if now >= next_judge:
                bad = [row for row in self.judge_clocks() if row["reason"]]
                settled = all(r["reason"].startswith("offset beyond") for r in bad)
                if not bad or settled or now >= deadline:   # a known offset beyond: conclusive
                    return bad
                next_judge = now + 0.05
            for proc in self.procs.values():
                if proc.popen is not None and proc.popen.poll() is not None:
                    raise RuntimeError(f"node {proc.cli_name} exited before the run started "
                                       f"(code {proc.popen.returncode})")
            time.sleep(0.002)

    def _watch_clocks(self, now_s: float) -> None:
        """During the run: a pair beyond tolerance (or whose offset was known and is lost) is
        reported as a fault notice, again whenever its reason changes."""
        if now_s < self._clock_checked_s + CLOCK_CHECK_PERIOD_S or self.bus is None:
            return
        self._clock_checked_s = now_s
        for row in self.judge_clocks():
            key = (row["a"], row["b"], row["reason"])
            if row["reason"] and row["offset_s"] is not None and key not in self._clock_faulted:
                self._clock_faulted.add(key)
                self.bus.publish(Topic.NOTICE, Notice(kind="fault", source=LAUNCHER_USER,
                                                      code="clock_offset", reason=describe_pair(row)))

    def clocks_report(self) -> dict[str, Any]:
        """``summary.json`` -> ``launch.clocks``."""
        return {"max_offset_s": MAX_CLOCK_OFFSET_S, "max_uncertainty_s": MAX_CLOCK_UNCERTAINTY_S,
                "offset_is": "clock of b minus clock of a; lo_s <= offset <= hi_s",
                "injected": {n: {"offset_s": o, "drift_ppm": d}
                             for n, (o, d) in sorted(self.clock_offsets.items())},
                "pairs": self.clock_rows,
                "worst": [{"a": a, "b": b, **w} for (a, b), w in self._clock_worst.items()]}

    def _stop_proc(self, proc: NodeProcess, sig: int = signal.SIGTERM) -> None:
        if proc.popen is None:
            return
        proc.expected_exit = True
        if stop_process_group(proc.popen, sig, STOP_GRACE_S):
            proc.killed_at_stop = True

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
        refused = [describe_pair(row) for row in self._sync_clocks()]   # before anything plays
        faults = channel_faults(scenario)
        self.bus.channel = faults
        out_path = self.out_dir
        with contextlib.ExitStack() as stack:
            trace_file = open_trace(stack, out_path)
            recorder = self.recorder = Recorder(trace_file, keep_rows=False)
            monitor = make_monitor(scenario, DEFAULT_PERIOD_S)
            self.bus.tap(recorder.observe)
            if self.display is not None:
                self.bus.tap(self.display.observe)
            epoch = self._epoch = time.monotonic() + START_LEAD_S

            def judge(topic: str, msg: Any, sent_s: float) -> None:
                """The monitor sees each message at its send time on the run's axis."""
                monitor.now_s = sent_s - epoch if math.isfinite(sent_s) else self.now_s
                monitor.observe(topic, msg)
                if topic in DELIVERED_TOPICS:
                    # across processes the launcher receives what crossed each process boundary
                    # after the publisher's channel faults: what the nodes were delivered too
                    monitor.observe_delivered(topic, msg)

            self.bus.tap_stamped(judge)
            liveness = self.liveness = Liveness(
                [*(NODE_CLASSES[n] for n in self.names), *([GATE] if self.gate is not None else [])])

            def tick(topic: str, msg: Any, sent_s: float, sender: str) -> None:
                """Liveness ticks, by their send time on the run's axis (``runtime.supervision``)."""
                if own_tick(topic, msg, sender):
                    for finding in liveness.tick(msg.process, msg.seq, sent_s - epoch,
                                                 self.bus.clock() - epoch):
                        self._report_liveness(finding)

            self.bus.tap_stamped(tick, sender=True)
            clock = LaunchClock(epoch_monotonic_s=epoch, scenario=scenario.name,
                                duration_s=spec.duration_s)
            if not refused:                 # refused: the nodes never get an epoch, never step
                self.bus.publish(CLOCK_TOPIC, clock)
            player = ScenarioPlayer(scenario)
            runtime = WallRuntime([player, _ClockNode(clock, self._supervise),
                                   ClockReporter(self.bus)], self.bus)
            runtime.start_s = epoch

            def before(now_s: float) -> None:
                faults.now_s = recorder.now_s = now_s
                if self.display is not None:
                    self.display.set_time(now_s)
                self._act(now_s)       # fault injection at the player's resolution (10 ms)
                if on_tick is not None:
                    on_tick(now_s)

            def after(node: Node, now_s: float) -> None:
                if node is player:
                    recorder.tick(now_s)
                    monitor.now_s = now_s - JUDGE_LAG_S
                    monitor.tick(now_s - JUDGE_LAG_S)

            wall_start = time.monotonic()
            if refused:
                for line in refused:
                    self._event("fault", source=LAUNCHER_USER, code="clock_offset", message=line)
                self.violations.extend(f"refused to engage: {line}" for line in refused)
            else:
                runtime.run(spec.duration_s, on_tick=before, after_step=after)
                self._supervise(runtime.now_s)
            wall_time_s = max(time.monotonic() - wall_start, 1e-9)
            reports = self.stop()
        stand_in = VehicleSim(scenario.vehicle, world_from_spec(spec.world), spec.seed)
        stand_in.gate_interventions = dict(reports.get("vehicle-sim", {}).get("gate_interventions", {}))
        channel_counts = dict(faults.counts)
        for report in reports.values():
            for kind, n in report.get("channel_faults", {}).items():
                channel_counts[kind] = channel_counts.get(kind, 0) + n
        recorder.events.extend(self.events)
        recorder.events.sort(key=lambda e: e["t_s"])
        summary = make_summary(scenario, recorder, 0.0 if refused else spec.duration_s,
                               wall_time_s, [stand_in],
                               monitor.finish(), channel_counts)
        summary["violations"].extend(self.violations)
        if not refused:   # no silent pass: clocks lost or beyond tolerance during the run
            summary["violations"].extend(
                f"clocks {a}-{b}: {reason} during the run"
                for a, b, reason in sorted(self._clock_faulted) if reason != "offset unknown")
        add_judgement(summary, monitor)
        summary["launch"] = {
            "mode": "multi-process (zenoh, wall clock)",
            "endpoint": self.listen,
            "processes": {name: {"listen": p.listen, "starts": p.starts, "exits": p.exits,
                                 "killed_at_stop": p.killed_at_stop,
                                 "report": name in reports}
                          for name, p in self.procs.items()},
            "gate": {"listen": self.gate_listen, "public": self.listen,
                     "exits": self._gate_exits} if self.gate_listen else None,
            "liveness": self.liveness.report() if self.liveness is not None else None,
            "launcher": {"runtime": runtime.stats(), "bus": self.bus.stats.as_dict()},
            "nodes": reports,
            "access": self.access_report(),
            "clocks": self.clocks_report(),
        }
        if refused:
            summary["launch"]["refused_to_engage"] = refused
        self.close()
        exit_code = 1 if summary["violations"] else 0
        write_summary(out_path, summary, plot=self.plot and not refused)
        return LaunchResult(summary, exit_code, out_path, reports)

    def stop(self) -> dict[str, dict[str, Any]]:
        """Stop every node (SIGTERM, then SIGKILL) and collect their reports."""
        procs = list(self.procs.values())
        popens = [p.popen for p in procs if p.popen is not None]
        for proc in procs:
            proc.expected_exit = True
        self._gate_expected_exit = True
        for popen in [*popens, *([self.gate] if self.gate is not None else [])]:
            if popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(popen.pid, signal.SIGTERM)
                    os.killpg(popen.pid, signal.SIGCONT)   # a stalled one (--stall) handles it
        for proc in procs:
            self._stop_proc(proc)
        self._stop_gate()
        reports: dict[str, dict[str, Any]] = {}
        for name, proc in self.procs.items():
            with contextlib.suppress(FileNotFoundError, json.JSONDecodeError):
                reports[name] = json.loads(proc.report.read_text(encoding="utf-8"))
        return reports

    def _stop_gate(self, sig: int = signal.SIGTERM) -> None:
        if self.gate is not None:
            stop_process_group(self.gate, sig, STOP_GRACE_S, dump=False)

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
