"""Monte Carlo sweeps: sampling, parallel runs, invariant figures, replayable worst cases."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.run.sweep import sample_scenario, sweep
from overdrive.scenario.schema import SweepSpec

ROOT = Path(__file__).resolve().parent.parent
SPSS_LOSS = ROOT / "scenarios" / "sweep-spss-loss.yaml"


def test_sampling_is_seeded_and_within_ranges() -> None:
    data = yaml.safe_load(SPSS_LOSS.read_text())
    spec = SweepSpec(friction=(0.6, 1.0), grade_percent=(-5.0, 5.0), event_jitter_s=4.0)
    a = [sample_scenario(data, i, 100, spec) for i in range(50)]
    assert a == [sample_scenario(data, i, 100, spec) for i in range(50)], "deterministic"
    drops = [next(e for e in s["events"] if "drop" in e)["at_s"] for s in a]
    assert min(drops) >= 2.0 and max(drops) <= 10.0 and len(set(drops)) > 40
    assert all(0.6 <= s["world"]["friction"] <= 1.0 and -5 <= s["world"]["grade_percent"] <= 5 for s in a)
    commands = [next(e for e in s["events"] if "set_speed" in e)["at_s"] for s in a]
    assert set(commands) == {0.5}, "commands keep their times; only faults are jittered"


def test_spss_stream_lost_at_random_times_200_runs(tmp_path: Path) -> None:
    report = sweep(SPSS_LOSS, 200, 2, tmp_path)
    assert report["violations"] == 0, report["violating_runs"]
    runs = (tmp_path / "runs.csv").read_text().splitlines()[1:]
    assert len(runs) == 200
    rows = list(csv.DictReader((tmp_path / "runs.csv").read_text().splitlines()))
    estops = [int(row["estops"]) for row in rows]
    assert min(estops) >= 1, "every run shows the watchdog's emergency stop"
    assert report["expectation_failures"] == 0


def test_move_sweep_and_worst_cases_replay(tmp_path: Path) -> None:
    scenario = ROOT / "scenarios" / "move-straight.yaml"
    result = CliRunner().invoke(main, ["sweep", str(scenario), "--runs", "20", "--jobs", "2",
                                       "--out", str(tmp_path / "sw")])
    assert result.exit_code == 0, result.output
    assert "0 violations in 20 runs" in result.output
    report = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    worst = report["worst"][0]
    assert worst["authorization_margin_m"] >= 0.0
    replay = CliRunner().invoke(main, ["sim", str(tmp_path / "sw" / "worst" / f"run-{worst['run']}.yaml"),
                                       "--out", str(tmp_path / "replay"), "--quiet"])
    assert replay.exit_code in (0, 1)
    summary = json.loads((tmp_path / "replay" / "summary.json").read_text())
    assert min(s["authorization_margin_m"] for s in summary["stops"]) == worst["authorization_margin_m"]
    assert (tmp_path / "sw" / "distributions.png").stat().st_size > 10_000


def test_sweep_exits_1_on_invariant_violation(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"name": "bad", "duration_s": 3, "events": [
        {"at_s": 1, "actuators": {"throttle_pct": 10, "brake_pct": 10}}]}))
    result = CliRunner().invoke(main, ["sweep", str(bad), "--runs", "3", "--jobs", "1",
                                       "--out", str(tmp_path / "o")])
    assert result.exit_code == 1 and "3 violations in 3 runs" in result.output


def test_sweep_rejects_invalid_scenario(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nsweep: {friction: [0.2, 9]}\n")
    result = CliRunner().invoke(main, ["sweep", str(bad), "--runs", "2", "--out", str(tmp_path / "o")])
    assert result.exit_code == 2 and "sweep.friction" in result.output


FAULTS_SWEEP = ROOT / "scenarios" / "sweep-faults.yaml"


def test_every_swept_fault_kind_is_a_valid_scenario_event() -> None:
    import random

    from overdrive.run.sweep import fault_event
    from overdrive.scenario.schema import SWEPT_FAULTS, parse_scenario

    data = yaml.safe_load(FAULTS_SWEEP.read_text())
    data.pop("sweep")
    for kind in SWEPT_FAULTS:
        event = fault_event(kind, 3.0, random.Random(kind))
        parse_scenario({**data, "events": [*data["events"], event]}, kind)


@pytest.fixture(scope="module")
def fault_sweep(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("fault-sweep")
    return sweep(FAULTS_SWEEP, 30, 2, out), out


def test_fault_sweep_draws_faults_and_reports_per_fault_and_rule(fault_sweep) -> None:
    from overdrive.run.sweep import sample_run

    data = yaml.safe_load(FAULTS_SWEEP.read_text())
    spec = SweepSpec(**{**data["sweep"], "faults": None})
    assert sample_run(data, 0, 1, spec)[1] is None, "no faults block: no drawn fault"
    report, tmp_path = fault_sweep
    by_fault = report["runs_by_fault"]
    assert sum(row["runs"] for row in by_fault.values()) == 30
    assert len(by_fault) >= 10, "the draw covers most fault kinds"
    rows = list(csv.DictReader((tmp_path / "runs.csv").read_text().splitlines()))
    assert {r["fault"] for r in rows} - {""} == set(by_fault) - {"none"}
    violating = sum(row["violating"] for row in by_fault.values())
    assert violating == len(report["violating_runs"])
    for rule, runs in report["violations_by_rule"].items():
        assert runs == sum(row["rules"].get(rule, 0) for row in by_fault.values())


def test_fault_sweep_has_no_avoidable_violation(fault_sweep) -> None:
    """Only a run whose fault left no way to meet a rule may violate it, and only after the
    stack reacted (issue 16: brakes stuck released -> emergency stop, engine cut, fault)."""
    report, _ = fault_sweep
    assert report["avoidable_violating_runs"] == [], report["runs_by_fault"]
    assert len(report["unavoidable"]) == len(report["violating_runs"])


ESTOP = {"kind": "estop", "source": "speed", "code": "1133"}
BRAKE_STUCK = {"kind": "fault", "source": "speed", "code": "1133"}
TAKEOVER = {"kind": "takeover", "source": "speed", "code": "1133"}
REACTED = [ESTOP, BRAKE_STUCK, TAKEOVER]
USED = {"all_used": True, "within": True, "allowed_m": 20.0, "distance_m": 19.5}
NO_STOP = {"all_used": True, "within": False, "allowed_m": None, "distance_m": None}


@pytest.mark.parametrize(("fault", "rules", "events", "audit", "unavoidable"), [
    ("brake_stuck", ["authorization"], REACTED, USED, True),
    ("brake_stuck", ["authorization", "contact"], REACTED, USED, True),
    ("brake_stuck", ["authorization"], [{**e, "code": "1136"} for e in REACTED], USED, True),
    ("brake_stuck", ["speed"], REACTED, NO_STOP, True),             # coasting down a steep grade
    ("brake_stuck", ["authorization"], [ESTOP, TAKEOVER], USED, False),       # no fault reported
    ("brake_stuck", ["authorization"], [ESTOP, BRAKE_STUCK], USED, False),    # no takeover request
    ("brake_stuck", ["authorization"], [BRAKE_STUCK, TAKEOVER], USED, False),  # no emergency stop
    ("brake_stuck", ["authorization"], [{**e, "code": "1131"} for e in REACTED], USED, False),
    ("brake_stuck", ["authorization"], [ESTOP, {**BRAKE_STUCK, "source": "move"}, TAKEOVER], USED,
     False),
    ("brake_stuck", ["authorization"], REACTED, None, False),                 # no audit
    ("brake_stuck", ["authorization"], REACTED, {**USED, "all_used": False}, False),  # a means unused
    ("brake_stuck", ["authorization"], REACTED, {**USED, "within": False}, False),    # stopped too late
    ("brake_stuck", ["direction"], REACTED, USED, False),       # a rule it could meet
    ("throttle_stuck", ["authorization"], REACTED, USED, False),
    (None, ["authorization"], REACTED, USED, False),
    ("brake_stuck", [], REACTED, USED, False),                  # nothing to excuse
])
def test_a_violation_is_unavoidable_only_after_the_required_reaction(fault, rules, events, audit,
                                                                    unavoidable) -> None:
    from overdrive.run.sweep import BRAKE_LOST_CODES, unavoidable_cause
    from overdrive.safety.actuators import ActuatorFault

    assert {str(int(ActuatorFault.BRAKE_NOT_APPLYING)),
                                str(int(ActuatorFault.BRAKE_FAILED))} == BRAKE_LOST_CODES
    summary = {"events": events, "final": {"engine": "off"}, "secondary_braking": audit}
    assert (unavoidable_cause(fault, rules, summary) is not None) is unavoidable
