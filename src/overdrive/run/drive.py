"""``overdrive drive``: the stack against a real or simulated XGV (or a plain JAUS 3.3 vehicle)
over JAUS/UDP, in wall-clock time; the run folder is the one ``overdrive sim`` writes."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from overdrive.observe.display import DisplayLines
from overdrive.run.compose import build_servers, drive_nodes
from overdrive.run.sim import run_scenario
from overdrive.runtime.xgv_link import Address
from overdrive.scenario.schema import Scenario
from overdrive.vehicle.plain_jaus import JausProfile
from overdrive.vehicle.xgv import POSITION_RMS_M

REPORTED_POSE_BOUND_M = 6.0 * POSITION_RMS_M
"""No simulator truth in ``overdrive drive``: the judge takes the XGV's reported pose, whose error
stays within six standard deviations of its reported accuracy over a run's samples."""



def run_drive(scenario: Scenario, remote: Address, out_dir: Any = None, *,
              bind: Address = ("0.0.0.0", 0), plot: bool = True, keep_trace: bool = False,
              profile: JausProfile = "xgv",
              display: Callable[[str], Any] | None = None) -> Any:
    """``overdrive drive``: the stack against the XGV at ``remote``, in wall-clock time.

    The servers are those ``overdrive sim`` builds for the scenario; the run folder is the
    same, its trace and final state taken from the XGV's reports. Safety-device and world
    events are physical: the XGV (or ``overdrive xgv-sim --scenario``) plays them, not the stack.
    ``display``: called with one line each time the fault display's text changes.
    """
    servers = build_servers(scenario, over_jaus=True)
    return run_scenario(scenario, out_dir, realtime=True, plot=plot, keep_trace=keep_trace,
                        nodes=drive_nodes(scenario, servers, remote, bind, profile),
                        position_noise_m=REPORTED_POSE_BOUND_M, follow_wall_clock=True,
                        observers=[DisplayLines(display)] if display is not None else [])
