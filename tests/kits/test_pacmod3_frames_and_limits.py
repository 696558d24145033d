"""The PACMod 3 codec against frames worked out by hand from the DBC text and pacmod3_common's
generated C (tests/kits/pacmod3_layouts.py), with every value swept around its limit: what the
DBC can carry is encoded exactly, what it cannot (out of range, NaN, infinite, a report-only
gear) is refused with ``KitEncodeError``, never clamped or wrapped; frames of the wrong length,
extended or unknown ids, bad complements and out-of-range report values are refused on decoding
with the right error."""

from __future__ import annotations

import hashlib
import math
import shutil
from pathlib import Path

import pacmod3_layouts as L
import pytest

from overdrive.kits.frames import CanFrame, KitDecodeError, KitEncodeError, KitError, UnknownFrame
from overdrive.kits.pacmod3 import (
    SHIPPED_DBC,
    SHIPPED_DBC_SHA256,
    V14_GLOBAL_DBC,
    AccelCmd,
    AccelRpt,
    BrakeCmd,
    BrakeRpt,
    Gear,
    GlobalCmd,
    GlobalRpt,
    Pacmod3Codec,
    ShiftCmd,
    ShiftRpt,
    SteeringCmd,
    SteeringRpt,
    SupervisoryCtrl,
    VehicleSpeedRpt,
    WheelSpeedRpt,
    YawRateRpt,
    complement4,
)

V3 = Pacmod3Codec("v3")
V14 = Pacmod3Codec("v14")
NON_FINITE = (math.nan, math.inf, -math.inf)


def frame(can_id: int, hex_data: str) -> CanFrame:
    return CanFrame(arbitration_id=can_id, data=bytes.fromhex(hex_data))


# ----------------------------------------------------------------- known answers, by hand

KNOWN_V3 = [
    # 0.25 of the travel -> raw 250 = 0x00FA in bytes 1-2; ENABLE bit 0
    (AccelCmd(enable=True, accel_ratio=0.25), frame(0x100, "0100FA0000000000")),
    # all four flags (bits 1-3) with enable off; 1.0 -> raw 1000 = 0x03E8
    (AccelCmd(enable=False, ignore_overrides=True, clear_override=True, clear_faults=True,
              accel_ratio=1.0), frame(0x100, "0E03E80000000000")),
    (BrakeCmd(enable=True, brake_ratio=0.001), frame(0x104, "0100010000000000")),
    # -1 rad -> -1000 = 0xFC18 (two's complement), 2 rad/s -> 2000 = 0x07D0
    (SteeringCmd(enable=True, position_rad=-1.0, rotation_rate_radps=2.0),
     frame(0x12C, "01FC1807D0000000")),
    (SteeringCmd(enable=True, position_rad=32.767, rotation_rate_radps=65.535),
     frame(0x12C, "017FFFFFFF000000")),
    (SteeringCmd(enable=True, position_rad=-32.767, rotation_rate_radps=0.0),
     frame(0x12C, "0180010000000000")),
    (ShiftCmd(enable=True, gear=Gear.REVERSE), frame(0x128, "0101000000000000")),
    (ShiftCmd(enable=True, gear=Gear.NONE), frame(0x128, "0107000000000000")),
    # enabled, usr_can_timeout (bit 2), fault_active (bit 7); config fault byte 1 bit 7;
    # 0x1234 read errors in bytes 6-7
    (GlobalRpt(enabled=True, override_active=False, usr_can_timeout=True, str_can_timeout=False,
               brk_can_timeout=False, subsystem_timeout=False, veh_can_timeout=False,
               fault_active=True, config_fault_active=True, usr_can_read_errors=0x1234),
     frame(0x10, "8580000000001234")),
    (AccelRpt(enabled=True, override_active=True, vehicle_fault=True, manual_input=0.1,
              commanded_value=0.5, output_value=1.0), frame(0x200, "43006401F403E800")),
    (SteeringRpt(enabled=True, override_active=False, manual_input=-1.0, commanded_value=0.0,
                 output_value=1.5), frame(0x22C, "01FC18000005DC00")),
    (ShiftRpt(enabled=True, override_active=False, manual_input=Gear.BETWEEN_GEARS,
              commanded_value=Gear.FORWARD, output_value=Gear.ERROR),
     frame(0x228, "0105030600000000")),
    # -1.5 m/s -> -150 = 0xFF6A; VALID byte 2 bit 0
    (VehicleSpeedRpt(speed_mps=-1.5, valid=True), frame(0x400, "FF6A010000000000")),
    (WheelSpeedRpt(front_left_radps=327.67, front_right_radps=-0.01, rear_left_radps=1.0,
                   rear_right_radps=-327.68), frame(0x407, "7FFFFFFF00648000")),
    (YawRateRpt(yaw_rate_radps=0.5), frame(0x40D, "0032000000000000")),
]

