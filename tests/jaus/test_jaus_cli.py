"""``jaus`` click group, through CliRunner: decode/encode, JSON contract, exit codes."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from overdrive.cli.jaus import jaus
from overdrive.jaus import (
    ReportHeartbeatPulse,
    ReportVehicleMode,
    SetWrenchEffort,
    decode,
    decode_datagram,
    encode,
    encode_datagram,
)

REQUEST_HEX = "06 02 0D 00 01 21 01 01 01 04 02 02 01 00 00 00 06"
MOTION_HEX = "86 02 28 E3 01 0A 01 01 01 04 02 01 0C 00 00 00 01 01 C4 89 1F 05 00 80 00 00 90 01"
CONTRACT_KEYS = {"code", "name", "priority", "ack_nak", "service_connection", "experimental",
                 "version", "destination", "source", "data_flag", "sequence", "fields"}  # fmt: skip


@pytest.fixture
def runner() -> CliRunner:
    return CliRunner()


def lines(output: str) -> list[dict]:  # type: ignore[type-arg]
    return [json.loads(line) for line in output.splitlines()]


def test_decode_single_message(runner: CliRunner) -> None:
    result = runner.invoke(jaus, ["decode", REQUEST_HEX])
    assert result.exit_code == 0, result.output
    (obj,) = lines(result.stdout)
    assert set(obj) >= CONTRACT_KEYS
    assert obj["code"] == 0x000D
    assert obj["name"] == "request-component-control"
    assert obj["destination"] == "1.1.33.1" and obj["source"] == "2.2.4.1"
    assert obj["priority"] == 6 and obj["version"] == 2 and obj["sequence"] == 0
    assert obj["experimental"] is False and obj["data_flag"] == 0
    assert obj["fields"] == {"authority": 6}


def test_decode_accepts_unquoted_and_compact_hex(runner: CliRunner) -> None:
    spaced = runner.invoke(jaus, ["decode", *MOTION_HEX.split()])
    compact = runner.invoke(jaus, ["decode", MOTION_HEX.replace(" ", "").lower()])
    assert spaced.exit_code == compact.exit_code == 0
    assert spaced.stdout == compact.stdout
    (obj,) = lines(spaced.stdout)
    assert obj["experimental"] is True
    (motion,) = obj["fields"]["motions"]
    assert motion["speed_mps"] == pytest.approx(5.0, abs=0.002)
    assert motion["duration_s"] == 0.4


def test_decode_datagram_prints_one_line_per_message(runner: CliRunner) -> None:
    datagram = encode_datagram(
        [SetWrenchEffort.xgv(throttle_pct=30.0, brake_pct=0.0), ReportVehicleMode(safety_mode=8)]
    )
    result = runner.invoke(jaus, ["decode", datagram.hex()])
    assert result.exit_code == 0, result.output
    first, second = lines(result.stdout)
    assert first["fields"] == {"propulsive_linear_x_pct": pytest.approx(30.0, abs=0.004),
                               "resistive_linear_x_pct": 0.0}  # fmt: skip
    assert second["fields"]["safety_mode_name"] == "estop-pause"


@pytest.mark.parametrize(
    ("args", "reason"),
    [
        (["decode", "06 02 0D"], "truncated"),
        (["decode", "zz"], "not hexadecimal"),
        (["decode", "0x"], "no hex"),
        (["decode", REQUEST_HEX + " 00"], "wrong length"),
        (["decode", "01 00 00 00 20" + REQUEST_HEX], "truncated message"),
        (["decode", "--as", "datagram", REQUEST_HEX], "transport version"),
        (["encode", "set-wrench-effort", "--throttle-pct", "nan"], "non-finite"),
        (["encode", "set-discrete-devices", "--gear", "300"], "gear"),
    ],
)
def test_malformed_input_exits_2_with_one_line(
    runner: CliRunner, args: list[str], reason: str
) -> None:
    result = runner.invoke(jaus, args)
    assert result.exit_code == 2
    assert result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1
    assert reason in result.stderr
    assert result.exception is None or isinstance(result.exception, SystemExit)


def test_encode_request_component_control_matches_reference(runner: CliRunner) -> None:
    result = runner.invoke(
        jaus, ["encode", "request-component-control", "--authority", "6", "--src", "2.2.4.1",
               "--dst", "1.1.33.1", "--seq", "0"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert result.stdout.strip() == REQUEST_HEX


def test_encode_motion_profile_matches_reference(runner: CliRunner) -> None:
    result = runner.invoke(
        jaus, ["encode", "set-motion-profile", "--speed-mps", "5", "--max-accel-mps2", "2",
               "--src", "1.2.4.1", "--dst", "1.1.10.1"],
    )  # fmt: skip
    assert result.stdout.strip() == MOTION_HEX


def test_encode_wrench_with_xgv_names_and_judp(runner: CliRunner) -> None:
    result = runner.invoke(
        jaus, ["encode", "set-wrench-effort", "--throttle-pct", "50", "--brake-pct", "25",
               "--seq", "9", "--priority", "12", "--judp"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    (message,) = decode_datagram(bytes.fromhex(result.stdout))
    assert encode(message)[16:] == bytes.fromhex("41 00 00 40 40")
    assert message.header.sequence == 9 and message.header.priority == 12


@pytest.mark.parametrize(
    ("args", "name", "fields"),
    [
        (["release-component-control"], "release-component-control", {}),
        (["resume"], "resume", {}),
        (["standby"], "standby", {}),
        (["query-component-status"], "query-component-status", {}),
        (["report-heartbeat-pulse"], "report-heartbeat-pulse", {}),
        (["set-discrete-devices", "--gear", "2"], "set-discrete-devices", {"gear": 2}),
        (["create-service-connection", "--command-code", "0x4404", "--rate-hz", "50",
          "--presence-vector", "1"], "create-service-connection",
         {"command_code": 0x4404, "presence_vector": 1}),
        (["set-signals", "--turn-signal", "3", "--lights-state", "2"], "set-signals",
         {"turn_signal": 3, "lights": {"state": 2, "period_on_raw": 0, "period_off_raw": 0}}),
        (["report-error-count", "--count", "4", "--count", "-1"], "report-error-count",
         {"counts": [4, -1]}),
        (["report-curvature", "--timestamp", "21:13:45:30.250"], "report-curvature",
         {"timestamp": {"day": 21, "hour": 13, "minute": 45, "second": 30, "millisecond": 250}}),
    ],
)  # fmt: skip
def test_encode_then_decode(runner: CliRunner, args: list[str], name: str, fields: dict) -> None:  # type: ignore[type-arg]
    encoded = runner.invoke(jaus, ["encode", *args])
    assert encoded.exit_code == 0, encoded.output
    decoded = runner.invoke(jaus, ["decode", encoded.stdout])
    (obj,) = lines(decoded.stdout)
    assert obj["name"] == name
    assert obj["fields"].items() >= fields.items()


def test_encode_defaults_address_the_right_component(runner: CliRunner) -> None:
    heartbeat = decode(
        bytes.fromhex(runner.invoke(jaus, ["encode", "report-heartbeat-pulse"]).stdout)
    )
    assert isinstance(heartbeat, ReportHeartbeatPulse)
    assert str(heartbeat.header.source) == "1.1.1.1"
    motion = runner.invoke(jaus, ["encode", "set-motion-profile", "--speed-mps", "1",
                                  "--max-accel-mps2", "1"])  # fmt: skip
    assert str(decode(bytes.fromhex(motion.stdout)).header.destination) == "1.1.10.1"


def test_bad_option_values_are_usage_errors(runner: CliRunner) -> None:
    result = runner.invoke(jaus, ["encode", "resume", "--dst", "1.1.33"])
    assert result.exit_code == 2
    assert "JAUS ID" in result.stderr
