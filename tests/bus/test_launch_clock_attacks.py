"""Attacks on the clocks across processes in real launches (``--clock-offset``: a node's process
on another, drifting clock). Judged from the injected clocks, the truth of the run."""

from __future__ import annotations

from pathlib import Path

import pytest

from overdrive.run.launch import launch_scenario
from overdrive.scenario.schema import parse_scenario
from tests.bus.conftest import retry_when_stalled
from tests.bus.test_launch import DRIVING_SCENARIO

pytestmark = pytest.mark.wallclock   # real time: run on an idle machine (Makefile)


@retry_when_stalled
def test_a_clock_drifting_beyond_the_allowance_never_engages_and_says_which(run_dir: Path) -> None:
    """speed's clock starts 200 ms ahead and runs 1 % fast (20 times the 500 ppm allowance).
    Was: the launch engaged, each pair with speed was faulted once, "offset unknown", and when
    the offset went beyond 250 ms nothing said so, while its stamps passed unconverted (up to
    120 ms later than sent). Now its bounds cross, are dropped, and its stamps convert
    fail-safe; the launch refuses to engage and names every pair with speed, or (when its bounds
    happen to agree at the start) the pairs are reported lost or beyond during the run, which
    fails it; exit 1 either way, and nothing drives past what the stack allowed."""
    scenario = parse_scenario({**DRIVING_SCENARIO, "duration_s": 6}, "drift-out")
    result = launch_scenario(scenario, run_dir / "run", listen="", plot=False,
                             clock_offsets={"speed": (0.2, 10_000.0)})
    summary = result.summary
    assert result.exit_code == 1
    clocks = [v for v in summary["violations"] if v.startswith(("refused to engage", "clocks"))]
    assert clocks and all("speed" in v for v in clocks), summary["violations"]
    assert not [v for v in summary["violations"] if v.startswith("invariant")], summary["violations"]
    faults = [e["message"] for e in summary["events"] if e.get("code") == "clock_offset"]
    assert any("lost" in m or "beyond" in m for m in faults), faults