KNOWN_V14 = [
    # sanity_check_required defaults on: d0 = 0b010; counter 0, complement 0xF -> d1 = 0xF0
    (GlobalCmd(counter=0), frame(0x80, "02F0")),
    # clear_faults | clear_overrides << 2 = 0x05; counter 11 = 0xB, complement 0x4 -> 0x4B
    (GlobalCmd(counter=11, clear_faults=True, clear_overrides=True, sanity_check_required=False),
     frame(0x80, "054B")),
    (SupervisoryCtrl(counter=15, enable=True), frame(0x81, "010F")),
    (SupervisoryCtrl(counter=1, enable=False), frame(0x81, "00E1")),
    (AccelCmd(enable=True, accel_ratio=0.25), frame(0x100, "0100FA")),
    (SteeringCmd(enable=True, ignore_overrides=True, position_rad=-1.0, rotation_rate_radps=2.0),
     frame(0x12C, "03FC1807D0")),
    (ShiftCmd(enable=True, gear=Gear.PARK), frame(0x128, "0100")),
    (VehicleSpeedRpt(speed_mps=2.0, valid=False), frame(0x400, "00C800")),
    (YawRateRpt(yaw_rate_radps=-0.01), frame(0x40D, "FFFF")),
    # command_timeout (bit 7), enabled
    (AccelRpt(enabled=True, override_active=False, command_timeout=True, manual_input=0.0,
              commanded_value=0.5, output_value=0.5), frame(0x200, "81000001F401F400")),
    (ShiftRpt(enabled=False, override_active=False, manual_input=3, commanded_value=3,
              output_value=3), frame(0x228, "00030303")),
    # the front-left wheel speed is signed in DBC 12 (int16_t WHEEL_SPD_AXLE_1_LEFT_ro)
    (WheelSpeedRpt(front_left_radps=-1.0, front_right_radps=0.0, rear_left_radps=0.0,
                   rear_right_radps=0.0), frame(0x407, "FF9C000000000000")),
    (GlobalRpt(enabled=False, override_active=False, usr_can_timeout=False, str_can_timeout=False,
               brk_can_timeout=False, subsystem_timeout=False, veh_can_timeout=False,
               fault_active=False, config_fault_active=False, usr_can_read_errors=0,
               supervisory_enable_required=True), frame(0x10, "0040000000000000")),
]


@pytest.mark.parametrize(("msg", "expected"), KNOWN_V3, ids=lambda x: type(x).__name__)
def test_v3_frames_are_the_ones_worked_out_by_hand(msg, expected):
    assert V3.encode(msg) == expected
    assert V3.decode(expected) == msg


@pytest.mark.parametrize(("msg", "expected"), KNOWN_V14, ids=lambda x: type(x).__name__)
def test_v14_frames_are_the_ones_pacmod12_c_packs(msg, expected):
    assert V14.encode(msg) == expected
    assert V14.decode(expected) == msg


def test_v3_front_left_wheel_speed_is_unsigned_as_its_dbc_says():
    """The v3.4.0 DBC declares WHEEL_SPD_FRONT_LEFT unsigned (``7|16@0+``) with a signed
    range: a negative speed cannot be put in it, and the raw 0xFFFF it would become on a kit
    that sends it signed decodes to 655.35 rad/s, outside the range: refused, never read as a
    speed."""
    with pytest.raises(KitEncodeError, match="WHEEL_SPEED_RPT"):
        V3.encode(WheelSpeedRpt(front_left_radps=-0.01, front_right_radps=0.0,
                                rear_left_radps=0.0, rear_right_radps=0.0))
    with pytest.raises(KitDecodeError, match="WHEEL_SPD_FRONT_LEFT"):
        V3.decode(frame(0x407, "FFFF000000000000"))
    assert V3.decode(frame(0x407, "7FFF000000000000")).front_left_radps == 327.67


