"""``overdrive xgv-sim`` and ``overdrive drive``: usage errors exit 2 with a one-line reason."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.runtime.udp import parse_address


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


@pytest.mark.parametrize(("text", "bind"), [
    ("127.0.0.1:²", True), ("127.0.0.1:١٢", False), ("host:0", False), ("host:65536", True),
    ("host:-1", True), ("host: 5", True), ("host:", True), (":5", True), ("host", True),
    ("host:000000001", True)])
def test_an_address_needs_ascii_digits_and_a_port_in_range(text: str, bind: bool) -> None:
    with pytest.raises(ValueError, match="--x: expected HOST:PORT") as err:
        parse_address(text, "--x", bind=bind)
    assert "\n" not in str(err.value)


def test_port_0_is_only_for_a_bind_and_a_default_port_fills_a_bare_host() -> None:
    assert parse_address("0.0.0.0:0", "--bind", bind=True) == ("0.0.0.0", 0)
    assert parse_address("xgv", "--xgv", bind=False, default_port=3794) == ("xgv", 3794)
    assert parse_address("10.0.0.2:65535", "--to", bind=False) == ("10.0.0.2", 65535)
    with pytest.raises(ValueError, match=r"port 1\.\.65535"):
        parse_address("10.0.0.2:0", "--xgv", bind=False, default_port=3794)


@pytest.mark.parametrize("args", [
    ["link-proxy", "--listen", "127.0.0.1:²", "--to", "127.0.0.1:9", "--duration-s", "0.1"],
    ["link-proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:0", "--duration-s", "0.1"],
    ["link-proxy", "--listen", "127.0.0.1:0", "--to", "127.0.0.1:9", "--from", "h:²"],
    ["drive", "--xgv", "127.0.0.1:0", "s.yaml"],
    ["drive", "--xgv", "127.0.0.1:³", "s.yaml"],
    ["drive", "--xgv", "127.0.0.1", "--bind", "0.0.0.0:¹", "s.yaml"]])
def test_a_bad_port_exits_2_with_one_line_and_no_traceback(args: list[str]) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and result.exception is not None
    assert isinstance(result.exception, SystemExit)
    assert "expected HOST" in result.output
