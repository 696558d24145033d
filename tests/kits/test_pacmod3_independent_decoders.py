"""Every command the project encodes, read back by decoders that are not ``Pacmod3Codec``:
cantools reading the shipped v3.4.0 DBC file itself (the acceptance check of issue 32), and for
the v14 dialect, whose DBC is not shipped, the byte layout of pacmod3_common's ``pacmod12.c``
written out by hand (tests/kits/pacmod3_layouts.py). Plus the properties: decoding random
bytes under any id raises nothing but ``KitError``, and a valid frame round-trips exactly."""

from __future__ import annotations

import itertools

import cantools
import pacmod3_layouts as L
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive.kits.frames import CanFrame, KitEncodeError, KitError
from overdrive.kits.pacmod3 import (
    SHIPPED_DBC,
    AccelCmd,
    BrakeCmd,
    Gear,
    GlobalCmd,
    Pacmod3Codec,
    ShiftCmd,
    SteeringCmd,
    SupervisoryCtrl,
    complement4,
)

V3 = Pacmod3Codec("v3")
V14 = Pacmod3Codec("v14")
DBC = cantools.database.load_file(str(SHIPPED_DBC))
FLAG_SETS = list(itertools.product((False, True), repeat=4))
RATIOS = (0.0, 0.001, 0.1, 0.25, 0.5, 0.999, 1.0)
POSITIONS_RAD = (-32.767, -7.5, -0.001, 0.0, 0.001, 3.14159, 32.767)
RATES_RADPS = (0.0, 0.001, 1.0, 65.535)
COMMAND_GEARS = (Gear.PARK, Gear.REVERSE, Gear.NEUTRAL, Gear.FORWARD, Gear.LOW, Gear.NONE)


def v3_commands():
    for enable, ignore, clear_override, clear_faults in FLAG_SETS:
        bits = dict(enable=enable, ignore_overrides=ignore, clear_override=clear_override,
                    clear_faults=clear_faults)
        for ratio in RATIOS:
            yield AccelCmd(**bits, accel_ratio=ratio)
            yield BrakeCmd(**bits, brake_ratio=ratio)
        for position, rate in itertools.product(POSITIONS_RAD, RATES_RADPS):
            yield SteeringCmd(**bits, position_rad=position, rotation_rate_radps=rate)
        for gear in COMMAND_GEARS:
            yield ShiftCmd(**bits, gear=gear)


def _flags(msg) -> dict[str, int]:
    return {"ENABLE": int(msg.enable), "IGNORE_OVERRIDES": int(msg.ignore_overrides),
            "CLEAR_OVERRIDE": int(msg.clear_override), "CLEAR_FAULTS": int(msg.clear_faults)}


def intended(msg) -> tuple[str, dict[str, float]]:
    """The DBC message and the signal values ``msg`` means, written from the DBC's names."""
    if isinstance(msg, AccelCmd):
        return "ACCEL_CMD", {**_flags(msg), "ACCEL_CMD": msg.accel_ratio}
    if isinstance(msg, BrakeCmd):
        return "BRAKE_CMD", {**_flags(msg), "BRAKE_CMD": msg.brake_ratio}
    if isinstance(msg, SteeringCmd):
        return "STEERING_CMD", {**_flags(msg), "POSITION": msg.position_rad,
                                "ROTATION_RATE": msg.rotation_rate_radps}
    return "SHIFT_CMD", {**_flags(msg), "SHIFT_CMD": int(msg.gear)}


def test_every_command_decodes_to_what_was_meant_with_cantools_on_the_shipped_dbc():
    count = 0
    for msg in v3_commands():
        sent = V3.encode(msg)
        name, want = intended(msg)
        dbc_message = DBC.get_message_by_frame_id(sent.arbitration_id)
        assert dbc_message.name == name
        assert len(sent.data) == dbc_message.length and not sent.is_extended
        got = DBC.decode_message(sent.arbitration_id, sent.data, decode_choices=False)
        assert set(got) == set(want)
        for signal, value in want.items():
            assert got[signal] == pytest.approx(value, abs=5e-4), (msg, signal)
        count += 1
    assert count == 16 * (2 * len(RATIOS) + len(POSITIONS_RAD) * len(RATES_RADPS)
                          + len(COMMAND_GEARS))


def test_every_v3_command_is_the_bytes_the_dbc_text_lays_out_by_hand():
    for msg in v3_commands():
        flags = [int(msg.enable), int(msg.ignore_overrides), int(msg.clear_override),
                 int(msg.clear_faults)]
        if isinstance(msg, AccelCmd | BrakeCmd):
            ratio = msg.accel_ratio if isinstance(msg, AccelCmd) else msg.brake_ratio
            want = L.pack_pedal_cmd(*flags, round(ratio * 1000))
        elif isinstance(msg, SteeringCmd):
            want = L.pack_steering_cmd(*flags, round(msg.position_rad * 1000),
                                       round(msg.rotation_rate_radps * 1000))
        else:
            want = L.pack_shift_cmd(*flags, int(msg.gear))
        assert V3.encode(msg).data == want, msg


