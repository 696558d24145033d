"""The operator's engage endpoint (``runtime.can_link.EngageEndpoint``) and the CLI's usage
rules for ``drive --can`` and ``engage``."""

from __future__ import annotations

import json
import socket
import stat
import threading

import pytest
from click.testing import CliRunner

from overdrive.cli.main import main
from overdrive.runtime.can_link import ENGAGE_FILE, EngageEndpoint, request_engage


def send(port: int, payload: bytes) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.sendto(payload, ("127.0.0.1", port))


def test_the_endpoint_file_is_private_and_goes_with_the_drive(tmp_path) -> None:
    endpoint = EngageEndpoint(tmp_path)
    path = tmp_path / ENGAGE_FILE
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    info = json.loads(path.read_text())
    assert info["host"] == "127.0.0.1" and info["port"] == endpoint.port
    assert len(info["token"]) == 32
    endpoint.close()
    assert not path.exists()


@pytest.mark.parametrize("payload", [
    b"not json", b"[]", b'{"act": "engage"}', b'{"token": 5, "act": "engage"}',
    b'{"token": "0000", "act": "engage"}', b"x" * 600,
])
def test_requests_without_the_token_are_dropped_unanswered(tmp_path, payload) -> None:
    endpoint = EngageEndpoint(tmp_path)
    try:
        send(endpoint.port, payload)
        for _ in range(50):
            got = endpoint.requests()
            if got or endpoint.refused:
                break
            threading.Event().wait(0.01)
        assert got == [] and endpoint.refused == 1
    finally:
        endpoint.close()


@pytest.mark.parametrize("act", ["engage", "status", "reboot"])
def test_a_request_with_the_token_is_answered(tmp_path, act) -> None:
    endpoint = EngageEndpoint(tmp_path)
    answers: list = []

    def serve() -> None:
        for _ in range(200):
            for got, sender in endpoint.requests():
                answers.append(got)
                endpoint.answer(sender, {"ok": True, "state": "engaging", "reason": ""})
                return
            threading.Event().wait(0.005)

    thread = threading.Thread(target=serve)
    thread.start()
    try:
        if act == "reboot":
            info = json.loads((tmp_path / ENGAGE_FILE).read_text())
            send(endpoint.port, json.dumps({"token": info["token"], "act": act}).encode())
            thread.join()
            assert answers == [] and endpoint.refused == 1
        else:
            assert request_engage(tmp_path, act)["state"] == "engaging"
            thread.join()
            assert answers == [act]
    finally:
        endpoint.close()


@pytest.mark.parametrize("args", [
    ["drive", "s.yaml"],                                           # neither --xgv nor --can
    ["drive", "s.yaml", "--xgv", "127.0.0.1", "--can", "pacmod3"],  # both
    ["drive", "s.yaml", "--xgv", "127.0.0.1", "--engage"],          # a CAN flag on --xgv
    ["drive", "s.yaml", "--xgv", "127.0.0.1", "--bring-up", "brake"],
])
def test_drive_usage_errors_exit_2(tmp_path, args) -> None:
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2, result.output


def test_engage_without_a_running_drive_exits_2(tmp_path) -> None:
    result = CliRunner().invoke(main, ["engage", "--run", str(tmp_path)])
    assert result.exit_code == 2
    (tmp_path / ENGAGE_FILE).write_text('{"host": "10.0.0.1", "port": 1, "token": "x"}')
    result = CliRunner().invoke(main, ["engage", "--run", str(tmp_path)])
    assert result.exit_code == 2 and "not an engage endpoint" in result.output
