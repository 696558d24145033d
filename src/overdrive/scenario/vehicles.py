"""Vehicle files: one YAML file per vehicle, read with the hostile-input-safe reader.

A vehicle file holds ``name`` and every parameter of ``VehicleParams`` (units in the names, the
gear table as a list), each number with its source in a comment; ``vehicle_from_data`` in
``overdrive.dynamics.vehicle_params`` checks it, this module reads it. ``PRESETS`` are the files
shipped in the package (``overdrive/dynamics/vehicles/NAME.yaml``): the simulated vehicles every
preset sweep of the test suite runs on. ``KIT_VEHICLES`` (``vehicles/kits/NAME.yaml``) are the
shipped defaults of the CAN kits (``lexus-rx450h``, PACMod 3): named like presets, validated
through their kit's emulator, not (yet) across the simulation sweeps (docs/safety-case.md H85).

A scenario's ``vehicle`` (``vehicle_from_spec``) is one of:

- ``escape-hybrid``: a shipped preset;
- ``path/to/my-truck.yaml``: a vehicle file (a path relative to the scenario file's folder);
- ``{preset: NAME, PARAM: VALUE, ...}`` or ``{file: PATH, PARAM: VALUE, ...}``: with overrides;
- ``{name: NAME, ...every field...}``: a whole vehicle inline, as a vehicle file holds it. A
  scenario naming a file holds this once read (``Scenario.spec.vehicle``), so the copies of it a
  run makes (the launcher's JSON for its nodes, the scenario in ``run.mcap``, a sweep's samples)
  carry the parameters themselves, needing neither the file nor the scenario's folder.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from overdrive.dynamics.vehicle_params import (
    VehicleParams,
    VehicleSpecError,
    vehicle_from_data,
    with_overrides,
)
from overdrive.scenario.safe_yaml import InputError, load_yaml, one_line, read_text

PRESET_DIR = Path(str(resources.files("overdrive.dynamics").joinpath("vehicles")))
"""The shipped vehicle files (package data: ``tool.setuptools.package-data`` in pyproject)."""
FILE_SUFFIXES = (".yaml", ".yml")
MAX_PATH_CHARS = 4096


class VehicleFileError(ValueError):
    """An invalid vehicle file: ``str()`` is ``"<path>: <field>: <reason>"``."""

    def __init__(self, path: str, field: str, reason: str) -> None:
        self.path, self.field, self.reason = path, field, reason
        super().__init__(one_line(f"{path}: {field}: {reason}" if field else f"{path}: {reason}"))


def read_vehicle_file(path: str | Path) -> VehicleParams:
    """Read and check a vehicle file, or raise ``VehicleFileError`` naming the field path."""
    path = Path(path)
    try:
        data = load_yaml(read_text(path))
    except InputError as exc:
        raise VehicleFileError(str(path), exc.field, exc.reason) from None
    try:
        return vehicle_from_data(data)
    except VehicleSpecError as exc:
        raise VehicleFileError(str(path), exc.field, exc.reason) from None


def _load_presets(folder: Path = PRESET_DIR) -> dict[str, VehicleParams]:
    presets: dict[str, VehicleParams] = {}
    for path in sorted(folder.glob("*.yaml")):
        params = read_vehicle_file(path)
        if params.preset != path.stem:
            raise VehicleFileError(str(path), "name", f"{params.preset!r} must be the file's "
                                                      f"name {path.stem!r}")
        presets[params.preset] = params
    if not presets:
        raise VehicleFileError(str(PRESET_DIR), "", "no vehicle files (the package data is "
                                                    "missing from this install)")
    return presets


PRESETS: dict[str, VehicleParams] = _load_presets()
"""The shipped simulated vehicles by name, in file-name order."""
KIT_VEHICLES: dict[str, VehicleParams] = _load_presets(PRESET_DIR / "kits")
"""The CAN kits' default vehicles by name (a scenario or ``--vehicle`` names them as presets)."""
SHIPPED: dict[str, VehicleParams] = {**PRESETS, **KIT_VEHICLES}
"""Every vehicle the package ships, by name."""


def names_a_file(spec: Any) -> bool:
    """Whether a scenario's ``vehicle`` reads a vehicle file: a path (a ``/`` or a name ending in
    ``.yaml``/``.yml``) or ``{file: PATH, ...}``."""
    if isinstance(spec, str):
        return "/" in spec or spec.endswith(FILE_SUFFIXES)
    return isinstance(spec, dict) and "file" in spec


def vehicle_path(value: Any, base_dir: str | Path) -> Path:
    """The file a scenario's vehicle path names: relative paths from ``base_dir`` (the scenario
    file's folder)."""
    if not isinstance(value, str) or not value or "\0" in value or len(value) > MAX_PATH_CHARS:
        shown = f"{value!r:.40}" if isinstance(value, str) else type(value).__name__
        raise VehicleSpecError("file", "must be the path of a vehicle file (relative to the "
                                       f"scenario file's folder), got {shown}")
    return Path(base_dir) / value


def vehicle_from_spec(spec: Any, base_dir: str | Path = ".") -> VehicleParams:
    """The vehicle a scenario names (the forms are in the module docstring).

    Raises ``VehicleSpecError`` naming the field of the scenario's ``vehicle`` (an unknown
    preset, an override ``with_overrides`` refuses, a whole vehicle ``vehicle_from_data``
    refuses), or ``VehicleFileError`` naming the vehicle file and the field in it.
    """
    if isinstance(spec, str):
        spec = {"file": spec} if names_a_file(spec) else {"preset": spec}
    if not isinstance(spec, dict):
        raise VehicleSpecError("", "must be a preset name, the path of a vehicle file or a "
                                   "mapping")
    overrides = dict(spec)
    if "preset" in spec and "file" in spec:
        raise VehicleSpecError("file", "give preset: or file:, not both")
    if "file" in spec:
        path = vehicle_path(overrides.pop("file"), base_dir)
        base = read_vehicle_file(path)
        if base.preset in SHIPPED and base != SHIPPED[base.preset]:
            raise VehicleFileError(str(path), "name", _shipped_name(base.preset))
        return with_overrides(base, overrides)
    if "preset" in spec:
        name = overrides.pop("preset")
        if not isinstance(name, str) or name not in SHIPPED:
            raise VehicleSpecError("preset", f"unknown vehicle preset {name!r:.40} (known: "
                                             f"{', '.join(SHIPPED)}; a vehicle file is a path "
                                             "ending in .yaml)")
        return with_overrides(SHIPPED[name], overrides)
    if "name" in spec:
        params = vehicle_from_data(spec)
        if params.preset in SHIPPED and params != SHIPPED[params.preset]:
            raise VehicleSpecError("name", _shipped_name(params.preset))
        return params
    raise VehicleSpecError("", "a mapping needs preset: NAME or file: PATH (then the parameters "
                               "it overrides), or is a whole vehicle with every field of a "
                               "vehicle file")


def _shipped_name(name: str) -> str:
    """Why a vehicle of the user's own may not take a shipped preset's name with other values: a
    run's records name the vehicle, and the name picks the preset's tuned gains. The preset's own
    file (or a copy, or a recorded run of it) is that preset, and is taken."""
    return (f"{name!r} is the name of a shipped preset; give your vehicle its own name (or use "
            f"{{preset: {name}, PARAM: VALUE}} to change a few values)")
