"""Hostile inputs to the CAN commands: a user DBC that puts two of the messages the codec uses on
one id, a --dbc that is not a DBC by name, a CAN log that is not what its suffix says, a hub
address not ours. Each must be refused with a clear error and a non-zero exit, never loaded,
never a traceback."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.kits.frames import KitError
from overdrive.kits.pacmod3 import SHIPPED_DBC, Pacmod3Codec

SHARED_ID = {   # (message moved, onto the id of): a report onto a report, a report onto a command
    "BRAKE_RPT on ACCEL_RPT's id": ("BO_ 516 BRAKE_RPT", "BO_ 512 BRAKE_RPT"),
    "BRAKE_RPT on BRAKE_CMD's id": ("BO_ 516 BRAKE_RPT", "BO_ 260 BRAKE_RPT"),
}


@pytest.mark.parametrize("case", list(SHARED_ID))
def test_a_dbc_with_two_used_messages_on_one_id_is_refused(tmp_path, case) -> None:
    """Measured 2026-11-26: both DBCs load (11 ids instead of 12): frames on 0x200 decode as
    BRAKE_RPT, so the kit's accelerator report is read as the brake's (its enabled bit, its
    output), and ACCEL_RPT is never decoded."""
    old, new = SHARED_ID[case]
    dbc = tmp_path / "mine.dbc"
    dbc.write_text(SHIPPED_DBC.read_text().replace(old, new))
    with pytest.raises(KitError):
        Pacmod3Codec("v3", dbc)


@pytest.mark.parametrize("command", ["can-monitor", "can-log replay"])
def test_a_dbc_flag_naming_a_file_that_is_not_a_dbc_is_a_clear_error(tmp_path, command) -> None:
    """Measured 2026-11-26: --dbc FILE.log -> ValueError "expected database format 'arxml',
    'dbc', ..." traceback, exit 1 (drive --can refuses it cleanly with exit 2)."""
    bogus = tmp_path / "frames.log"
    bogus.write_text("(1.0) can0 400#0000000000000000\n")
    argv = (["can-monitor", "--can-interface", "virtual", "--can-channel", "dbc-flag",
             "--duration", "0.2"] if command == "can-monitor" else ["can-log", "replay",
                                                                   str(bogus)])
    result = CliRunner().invoke(main, [*argv, "--dbc", str(bogus)])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    assert result.exit_code == 2, result.output


def test_a_blf_log_that_is_garbage_is_a_clear_error(tmp_path) -> None:
    """Measured 2026-11-26: 500 bytes that are not BLF, named .blf -> BLFParseError
    traceback, exit 1 (a garbage .log or .asc is reported cleanly, exit 2)."""
    log = tmp_path / "garbage.blf"
    log.write_bytes(bytes(range(256)) * 2)
    result = CliRunner().invoke(main, ["can-log", "replay", str(log)])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    assert result.exit_code != 0


@pytest.mark.parametrize("host", ["192.0.2.1", "no-such-host.invalid"])
def test_a_hub_address_it_cannot_listen_on_is_a_clear_error(host) -> None:
    """Measured 2026-11-26: --host 8.8.8.8 (not this machine; 192.0.2.1 here) -> OSError
    [Errno 99] traceback; an unresolvable
    name -> OSError [Errno -2] traceback; both exit 1."""
    result = CliRunner().invoke(main, ["can-hub", "--host", host, "--port", "0"])
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    assert result.exit_code != 0
