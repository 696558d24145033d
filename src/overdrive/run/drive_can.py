"""``overdrive drive --can pacmod3``: the stack against a PACMod 3 kit over CAN, in wall-clock time.

The servers are those ``overdrive drive --xgv`` builds (no actuator monitoring, no radar: the
kit reports pedal outputs, not positions the stack can judge, and carries no radar). The run
folder is the same (``summary.json``, ``trace.csv``, ``run.mcap`` with the raw frames on
``can/frames``), plus ``can.json`` (the resolved python-can configuration and where each key
came from, the DBC's path, version and sha256, the dialect, the bring-up axis) and the vehicle
file as driven (``vehicle.yaml``). While the drive runs, ``engage.json`` names its engage
endpoint (``runtime.can_link.EngageEndpoint``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final

import msgspec
import yaml

from overdrive.dynamics.vehicle_params import VehicleParams, vehicle_to_data
from overdrive.kits.frames import KitError
from overdrive.kits.pacmod3 import Dialect, Pacmod3Codec
from overdrive.observe.display import DisplayLines
from overdrive.run.compose import build_servers
from overdrive.run.sim import RunResult, run_scenario
from overdrive.runtime.can_edge import CanConfig, CanConfigError, CanPort
from overdrive.runtime.can_link import (
    CanCommandNode,
    CanSensorNode,
    EngageEndpoint,
    request_engage,
)
from overdrive.scenario.schema import Scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import BringUp, Pacmod3Client, Pacmod3ClientConfig

DEFAULT_VEHICLE: Final = "lexus-rx450h"
"""The PACMod default (issue 32): the Lexus RX 450h, wheelbase 2.79 m, variable steering ratio."""
DEAD_RECKONING_BOUND_M: Final = 0.05
"""The judge's pose error bound: the pose is dead reckoned from the kit's own speed and yaw
reports, the same numbers the kit's odometry integrates; 0.05 m covers the 30 Hz sampling of a
run's speed changes."""


def pacmod_vehicle(scenario: Scenario, vehicle: VehicleParams | None) -> Scenario:
    """``scenario`` driving ``vehicle`` (None: the PACMod default, ``DEFAULT_VEHICLE``)."""
    params = vehicle if vehicle is not None else KIT_VEHICLES[DEFAULT_VEHICLE]
    return msgspec.structs.replace(scenario, vehicle=params)


def can_record(config: CanConfig, codec: Pacmod3Codec, bring_up: str | None,
               engage: bool) -> dict[str, Any]:
    """``can.json``: what the drive talked to and how."""
    return {"kit": "pacmod3", "dialect": codec.dialect, "dbc": {
        "path": str(codec.dbc_path), "version": codec.dbc_version, "sha256": codec.dbc_sha256,
        "files": [{"path": path, "sha256": digest} for path, digest in codec.dbc_files]},
        "python_can": config.to_json(), "bring_up": bring_up, "engage_at_start": engage}


def run_drive_can(scenario: Scenario, config: CanConfig, out_dir: str | Path | None = None, *,
                  vehicle: VehicleParams | None = None, dialect: Dialect = "v3",
                  dbc: str | Path | None = None, engage: bool = False,
                  bring_up: BringUp | None = None, plot: bool = True, keep_trace: bool = False,
                  display: Callable[[str], Any] | None = None) -> RunResult:
    """The stack against the PACMod 3 on the bus ``config`` names (module docstring).

    ``engage``: the operator's act on the command line (engage once the kit is heard); without
    it the drive waits disengaged for ``overdrive engage --run RUN_DIR``. Raises
    ``CanConfigError`` (the bus does not open), ``KitError`` (a DBC that does not fit),
    ``ValueError`` (a vehicle without a steering ratio).
    """
    scenario = pacmod_vehicle(scenario, vehicle)
    codec = Pacmod3Codec(dialect, dbc)
    client = Pacmod3Client(scenario.vehicle, Pacmod3ClientConfig(
        dialect=dialect, bring_up=bring_up, publish_truth=True), codec=codec)
    out_path = Path(out_dir) if out_dir is not None else None
    if out_path is not None:
        out_path.mkdir(parents=True, exist_ok=True)
        (out_path / "can.json").write_text(
            json.dumps(can_record(config, codec, bring_up, engage), indent=2) + "\n",
            encoding="utf-8")
        (out_path / "vehicle.yaml").write_text(
            yaml.safe_dump(vehicle_to_data(scenario.vehicle), sort_keys=False), encoding="utf-8")
    port = CanPort(config)
    endpoint = None
    try:
        endpoint = EngageEndpoint(out_path)
        servers = build_servers(scenario, over_jaus=True)
        sensor = CanSensorNode(client, port, endpoint)
        nodes = [sensor, *servers,
                 CanCommandNode(client, port, endpoint, engage_at_start=engage, sensor=sensor)]
    except BaseException:
        if endpoint is not None:
            endpoint.close()
        port.close()
        raise
    return run_scenario(scenario, out_path, realtime=True, plot=plot, keep_trace=keep_trace,
                        nodes=nodes, position_noise_m=DEAD_RECKONING_BOUND_M,
                        follow_wall_clock=True,
                        observers=[DisplayLines(display)] if display is not None else [])


__all__ = ["DEFAULT_VEHICLE", "CanConfigError", "KitError", "can_record", "pacmod_vehicle",
           "request_engage", "run_drive_can"]
