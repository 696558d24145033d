"""The nodes of a run, composed from its scenario: the simulated vehicle or the XGV link, the
scenario player and the servers the scenario's events need, in tick order. Every runner
(``sim``, ``drive``, ``launch``, ``replay``, ``docs``) builds its nodes here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Literal

import msgspec

from overdrive.runtime.lockstep import Node
from overdrive.runtime.xgv_link import (
    Address,
    ClientPort,
    JausFault,
    LoopbackLink,
    UdpPort,
    XgvCommandNode,
    XgvSensorNode,
    XgvSimNode,
)
from overdrive.scenario.player import ScenarioPlayer, world_from_spec
from overdrive.scenario.schema import (
    DRIVING_KINDS,
    MOVE_KINDS,
    OPEN_LOOP_KINDS,
    SPEED_KINDS,
    Scenario,
    ScenarioError,
)
from overdrive.servers.driving import DrivingConfig, DrivingModule
from overdrive.servers.move import MoveServer, MoveServerConfig
from overdrive.servers.speed import SpeedServer, SpeedServerConfig
from overdrive.vehicle.plain_jaus import JausProfile
from overdrive.vehicle.sim_node import VehicleSim
from overdrive.vehicle.xgv import XgvSimulator
from overdrive.vehicle.xgv_client import XgvClient, XgvClientConfig


def build_nodes(scenario: Scenario) -> list[Node]:
    """The nodes a scenario needs, in tick order (vehicle first). Raises ScenarioError."""
    spec = scenario.spec
    kinds = scenario.event_kinds
    closed_loop = kinds & (SPEED_KINDS | DRIVING_KINDS | MOVE_KINDS)
    if kinds & OPEN_LOOP_KINDS and closed_loop:
        raise ScenarioError(scenario.source, "events",
                            "open-loop events (actuators, gear, engine) cannot be mixed with "
                            f"server events ({', '.join(sorted(closed_loop))})")
    if kinds & SPEED_KINDS and kinds & (DRIVING_KINDS | MOVE_KINDS):
        raise ScenarioError(scenario.source, "events",
                            "set_speed makes the scenario the speed server's client; it cannot be "
                            "mixed with move/advance/max_speed/steer, whose client is the driving module")
    if spec.interface == "jaus" or spec.control == "motion-profile":
        # the simulated XGV and the stack's JAUS client stand where VehicleSim stands
        return lockstep_nodes(scenario, build_servers(scenario, over_jaus=True))
    vehicle = VehicleSim(scenario.vehicle, world_from_spec(spec.world), spec.seed,
                         ready=spec.start == "ready")
    return [vehicle, *build_servers(scenario, over_jaus=False)]


def build_servers(scenario: Scenario, *, over_jaus: bool) -> list[Node]:
    """The scenario player and the servers its events need, in tick order.

    ``over_jaus``: the vehicle is an XGV (or a plain JAUS 3.3 vehicle). JAUS 3.3 reports the
    wrench *efforts* (under motion profile the XGV's own loops set them), not actuator positions,
    so the servers are built without actuator monitoring (residual hazards H11, H14); nor has an
    XGV the collision radar, so the move server is built with none fitted (H22: over JAUS the
    planner owns the clearance ahead).
    """
    spec, kinds, params = scenario.spec, scenario.event_kinds, scenario.vehicle
    ready = spec.start == "ready"
    nodes: list[Node] = [ScenarioPlayer(scenario)]
    # over JAUS the configurations differ from the defaults; elsewhere each server takes its own
    # default (None), so a test that swaps a server's default configuration reaches it
    if kinds & MOVE_KINDS:
        move = MoveServerConfig(friction=spec.world.friction, friction_max=spec.friction_max,
                                planner_machine=spec.planner_machine)
        if over_jaus:
            move = msgspec.structs.replace(
                move, radar=msgspec.structs.replace(move.radar, fitted=False))
        nodes.append(MoveServer(params, config=move))
    if kinds & (DRIVING_KINDS | MOVE_KINDS):
        driving = DrivingConfig(monitor_actuators=False) if over_jaus else None
        nodes.append(DrivingModule(params, config=driving, friction=spec.world.friction,
                                   friction_max=spec.friction_max))
    if kinds & (SPEED_KINDS | DRIVING_KINDS | MOVE_KINDS):
        speed = SpeedServerConfig(monitor_actuators=False) if over_jaus else None
        nodes.append(SpeedServer(params, initial_state="run" if ready else "parked",
                                 initial_gear=params.drive_gear if ready else None, config=speed))
    return nodes


def jaus_faults(scenario: Scenario) -> list[JausFault]:
    """The scenario's faults on channel ``jaus`` (each one way or both, ``direction``)."""
    found = []
    for event in scenario.events:
        body = event.body
        if (event.kind in ("drop", "loss", "delay", "duplicate", "reorder")
                and body.channel == "jaus"):
            found.append(JausFault(event.kind, event.at_s, body.for_s,
                                   getattr(body, "delay_s", 0.0), getattr(body, "fraction", 1.0),
                                   body.direction or "both"))
    return found


def _check_built_for_jaus(servers: Sequence[Any]) -> None:
    """Servers for a JAUS vehicle are built by ``build_servers(..., over_jaus=True)``."""
    for node in servers:
        if getattr(node, "monitor_actuators", False) or getattr(
                getattr(node, "corridor", None), "fitted", False):
            raise ValueError(f"{getattr(node, 'name', node)}: built for a vehicle that reports "
                             "actuator positions and has a radar; over JAUS build the servers "
                             "with build_servers(scenario, over_jaus=True)")


def lockstep_nodes(scenario: Scenario, servers: Sequence[Any],
                   profile: JausProfile = "xgv") -> list[Any]:
    """The XGV, the client and ``servers`` (player first) for a lock-step run of ``scenario``
    (``profile="plain"``: the client reads the simulated XGV as a plain JAUS vehicle)."""
    spec = scenario.spec
    transport: Literal["udp", "memory"] = "udp" if spec.interface == "jaus" else "memory"
    link = LoopbackLink(transport, jaus_faults(scenario), seed=spec.seed)
    simulator = XgvSimulator(scenario.vehicle, world_from_spec(spec.world), spec.seed,
                             ready=spec.start == "ready")
    control = "motion-profile" if spec.control == "motion-profile" else "wrench"
    client = XgvClient(scenario.vehicle, XgvClientConfig(control=control, profile=profile))
    port = ClientPort(link)
    _check_built_for_jaus(servers)
    return [XgvSimNode(simulator, link), XgvSensorNode(client, port), *servers,
            XgvCommandNode(client, port)]


def drive_nodes(scenario: Scenario, servers: Sequence[Any], remote: Address,
                bind: Address = ("0.0.0.0", 0), profile: JausProfile = "xgv") -> list[Any]:
    """The client and ``servers`` for a wall-clock run against the vehicle at ``remote``
    (``profile``: an XGV, or a plain JAUS 3.3 vehicle, ``vehicle.plain_jaus``)."""
    control = "motion-profile" if scenario.spec.control == "motion-profile" else "wrench"
    client = XgvClient(scenario.vehicle, XgvClientConfig(control=control, publish_truth=True,
                                                         accel_filter_s=0.05, profile=profile))
    port = ClientPort(UdpPort(remote, bind))
    _check_built_for_jaus(servers)
    return [XgvSensorNode(client, port), *servers, XgvCommandNode(client, port)]


def plain_profile_problem(scenario: Scenario) -> str | None:
    """Why ``scenario`` cannot drive a plain JAUS vehicle (None: it can). Such a vehicle has
    no Motion Profile Driver and reports no engine or gear (``vehicle.plain_jaus``)."""
    if scenario.spec.control != "wrench":
        return "control: a plain JAUS vehicle has no Motion Profile Driver; use control: wrench"
    if scenario.spec.start != "ready":
        return ("start: a plain JAUS vehicle reports no engine or gear, so the stack cannot "
                "start or shift it; use start: ready (engine running, in drive)")
    return None
