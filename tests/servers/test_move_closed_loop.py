"""Move server acceptance in closed loop: vehicle + move server + driving module + speed server."""

from __future__ import annotations

import math

import pytest

from overdrive.bus.local import LocalBus
from overdrive.dynamics.ellipse import ellipse_for
from overdrive.messages import Topic
from overdrive.run.move_sim import simulation_nodes
from overdrive.runtime.lockstep import LockstepRuntime
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.adaptive import ESTIMATES_TOPIC
from tests.servers.move_harness import simulate

PRESET_NAMES = tuple(PRESETS)


def mv(at: float, d: float, v: float, k: float = 0.0, kind: str = "move") -> dict:
    return {"at_s": at, kind: {"distance_m": d, "maxspeed_mps": v, "curvature_1pm": k}}


@pytest.mark.parametrize("vehicle", PRESET_NAMES)
def test_move_30m_from_parked(vehicle: str) -> None:
    run = simulate({"vehicle": vehicle, "start": "parked", "duration_s": 35,
                    "events": [mv(1.0, 30.0, 8.0)]}, keep=(Topic.MOVE_STATUS,))
    assert 29.7 <= run.summary["odometer_m"] <= 30.0
    assert abs(run.summary["final"]["speed_mps"]) < 0.05
    states = [(e["t_s"], e["to"]) for e in run.events("speed_state")]
    runwait_end = next(t for t, s in states if s == "shifting" and t > 5.0)
    first_motion = next(t for t, v in run.column("speed_mps") if abs(v) > 0.01)
    assert [s for _, s in states][:3] == ["reset", "starting", "paused"]
    assert first_motion > runwait_end                 # waited out runwait before moving
    phases = [m.phase for _, m in run.series[Topic.MOVE_STATUS]]
    assert phases[0] == "idle" and "starting" in phases and phases[-1] == "idle"


