"""A process of a launch stalled, killed or restarted in the middle of a 60 m MOVE: judged from
the simulated vehicle's own state (the vehicle-sim process's truth in the trace), no speed above
the MOVE's limit, no overrun, and no motion after the stop until a new command (none comes).

A sparse sample of the sweep in ``tests/bus/fault_launches.py`` (every node, stalls of 0.1-2 s,
kills and restarts, two speeds: run it as a script; figures in docs/multiprocess.md)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bus.fault_launches import Fault, run_fault

pytestmark = pytest.mark.wallclock

SAMPLE = [
    pytest.param(Fault("speed", "stall", 8.0, 0.3),   # past the vehicle's command timeout
                 marks=pytest.mark.variant_edge),    # (issue 38, case 3): always run
    Fault("driving", "kill", 8.0),          # the SPSS watchdog, then the node comes back
    Fault("move", "restart", 8.0),          # a fresh move server: the old MOVE is gone
]


@pytest.mark.variants   # `make test`: the stall and one of the other two; test-variants: all
@pytest.mark.parametrize("fault", SAMPLE, ids=["speed stall 0.3 s at 8 m/s",
                                              "driving kill at 8 m/s", "move restart at 8 m/s"])
def test_a_stalled_killed_or_restarted_process_never_overruns_speeds_or_drives_on(
        run_dir: Path, fault: Fault) -> None:
    outcome, summary = run_fault(fault, run_dir / "run")
    assert outcome.ok, (outcome, summary["violations"])
    if fault.kind == "stall" and fault.for_s < 0.5:
        assert not [line for line in outcome.process_lines if "hung" in line], "under the bound"
    if fault.kind == "kill":
        assert summary["launch"]["processes"][fault.node]["starts"] == 2
        assert outcome.exit_code == 1, "a death fails the run"