def test_every_v14_command_is_the_bytes_pacmod12_c_packs():
    count = 0
    for msg in v3_commands():
        if msg.clear_faults:   # DBC 12 has no CLEAR_FAULTS in the system commands
            with pytest.raises(KitEncodeError):
                V14.encode(msg)
            continue
        flags = [int(msg.enable), int(msg.ignore_overrides), int(msg.clear_override), 0]
        if isinstance(msg, AccelCmd | BrakeCmd):
            ratio = msg.accel_ratio if isinstance(msg, AccelCmd) else msg.brake_ratio
            want = L.pack_pedal_cmd(*flags, round(ratio * 1000), length=3)
        elif isinstance(msg, SteeringCmd):
            want = L.pack_steering_cmd(*flags, round(msg.position_rad * 1000),
                                       round(msg.rotation_rate_radps * 1000), length=5)
        else:
            want = L.pack_shift_cmd(*flags, int(msg.gear), length=2)
        sent = V14.encode(msg)
        assert sent.data == want, msg
        assert len(sent.data) == L.V14_LENGTH[sent.arbitration_id]
        count += 1
    for counter in range(16):
        for cf, sane, co in itertools.product((0, 1), repeat=3):
            msg = GlobalCmd(counter=counter, clear_faults=bool(cf), sanity_check_required=bool(sane),
                            clear_overrides=bool(co))
            want = L.pack_global_cmd(cf, sane, co, counter, 15 - counter)
            assert V14.encode(msg) == CanFrame(arbitration_id=L.GLOBAL_CMD_ID, data=want)
            count += 1
        for enable in (0, 1):
            msg = SupervisoryCtrl(counter=counter, enable=bool(enable))
            want = L.pack_supervisory_ctrl(enable, counter, 15 - counter)
            assert V14.encode(msg) == CanFrame(arbitration_id=L.SUPERVISORY_CTRL_ID, data=want)
            count += 1
    assert count > 8 * 16


# ----------------------------------------------------------------- properties

IDS = st.one_of(st.sampled_from(sorted(V3.frame_ids | V14.frame_ids)),
                st.integers(0, 0x7FF))
DATA = st.sampled_from([8, 8, 8, 2, 3, 4, 5, None]).flatmap(
    lambda n: st.binary(max_size=8) if n is None else st.binary(min_size=n, max_size=n))
"""Mostly the lengths the dialects use, so most frames get past the length check."""


@settings(max_examples=400, deadline=None)
@given(can_id=IDS, data=DATA, extended=st.booleans(),
       dialect=st.sampled_from(["v3", "v14"]))
def test_decoding_any_bytes_raises_nothing_but_kit_error(can_id, data, extended, dialect):
    codec = V3 if dialect == "v3" else V14
    try:
        got = codec.decode(CanFrame(arbitration_id=can_id, data=data, is_extended=extended))
    except KitError:
        return
    # whatever decodes is a message the codec can put back on the wire, identically decoded
    again = codec.encode(got)
    assert codec.decode(again) == got
    assert again.arbitration_id == can_id


def _raw_frames():
    """Valid frames built from raw integers by the hand layouts (every used bit free)."""
    bit = st.integers(0, 1)
    bits7 = st.tuples(*[bit] * 7)
    pedal = st.integers(0, 1000)
    s16 = st.integers(-32767, 32767)
    return st.one_of(
        st.builds(lambda f, r: (L.ACCEL_CMD_ID, L.pack_pedal_cmd(*f, r)), st.tuples(*[bit] * 4),
                  pedal),
        st.builds(lambda f, r: (L.BRAKE_CMD_ID, L.pack_pedal_cmd(*f, r)), st.tuples(*[bit] * 4),
                  pedal),
        st.builds(lambda f, p, r: (L.STEERING_CMD_ID, L.pack_steering_cmd(*f, p, r)),
                  st.tuples(*[bit] * 4), s16, st.integers(0, 65535)),
        st.builds(lambda f, g: (L.SHIFT_CMD_ID, L.pack_shift_cmd(*f, g)), st.tuples(*[bit] * 4),
                  st.sampled_from([0, 1, 2, 3, 4, 7])),
        st.builds(lambda b, c, e: (L.GLOBAL_RPT_ID, L.pack_global_rpt(b, c, e)),
                  st.tuples(*[bit] * 8), bit, st.integers(0, 65535)),
        st.builds(lambda b, m, c, o: (L.ACCEL_RPT_ID, L.pack_system_rpt(b, m, c, o)),
                  bits7, pedal, pedal, pedal),
        st.builds(lambda b, m, c, o: (L.STEERING_RPT_ID, L.pack_system_rpt(b, m, c, o)),
                  bits7, s16, s16, s16),
        st.builds(lambda b, m, c, o: (L.SHIFT_RPT_ID, L.pack_shift_rpt(b, m, c, o)), bits7,
                  st.integers(0, 7), st.sampled_from([0, 1, 2, 3, 4, 7]), st.integers(0, 7)),
        st.builds(lambda s, v: (L.VEHICLE_SPEED_RPT_ID, L.pack_vehicle_speed_rpt(s, v)), s16, bit),
        st.builds(lambda a, b, c, d: (L.WHEEL_SPEED_RPT_ID, L.pack_wheel_speed_rpt(a, b, c, d)),
                  st.integers(0, 32767), s16, s16, s16),
        st.builds(lambda y: (L.YAW_RATE_RPT_ID, L.pack_yaw_rate_rpt(y)), s16),
    )


