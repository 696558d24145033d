"""Helpers for the plain JAUS profile's tests: lock-step runs against the simulated XGV read as a
plain vehicle with its reports rewritten (a faulty or hostile vehicle, or the network), and what
they are judged by (the judge's violations, the fault events)."""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from typing import Any

import msgspec

from overdrive.jaus import ReportGlobalPose
from overdrive.messages import PedalCommand, Topic, VehicleStatus
from overdrive.run.compose import build_servers, lockstep_nodes
from overdrive.run.sim import run_scenario
from overdrive.vehicle.plain_jaus import local_radii_m
from overdrive.vehicle.xgv_client import XgvClient
from tests.xgv.test_xgv_plain_profile import ready

MOVE_M = 12.0                 # openjaus-wrench-drive.yaml's move
MAX_SPEED_MPS = 2.5           # and its speed limit
OJ_RMS_M = 1.0                # ojVehicleSim's claimed position rms (its gpos.c)

Hook = Callable[[Any, Any, float], Any]


def hooked_run(name: str, preset: str, hook: Hook) -> Any:
    """``name`` against the simulated XGV read as a plain vehicle, every report it sends
    rewritten by ``hook(simulator, report, now_s)``."""
    scenario = ready(name, preset)
    nodes = lockstep_nodes(scenario, build_servers(scenario, over_jaus=True), profile="plain")
    simulator = nodes[0].simulator
    original = simulator._report

    def rewritten(cid: int, code: int, presence: int, now_s: float) -> Any:
        message = original(cid, code, presence, now_s)
        return message if message is None else hook(simulator, message, now_s)

    simulator._report = rewritten
    return run_scenario(scenario, None, keep_trace=True, nodes=nodes, plot=False)


def noisy(rms_m: float, seed: int) -> Callable[[Any, Any, float], Any]:
    """Global Pose with white noise of ``rms_m`` on each axis (more than a 2-D rms of
    ``rms_m``), claiming ``rms_m``."""
    rng = random.Random(seed)

    def add_noise(simulator: Any, m: Any, now_s: float) -> Any:
        if not isinstance(m, ReportGlobalPose):
            return m
        lat0 = simulator.origin_deg[0]
        meridian_m, prime_vertical_m = local_radii_m(lat0)
        return msgspec.structs.replace(
            m, position_rms_m=rms_m,
            latitude_deg=m.latitude_deg + math.degrees(rng.gauss(0.0, rms_m) / meridian_m),
            longitude_deg=m.longitude_deg + math.degrees(
                rng.gauss(0.0, rms_m) / (prime_vertical_m * math.cos(math.radians(lat0)))))
    return add_noise


def judged(summary: dict) -> list[str]:
    return [v for v in summary["violations"] if not v.startswith("expect")]


def faults(summary: dict) -> list[tuple[str, float]]:
    return [(e.get("code"), e.get("t_s")) for e in summary["events"] if e["kind"] == "fault"]


def throttling(client: XgvClient) -> XgvClient:
    """The stack asks for throttle (as the speed server does when driving)."""
    client.take_inputs([(Topic.PEDALS, PedalCommand(source="speed", throttle_pct=40.0,
                                              brake_pct=0.0))])
    return client


def mode_of(out: dict[str, Any]) -> str:
    status = out[Topic.VEHICLE_STATUS]
    assert isinstance(status, VehicleStatus)
    return status.safety_mode