# ----------------------------------------------------------------- sweeps around every limit

PEDAL_OK = (0.0, -0.0, 0.001, 0.5, 0.999, 1.0)
PEDAL_BAD = (-0.001, -1e-9, 1.0 + 1e-9, 1.001, 2.0, *NON_FINITE)


@pytest.mark.parametrize("cls", [AccelCmd, BrakeCmd])
@pytest.mark.parametrize("ratio", PEDAL_OK)
def test_pedal_ratio_inside_0_to_1_is_carried_to_the_bit(cls, ratio):
    field = "accel_ratio" if cls is AccelCmd else "brake_ratio"
    for codec in (V3, V14):
        sent = codec.encode(cls(enable=True, **{field: ratio}))
        assert L.uint16(sent.data, 1) == round(ratio * 1000)
        assert getattr(codec.decode(sent), field) == pytest.approx(ratio, abs=1e-12)


@pytest.mark.parametrize("cls", [AccelCmd, BrakeCmd])
@pytest.mark.parametrize("ratio", PEDAL_BAD)
def test_pedal_ratio_outside_0_to_1_or_not_finite_is_refused(cls, ratio):
    field = "accel_ratio" if cls is AccelCmd else "brake_ratio"
    for codec in (V3, V14):
        with pytest.raises(KitEncodeError):
            codec.encode(cls(enable=True, **{field: ratio}))


@pytest.mark.parametrize("position_rad", (-32.767, -1.0, -0.001, 0.0, 0.001, 32.767))
@pytest.mark.parametrize("rate_radps", (0.0, 0.001, 65.535))
def test_steering_inside_its_bits_is_carried_to_the_bit(position_rad, rate_radps):
    for codec in (V3, V14):
        sent = codec.encode(SteeringCmd(enable=True, position_rad=position_rad,
                                        rotation_rate_radps=rate_radps))
        assert L.s16(sent.data, 1) == round(position_rad * 1000)
        assert L.uint16(sent.data, 3) == round(rate_radps * 1000)
        got = codec.decode(sent)
        assert got.position_rad == pytest.approx(position_rad, abs=1e-12)
        assert got.rotation_rate_radps == pytest.approx(rate_radps, abs=1e-12)


@pytest.mark.parametrize(("position_rad", "rate_radps"), [
    (32.768, 1.0), (-32.768, 1.0), (32.7671, 1.0), (-40.0, 1.0), (0.0, 65.536), (0.0, -0.001),
    (0.0, 100.0), *((bad, 1.0) for bad in NON_FINITE), *((0.0, bad) for bad in NON_FINITE)])
def test_steering_beyond_its_bits_or_not_finite_is_refused(position_rad, rate_radps):
    for codec in (V3, V14):
        with pytest.raises(KitEncodeError):
            codec.encode(SteeringCmd(enable=True, position_rad=position_rad,
                                     rotation_rate_radps=rate_radps))


@pytest.mark.parametrize("gear", list(Gear))
def test_every_gear_a_command_may_carry_is_sent_and_report_only_gears_are_refused(gear):
    for codec in (V3, V14):
        if gear in (Gear.BETWEEN_GEARS, Gear.ERROR):
            with pytest.raises(KitEncodeError, match="report value"):
                codec.encode(ShiftCmd(enable=True, gear=gear))
            continue
        sent = codec.encode(ShiftCmd(enable=True, gear=gear))
        assert sent.data[1] == int(gear)
        assert codec.decode(sent).gear is gear


@pytest.mark.parametrize("raw", [5, 6, 8, 0x7F, 0xFF])
def test_a_shift_command_frame_with_a_gear_no_command_has_is_refused(raw):
    with pytest.raises(KitDecodeError):
        V3.decode(CanFrame(arbitration_id=0x128, data=L.pack_shift_cmd(1, 0, 0, 0, raw)))


@pytest.mark.parametrize("counter", range(16))
def test_every_counter_carries_its_complement_and_any_other_complement_is_refused(counter):
    for msg in (GlobalCmd(counter=counter), SupervisoryCtrl(counter=counter, enable=True)):
        sent = V14.encode(msg)
        assert sent.data[1] == counter | complement4(counter) << 4
        assert complement4(counter) == 15 - counter
        assert V14.decode(sent) == msg
        for wrong in range(16):
            if wrong != complement4(counter):
                bad = CanFrame(arbitration_id=sent.arbitration_id,
                               data=bytes([sent.data[0], counter | wrong << 4]))
                with pytest.raises(KitDecodeError, match="complement"):
                    V14.decode(bad)


