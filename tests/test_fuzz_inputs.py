"""Fuzzing every user-facing validator: scenario data and CLI arguments.

Whatever arrives, the outcome is a validated object or the documented error (ScenarioError,
exit code 2 with a one-line message), never another exception and never a traceback.
"""

from __future__ import annotations

import math
from datetime import timedelta
from pathlib import Path

import yaml
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from overdrive.cli.main import main
from overdrive.fuzzing import mutate
from overdrive.kits.frames import CanFrame, KitError
from overdrive.kits.pacmod3 import (
    AccelCmd,
    GlobalCmd,
    Pacmod3Codec,
    SteeringCmd,
    SupervisoryCtrl,
    VehicleSpeedRpt,
)
from overdrive.scenario.schema import EVENT_KINDS, ScenarioError, load_scenario, parse_scenario

scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12))
keys = st.one_of(st.sampled_from(["name", "vehicle", "duration_s", "world", "events", "expect",
                                  "friction", "grade_percent", "obstacles", "at_s", "preset",
                                  "distance_m", "maxspeed_mps", "curvature_1pm", "speed_mps",
                                  "seed", "start", "interface", "control", "sweep", *EVENT_KINDS]),
                 st.text(max_size=8))
data = st.recursive(scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(keys, children, max_size=5)), max_leaves=20)


@settings(max_examples=600, suppress_health_check=[HealthCheck.too_slow])
@given(data)
def test_scenario_validator_only_raises_scenario_error(raw) -> None:
    try:
        parse_scenario(raw, "fuzz.yaml")
    except ScenarioError as exc:
        assert str(exc).startswith("fuzz.yaml")


event = st.fixed_dictionaries({"at_s": st.one_of(st.floats(-1, 100), st.sampled_from([math.nan, math.inf]))},
                              optional={k: st.one_of(scalars, st.dictionaries(keys, scalars, max_size=4))
                                        for k in EVENT_KINDS})


@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(event, max_size=4), st.dictionaries(keys, scalars, max_size=3))
def test_structured_scenarios_validate_or_name_a_field(events, world) -> None:
    raw = {"name": "f", "duration_s": 5, "events": events, "world": world}
    try:
        scenario = parse_scenario(raw, "fuzz.yaml")
    except ScenarioError as exc:
        assert exc.field or exc.reason
        return
    for e in scenario.events:    # what validates is finite and in time order
        assert math.isfinite(e.at_s) and 0 <= e.at_s <= 5


argv_words = st.sampled_from(["sim", "sweep", "jaus", "decode", "encode", "replay", "plot",
                              "can-log", "export", "--format", "asc", "--dialect", "v14",
                              "--seed", "--out", "--runs", "--jobs", "-1", "0", "nan", "inf",
                              "zz", "01", "--quiet", "--realtime", "--xgv", "drive",
                              "move-server", "-s", "--duration-s", "1e309", "", "--help"])


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(argv_words, max_size=5))
def test_cli_arguments_never_crash(tmp_path_factory, argv) -> None:
    if "move-server" in argv and "-s" in argv and "--help" not in argv:
        return   # a valid simulation run: covered elsewhere, too slow for fuzzing
    out = tmp_path_factory.mktemp("cli")
    if "--out" in argv:
        argv = [str(out / "o") if a == "--out" else a for a in argv]
    result = CliRunner().invoke(main, argv)
    assert result.exit_code in (0, 1, 2), (argv, result.output)
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), (argv, result.exception)


def test_shipped_scenarios_round_trip_through_yaml() -> None:
    for path in sorted((Path(__file__).resolve().parent.parent / "scenarios").rglob("*.yaml")):
        raw = yaml.safe_load(path.read_text())
        assert parse_scenario(raw, str(path)).spec == parse_scenario(
            yaml.safe_load(yaml.safe_dump(raw)), str(path)).spec


# ----------------------------------------------------------------- the YAML loader

SHIPPED = sorted((Path(__file__).resolve().parent.parent / "scenarios").rglob("*.yaml"))
LOAD_BOUND = timedelta(seconds=5)   # issue 18: every hostile input ends within 5 s


def _load_file(directory: Path, content: bytes) -> None:
    """``load_scenario`` on a file with ``content``: a Scenario or a ScenarioError naming it."""
    path = directory / "fuzz.yaml"
    path.write_bytes(content)
    try:
        load_scenario(path)
    except ScenarioError as exc:
        assert str(exc).startswith(f"{path}") and "\n" not in str(exc), str(exc)