@settings(max_examples=300, deadline=None)
@given(raw=_raw_frames())
def test_a_valid_v3_frame_round_trips_exactly(raw):
    can_id, data = raw
    sent = CanFrame(arbitration_id=can_id, data=data)
    assert V3.encode(V3.decode(sent)) == sent


@settings(max_examples=100, deadline=None)
@given(counter=st.integers(0, 15), enable=st.booleans(), bits=st.tuples(*[st.integers(0, 1)] * 3))
def test_a_valid_v14_global_frame_round_trips_exactly(counter, enable, bits):
    for sent in (CanFrame(arbitration_id=L.GLOBAL_CMD_ID,
                          data=L.pack_global_cmd(*bits, counter, complement4(counter))),
                 CanFrame(arbitration_id=L.SUPERVISORY_CTRL_ID,
                          data=L.pack_supervisory_ctrl(int(enable), counter,
                                                       complement4(counter)))):
        assert V14.encode(V14.decode(sent)) == sent


def _raw_v14_frames():
    """Valid v14 frames built by pacmod12.c's layout by hand: the shorter frames, the status
    byte's COMMAND_TIMEOUT (bit 7), the signed front-left wheel speed, no CLEAR_FAULTS."""
    bit = st.integers(0, 1)
    bits8 = st.tuples(*[bit] * 8)
    flags3 = st.tuples(bit, bit, bit).map(lambda f: (*f, 0))
    pedal = st.integers(0, 1000)
    s16 = st.integers(-32767, 32767)
    gear = st.sampled_from([0, 1, 2, 3, 4, 7])
    return st.one_of(
        st.builds(lambda f, r: (L.ACCEL_CMD_ID, L.pack_pedal_cmd(*f, r, length=3)), flags3, pedal),
        st.builds(lambda f, r: (L.BRAKE_CMD_ID, L.pack_pedal_cmd(*f, r, length=3)), flags3, pedal),
        st.builds(lambda f, p, r: (L.STEERING_CMD_ID, L.pack_steering_cmd(*f, p, r, length=5)),
                  flags3, s16, st.integers(0, 65535)),
        st.builds(lambda f, g: (L.SHIFT_CMD_ID, L.pack_shift_cmd(*f, g, length=2)), flags3, gear),
        st.builds(lambda b, c, e, s: (L.GLOBAL_RPT_ID, L.pack_global_rpt(b, c, e, s)),
                  bits8, bit, st.integers(0, 65535), bit),
        st.builds(lambda b, m, c, o: (L.BRAKE_RPT_ID, L.pack_system_rpt(b, m, c, o)),
                  bits8, pedal, pedal, pedal),
        st.builds(lambda b, m, c, o: (L.STEERING_RPT_ID, L.pack_system_rpt(b, m, c, o)),
                  bits8, s16, s16, s16),
        st.builds(lambda b, m, c, o: (L.SHIFT_RPT_ID, L.pack_shift_rpt(b, m, c, o, length=4)),
                  bits8, st.integers(0, 7), gear, st.integers(0, 7)),
        st.builds(lambda s, v: (L.VEHICLE_SPEED_RPT_ID, L.pack_vehicle_speed_rpt(s, v, length=3)),
                  s16, bit),
        st.builds(lambda a, b, c, d: (L.WHEEL_SPEED_RPT_ID, L.pack_wheel_speed_rpt(a, b, c, d)),
                  s16, s16, s16, s16),
        st.builds(lambda y: (L.YAW_RATE_RPT_ID, L.pack_yaw_rate_rpt(y, length=2)), s16),
    )


@settings(max_examples=300, deadline=None)
@given(raw=_raw_v14_frames())
def test_a_valid_v14_frame_round_trips_exactly(raw):
    can_id, data = raw
    sent = CanFrame(arbitration_id=can_id, data=data)
    got = V14.decode(sent)
    assert V14.encode(got) == sent
    if can_id == L.WHEEL_SPEED_RPT_ID:   # signed in DBC 12, all four
        assert got.front_left_radps == L.s16(data, 0) / 100
    if can_id in (L.BRAKE_RPT_ID, L.STEERING_RPT_ID, L.SHIFT_RPT_ID):
        assert got.command_timeout == bool(data[0] & 0x80)
