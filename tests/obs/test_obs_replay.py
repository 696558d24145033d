"""overdrive replay: an unchanged stack replays with no difference; a changed gain is caught."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from obs_helpers import record_run, speed_scenario

from overdrive.bus.faults import ChannelFaults
from overdrive.bus.local import LocalBus
from overdrive.cli.observe import replay as replay_command
from overdrive.dynamics import speed_control
from overdrive.observe.mcap_log import PUBLISHERS_TOPIC, McapRecorder
from overdrive.run import replay as replay_module
from overdrive.run.compose import build_nodes
from overdrive.run.replay import ReplayError, infer_publisher, replay
from overdrive.runtime.lockstep import LockstepRuntime
from overdrive.scenario.player import channel_faults
from overdrive.scenario.schema import parse_scenario


@pytest.fixture(scope="module")
def speed_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return record_run(speed_scenario(), tmp_path_factory.mktemp("speed"))


def test_unchanged_stack_replays_without_difference(speed_run: Path) -> None:
    report = replay(speed_run)
    assert report.servers == ["speed"] and report.played_back == ["vehicle", "scenario"]
    assert report.ticks == round(16 / 0.01) + 1
    assert report.compared >= 3 * report.ticks, "pedals, powertrain and state every tick"
    assert report.differences == 0 and report.first is None, report.format()
    assert "no differences" in report.format()


def test_changed_gain_reports_the_first_differing_decision(
        speed_run: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    tuned = speed_control.GAINS["escape-hybrid"]
    monkeypatch.setitem(speed_control.GAINS, "escape-hybrid",
                        msgspec.structs.replace(tuned, speed_kp_1ps=tuned.speed_kp_1ps * 1.5))
    report = replay(speed_run)
    assert report.differences > 0
    first = report.first
    assert first is not None and first.node == "speed"
    assert first.topic == "vehicle/pedals", first.describe()
    assert 7.0 < first.t_s < 8.0, "the speed loop runs once the server reaches run (~7.4 s)"
    assert set(first.fields) <= {"throttle_pct", "brake_pct"} and first.fields
    recorded, replayed = next(iter(first.fields.values()))
    assert recorded != replayed
    text = report.format()
    assert "first difference: t=" in text and "vehicle/pedals" in text and "speed" in text
    assert report.to_dict()["first"]["tick"] == first.tick


def test_channel_faults_are_reapplied(speed_run: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The recording holds the dropped SPSS (taps see messages before faults): replay must drop
    it again, or the speed server's replies differ."""
    monkeypatch.setattr(replay_module, "channel_faults", lambda scenario: ChannelFaults())
    report = replay(speed_run)
    assert report.differences > 0 and report.first is not None
    assert 12.4 < report.first.t_s < 12.8, report.first.describe()


def test_recording_without_publisher_index_is_attributed_by_topic(tmp_path: Path) -> None:
    scenario = parse_scenario(speed_scenario(duration_s=9, events=speed_scenario()["events"][:1]))
    nodes = build_nodes(scenario)
    bus = LocalBus()
    faults = channel_faults(scenario)
    bus.channel = faults
    path = tmp_path / "run.mcap"
    with McapRecorder(path, scenario=scenario) as rec:      # a plain tap: no wrap()
        bus.tap(rec.observe)
        runtime = LockstepRuntime(nodes, bus, 0.01)
        while runtime.tick <= 900:
            faults.now_s = runtime.tick * 0.01
            rec.set_time(faults.now_s)
            runtime.step()
    with open(path, "rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    assert PUBLISHERS_TOPIC not in topics
    report = replay(path)
    assert report.ticks == 901 and report.compared > 0
    assert report.differences == 0, report.format()


def test_infer_publisher() -> None:
    assert infer_publisher("sensors/gps_ins", {}, ["speed"]) == "vehicle"
    assert infer_publisher("events", {"source": "speed"}, ["speed"]) == "speed"
    assert infer_publisher("speed/set_speed", {}, ["speed"]) == "scenario"
    assert infer_publisher("speed/set_speed", {}, ["driving", "speed"]) == "driving"
    assert infer_publisher("vehicle/pedals", {"source": "scenario"}, []) == "scenario"
    assert infer_publisher("driving/advance", {"source": "lidar"}, ["driving"]) == "scenario"
    assert infer_publisher("speed/state", {}, ["speed"]) == "speed"
    with pytest.raises(ReplayError):
        infer_publisher("driving/unknown", {}, [])


def test_cli_exit_codes(speed_run: Path, tmp_path: Path,
                        monkeypatch: pytest.MonkeyPatch) -> None:
    runner = CliRunner()
    same = runner.invoke(replay_command, [str(speed_run.parent)])
    assert same.exit_code == 0, same.output
    assert "no differences" in same.output
    bogus = tmp_path / "bogus.mcap"
    bogus.write_bytes(b"not an mcap")
    bad = runner.invoke(replay_command, [str(bogus)])
    assert bad.exit_code == 2 and "bogus.mcap" in bad.output
    missing = runner.invoke(replay_command, [str(tmp_path / "nope.mcap")])
    assert missing.exit_code == 2
    tuned = speed_control.GAINS["escape-hybrid"]
    monkeypatch.setitem(speed_control.GAINS, "escape-hybrid",
                        msgspec.structs.replace(tuned, speed_kp_1ps=tuned.speed_kp_1ps * 1.5))
    differs = runner.invoke(replay_command, [str(speed_run), "--json"])
    assert differs.exit_code == 1, differs.output
    assert '"node": "speed"' in differs.output


def test_whole_stack_replays_without_difference(tmp_path: Path) -> None:
    pytest.importorskip("overdrive.servers.move")
    pytest.importorskip("overdrive.servers.driving")
    path = record_run({
        "name": "move-replay", "start": "ready", "seed": 5, "duration_s": 12,
        "world": {"obstacles": [{"x_m": 40, "y_m": 0}]},
        "events": [{"at_s": 0.5, "move": {"distance_m": 8, "maxspeed_mps": 3}},
                   {"at_s": 0.5, "max_speed": {"source": "map", "speed_mps": 4}},
                   {"at_s": 7.0, "reverse": {"distance_m": 2, "maxspeed_mps": 1}}]}, tmp_path)
    report = replay(path)
    assert report.servers == ["move", "driving", "speed"]
    assert min(report.per_node.values()) == 0 and report.compared > 5 * report.ticks
    assert report.differences == 0, report.format()