@pytest.mark.parametrize("vehicle", PRESET_NAMES)
def test_curve_follows_the_arc(vehicle: str) -> None:
    k = 0.05
    run = simulate({"vehicle": vehicle, "start": "ready", "duration_s": 25,
                    "events": [mv(0.5, 60.0, 6.0, k)]})
    rows = [r for r in run.rows if float(r["speed_mps"]) > 1.0]
    first, last = rows[len(rows) // 5], rows[-len(rows) // 5]
    turned = float(last["heading_rad"]) - float(first["heading_rad"])
    travelled = float(last["odometer_m"]) - float(first["odometer_m"])
    assert travelled > 20.0
    assert -turned / travelled == pytest.approx(k, rel=0.05)   # + curvature turns right
    # circle fit through three points of the arc
    xs = [(float(r["x_m"]), float(r["y_m"])) for r in (first, rows[len(rows) // 2], last)]
    (ax, ay), (bx, by), (cx, cy) = xs
    d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    ux = ((ax**2 + ay**2) * (by - cy) + (bx**2 + by**2) * (cy - ay) + (cx**2 + cy**2) * (ay - by)) / d
    uy = ((ax**2 + ay**2) * (cx - bx) + (bx**2 + by**2) * (ax - cx) + (cx**2 + cy**2) * (bx - ax)) / d
    assert 1.0 / math.hypot(ax - ux, ay - uy) == pytest.approx(k, rel=0.05)
    lat_axis = ellipse_for(PRESETS[vehicle], 0.8).lat_mps2
    assert run.summary["peaks"]["max_lateral_accel_mps2"] <= lat_axis
    assert 59.5 <= run.summary["odometer_m"] <= 60.0


@pytest.mark.parametrize("vehicle", PRESET_NAMES)
def test_command_stream_keeps_speed(vehicle: str) -> None:
    limit = 8.0
    events = [mv(round(0.5 + 0.2 * i, 2), 20.0, limit) for i in range(100)]
    run = simulate({"vehicle": vehicle, "start": "ready", "duration_s": 30, "events": events})
    speeds = run.column("speed_mps")
    ramp_done = next(t for t, v in speeds if v >= limit - 0.1)
    last_cmd = events[-1]["at_s"]
    between = [v for t, v in speeds if ramp_done <= t <= last_cmd]
    assert last_cmd - ramp_done > 3.0
    assert min(between) >= limit - 0.3
    assert max(v for _, v in speeds) < limit + 0.3
    assert abs(run.summary["final"]["speed_mps"]) < 0.05     # stops after the last one


@pytest.mark.parametrize("vehicle", PRESET_NAMES)
def test_reverse_after_forward_move(vehicle: str) -> None:
    run = simulate({"vehicle": vehicle, "start": "ready", "duration_s": 55,
                    "events": [mv(0.5, 20.0, 5.0), mv(25.0, 5.0, 1.5, kind="reverse")]},
                   keep=(Topic.MOVE_REPLY,))
    assert all(r.accepted for _, r in run.series[Topic.MOVE_REPLY])
    x_before = next(float(r["x_m"]) for r in run.rows if float(r["t_s"]) >= 25.0)
    backed = x_before - run.summary["final"]["x_m"]
    assert 4.7 <= backed <= 5.0
    gears = [r["gear"] for r in run.rows if float(r["t_s"]) >= 25.0]
    assert gears[-1] == PRESETS[vehicle].reverse_gear
    after = [e["to"] for e in run.events("speed_state") if e["t_s"] >= 10.0]
    assert after[-1] == "run"
    assert "idle" in after and "shifting" in after               # stopped, shifted through idle
    assert min(v for _, v in run.column("speed_mps")) < -0.5


@pytest.mark.parametrize("vehicle", PRESET_NAMES)
def test_obstacle_emergency_stop_then_resume(vehicle: str) -> None:
    run = simulate({"vehicle": vehicle, "start": "ready", "duration_s": 48,
                    "world": {"obstacles": [{"x_m": 40.0, "y_m": 0.0}]},
                    "events": [mv(0.5, 60.0, 8.0), mv(22.0, 10.0, 3.0),
                               {"at_s": 24.0, "world": {"obstacles": []}}, mv(25.0, 10.0, 3.0)]})
    estops = [e for e in run.events("estop") if e["source"] == "move"]
    assert len(estops) == 1 and estops[0]["reason"].startswith("radar: obstacle at")
    assert not run.summary["contact"]
    ranges = [v for _, v in run.column("radar_range_m")]
    assert min(ranges) > 0.0
    rejected = run.events("rejected")
    assert [(e["command"], e["reason"]) for e in rejected] == [("move", "not_ready")]
    x_stop = next(float(r["x_m"]) for r in run.rows if float(r["t_s"]) >= 24.0)
    assert x_stop < 40.0 - (PRESETS[vehicle].length_m - PRESETS[vehicle].rear_overhang_m)
    assert run.summary["final"]["x_m"] - x_stop == pytest.approx(10.0, abs=0.3)


@pytest.mark.parametrize("vehicle, fault_s", [("escape-hybrid", 5.4), ("ranger-6x6", 5.0)])
def test_brake_fade_learned_and_stops_inside_authorizations(vehicle: str, fault_s: float) -> None:
    # the fault comes while cruising, about 1 s before the first stop starts braking
    events = [mv(0.5, 40.0, 8.0), {"at_s": fault_s, "actuator": {"brake": {"effectiveness": 0.6}}},
              mv(20.5, 15.0, 8.0), mv(28.0, 15.0, 8.0), mv(36.0, 15.0, 8.0)]
    run = simulate({"vehicle": vehicle, "start": "ready", "duration_s": 46, "events": events},
                   keep=(ESTIMATES_TOPIC,))
    est = run.series[ESTIMATES_TOPIC]
    assert all(m.brake_effectiveness == pytest.approx(1.0, abs=0.03) for t, m in est if t < fault_s)
    converged = next(t for t, m in est if t > fault_s and abs(m.brake_effectiveness - 0.6) < 0.03)
    assert converged - fault_s < 5.0
    assert all(abs(m.brake_effectiveness - 0.6) < 0.05 for t, m in est if t > converged)
    odo = run.column("odometer_m")
    moves = [e for e in events if "move" in e]
    for i, e in enumerate(moves):
        start = next(o for t, o in odo if t >= e["at_s"])
        end_t = moves[i + 1]["at_s"] if i + 1 < len(moves) else math.inf
        reached = max(o for t, o in odo if e["at_s"] <= t < end_t)
        assert reached <= start + e["move"]["distance_m"] + 1e-3
    assert [e["code"] for e in run.events("speed_reduction")] == ["actuator"]


@pytest.mark.parametrize("vehicle, seed", [("escape-hybrid", 1), ("ranger-6x6", 2)])
def test_fake_planner_simulation_mode(vehicle: str, seed: int) -> None:
    def once() -> tuple:
        nodes = simulation_nodes(PRESETS[vehicle], seed)
        bus = LocalBus()
        truth = []
        contact = []
        bus.tap(lambda t, m: truth.append(m) if t == Topic.TRUTH else None)
        bus.tap(lambda t, m: contact.append(m.contact) if t == Topic.TRUTH else None)
        LockstepRuntime(nodes, bus).run(60.0)
        planner = nodes[1]
        return truth[-1], planner, any(contact)

    final, planner, contact = once()
    assert final.odometer_m > 60.0
    assert not contact
    assert planner.rejected == []
    assert len(planner.sent) > 100
    assert all(abs(c.curvature_1pm) <= PRESETS[vehicle].max_curvature_1pm for c in planner.sent)
    again, _, _ = once()
    assert (again.x_m, again.y_m) == (final.x_m, final.y_m)      # seeded: reproducible
