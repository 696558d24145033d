"""Running a scenario against the simulated vehicle and writing the run folder.

This is the runtime edge for ``overdrive sim``: it composes the nodes a scenario needs, steps
them on the lock-step runtime, reads the wall clock (only for ``--realtime`` pacing and the
real-time factor), and writes ``summary.json``, ``trace.csv`` and ``plot.png``.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from overdrive.bus.local import LocalBus
from overdrive.messages import Topic
from overdrive.observe.judge import DELIVERED_TOPICS, Monitor
from overdrive.observe.mcap_log import McapRecorder
from overdrive.observe.provenance import code_provenance, run_provenance
from overdrive.observe.recorder import Recorder
from overdrive.observe.run_files import open_trace, write_summary
from overdrive.run.compose import build_nodes
from overdrive.runtime.lockstep import DEFAULT_PERIOD_S, LockstepRuntime, Node
from overdrive.scenario.expect import check
from overdrive.scenario.player import channel_faults, stall_windows
from overdrive.scenario.schema import (
    Scenario,
    ScenarioError,
)
from overdrive.vehicle.xgv_client import LINK_FAULTS


@dataclass
class RunResult:
    summary: dict[str, Any]
    exit_code: int
    out_dir: Path | None = None
    trace: list[dict[str, str]] | None = None
    nodes: dict[str, Node] = field(default_factory=dict)


def default_out_dir(scenario: Scenario) -> Path:
    return Path("runs") / f"{scenario.name}-{time.strftime('%Y%m%d-%H%M%S')}"


def run_scenario(scenario: Scenario, out_dir: str | Path | None = None, *, keep_trace: bool = True,
                 realtime: bool = False, plot: bool = True,
                 progress: Callable[[float, float], None] | None = None,
                 period_s: float = DEFAULT_PERIOD_S, nodes: list[Node] | None = None,
                 observers: Sequence[Any] = (), record_mcap: bool = True,
                 position_noise_m: float = 0.0, follow_wall_clock: bool = False) -> RunResult:
    """Run ``scenario`` to its ``duration_s``; write the run folder when ``out_dir`` is given.

    ``nodes`` replaces the scenario's own composition (e.g. the move server's simulation mode,
    where a fake planner stands in for the scenario player). ``observers``: extra bus taps with
    ``set_time(now_s)`` and ``observe(topic, msg)`` (the ``--live`` view); ``record_mcap``:
    write ``run.mcap`` into the run folder. ``position_noise_m``: the error bound of the pose
    the judge takes as truth when there is no simulator (``overdrive drive``).
    ``follow_wall_clock`` (with ``realtime``; ``overdrive drive``): a tick late by more than a
    period skips to the wall clock, so the stack's clock stays the world's (a stall of the
    process is one long step the nodes see, never time compressed to catch up, which would
    make the vehicle's reports look early and its motion too fast); counted in
    ``summary.json`` ``wall_clock``.
    """
    nodes = nodes if nodes is not None else build_nodes(scenario)
    code_provenance()     # read before the run folder exists: it may lie inside the checkout
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    out_path = Path(out_dir) if out_dir is not None else None
    with contextlib.ExitStack() as stack:
        trace_file = open_trace(stack, out_path)
        taps = list(observers)
        mcap = None
        if out_path is not None and record_mcap:
            mcap = stack.enter_context(
                McapRecorder(out_path / "run.mcap", scenario=scenario, period_s=period_s))
            taps.append(mcap)
        for node in nodes:   # nodes holding sockets (the XGV link) close them, in reverse order
            if callable(getattr(node, "close", None)):
                stack.callback(node.close)
        recorder = Recorder(trace_file, keep_rows=keep_trace)
        bus.tap(recorder.observe)
        for tap in taps:
            bus.tap(tap.observe)
        monitor = make_monitor(scenario, period_s, position_noise_m)
        bus.tap(monitor.observe)
        bus.tap_delivered(monitor.observe_delivered, DELIVERED_TOPICS)
        try:
            runtime = LockstepRuntime(mcap.wrap(nodes) if mcap else nodes, bus, period_s,
                                      stalls=stall_windows(scenario))
        except ValueError as exc:
            raise ScenarioError(scenario.source, "events", str(exc)) from exc
        duration_s = scenario.spec.duration_s
        wall_start = time.monotonic()
        end_tick = round(duration_s / period_s)
        report_every = max(1, end_tick // 200)
        late_ticks = late_steps = 0
        longest_late_s = 0.0
        while runtime.tick <= end_tick:
            if follow_wall_clock and realtime:   # before the step: it reads what came meanwhile
                late_s = (time.monotonic() - wall_start) - runtime.now_s
                if late_s > period_s:
                    skip = int(late_s / period_s)
                    runtime.tick += skip
                    late_ticks += skip
                    late_steps += 1
                    longest_late_s = max(longest_late_s, late_s)
            faults.now_s = recorder.now_s = monitor.now_s = runtime.tick * period_s
            for tap in taps:
                tap.set_time(faults.now_s)
            now_s = runtime.step()
            recorder.tick(now_s)
            monitor.tick(now_s)
            if realtime:
                lag = now_s - (time.monotonic() - wall_start)
                if lag > 0:
                    time.sleep(lag)
            if progress is not None and runtime.tick % report_every == 0:
                progress(now_s, duration_s)
        wall_time_s = time.monotonic() - wall_start
    summary = make_summary(scenario, recorder, runtime.now_s - period_s, wall_time_s, nodes,
                           monitor.finish(), faults.counts)
    add_judgement(summary, monitor)
    if follow_wall_clock:
        summary["wall_clock"] = {"late_steps": late_steps, "skipped_ticks": late_ticks,
                                 "longest_late_s": round(longest_late_s, 3)}
    exit_code = 1 if summary["violations"] else 0
    write_summary(out_path, summary, plot=plot)
    return RunResult(summary=summary, exit_code=exit_code, out_dir=out_path,
                     trace=recorder.rows, nodes={n.name: n for n in nodes})


def make_monitor(scenario: Scenario, period_s: float, position_noise_m: float = 0.0) -> Monitor:
    """The safety judge for ``scenario`` (the scenario is the SPSS client in set_speed runs)."""
    return Monitor(scenario.vehicle, scenario.spec.world.friction, period_s,
                   spss_is_command="set_speed" in scenario.event_kinds,
                   position_noise_m=position_noise_m)


def add_judgement(summary: dict[str, Any], monitor: Monitor) -> None:
    """The judge's records beyond the violation strings: details, notes, stop margins."""
    summary["violation_details"] = monitor.details()
    summary["judge_notes"] = monitor.notes
    summary["stops"] = [{"authorization_margin_m": round(m, 4)} for m in monitor.stop_margins_m]
    summary["secondary_braking"] = monitor.secondary.result()


def clock_report(rec: Recorder) -> dict[str, Any]:
    """The clock offsets the stack measured (``ClockEstimate``, last of each peer): offset is
    the stack's clock minus the peer's, ``uncertainty_s`` the bounds' width (round trip)."""
    est = rec.latest.get(Topic.PLANNER_CLOCK)
    if est is None:
        return {}
    def r6(value: float | None) -> float | None:
        return None if value is None else round(value, 6)

    return {est.peer: {"offset_s": r6(est.offset_s), "lo_s": r6(est.lo_s),
                       "hi_s": r6(est.hi_s), "uncertainty_s": r6(est.uncertainty_s),
                       "worst_uncertainty_s": round(est.worst_uncertainty_s, 6),
                       "refusals": est.refusals, "resets": est.resets}}


def unexpected_link_faults(scenario: Scenario, events: list[dict[str, Any]]) -> list[str]:
    """No silent pass: a JAUS link that stalled, lost reports, delivered them too old or was
    degraded fails the run unless the scenario expects that fault (``expect: event: kind:
    fault, match: {code: ...}``)."""
    expected = {e.event.match.get("code") for e in scenario.spec.expect
                if e.event is not None and e.event.kind == "fault"}
    failures: dict[str, str] = {}
    for event in events:
        code = event.get("code")
        if event.get("kind") == "fault" and code in LINK_FAULTS and code not in expected:
            failures.setdefault(code, f"link fault {code} at {event.get('t_s')} s: "
                                      f"{event.get('message', '')}")
    return list(failures.values())


def make_summary(scenario: Scenario, rec: Recorder, sim_time_s: float, wall_time_s: float,
                 nodes: list[Node], invariant_violations: list[str],
                 faults_counts: dict[str, int] | None = None) -> dict[str, Any]:
    p = scenario.vehicle
    faults_counts = faults_counts or {}
    truth = rec.latest.get(Topic.TRUTH)
    status = rec.latest.get(Topic.VEHICLE_STATUS)
    speed_state = rec.latest.get(Topic.SPEED_STATE)
    vehicle_node = next((n for n in nodes if hasattr(n, "gate_interventions")), None)
    summary: dict[str, Any] = {
        "name": scenario.name,
        "scenario": scenario.source,
        "seed": scenario.spec.seed,
        "sim_time_s": round(sim_time_s, 3),
        "wall_time_s": round(wall_time_s, 3),
        "real_time_factor": round(sim_time_s / wall_time_s, 1) if wall_time_s > 0 else None,
        "vehicle": {"preset": p.preset, "length_m": p.length_m, "width_m": p.width_m,
                    "wheelbase_m": p.wheelbase_m, "rear_overhang_m": p.rear_overhang_m},
        "odometer_m": round(truth.odometer_m, 4) if truth else 0.0,
        "final": {
            "x_m": round(truth.x_m, 4) if truth else 0.0,
            "y_m": round(truth.y_m, 4) if truth else 0.0,
            "heading_rad": round(truth.heading_rad, 5) if truth else 0.0,
            "speed_mps": round(truth.speed_mps, 4) if truth else 0.0,
            "gear": status.gear if status else None,
            "engine": status.engine if status else None,
            "speed_state": speed_state.state if speed_state else None,
            "safety_mode": status.safety_mode if status else None,
        },
        "peaks": {
            "max_speed_mps": round(rec.max_speed_mps, 4),
            "max_accel_mps2": round(rec.max_accel_mps2, 4),
            "max_decel_mps2": round(rec.max_decel_mps2, 4),
            "max_lateral_accel_mps2": round(rec.max_lat_accel_mps2, 4),
        },
        "gate_interventions": dict(sorted(vehicle_node.gate_interventions.items()))
        if vehicle_node is not None else {},
        "channel_faults": {k: v for k, v in faults_counts.items() if v},
        "clocks": clock_report(rec),
        "events": rec.events,
        "violations": [],
        "provenance": run_provenance(scenario.spec, scenario.vehicle),
    }
    violations = [f"invariant {v}" for v in invariant_violations]
    expects_refusal = any(e.event is not None and e.event.kind == "rejected"
                          for e in scenario.spec.expect)
    if rec.moves_refused and not rec.moves_accepted and not expects_refusal:
        # no silent pass: the planner's every MOVE / REVERSE was refused, nothing was driven
        violations.append(f"refused everything: none of {rec.moves_refused} MOVE/REVERSE "
                          f"commands was accepted (first: {rec.first_refusal})")
    violations.extend(unexpected_link_faults(scenario, rec.events))
    for expect in scenario.spec.expect:
        failure = check(expect, summary, rec.states_seen, rec.modes_seen)
        if failure:
            violations.append(failure)
    link_node = next((n for n in nodes if hasattr(n, "link_report")), None)
    if link_node is not None:   # a JAUS link (docs/scenarios.md, "summary.json")
        summary["link"] = link_node.link_report()
    summary["violations"] = violations
    return summary
