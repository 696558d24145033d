"""Vehicles as files: the shipped presets load to exactly the values they had as Python objects,
every number in a vehicle file carries its source, a bad vehicle file is refused naming the
scenario, the vehicle file and the field path (exit 2, one line, through the real CLI), and a
scenario names a preset, a file (relative to its own folder) or either with overrides; a copy of
a scenario naming a file (the launcher's JSON for its nodes, the scenario in run.mcap, a sweep's
samples) carries the vehicle itself."""

from __future__ import annotations

import fnmatch
import math
import re
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest
import yaml
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.dynamics.vehicle_params import (
    FILE_FIELDS,
    GEAR_RANGES,
    MAX_GEARS,
    PLAUSIBLE_RANGES,
    Gear,
    VehicleParams,
    VehicleSpecError,
    vehicle_from_data,
    vehicle_to_data,
)
from overdrive.observe.mcap_log import scenario_yaml
from overdrive.run.sweep import load_raw
from overdrive.scenario.schema import (
    ScenarioError,
    load_scenario,
    load_scenario_text,
    parse_scenario,
)
from overdrive.scenario.vehicles import (
    KIT_VEHICLES,
    PRESET_DIR,
    PRESETS,
    SHIPPED,
    read_vehicle_file,
    vehicle_from_spec,
)
from tests.test_hostile_inputs import _bomb, assert_usage_error, overdrive

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "docs" / "examples"
TEMPLATE = EXAMPLES / "my-van.yaml"
EXAMPLE_SCENARIO = EXAMPLES / "my-van-drive.yaml"
MPH = 0.44704

# ----------------------------------------------------------- the presets as they were in Python

REFERENCE: dict[str, VehicleParams] = {
    # The presets as src/overdrive/dynamics/vehicle_params.py built them before they became files
    # (commit 133e661), kept verbatim: the files must load to exactly these floats.
    "escape-hybrid": VehicleParams(
        preset="escape-hybrid",
        length_m=4.44, width_m=1.78, wheelbase_m=2.62, rear_overhang_m=0.92,
        mass_kg=1700.0,
        drag_area_m2=0.42 * 2.4,
        rolling_resistance=0.012,
        driven_weight_fraction=0.6,
        max_power_w=115_000.0,
        idle_rpm=800.0, redline_rpm=5500.0,
        gears=(
            Gear("park", 0, 0.0, 0.0, holds=True),
            Gear("reverse", -1, 9.0, 5000.0),
            Gear("neutral", 0, 0.0, 0.0),
            Gear("drive", 1, 45.0, 5200.0),
            Gear("low", 1, 20.0, 6000.0, engine_brake_decel_mps2=1.0),
        ),
        park_gear="park", drive_gear="drive", low_gear="low", reverse_gear="reverse",
        shift_time_s=0.5, shift_only_stopped=False, crank_time_s=1.2,
        max_brake_decel_mps2=9.0,
        max_steer_rad=math.atan(2.62 / 5.6),
        steer_rate_rps=0.5,
        skidpad_lat_g=0.74,
        stopping_distance_60mph_m=41.0,
        max_pitch_rad=math.atan(0.30),
        # issue 30 item 4 (added since): engine braking above, the parking brake here
        park_brake_decel_mps2=2.44, park_brake_apply_s=1.0, park_brake_max_apply_mps=10.0,
        # issue 31 item 7 (added since): rollover
        track_width_m=1.54, cg_height_m=0.66,
    ),
    "ranger-6x6": VehicleParams(
        preset="ranger-6x6",
        length_m=3.65, width_m=1.52, wheelbase_m=2.45, rear_overhang_m=0.55,
        mass_kg=1050.0,
        drag_area_m2=1.1 * 1.9,
        rolling_resistance=0.03,
        driven_weight_fraction=0.67,
        max_power_w=15_000.0,
        idle_rpm=1200.0, redline_rpm=4500.0,
        gears=(
            Gear("neutral", 0, 0.0, 0.0),
            Gear("low6wd", 1, 10.0 * MPH, 6500.0, all_wheel=True),
            Gear("low", 1, 17.0 * MPH, 4500.0),
            Gear("high", 1, 25.0 * MPH, 2600.0),
            Gear("reverse", -1, 8.0 * MPH, 4000.0),
        ),
        park_gear="neutral", drive_gear="high", low_gear="low6wd", reverse_gear="reverse",
        shift_time_s=1.5, shift_only_stopped=True, crank_time_s=2.0,
        max_brake_decel_mps2=6.5,
        max_steer_rad=math.atan(2.45 / 6.1),
        steer_rate_rps=0.35,
        skidpad_lat_g=0.55,
        stopping_distance_60mph_m=60.0,
        max_pitch_rad=math.atan(0.35),
        # issue 30 item 4 (added since): the parking brake (no engine braking)
        park_brake_decel_mps2=2.0, park_brake_apply_s=1.5, park_brake_max_apply_mps=25.0 * MPH,
        # issue 31 item 7 (added since): rollover
        track_width_m=1.22, cg_height_m=0.75,
    ),
}


