"""CAN logs: the raw frames a run recorded on ``can/frames`` come out of ``run.mcap`` as
candump and ASC files that python-can's own readers read back to the same frames (id, data,
extended flag, direction, time), and any CAN log replays through the PACMod 3 decoder with
unknown and malformed frames counted and shown, never a crash."""

from __future__ import annotations

import math
from pathlib import Path

import can
import pytest
from click.testing import CliRunner

from overdrive.cli.can_log import can_log
from overdrive.kits.pacmod3 import (
    AccelCmd,
    BrakeCmd,
    Gear,
    Pacmod3Codec,
    ShiftCmd,
    SteeringCmd,
    SteeringRpt,
    VehicleSpeedRpt,
)
from overdrive.messages import CanFrameRecord, CanTraffic, NodeTick, Topic
from overdrive.observe.can_log import (
    CanLogError,
    CanReplay,
    export_can_log,
    read_can_traffic,
    replay_can_log,
)
from overdrive.observe.mcap_log import McapRecorder

CODEC = Pacmod3Codec()
PERIOD_S = 1 / 30            # PACMod's command period
START_S = 12.5               # a run clock that does not start at zero


def sample_frames() -> list[CanFrameRecord]:
    """Three command periods of a drive: four commands out, two reports in, per period, plus
    an extended-id frame and a frame of another ECU heard on the bus."""
    records: list[CanFrameRecord] = []
    for k in range(3):
        t = START_S + k * PERIOD_S
        tx = [AccelCmd(enable=True, accel_ratio=0.1 * k), BrakeCmd(enable=True, brake_ratio=0.3),
              SteeringCmd(enable=True, position_rad=-0.5 * k, rotation_rate_radps=3.3),
              ShiftCmd(enable=True, gear=Gear.FORWARD)]
        for i, msg in enumerate(tx):
            f = CODEC.encode(msg)
            records.append(CanFrameRecord(time_s=t + i * 0.0005, arbitration_id=f.arbitration_id,
                                          data=f.data, direction="tx"))
        for i, msg in enumerate([VehicleSpeedRpt(speed_mps=1.25 * k, valid=True),
                                 SteeringRpt(enabled=True, override_active=k == 2,
                                             manual_input=0.0, commanded_value=-0.5 * k,
                                             output_value=-0.5 * k)]):
            f = CODEC.encode(msg)
            records.append(CanFrameRecord(time_s=t + 0.01 + i * 0.001,
                                          arbitration_id=f.arbitration_id, data=f.data,
                                          direction="rx"))
    records.append(CanFrameRecord(time_s=START_S + 0.02, arbitration_id=0x18FEF100,
                                  data=bytes(range(8)), direction="rx", is_extended=True))
    records.append(CanFrameRecord(time_s=START_S + 0.03, arbitration_id=0x7DF, data=b"\x02\x01",
                                  direction="rx"))
    return records


