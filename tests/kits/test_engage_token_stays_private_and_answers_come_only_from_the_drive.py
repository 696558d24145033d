"""The operator's engage channel against hostile local processes: the token the drive writes to
``RUN_DIR/engage.json`` must be readable by its user only, whatever was at that path before;
``overdrive engage`` must take its answer only from the drive it asked, and a hostile
engage.json must be a clear error, never a traceback."""

from __future__ import annotations

import json
import os
import socket
import stat
import threading

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.runtime.can_link import ENGAGE_FILE, EngageEndpoint, request_engage


def test_a_stale_world_readable_engage_file_does_not_expose_the_token(tmp_path) -> None:
    """Measured 2026-11-26: engage.json created beforehand with mode 0644 (a run folder
    reused, or prepared by another user in a shared /tmp folder) is still 0644 after the
    drive writes its token into it: any local user reads the token and engages."""
    path = tmp_path / ENGAGE_FILE
    path.write_text("{}")
    path.chmod(0o644)
    endpoint = EngageEndpoint(tmp_path)
    try:
        assert json.loads(path.read_text())["token"] == endpoint.token
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
    finally:
        endpoint.close()


def test_an_engage_file_symlink_is_not_followed(tmp_path) -> None:
    """Measured 2026-11-26: RUN_DIR/engage.json a symlink to OTHER/leak: the token is written
    to OTHER/leak, which remains after the drive ends (only the link is removed)."""
    other = tmp_path / "other"
    other.mkdir()
    run = tmp_path / "run"
    run.mkdir()
    (run / ENGAGE_FILE).symlink_to(other / "leak")
    try:
        endpoint = EngageEndpoint(run)
    except OSError:
        return   # refusing the path is a correct answer
    endpoint.close()
    assert not (other / "leak").exists(), "the token outlives the drive outside its run folder"


def test_an_answer_from_another_process_is_not_taken_for_the_drives(tmp_path) -> None:
    """Measured 2026-11-26: a local process that is not the drive (it learns the engage
    client's port from /proc/net/udp) answers {"ok": true, "state": "engaged"} first and
    `overdrive engage` reports the kit engaged while the drive never answered."""
    drive = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    drive.bind(("127.0.0.1", 0))           # the drive: reads requests, never answers
    forger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    forger.bind(("127.0.0.1", 0))
    (tmp_path / ENGAGE_FILE).write_text(json.dumps({
        "host": "127.0.0.1", "port": drive.getsockname()[1], "token": "t" * 32,
        "pid": os.getpid()}))

    def forge() -> None:
        drive.settimeout(3.0)
        _, client = drive.recvfrom(1024)
        forger.sendto(json.dumps({"ok": True, "state": "engaged", "reason": ""}).encode(),
                      client)

    thread = threading.Thread(target=forge)
    thread.start()
    try:
        with pytest.raises(OSError):   # no answer from the drive it asked
            request_engage(tmp_path, "engage", timeout_s=0.5)
    finally:
        thread.join()
        drive.close()
        forger.close()


@pytest.mark.parametrize("port", [70000, -5])
def test_an_engage_file_with_an_impossible_port_is_a_clear_error(tmp_path, port) -> None:
    """Measured 2026-11-26: engage.json with port 70000 or -5 -> OverflowError traceback,
    exit 1 (the documented exits: 0 engaged, 1 refused, 2 no drive there)."""
    (tmp_path / ENGAGE_FILE).write_text(json.dumps({"host": "127.0.0.1", "port": port,
                                                    "token": "x"}))
    result = CliRunner().invoke(main, ["engage", "--run", str(tmp_path)])
    assert not isinstance(result.exception, OverflowError), result.exception
    assert result.exit_code == 2, result.output
