"""python-can's own configuration (the CAN_CONFIG environment variable, ~/can.conf) broken or
stale: every CAN command must say what is wrong and exit non-zero, never a traceback; and a value
a config file supplied must name the file it came from."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from overdrive.cli.main import main

VIRTUAL = ("--can-interface", "virtual", "--can-channel", "broken-config")


def commands(tmp_path: Path) -> dict[str, list[str]]:
    scenario = tmp_path / "s.yaml"
    scenario.write_text(yaml.safe_dump({"name": "c", "start": "ready", "seed": 1,
                                        "duration_s": 1.0, "events": []}))
    return {"drive": ["drive", "--can", "pacmod3", str(scenario), "--out",
                      str(tmp_path / "run"), *VIRTUAL],
            "can-monitor": ["can-monitor", "--duration", "0.2", *VIRTUAL],
            "kit-sim": ["kit-sim", "pacmod3", "--duration", "0.2", *VIRTUAL]}


BROKEN_ENV = {
    "CAN_CONFIG not JSON": {"CAN_CONFIG": "{not json"},
    "CAN_CONFIG a list": {"CAN_CONFIG": "[1, 2]"},
}
BROKEN_FILES = {
    "can.conf without a section": "interface = virtual\n",
    "can.conf with a section twice": "[default]\ninterface = virtual\n[default]\nchannel = x\n",
}


def run(tmp_path: Path, argv: list[str], env: dict[str, str]):
    result = CliRunner().invoke(main, argv, env={"HOME": str(tmp_path), **env})
    raised = result.exception if not isinstance(result.exception, SystemExit) else None
    return result, raised


@pytest.mark.parametrize("command", ["drive", "can-monitor", "kit-sim"])
@pytest.mark.parametrize("broken", list(BROKEN_ENV))
def test_a_broken_can_config_variable_is_a_clear_error(tmp_path, command, broken) -> None:
    """Measured 2026-11-26: CAN_CONFIG='{not json' -> JSONDecodeError traceback, exit 1;
    CAN_CONFIG='[1, 2]' -> TypeError traceback, in drive --can, can-monitor and kit-sim."""
    result, raised = run(tmp_path, commands(tmp_path)[command], BROKEN_ENV[broken])
    assert raised is None, f"{type(raised).__name__}: {raised}"
    assert result.exit_code != 0 and "CAN_CONFIG" in result.output


@pytest.mark.parametrize("command", ["drive", "can-monitor", "kit-sim"])
@pytest.mark.parametrize("broken", list(BROKEN_FILES))
def test_a_broken_can_conf_file_is_a_clear_error(tmp_path, command, broken) -> None:
    """Measured 2026-11-26: a ~/can.conf without a section header ->
    MissingSectionHeaderError traceback; with [default] twice -> DuplicateSectionError."""
    (tmp_path / "can.conf").write_text(BROKEN_FILES[broken])
    result, raised = run(tmp_path, commands(tmp_path)[command], {})
    assert raised is None, f"{type(raised).__name__}: {raised}"
    assert result.exit_code != 0 and "can.conf" in result.output


def test_a_nan_port_in_can_config_is_a_clear_error(tmp_path) -> None:
    """Measured 2026-11-26: CAN_CONFIG='{"port": NaN, ...}' (json.loads takes NaN) ->
    TypeError 'Port config must be string or integer!' traceback, exit 1."""
    env = {"CAN_CONFIG": '{"interface": "socketcand", "channel": "can0", '
                         '"host": "127.0.0.1", "port": NaN}'}
    result, raised = run(tmp_path, ["can-monitor", "--duration", "0.2"], env)
    assert raised is None, f"{type(raised).__name__}: {raised}"
    assert result.exit_code != 0


def test_a_stale_can_conf_value_names_the_file_it_came_from(tmp_path) -> None:
    """Measured 2026-11-26: with HOME=tmp and ~/can.conf supplying bitrate, the drive prints
    and can.json records 'config file [default] (~/can.conf, /etc/can.conf, ~/.can,
    ~/.canrc)': the operator is not told which file to fix (a system-wide /etc/can.conf and a
    stale ~/.canrc read the same)."""
    conf = tmp_path / ".canrc"
    conf.write_text("[default]\nbitrate = 250000\nreceive_own_messages = True\n")
    result, raised = run(tmp_path, commands(tmp_path)["drive"], {})
    assert raised is None
    assert "bitrate = 250000" in result.output, "the stale value is printed"
    line = next(x for x in result.output.split("; ") if x.startswith("bitrate"))
    assert str(conf) in line and "/etc/can.conf" not in line, line
