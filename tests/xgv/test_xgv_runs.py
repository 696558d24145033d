"""The stack driving the simulated XGV: ``interface: jaus`` runs against the embedded ones,
the shipped xgv scenarios, determinism, sockets, and ``overdrive drive`` in wall-clock time."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest
import yaml
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.messages import PedalCommand, SteerCommand, Topic
from overdrive.run.sim import run_scenario
from overdrive.runtime.xgv_link import LoopbackLink
from overdrive.scenario.schema import Scenario, load_scenario, parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv_client import ESTOP_DECEL_MPS2, XgvClient, XgvClientConfig

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
SAME_PLACE_M = 0.5   # issue 7: embedded and jaus runs end within 0.5 m of each other


def variant(scenario: Scenario, interface: str, control: str) -> Scenario:
    return msgspec.structs.replace(scenario, spec=msgspec.structs.replace(
        scenario.spec, interface=interface, control=control))


def final_xy(summary: dict) -> tuple[float, float]:
    return summary["final"]["x_m"], summary["final"]["y_m"]


@pytest.fixture(scope="module")
def straight() -> dict[str, dict]:
    base = load_scenario(SCENARIOS / "move-straight.yaml")
    runs = {}
    for interface, control in (("embedded", "wrench"), ("jaus", "wrench"),
                               ("jaus", "motion-profile")):
        result = run_scenario(variant(base, interface, control), None, keep_trace=False)
        runs[f"{interface}/{control}"] = result.summary
        if interface == "jaus":
            link = result.nodes["xgv"].link      # type: ignore[attr-defined]
            assert link.closed and not link.sockets and link.lost == 0
    return runs


@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
def test_jaus_run_ends_where_the_embedded_run_ends(straight: dict[str, dict], control: str) -> None:
    embedded, jaus = straight["embedded/wrench"], straight[f"jaus/{control}"]
    assert embedded["violations"] == [] and jaus["violations"] == []
    gap = math.dist(final_xy(embedded), final_xy(jaus))
    assert gap <= SAME_PLACE_M, f"{control}: {gap:.3f} m apart"
    assert jaus["final"]["safety_mode"] == "drive-by-wire"
    assert not [e for e in jaus["events"] if e["kind"] in ("fault", "estop", "rejected")]


def test_motion_profile_on_a_curve_matches_embedded() -> None:
    base = load_scenario(SCENARIOS / "xgv-motion-profile-drive.yaml")
    embedded = run_scenario(variant(base, "embedded", "wrench"), None, keep_trace=False).summary
    memory = run_scenario(variant(base, "embedded", "motion-profile"), None,
                          keep_trace=False).summary
    jaus = run_scenario(base, None, keep_trace=False).summary
    assert embedded["violations"] == [] == jaus["violations"]
    assert math.dist(final_xy(embedded), final_xy(jaus)) <= SAME_PLACE_M
    # the in-memory link carries the same bytes: the same run, bit for bit
    assert memory["final"] == jaus["final"] and memory["events"] == jaus["events"]


@pytest.mark.parametrize("name", sorted(p.name for p in SCENARIOS.glob("xgv-*.yaml")))
def test_shipped_xgv_scenarios_hold(name: str) -> None:
    result = run_scenario(load_scenario(SCENARIOS / name), None, keep_trace=False)
    assert result.summary["violations"] == [], result.summary["violations"]
    assert result.exit_code == 0


def test_jaus_runs_are_deterministic() -> None:
    scenario = parse_scenario({
        "name": "det", "interface": "jaus", "start": "ready", "duration_s": 6, "seed": 5,
        "events": [{"at_s": 0.2, "move": {"distance_m": 3, "maxspeed_mps": 2}},
                   {"at_s": 3, "drop": {"channel": "jaus", "for_s": 0.3}}]}, "<det>")
    first = run_scenario(scenario, None, keep_trace=True)
    second = run_scenario(scenario, None, keep_trace=True)
    assert first.trace == second.trace and first.summary["events"] == second.summary["events"]


# --------------------------------------------------------------------------- the client alone

def test_client_rejects_commands_from_sources_without_control() -> None:
    client = XgvClient(PRESETS["escape-hybrid"])
    out = client.take_inputs([(Topic.PEDALS, PedalCommand(throttle_pct=90.0, brake_pct=0.0,
                                                           source="intruder")),
                              (Topic.STEER, SteerCommand(steer_pct=math.nan, source="driving"))])
    assert [n.code for _, n in out] == ["no_control"]
    assert client.pedals.throttle_pct == 0.0 and client.steer_pct == 0.0


def test_client_motion_profile_follows_the_speed_server() -> None:
    from overdrive.messages import SetSpeed, SpeedState

    client = XgvClient(PRESETS["escape-hybrid"], XgvClientConfig(control="motion-profile"))
    client.take_inputs([
        (Topic.SET_SPEED, SetSpeed(speed_mps=4.0, accel_mps2=1.2, gear="reverse", state="run")),
        (Topic.SPEED_STATE, SpeedState(speed_mps=0.0, accel_mps2=0.0, gear="reverse",
                                       state="run"))])
    assert client.motion_command()[:2] == (-4.0, 1.2)
    client.take_inputs([(Topic.SPEED_STATE, SpeedState(speed_mps=0.0, accel_mps2=0.0,
                                                       gear="reverse", state="run", estop=True))])
    assert client.motion_command()[:2] == (0.0, ESTOP_DECEL_MPS2)


def test_memory_link_drop_window() -> None:
    link = LoopbackLink("memory", [("drop", 1.0, 0.5, 0.0)])
    link.send("client", b"a", 0.5)
    link.send("client", b"b", 1.2)
    link.send("xgv", b"c", 1.6)
    assert [d for d, _ in link.receive("xgv", 1.6)] == [b"a"]
    assert [d for d, _ in link.receive("client", 1.6)] == [b"c"]


# --------------------------------------------------------------------------- overdrive drive

@pytest.mark.wallclock
def test_overdrive_drive_against_xgv_sim_in_wall_clock_time(tmp_path: Path) -> None:
    """Both commands as a user runs them: ``overdrive xgv-sim`` in its own process."""
    data = {"name": "drive-e2e", "interface": "jaus", "start": "ready", "duration_s": 13,
            "events": [{"at_s": 0.2, "move": {"distance_m": 1.5, "maxspeed_mps": 2}}],
            "expect": [{"final_speed_below_mps": 0.05}, {"odometer_between_m": [1.2, 1.55]}]}
    path = tmp_path / "drive.yaml"
    path.write_text(yaml.safe_dump(data))
    xgv = subprocess.Popen([sys.executable, "-m", "overdrive.cli.main", "xgv-sim", "--port", "0",
                            "--scenario", str(path), "--duration-s", "60"],
                           stderr=subprocess.PIPE, text=True)
    try:
        assert xgv.stderr is not None
        banner = xgv.stderr.readline()
        port = int(banner.rsplit(":", 1)[1].split()[0])
        result = CliRunner().invoke(main, ["drive", "--xgv", f"127.0.0.1:{port}", str(path),
                                           "--bind", "127.0.0.1:0", "--out",
                                           str(tmp_path / "run"), "--quiet"])
    finally:
        xgv.terminate()
        xgv.communicate(timeout=10)
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["violations"] == []
    assert summary["final"]["safety_mode"] == "drive-by-wire"
    assert (tmp_path / "run" / "trace.csv").stat().st_size > 0