@pytest.mark.parametrize("counter", [-1, 16, 17, 255])
def test_a_counter_outside_4_bits_is_refused_not_wrapped(counter):
    for msg in (GlobalCmd(counter=counter), SupervisoryCtrl(counter=counter, enable=True)):
        with pytest.raises(KitEncodeError, match="counter"):
            V14.encode(msg)


def test_report_floats_not_finite_are_refused():
    for bad in NON_FINITE:
        for msg in (VehicleSpeedRpt(speed_mps=bad, valid=True), YawRateRpt(yaw_rate_radps=bad),
                    AccelRpt(enabled=True, override_active=False, manual_input=bad,
                             commanded_value=0.0, output_value=0.0)):
            with pytest.raises(KitEncodeError, match="not finite"):
                V3.encode(msg)


@pytest.mark.parametrize(("can_id", "hex_data", "signal"), [
    (0x100, "0103E90000000000", "ACCEL_CMD"),          # 1.001 of the travel
    (0x104, "01FFFF0000000000", "BRAKE_CMD"),          # 65.535 of the travel
    (0x200, "0103E90000000000", "MANUAL_INPUT"),
    (0x204, "01000003E9000000", "COMMANDED_VALUE"),
    (0x228, "0108000000000000", "MANUAL_INPUT"),       # gear 8
    (0x228, "0100050000000000", "COMMANDED_VALUE"),    # a command cannot be between gears
    (0x12C, "0180000000000000", "position -32.768"),   # in the DBC range, not in +-32.767
])
def test_a_report_or_command_frame_outside_its_dbc_range_is_refused(can_id, hex_data, signal):
    with pytest.raises(KitDecodeError, match=signal):
        V3.decode(frame(can_id, hex_data))


# ----------------------------------------------------------------- frames that are not ours

@pytest.mark.parametrize("codec", [V3, V14], ids=["v3", "v14"])
def test_every_known_id_with_any_other_length_is_refused_as_malformed(codec):
    for can_id in sorted(codec.frame_ids):
        good = L.V3_LENGTH if codec is V3 else L.V14_LENGTH[can_id]
        for length in range(9):
            if length == good:
                continue
            with pytest.raises(KitDecodeError, match="bytes, expected") as err:
                codec.decode(CanFrame(arbitration_id=can_id, data=bytes(length)))
            assert not isinstance(err.value, UnknownFrame)


@pytest.mark.parametrize("can_id", [0x0, 0x11, 0x101, 0x12D, 0x7FF, 0x300])
def test_an_id_the_codec_does_not_read_is_an_unknown_frame(can_id):
    for codec in (V3, V14):
        with pytest.raises(UnknownFrame):
            codec.decode(CanFrame(arbitration_id=can_id, data=bytes(8)))


def test_v3_does_not_read_the_v14_global_commands():
    for can_id in (0x80, 0x81):
        with pytest.raises(UnknownFrame):
            V3.decode(frame(can_id, "02F0"))
    with pytest.raises(KitEncodeError, match="not a PACMod 3 v3 message"):
        V3.encode(GlobalCmd(counter=0))


def test_an_extended_id_is_an_unknown_frame_even_when_its_low_bits_match():
    for can_id in (0x100, 0x12C, 0x1FFFFFFF):
        with pytest.raises(UnknownFrame, match="extended"):
            V3.decode(CanFrame(arbitration_id=can_id, data=bytes(8), is_extended=True))


def test_a_can_frame_beyond_classic_can_cannot_be_made():
    with pytest.raises(KitDecodeError):
        CanFrame(arbitration_id=0x100, data=bytes(9))
    with pytest.raises(KitDecodeError):
        CanFrame(arbitration_id=0x800, data=bytes(8))
    with pytest.raises(KitDecodeError):
        CanFrame(arbitration_id=-1, data=b"")


