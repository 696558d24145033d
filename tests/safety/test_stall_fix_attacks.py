"""Red team (issue 38 fixes): attacks on the command-silence stop, the move-stall latch and the
JAUS one-way-cut checks, judged from ground truth (the trace's x / speed / odometer: the
simulated vehicle's own state). Lock-step whole runs. Each test here is a defect found."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.compose import build_nodes
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.servers.move_radar import RadarConfig
from tests.safety.fault_runs import run

AT_REST_MPS = 0.01


def _jaus_low_speed_cut(speed_mps: float, cut_s: float) -> Any:
    sc = parse_scenario({
        "name": "mp-low-cut", "interface": "jaus", "control": "motion-profile",
        "vehicle": "escape-hybrid", "start": "ready", "seed": 1, "duration_s": 30.0,
        "events": [{"at_s": 0.5, "move": {"distance_m": 10.0, "maxspeed_mps": speed_mps,
                                          "curvature_1pm": 0}},
                   {"at_s": 5.0, "drop": {"channel": "jaus", "for_s": cut_s,
                                          "direction": "to_vehicle"}}]}, "test")
    return run_scenario(sc, None, keep_trace=True, nodes=build_nodes(sc), plot=False)


@pytest.mark.parametrize(("speed_mps", "cut_s"), [(0.3, 1.0), (0.3, 2.0), (0.3, 3.0), (0.2, 2.0)])
def test_a_one_way_cut_at_low_speed_in_motion_profile_never_drives_on_after_the_xgv_stopped(
        speed_mps: float, cut_s: float) -> None:
    """Motion profile, MOVE 10 m at 0.3 m/s, the link cut towards the XGV at 5.0 s. Found: the
    XGV's motion lapses and the vehicle comes to rest (5.99 s, x 1.27 m); when the link comes
    back the old MOVE drives on by itself: 6.92 m (1 s cut), 6.59 m (2 s), 6.29 m (3 s), with
    no fault, no e-stop, no interruption and no violation (a 0.5 m/s MOVE with a 2 s cut is
    caught: xgv_not_following at 6.4 s; 0.35 m/s at 6.04 s). At 0.2 m/s, 2 s cut: at rest 5.84 s
    (x 0.87 m), then 4.46 m on, silently. ``FollowCheck`` takes |commanded| <= speed + 0.3 as
    following, so a command of 0.3 m/s or less is 'followed' even at rest."""
    result = _jaus_low_speed_cut(speed_mps, cut_s)
    rows = result.trace
    rest = next(i for i, r in enumerate(rows)
                if float(r["t_s"]) > 5.0 and abs(float(r["speed_mps"])) < AT_REST_MPS)
    x_rest = float(rows[rest]["x_m"])
    moved_m = max(float(r["x_m"]) for r in rows[rest:]) - x_rest
    assert moved_m < 0.05, (float(rows[rest]["t_s"]), x_rest, moved_m,
                            result.summary["violations"])


@pytest.mark.parametrize(("distance_m", "speed_mps"), [(3.0, 0.5), (5.0, 1.5), (10.0, 2.0)])
def test_a_reverse_from_ready_backs_no_further_than_the_blind_allowance(
        distance_m: float, speed_mps: float) -> None:
    """A REVERSE from ``ready`` (no forward track behind to verify: no rear sensor) backs at
    most ``reverse_blind_m`` (1 m, docs/move-server.md), whatever it asked; the reply says the
    distance was clamped (tests/servers/test_move_server.py). Found by a red team as a silent
    short reverse: the clamp is the documented policy, told in the MoveReply."""
    result = run("escape-hybrid", [{"at_s": 0.5, "reverse": {
        "distance_m": distance_m, "maxspeed_mps": speed_mps, "curvature_1pm": 0}}],
        duration_s=40.0)
    xs = [float(r["x_m"]) for r in result.trace]
    assert -RadarConfig().reverse_blind_m <= min(xs) < -0.5
    assert result.summary["violations"] == []