def _typed(value: Any) -> Any:
    """``value`` with the type of every number kept: 1700 and 1700.0 compare equal, these not."""
    if isinstance(value, msgspec.Struct):
        return _typed(msgspec.structs.asdict(value))
    if isinstance(value, dict):
        return {k: _typed(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_typed(v) for v in value]
    return (type(value).__name__, value.hex() if isinstance(value, float) else value)


def test_the_shipped_presets_are_the_files_in_file_name_order() -> None:
    assert (list(PRESETS) == sorted(REFERENCE)
            == [p.stem for p in sorted(PRESET_DIR.glob("*.yaml"))])
    assert list(KIT_VEHICLES) == [p.stem for p in sorted((PRESET_DIR / "kits").glob("*.yaml"))]
    assert set(SHIPPED) == set(PRESETS) | set(KIT_VEHICLES)
    assert not set(PRESETS) & set(KIT_VEHICLES)


def test_a_kit_vehicle_is_named_like_a_preset_and_round_trips_through_plain_data() -> None:
    params = vehicle_from_spec("lexus-rx450h")
    assert params == KIT_VEHICLES["lexus-rx450h"] and params.wheelbase_m == 2.79
    data = vehicle_to_data(params)
    assert tuple(data) == FILE_FIELDS and vehicle_from_data(data) == params


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_each_preset_file_loads_to_exactly_the_old_python_values(name: str) -> None:
    loaded = read_vehicle_file(PRESET_DIR / f"{name}.yaml")
    assert loaded == REFERENCE[name] == PRESETS[name]
    assert _typed(loaded) == _typed(REFERENCE[name]), "same values, same types, same bits"


@pytest.mark.parametrize("name", sorted(REFERENCE))
def test_a_preset_round_trips_through_plain_data(name: str) -> None:
    data = vehicle_to_data(PRESETS[name])
    assert tuple(data) == FILE_FIELDS
    assert vehicle_from_data(data) == PRESETS[name]
    assert list(yaml.safe_load((PRESET_DIR / f"{name}.yaml").read_text())) == list(FILE_FIELDS)


def test_the_package_data_glob_carries_every_shipped_vehicle_file() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    globs = config["tool"]["setuptools"]["package-data"]["overdrive"]
    package = ROOT / "src" / "overdrive"
    for path in PRESET_DIR.glob("*.yaml"):
        relative = path.relative_to(package).as_posix()
        assert any(fnmatch.fnmatch(relative, g) for g in globs), (relative, globs)


# ------------------------------------------------------------- every number says where it's from

_NUMBER = re.compile(r"(?:^|[{,]\s*)([a-z_0-9]+):\s*(-?[0-9][0-9_.e+-]*)\s*(?=[,}]|#|$)")
_FORMULA = re.compile(r"#\s*=\s*([^:]+):")


def _formula_value(expr: str) -> float:
    expr = re.sub(r"^([0-9.]+) mph$", rf"\1 * {MPH}", expr.strip())
    assert re.fullmatch(r"[0-9.*/+\- ()a-z]+", expr), expr
    return eval(expr, {"__builtins__": {}}, {"atan": math.atan})


@pytest.mark.parametrize("path", [*sorted(PRESET_DIR.glob("*.yaml")), TEMPLATE],
                         ids=lambda p: p.name)
def test_every_number_in_a_vehicle_file_has_its_source_in_a_comment(path: Path) -> None:
    """A trailing comment on every line holding a number; a computed value (``= FORMULA:``) is
    the formula's float exactly in the shipped files (the template rounds: within 1e-12)."""
    numbers = 0
    for line in path.read_text(encoding="utf-8").splitlines():
        code = line.split("#", 1)[0]
        found = _NUMBER.findall(code)
        if not found:
            continue
        numbers += len(found)
        comment = line.partition("#")[2].strip()
        assert comment, f"{path.name}: no source for: {line}"
        formula = _FORMULA.search(line)
        if formula:
            _, text = next((k, v) for k, v in found if k in ("max_speed_mps", *PLAUSIBLE_RANGES))
            expected = _formula_value(formula.group(1))
            if path.parent == PRESET_DIR:
                assert float(text) == expected, (line, repr(expected))
            else:
                assert float(text) == pytest.approx(expected, rel=1e-12), line
    assert numbers >= len(PLAUSIBLE_RANGES) + 4 * 2, "the pattern missed the numbers"


# ------------------------------------------------------------------------------ bad vehicle files

def sub(pattern: str, replacement: str) -> Callable[[str], str]:
    def edit(text: str) -> str:
        changed, n = re.subn(pattern, replacement, text, count=1, flags=re.M)
        assert n == 1, pattern
        return changed
    return edit


def both(*edits: Callable[[str], str]) -> Callable[[str], str]:
    def edit(text: str) -> str:
        for one in edits:
            text = one(text)
        return text
    return edit


def data_edit(change: Callable[[dict[str, Any]], Any]) -> Callable[[str], str]:
    """An edit of the loaded template, written back as YAML (comments lost: the structure counts)."""
    def edit(text: str) -> str:
        data = yaml.safe_load(text)
        change(data)
        return yaml.safe_dump(data, sort_keys=False)
    return edit


def _drop(key: str) -> Callable[[dict[str, Any]], None]:
    return lambda d: d.pop(key)


def _set(key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    return lambda d: d.__setitem__(key, value)


def _gear(i: int, key: str, value: Any = None) -> Callable[[dict[str, Any]], None]:
    return lambda d: d["gears"][i].pop(key) if value is None else d["gears"][i].__setitem__(key, value)


BAD_FILES: dict[str, tuple[Callable[[str], str], str, tuple[str, ...]]] = {
    # case: (edit of the template, field path named, what the reason says)
    "wrong unit: mass in lb": (sub(r"^mass_kg:", "mass_lb:"), "mass_lb",
                               ("not a vehicle parameter", "did you mean mass_kg? (the unit is kg)")),
    "wrong unit: length in ft": (sub(r"^length_m:", "length_ft:"), "length_ft",
                                 ("did you mean length_m? (the unit is m)",)),
    "wrong unit: power in hp": (sub(r"^max_power_w:", "max_power_hp:"), "max_power_hp",
                                ("did you mean max_power_w? (the unit is W)",)),
    "wrong unit: steering lock in degrees": (sub(r"^max_steer_rad:", "max_steer_deg:"),
                                             "max_steer_deg", ("did you mean max_steer_rad?",)),
    "wrong unit in a gear": (sub(r"max_speed_mps: 40.0", "max_speed_mph: 90.0"),
                             "gears[3].max_speed_mph",
                             ("not a gear field", "did you mean max_speed_mps? (the unit is m/s)")),
    "misspelt field": (sub(r"^rolling_resistance:", "rolling_resistence:"), "rolling_resistence",
                       ("did you mean rolling_resistance?",)),
    "unknown field": (sub(r"^name: my-van", "name: my-van\ncolour: red"), "colour",
                      ("not a vehicle parameter",)),
    "preset instead of name": (sub(r"^name:", "preset:"), "preset", ("name:",)),
    "missing field": (sub(r"^width_m:.*\n", ""), "width_m", ("required field missing",)),
    "missing gear table": (data_edit(_drop("gears")), "gears", ("required field missing",)),
    "missing gear field": (data_edit(_gear(3, "max_force_n")), "gears[3].max_force_n",
                           ("required field missing",)),
    "quoted number": (sub(r"^mass_kg: 1600.0", 'mass_kg: "1600"'), "mass_kg",
                      ("must be a number", "the string '1600'")),
    "boolean as a number": (sub(r"^mass_kg: 1600.0", "mass_kg: true"), "mass_kg",
                            ("must be a number, got true",)),
    "fraction as a whole number": (sub(r"^start_failures: 0", "start_failures: 1.5"),
                                   "start_failures", ("whole number",)),
    "string as a boolean": (sub(r"^shift_only_stopped: false", 'shift_only_stopped: "false"'),
                            "shift_only_stopped", ("boolean",)),
    "number as a gear role": (sub(r"^low_gear: low", "low_gear: 1"), "low_gear", ("string",)),
    "NaN": (sub(r"^mass_kg: 1600.0", "mass_kg: .nan"), "mass_kg", ("finite", "nan")),
    "infinity": (sub(r"^max_power_w: 75000.0", "max_power_w: .inf"), "max_power_w", ("finite",)),
    "minus infinity in a gear": (sub(r"max_force_n: 5500.0", "max_force_n: -.inf"),
                                 "gears[3].max_force_n", ("finite",)),
    "implausible mass": (sub(r"^mass_kg: 1600.0", "mass_kg: 160000.0"), "mass_kg",
                         ("must be within 50..60000", "160000.0")),
    "implausible steering lock": (sub(r"^max_steer_rad: \S+", "max_steer_rad: 2.0"),
                                  "max_steer_rad", ("0.05..1.05",)),
    "implausible gear speed": (sub(r"max_speed_mps: 40.0", "max_speed_mps: 400.0"),
                               "gears[3].max_speed_mps", ("within 0..100",)),
    "negative gear force": (sub(r"max_force_n: 5500.0", "max_force_n: -5500.0"),
                            "gears[3].max_force_n", ("within 0..1e+06",)),
    "axles longer than the vehicle": (sub(r"^wheelbase_m: 2.66", "wheelbase_m: 3.66"),
                                      "wheelbase_m", ("longer than length_m 4.42",)),
    "idle above redline": (both(sub(r"^idle_rpm: 800.0", "idle_rpm: 2900.0"),
                                sub(r"^redline_rpm: 4500.0", "redline_rpm: 2500.0")), "idle_rpm",
                           ("idle_rpm 2900 must be below redline_rpm 2500",)),
    "gear role naming no gear": (sub(r"^low_gear: low", "low_gear: crawl"), "low_gear",
                                 ("'crawl' names no gear of my-van", "park, reverse, neutral")),
    "reverse as the low gear": (sub(r"^low_gear: low", "low_gear: reverse"), "low_gear",
                                ("direction -1", "forward gear")),
    "parked in drive": (sub(r"^park_gear: park", "park_gear: drive"), "park_gear",
                        ("direction 1", "does not drive")),
    "gears not a list": (data_edit(_set("gears", 5)), "gears", ("must be a list of gears",)),
    "no gears": (data_edit(_set("gears", [])), "gears", ("must be a list of gears",)),
    "too many gears": (data_edit(lambda d: d.__setitem__("gears", [
        {"name": f"g{i}", "direction": 1, "max_speed_mps": 10.0, "max_force_n": 1e3}
        for i in range(MAX_GEARS + 1)])), "gears", (f"at most {MAX_GEARS}",)),
    "gear not a mapping": (data_edit(lambda d: d["gears"].__setitem__(1, "reverse")), "gears[1]",
                           ("must be a mapping",)),
    "gear direction 2": (data_edit(_gear(3, "direction", 2)), "gears[3].direction",
                         ("must be 1 (forward), -1 (reverse) or 0",)),
    "gear direction as a fraction": (data_edit(_gear(3, "direction", 0.5)), "gears[3].direction",
                                     ("whole number",)),
    "gear name given twice": (data_edit(_gear(4, "name", "drive")), "gears[4].name",
                              ("already the name of gears[3]",)),
    "driving gear without a top speed": (data_edit(_gear(3, "max_speed_mps", 0.0)),
                                         "gears[3].max_speed_mps", ("needs a top speed",)),
    "vehicle name with spaces": (sub(r"^name: my-van", "name: my van!"), "name",
                                 ("letters, digits",)),
    "a shipped preset's name": (sub(r"^name: my-van", "name: ranger-6x6"), "name",
                                ("name of a shipped preset",)),
    "duplicate key": (sub(r"^mass_kg: 1600.0", "mass_kg: 1600.0\nmass_kg: 16.0"), "mass_kg",
                      ("duplicate key 'mass_kg'",)),
    "YAML tag": (sub(r"^mass_kg: 1600.0", "mass_kg: !!float 1600"), "mass_kg", ("YAML tags",)),
}

WHOLE_FILE: dict[str, tuple[bytes, tuple[str, ...]]] = {
    # case: (file content, what the one line says after "vehicle file PATH: ")
    "a list, not a mapping": (b"- a\n- b\n", ("a vehicle must be a mapping",)),
    "alias bomb": (_bomb(), ("more than 100000 values",)),
    "not UTF-8": (b"name: caf\xe9\n", ("not UTF-8",)),
    "empty": (b"", ("a vehicle must be a mapping", "null")),
}


def _scenario(folder: Path, vehicle: Any = "van.yaml") -> Path:
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump({"name": "t", "duration_s": 5, "vehicle": vehicle,
                                    "events": [{"at_s": 0.5, "engine": "on"}]}), encoding="utf-8")
    return path


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_bad_vehicle_file_names_the_scenario_the_file_and_the_field(tmp_path: Path,
                                                                     case: str) -> None:
    edit, field, needles = BAD_FILES[case]
    (tmp_path / "van.yaml").write_text(edit(TEMPLATE.read_text(encoding="utf-8")), encoding="utf-8")
    scenario = _scenario(tmp_path)
    with pytest.raises(ScenarioError) as info:
        load_scenario(scenario)
    message = str(info.value)
    assert message.startswith(f"{scenario}: vehicle file {tmp_path / 'van.yaml'}: {field}: "), message
    for needle in needles:
        assert needle in message, (needle, message)
    assert "\n" not in message


@pytest.mark.parametrize("case", sorted(WHOLE_FILE))
def test_a_vehicle_file_that_is_no_vehicle_is_refused_in_one_line(tmp_path: Path, case: str) -> None:
    content, needles = WHOLE_FILE[case]
    (tmp_path / "van.yaml").write_bytes(content)
    scenario = _scenario(tmp_path)
    with pytest.raises(ScenarioError) as info:
        load_scenario(scenario)
    message = str(info.value)
    assert message.startswith(f"{scenario}: vehicle file {tmp_path / 'van.yaml'}: "), message
    assert all(n in message for n in needles) and "\n" not in message, message


def test_a_missing_vehicle_file_is_named(tmp_path: Path) -> None:
    scenario = _scenario(tmp_path, "trucks/none.yaml")
    with pytest.raises(ScenarioError, match=re.escape(
            f"{scenario}: vehicle file {tmp_path / 'trucks' / 'none.yaml'}: cannot read: ")):
        load_scenario(scenario)


# ------------------------------------------------------------------ how a scenario names a vehicle

@pytest.fixture
def van(tmp_path: Path) -> Path:
    """The template as ``vehicles/van.yaml`` beside a scenario folder's file."""
    (tmp_path / "vehicles").mkdir()
    path = tmp_path / "vehicles" / "van.yaml"
    path.write_text(TEMPLATE.read_text(encoding="utf-8"), encoding="utf-8")
    return path


def test_a_vehicle_file_is_read_from_the_scenario_files_folder(tmp_path: Path, van: Path,
                                                              monkeypatch: pytest.MonkeyPatch) -> None:
    scenario = _scenario(tmp_path, "vehicles/van.yaml")
    monkeypatch.chdir(van.parent)   # not the working directory
    loaded = load_scenario(scenario)
    assert loaded.vehicle == read_vehicle_file(TEMPLATE)
    assert loaded.vehicle.preset == "my-van"


@pytest.mark.parametrize("spec,mass_kg", [
    ("vehicles/van.yaml", 1600.0),
    ({"file": "vehicles/van.yaml"}, 1600.0),
    ({"file": "vehicles/van.yaml", "mass_kg": 2400}, 2400.0),
])
def test_a_scenario_names_a_file_with_or_without_overrides(tmp_path: Path, van: Path,
                                                          spec: Any, mass_kg: float) -> None:
    vehicle = load_scenario(_scenario(tmp_path, spec)).vehicle
    assert vehicle.mass_kg == mass_kg and type(vehicle.mass_kg) is float
    assert msgspec.structs.replace(vehicle, mass_kg=1600.0) == read_vehicle_file(van)


def test_an_absolute_path_is_read_as_it_is(tmp_path: Path, van: Path) -> None:
    (tmp_path / "elsewhere").mkdir()
    scenario = _scenario(tmp_path / "elsewhere", str(van))
    assert load_scenario(scenario).vehicle.preset == "my-van"


@pytest.mark.parametrize("spec", ["escape-hybrid", {"preset": "ranger-6x6", "mass_kg": 1600}])
def test_a_preset_scenario_is_unchanged(spec: Any) -> None:
    scenario = parse_scenario({"name": "t", "vehicle": spec})
    assert scenario.spec.vehicle == spec
    name = spec if isinstance(spec, str) else spec["preset"]
    overrides = {} if isinstance(spec, str) else {k: v for k, v in spec.items() if k != "preset"}
    expected = msgspec.structs.replace(REFERENCE[name], **overrides)   # the Python presets
    assert scenario.vehicle == expected
    assert scenario.vehicle.gears == PRESETS[name].gears


BAD_SPECS: dict[str, tuple[Any, str, str]] = {
    # case: (the scenario's vehicle, field, what the reason says)
    "override in another unit": ({"file": "vehicles/van.yaml", "mass_lb": 3000}, "vehicle.mass_lb",
                                 "did you mean mass_kg? (the unit is kg)"),
    "preset override in another unit": ({"preset": "escape-hybrid", "mass_lb": 3000},
                                        "vehicle.mass_lb", "did you mean mass_kg?"),
    "implausible override of a file": ({"file": "vehicles/van.yaml", "mass_kg": -1},
                                       "vehicle.mass_kg", "within 50..60000"),
    "override that breaks the geometry": ({"file": "vehicles/van.yaml", "wheelbase_m": 4.0},
                                          "vehicle.wheelbase_m", "longer than length_m"),
    "override of the gear table": ({"file": "vehicles/van.yaml", "gears": []}, "vehicle.gears",
                                   "not a vehicle parameter"),
    "preset and file": ({"preset": "escape-hybrid", "file": "vehicles/van.yaml"}, "vehicle.file",
                        "not both"),
    "neither preset nor file": ({"mass_kg": 1200}, "vehicle", "needs preset: NAME or file: PATH"),
    "file not a path": ({"file": 5}, "vehicle.file", "must be the path of a vehicle file"),
    "path with a NUL byte": ({"file": "van\0.yaml"}, "vehicle.file", "must be the path"),
    "unknown preset": ("tractor", "vehicle", "a vehicle file is a path ending in .yaml"),
    "whole vehicle inline with a bad gear": (
        {**vehicle_to_data(PRESETS["ranger-6x6"]), "name": "r",
         "gears": [{"name": "n", "direction": 7, "max_speed_mps": 0.0, "max_force_n": 0.0}]},
        "vehicle.gears[0].direction", "must be 1 (forward)"),
    "whole vehicle inline under a preset's name, other values": (
        vehicle_to_data(msgspec.structs.replace(PRESETS["ranger-6x6"], mass_kg=2000.0)),
        "vehicle.name", "shipped preset"),
}


@pytest.mark.parametrize("case", sorted(BAD_SPECS))
def test_a_bad_vehicle_key_names_the_field_in_the_scenario(tmp_path: Path, van: Path,
                                                           case: str) -> None:
    spec, field, needle = BAD_SPECS[case]
    scenario = _scenario(tmp_path, spec)
    with pytest.raises(ScenarioError) as info:
        load_scenario(scenario)
    assert str(info.value).startswith(f"{scenario}: {field}: "), str(info.value)
    assert needle in str(info.value)


def test_the_pure_validation_names_the_field_without_any_file() -> None:
    with pytest.raises(VehicleSpecError) as info:
        vehicle_from_data({**vehicle_to_data(PRESETS["escape-hybrid"]), "mass_lb": 1.0})
    assert info.value.field == "mass_lb" and "did you mean mass_kg" in info.value.reason


def test_every_gear_number_has_a_plausible_range() -> None:
    numeric = {f for f in Gear.__struct_fields__ if f not in ("name", "direction", "holds",
                                                              "all_wheel")}
    assert numeric == set(GEAR_RANGES)


# --------------------------------------------------- copies of the scenario carry the vehicle

def test_a_scenario_naming_a_file_holds_the_vehicle_inline_once_read(tmp_path: Path,
                                                                    van: Path) -> None:
    loaded = load_scenario(_scenario(tmp_path, {"file": "vehicles/van.yaml", "mass_kg": 2400}))
    assert loaded.spec.vehicle == vehicle_to_data(loaded.vehicle)
    assert loaded.spec.vehicle["mass_kg"] == 2400.0


def test_the_launchers_json_copy_needs_neither_the_file_nor_the_folder(tmp_path: Path,
                                                                      van: Path) -> None:
    """As ``Launch.start`` writes it for its node processes, in the run's own folder."""
    loaded = load_scenario(_scenario(tmp_path, "vehicles/van.yaml"))
    nodes = tmp_path / "run" / "nodes"
    nodes.mkdir(parents=True)
    copy = nodes / "scenario.json"
    copy.write_bytes(msgspec.json.encode(msgspec.to_builtins(loaded.spec)))
    van.unlink()
    again = load_scenario(copy)
    assert again.vehicle == loaded.vehicle and _typed(again.vehicle) == _typed(loaded.vehicle)


def test_the_run_mcap_copy_replays_without_the_file(tmp_path: Path, van: Path) -> None:
    loaded = load_scenario(_scenario(tmp_path, "vehicles/van.yaml"))
    text = scenario_yaml(loaded)
    van.unlink()
    assert load_scenario_text(text, "run.mcap:scenario.yaml").vehicle == loaded.vehicle


def test_a_sweeps_samples_carry_the_vehicle(tmp_path: Path, van: Path,
                                            monkeypatch: pytest.MonkeyPatch) -> None:
    data, scenario = load_raw(_scenario(tmp_path, "vehicles/van.yaml"))
    monkeypatch.chdir(van.parent)
    assert parse_scenario(data, "sample (run 0)").vehicle == scenario.vehicle


# ------------------------------------------------------------------------ the real command line

CLI_CASES = ("wrong unit: mass in lb", "missing field", "implausible mass",
             "gear role naming no gear", "quoted number")


@pytest.mark.parametrize("case", CLI_CASES)
def test_overdrive_sim_refuses_a_bad_vehicle_file_exit_2_one_line(tmp_path: Path, case: str) -> None:
    edit, field, needles = BAD_FILES[case]
    (tmp_path / "van.yaml").write_text(edit(TEMPLATE.read_text(encoding="utf-8")), encoding="utf-8")
    scenario = _scenario(tmp_path)
    result = overdrive("sim", str(scenario), "--out", str(tmp_path / "run"), "--quiet",
                       cwd=tmp_path)
    assert_usage_error(result, f"error: {scenario}: vehicle file {tmp_path / 'van.yaml'}: {field}: ",
                       *needles)
    assert not (tmp_path / "run").exists(), "nothing may run on an invalid vehicle"


def test_the_worked_example_runs_with_exit_0(tmp_path: Path) -> None:
    """docs/drive-your-own-vehicle.md: the template vehicle file and the scenario naming it."""
    result = CliRunner().invoke(main, ["sim", str(EXAMPLE_SCENARIO), "--out",
                                       str(tmp_path / "run"), "--quiet"])
    assert result.exit_code == 0, result.output
    summary = msgspec.json.decode((tmp_path / "run" / "summary.json").read_bytes())
    assert summary["vehicle"]["preset"] == "my-van" and summary["violations"] == []


def test_a_presets_own_values_under_its_name_are_that_preset() -> None:
    """A recorded run of a preset (its values inline) or a copy of the preset's file is the
    preset: taken, not refused for its name."""
    scenario = parse_scenario({"name": "t", "vehicle": vehicle_to_data(PRESETS["ranger-6x6"])})
    assert scenario.vehicle == PRESETS["ranger-6x6"]
