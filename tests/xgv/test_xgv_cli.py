"""``overdrive xgv-sim`` and ``overdrive drive``: usage errors exit 2 with a one-line reason."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main


@pytest.mark.parametrize("address", ["nohost:", ":3794", "host:99999", "host:abc"])
def test_drive_rejects_bad_addresses(address: str, tmp_path: Path) -> None:
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\nduration_s: 1\n")
    result = CliRunner().invoke(main, ["drive", "--xgv", address, str(scenario)])
    assert result.exit_code == 2
    assert "--xgv" in result.output


def test_drive_and_xgv_sim_reject_bad_scenarios(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\ninterface: serial\n")
    for args in (["drive", "--xgv", "127.0.0.1", str(bad)], ["xgv-sim", "--scenario", str(bad)]):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 2
        assert "interface" in result.output


@pytest.mark.wallclock
def test_xgv_sim_runs_for_its_duration_on_an_ephemeral_port() -> None:
    result = CliRunner().invoke(main, ["xgv-sim", "--port", "0", "--duration-s", "0.2"])
    assert result.exit_code == 0, result.output
    assert "JAUS/JUDP on 127.0.0.1:" in result.output