def test_signals_a_dialect_lacks_decode_false_and_cannot_be_sent_set():
    """v14 moved CLEAR_FAULTS to GLOBAL_CMD; v3.4.0 has no per-system COMMAND_TIMEOUT."""
    with pytest.raises(KitEncodeError, match="GlobalCmd"):
        V14.encode(AccelCmd(enable=True, clear_faults=True, accel_ratio=0.0))
    with pytest.raises(KitEncodeError, match="COMMAND_TIMEOUT"):
        V3.encode(BrakeRpt(enabled=False, override_active=False, command_timeout=True,
                           manual_input=0.0, commanded_value=0.0, output_value=0.0))
    assert V14.decode(frame(0x100, "0F0000")).clear_faults is False   # bit 3 is no signal there
    assert V3.decode(frame(0x204, "8000000000000000")).command_timeout is False


# ----------------------------------------------------------------- DBC files

def test_the_shipped_dbc_is_the_one_named_by_its_hash():
    assert V3.dbc_sha256 == SHIPPED_DBC_SHA256
    assert V3.dbc_path == SHIPPED_DBC
    assert V3.dbc_files == ((str(SHIPPED_DBC), SHIPPED_DBC_SHA256),)
    fragment = hashlib.sha256(V14_GLOBAL_DBC.read_bytes()).hexdigest()
    assert V14.dbc_files == ((str(SHIPPED_DBC), SHIPPED_DBC_SHA256), (str(V14_GLOBAL_DBC), fragment))


@pytest.mark.parametrize("rate_radps", [0.001, 0.1, 0.3, 1.1, 3.3, 7.77, 65.535])
def test_decoded_values_read_as_the_decimals_they_were_sent_with(rate_radps):
    """raw 3300 at 0.001 rad/s is 3.3, not 3300 * 0.001 = 3.3000000000000003."""
    sent = SteeringCmd(enable=True, position_rad=-rate_radps / 3, rotation_rate_radps=rate_radps)
    got = V3.decode(V3.encode(sent))
    assert got.rotation_rate_radps == rate_radps
    assert got.position_rad == round(-rate_radps / 3, 3)
    speed = V3.decode(V3.encode(VehicleSpeedRpt(speed_mps=rate_radps, valid=True))).speed_mps
    assert speed == round(rate_radps, 2)


def test_a_user_dbc_missing_a_signal_is_refused_at_load(tmp_path: Path):
    text = SHIPPED_DBC.read_text()
    line = ' SG_ POSITION : 15|16@0- (0.001,0) [-32.768|32.767] "rad"  PACMOD\n'
    assert line in text
    user = tmp_path / "user.dbc"
    user.write_text(text.replace(line, ""))
    with pytest.raises(KitError, match="STEERING_CMD lacks POSITION"):
        Pacmod3Codec(dbc_path=user)
    with pytest.raises(KitError, match="STEERING_CMD lacks POSITION"):
        Pacmod3Codec("v14", dbc_path=user)


def test_a_user_dbc_missing_a_message_or_not_a_dbc_is_refused_at_load(tmp_path: Path):
    text = SHIPPED_DBC.read_text()
    start = text.index("BO_ 1037 YAW_RATE_RPT")
    end = text.index("\n\n", start)
    user = tmp_path / "user.dbc"
    user.write_text(text[:start] + text[end + 2:])
    with pytest.raises(KitError, match="no message YAW_RATE_RPT"):
        Pacmod3Codec(dbc_path=user)
    junk = tmp_path / "junk.dbc"
    junk.write_text("this is not a DBC\n")
    with pytest.raises(KitError, match="cannot read"):
        Pacmod3Codec(dbc_path=junk)
    with pytest.raises(KitError, match="cannot read"):
        Pacmod3Codec(dbc_path=tmp_path / "missing.dbc")


def test_a_user_copy_of_the_shipped_dbc_reads_the_same_and_names_its_own_hash(tmp_path: Path):
    user = tmp_path / "mine.dbc"
    shutil.copy(SHIPPED_DBC, user)
    codec = Pacmod3Codec(dbc_path=user)
    assert codec.dbc_path == user and codec.dbc_sha256 == SHIPPED_DBC_SHA256
    for msg, expected in KNOWN_V3:
        assert codec.encode(msg) == expected


def test_an_unknown_dialect_is_refused():
    with pytest.raises(ValueError, match="dialect"):
        Pacmod3Codec("v15")  # type: ignore[arg-type]