def write_run(folder: Path, records: list[CanFrameRecord], chunks: int = 3) -> Path:
    """A run.mcap written by the project's recorder: the frames in ``chunks`` CanTraffic
    messages (as a CAN edge hands them over), with another channel beside them."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "run.mcap"
    size = math.ceil(len(records) / chunks)
    with McapRecorder(path, pose_topic=None) as recorder:
        for n in range(chunks):
            part = tuple(records[n * size:(n + 1) * size])
            if not part:
                continue
            recorder.set_time(max(r.time_s for r in part))
            recorder.observe(Topic.CAN_FRAMES, CanTraffic(channel="can0", frames=part))
            recorder.observe("node/tick", NodeTick(process="drive", seq=n))
    return path


def in_time_order(records: list[CanFrameRecord]) -> list[CanFrameRecord]:
    return sorted(records, key=lambda r: r.time_s)


def assert_same_frames(read: list[can.Message], records: list[CanFrameRecord],
                       time_offset_s: float) -> None:
    assert len(read) == len(records)
    for got, want in zip(read, in_time_order(records), strict=True):
        assert got.arbitration_id == want.arbitration_id
        assert bytes(got.data) == want.data
        assert got.is_extended_id == want.is_extended
        assert got.is_rx == (want.direction == "rx")
        assert got.timestamp == pytest.approx(want.time_s - time_offset_s, abs=1.5e-6)
        assert not got.is_error_frame and not got.is_remote_frame


def test_recorded_frames_read_back_from_run_mcap_in_order(tmp_path):
    records = sample_frames()
    write_run(tmp_path, records)
    read = [record for _, record in read_can_traffic(tmp_path)]
    assert read == records
    assert {channel for channel, _ in read_can_traffic(tmp_path / "run.mcap")} == {"can0"}


def test_candump_export_reads_back_as_the_same_frames_with_python_can(tmp_path):
    records = sample_frames()
    write_run(tmp_path, records)
    out = tmp_path / "can.log"
    assert export_can_log(tmp_path, out, "candump") == len(records)
    lines = out.read_text().splitlines()
    assert sum(line.endswith(" T") for line in lines) == 12      # the commands sent
    assert sum(line.endswith(" R") for line in lines) == 8       # reports and others heard
    assert_same_frames(list(can.LogReader(str(out))), records, 0.0)


def test_asc_export_reads_back_as_the_same_frames_with_python_can(tmp_path):
    records = sample_frames()
    write_run(tmp_path, records)
    out = tmp_path / "can.asc"
    assert export_can_log(tmp_path, out, "asc") == len(records)
    text = out.read_text()
    assert text.count(" Tx ") == 12 and text.count(" Rx ") == 8
    # ASC times are relative to the first frame
    first_s = min(r.time_s for r in records)
    assert_same_frames(list(can.LogReader(str(out))), records, first_s)


def test_a_run_without_can_frames_is_refused_and_nothing_is_written(tmp_path):
    path = tmp_path / "run.mcap"
    with McapRecorder(path, pose_topic=None) as recorder:
        recorder.observe("node/tick", NodeTick(process="drive", seq=0))
    with pytest.raises(CanLogError, match="no CAN frames"):
        export_can_log(tmp_path, tmp_path / "can.log", "candump")
    assert not (tmp_path / "can.log").exists()
    with pytest.raises(CanLogError, match="no such file"):
        export_can_log(tmp_path / "absent", tmp_path / "x.log", "candump")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "run.mcap").write_bytes(b"not an mcap file at all")
    with pytest.raises(CanLogError, match=r"not a readable run\.mcap"):
        export_can_log(tmp_path / "junk", tmp_path / "x.log", "candump")
    write_run(tmp_path / "run", sample_frames())
    with pytest.raises(CanLogError, match="cannot write"):
        export_can_log(tmp_path / "run", tmp_path / "run", "candump")   # a folder


def test_replay_decodes_what_it_can_and_counts_unknown_and_malformed_frames(tmp_path):
    log = tmp_path / "bus.log"
    log.write_text(
        "(0.000000) can0 100#0100FA0000000000 T\n"     # ACCEL_CMD 0.25
        "(0.010000) can0 100#0100FA T\n"               # ACCEL_CMD 3 bytes: malformed in v3
        "(0.020000) can0 7FF#00 R\n"                   # another ECU: unknown
        "(0.030000) can0 18FEF100#0001020304050607 R\n"   # extended: unknown
        "(0.040000) can0 400#FF6A010000000000 R\n"     # speed -1.5 m/s, valid
        "(0.050000) can0 12C#R T\n"                    # remote frame: malformed
        "(0.060000) can0 20000080#0000000000000000\n"  # error frame: malformed
        "(0.070000) can0 104#01FFFF0000000000 T\n"     # brake 65.535 of its travel: malformed
    )
    summary = CanReplay()
    got = list(replay_can_log(log, CODEC, summary))
    assert [g.kind for g in got] == ["decoded", "malformed", "unknown", "unknown", "decoded",
                                     "malformed", "malformed", "malformed"]
    assert got[0].message == AccelCmd(enable=True, accel_ratio=0.25)
    assert got[0].direction == "tx" and got[4].direction == "rx"
    assert got[4].message == VehicleSpeedRpt(speed_mps=-1.5, valid=True)
    assert summary.counts == {"decoded": 2, "unknown": 2, "malformed": 4}
    assert not summary.error
    # the same 3-byte ACCEL_CMD is a v14 frame
    assert next(iter(replay_can_log(log, Pacmod3Codec("v14")))).kind == "malformed"
    assert list(replay_can_log(log, Pacmod3Codec("v14")))[1].message == AccelCmd(
        enable=True, accel_ratio=0.25)


def test_replay_stops_at_an_unreadable_line_and_says_where(tmp_path):
    log = tmp_path / "bus.log"
    log.write_text("(0.000000) can0 400#00C8010000000000 R\nthis is not candump\n"
                   "(0.020000) can0 400#00C8010000000000 R\n")
    summary = CanReplay()
    got = list(replay_can_log(log, CODEC, summary))
    assert len(got) == 1 and got[0].kind == "decoded"
    assert "unreadable after 1 frames" in summary.error
    with pytest.raises(CanLogError, match="no such file"):
        list(replay_can_log(tmp_path / "absent.log", CODEC))
    other = tmp_path / "bus.xyz"
    other.write_text("")
    with pytest.raises(CanLogError):
        list(replay_can_log(other, CODEC))


def test_replay_reads_blf_written_by_python_can(tmp_path):
    blf = tmp_path / "bus.blf"
    frames = [CODEC.encode(ShiftCmd(enable=True, gear=Gear.PARK)),
              CODEC.encode(VehicleSpeedRpt(speed_mps=0.0, valid=True))]
    with can.BLFWriter(str(blf)) as writer:
        for i, f in enumerate(frames):
            writer.on_message_received(can.Message(timestamp=1.0 + i, arbitration_id=f.arbitration_id,
                                                   data=f.data, is_extended_id=False,
                                                   is_rx=bool(i)))
    got = list(replay_can_log(blf, CODEC))
    assert [g.message for g in got] == [CODEC.decode(f) for f in frames]
    assert [g.direction for g in got] == ["tx", "rx"]


def test_cli_export_then_replay_end_to_end(tmp_path):
    records = sample_frames()
    write_run(tmp_path / "run", records)
    runner = CliRunner()
    result = runner.invoke(can_log, ["export", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "run" / "can.log").is_file()
    result = runner.invoke(can_log, ["export", str(tmp_path / "run"), "--format", "asc",
                                     "--out", str(tmp_path / "out" / "drive.asc")])
    assert result.exit_code == 0, result.output
    assert "20 frames" in result.output
    for log in (tmp_path / "run" / "can.log", tmp_path / "out" / "drive.asc"):
        result = runner.invoke(can_log, ["replay", str(log)])
        assert result.exit_code == 0, result.output
        assert result.output.strip().splitlines()[-1] == (
            "20 frames: 18 decoded, 2 unknown, 0 malformed")
        assert "SteeringRpt(enabled=True, override_active=True" in result.output


def test_cli_exit_codes_name_the_problem(tmp_path):
    runner = CliRunner()
    result = runner.invoke(can_log, ["export", str(tmp_path / "absent")])
    assert result.exit_code == 2 and "no such file" in result.output
    assert not (tmp_path / "absent").exists()
    bad = tmp_path / "bad.log"
    bad.write_text("(0.000000) can0 100#01 T\n")
    result = runner.invoke(can_log, ["replay", str(bad)])
    assert result.exit_code == 1 and "malformed" in result.output
    result = runner.invoke(can_log, ["replay", str(bad), "--dbc", str(tmp_path / "none.dbc")])
    assert result.exit_code == 2 and "cannot read" in result.output
    garbage = tmp_path / "garbage.log"
    garbage.write_text("garbage\n")
    result = runner.invoke(can_log, ["replay", str(garbage), "--quiet"])
    assert result.exit_code == 2 and "stopped" in result.output