@settings(max_examples=400, deadline=LOAD_BOUND, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(SHIPPED), st.randoms(use_true_random=False), st.integers(1, 8))
def test_mutated_scenario_files_load_or_raise_scenario_error(tmp_path_factory, source, rng,
                                                             rounds) -> None:
    data = source.read_bytes()
    for _ in range(rounds):
        data = mutate(data, rng)
    _load_file(tmp_path_factory.getbasetemp(), data)


@settings(max_examples=300, deadline=LOAD_BOUND, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=512))
def test_random_bytes_load_or_raise_scenario_error(tmp_path_factory, data) -> None:
    _load_file(tmp_path_factory.getbasetemp(), data)


YAML_TOKENS = st.sampled_from([
    "[", "]", "{", "}", ", ", ": ", "- ", "\n", "\n  ", "\n    ", "&a ", "&b ", "*a", "*b",
    "<<: ", "? ", "!!binary ", "!!python/object:os.system ", "!x ", "---\n", "...\n", "'", '"',
    "#", "|\n  ", ">\n  ", "name", "t", "vehicle", "preset", "escape-hybrid", "mass_kg",
    "events", "at_s", "world", "friction", "1", "-1", "1e400", ".nan", ".inf", "0x1F", "1_0",
    "2001-13-45", "~", "=", "true", "on", "\ufeff", "\t", "\r\n", "é", "\x00", "9" * 120,
])


@settings(max_examples=600, deadline=LOAD_BOUND, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(YAML_TOKENS, max_size=60))
def test_yaml_token_soup_loads_or_raises_scenario_error(tmp_path_factory, tokens) -> None:
    """Anchors, aliases, tags, merge keys, nesting and odd scalars in random order."""
    _load_file(tmp_path_factory.getbasetemp(), "".join(tokens).encode("utf-8"))


@settings(max_examples=200, deadline=LOAD_BOUND, suppress_health_check=[HealthCheck.too_slow])
@given(data, st.integers(0, 3))
def test_random_structures_through_yaml_load_or_raise_scenario_error(tmp_path_factory, raw,
                                                                     nesting) -> None:
    """Random trees (as YAML with every float spelled out), nested a few levels deeper."""
    for _ in range(nesting):
        raw = {"name": "t", "world": [raw]}
    _load_file(tmp_path_factory.getbasetemp(), yaml.safe_dump(raw, allow_unicode=True).encode())


@settings(max_examples=50, deadline=LOAD_BOUND, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(2, 12), st.integers(2, 12))
def test_alias_fan_out_is_bounded(tmp_path_factory, levels, fan_out) -> None:
    """Billion-laughs shapes of any size: the expansion is counted, never walked."""
    lines = ["a0: &a0 [x]"]
    for i in range(1, levels):
        lines.append(f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * fan_out)}]")
    _load_file(tmp_path_factory.getbasetemp(), ("\n".join(lines) + "\nname: t\n").encode())


# ----------------------------------------------------------------- PACMod 3 CAN frames

PACMOD3 = (Pacmod3Codec("v3"), Pacmod3Codec("v14"))
PACMOD3_SEEDS = [codec.encode(msg) for codec, msg in [
    (PACMOD3[0], AccelCmd(enable=True, accel_ratio=0.5)),
    (PACMOD3[0], SteeringCmd(enable=True, position_rad=-1.0, rotation_rate_radps=2.0)),
    (PACMOD3[0], VehicleSpeedRpt(speed_mps=3.0, valid=True)),
    (PACMOD3[1], GlobalCmd(counter=5)),
    (PACMOD3[1], SupervisoryCtrl(counter=9, enable=True)),
    (PACMOD3[1], AccelCmd(enable=True, accel_ratio=0.25))]]


@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(PACMOD3_SEEDS), st.randoms(use_true_random=False), st.integers(1, 4),
       st.booleans())
def test_mutated_pacmod3_frames_decode_or_raise_kit_error(seed, rng, rounds, keep_id) -> None:
    """A garbage frame never becomes a message the encoder would refuse: whatever decodes
    encodes back to a frame that decodes to the same message; the rest is a KitError."""
    data = seed.data
    can_id = seed.arbitration_id
    for _ in range(rounds):
        data = mutate(data, rng)
        if not keep_id:
            can_id = rng.choice([can_id, can_id ^ 1, can_id + 1, rng.randrange(0x800)]) & 0x7FF
    try:
        frame = CanFrame(arbitration_id=can_id, data=data)
    except KitError:
        return
    for codec in PACMOD3:
        try:
            msg = codec.decode(frame)
        except KitError:
            continue
        assert codec.decode(codec.encode(msg)) == msg
