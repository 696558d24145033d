"""Simulation mode of the move server (seed 004 "-s"): the nodes for ``overdrive move-server -s``.

The fake planner (``servers.move_planner.FakePlanner``) drives the whole stack against the
simulated vehicle. This module composes nodes, like ``overdrive.run.sim``; servers never import it.
"""

from __future__ import annotations

from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.runtime.lockstep import Node
from overdrive.servers.driving import DrivingModule
from overdrive.servers.move import MoveServer, MoveServerConfig
from overdrive.servers.move_planner import FakePlanner, PlannerConfig
from overdrive.servers.speed import SpeedServer
from overdrive.vehicle.plant import World
from overdrive.vehicle.sim_node import VehicleSim


def simulation_nodes(params: VehicleParams, seed: int, *, world: World | None = None,
                     planner: PlannerConfig | None = None) -> list[Node]:
    """Vehicle, fake planner, move server, driving module, speed server, in tick order.

    The vehicle starts parked; the move server brings it up on the first command.
    """
    world = world or World()
    return [
        VehicleSim(params, world, seed),
        FakePlanner(params, seed, config=planner),
        MoveServer(params, config=MoveServerConfig(friction=world.friction)),
        DrivingModule(params, friction=world.friction),
        SpeedServer(params),
    ]


__all__ = ["simulation_nodes"]
