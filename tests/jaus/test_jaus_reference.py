"""The codec against the reference: section 8 byte vectors, section 3 scaled-integer edge
cases, the header bit layout, and every message's payload built independently here with
``struct`` and the section 3 formula."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from overdrive.jaus import (
    ActivateServiceConnection,
    ClearEmergency,
    ConfigurationNode,
    ConfirmComponentControl,
    ConfirmServiceConnection,
    CreateServiceConnection,
    Header,
    Horn,
    JausDecodeError,
    JausId,
    JausTimestamp,
    Lights,
    Message,
    Motion,
    Propulsion,
    QueryComponentAuthority,
    QueryComponentControl,
    QueryComponentStatus,
    QueryConfiguration,
    QueryDiscreteDevices,
    QueryGlobalPose,
    QueryHeartbeatPulse,
    QueryIdentification,
    QueryLocalPose,
    QueryServices,
    QueryVelocityState,
    QueryWrenchEffort,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportComponentAuthority,
    ReportComponentControl,
    ReportComponentStatus,
    ReportConfiguration,
    ReportCurvature,
    ReportDiscreteDevices,
    ReportErrorCount,
    ReportGlobalPose,
    ReportHeartbeatPulse,
    ReportIdentification,
    ReportLocalPose,
    ReportServices,
    ReportSignals,
    ReportVehicleMode,
    ReportVelocityState,
    ReportWheelsSpeed,
    ReportWrenchEffort,
    RequestComponentControl,
    Reset,
    Resume,
    ScaledInt,
    Service,
    SetComponentAuthority,
    SetDiscreteDevices,
    SetEmergency,
    SetMotionProfile,
    SetSignals,
    SetWrenchEffort,
    Shutdown,
    Standby,
    SuspendServiceConnection,
    TerminateServiceConnection,
    XgvComponent,
    decode,
    encode,
    message_types,
    xgv_id,
)
from overdrive.jaus.messages import gear_name

PI = math.pi
RANGE = {"byte": 255.0, "short": 65534.0, "ushort": 65535.0, "integer": 4294967294.0,
         "uinteger": 4294967294.0}  # fmt: skip
SIGNED = {"short", "integer"}


def ref(value: float, lo: float, hi: float, kind: str) -> int:
    """Reference section 3, written out independently of the codec."""
    scale = (hi - lo) / RANGE[kind]
    bias = (hi + lo) / 2 if kind in SIGNED else lo
    value = min(max(value, lo), hi)
    return math.trunc((value - bias) / scale + 0.5)


def hexbytes(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


# --------------------------------------------------------------------------- section 8


def test_vector_request_component_control() -> None:
    msg = RequestComponentControl(
        authority=6, header=Header(destination=JausId(1, 1, 33, 1), source=JausId(2, 2, 4, 1))
    )
    wire = hexbytes("06 02 0D 00 01 21 01 01 01 04 02 02 01 00 00 00 06")
    assert encode(msg) == wire
    assert decode(wire) == msg


def test_vector_set_wrench_effort_payload() -> None:
    msg = SetWrenchEffort.xgv(throttle_pct=50, brake_pct=25)
    assert msg.encode_payload() == hexbytes("41 00 00 40 40")


def test_vector_set_motion_profile() -> None:
    msg = SetMotionProfile.single(
        speed_mps=5.0,
        max_accel_mps2=2.0,
        curvature_1pm=0.0,
        curvature_rate_1pms=0.0,
        duration_s=0.4,
        header=Header(destination=JausId(1, 1, 10, 1), source=JausId(1, 2, 4, 1)),
    )
    wire = hexbytes(
        "86 02 28 E3 01 0A 01 01 01 04 02 01 0C 00 00 00 01 01 C4 89 1F 05 00 80 00 00 90 01"
    )
    assert encode(msg) == wire
    assert encode(decode(wire)) == wire


def test_vector_motion_profile_zero_velocity() -> None:
    payload = SetMotionProfile.single(speed_mps=0.0, max_accel_mps2=1.0).encode_payload()
    assert payload[2:4] == hexbytes("FF 7F")


def test_vector_create_service_connection_payload() -> None:
    msg = CreateServiceConnection(command_code=0x4404, rate_hz=50.0, presence_vector=1)
    assert msg.encode_payload() == hexbytes("04 44 B9 0B 01 00 00 00")


# --------------------------------------------------------------------------- section 3

PERCENT = ScaledInt("short", -100.0, 100.0)


@pytest.mark.parametrize(
    ("value", "raw"), [(-1.0, -327), (1.0, 328), (-100.0, -32766), (100.0, 32767), (0.0, 0)]
)
def test_scaled_short_percent_edges(value: float, raw: int) -> None:
    assert PERCENT.to_raw(value) == raw
    assert SetWrenchEffort(propulsive_linear_x_pct=value).encode_payload() == struct.pack(
        "<Hh", 1, raw
    )


def test_scaled_ushort_symmetric_zero_is_0x7fff() -> None:
    assert ScaledInt("ushort", -65.535, 65.535).to_raw(0.0) == 0x7FFF


@pytest.mark.parametrize(("value", "raw"), [(-1e9, -32766), (1e9, 32767), (-100.5, -32766)])
def test_scaled_clamps_out_of_range(value: float, raw: int) -> None:
    assert PERCENT.to_raw(value) == raw


@pytest.mark.parametrize("kind", sorted(RANGE))
@given(data=st.data())
def test_scaled_matches_reference_formula(kind: str, data: st.DataObject) -> None:
    lo = data.draw(st.floats(-1e5, 1e5))
    hi = lo + data.draw(st.floats(1e-3, 1e5))
    value = data.draw(st.floats(lo - (hi - lo), hi + (hi - lo)))
    assert ScaledInt(kind, lo, hi).to_raw(value) == ref(value, lo, hi, kind)  # type: ignore[arg-type]


@pytest.mark.parametrize("kind", sorted(RANGE))
@given(data=st.data())
def test_decode_is_openjaus_formula(kind: str, data: st.DataObject) -> None:
    """Decode is OpenJAUS's raw * scale + bias (README of shared/interop/openjaus), clamped."""
    lo = data.draw(st.floats(-1e5, 1e5))
    hi = lo + data.draw(st.floats(1e-3, 1e5))
    scaled = ScaledInt(kind, lo, hi)  # type: ignore[arg-type]
    bits = {"byte": 8, "short": 16, "ushort": 16, "integer": 32, "uinteger": 32}[kind]
    signed = kind in ("short", "integer")
    raw = data.draw(st.integers(-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed
                    else st.integers(0, 2**bits - 1))
    value_range = RANGE[kind]
    openjaus = raw * ((hi - lo) / value_range) + ((hi + lo) / 2.0 if signed else lo)
    assert scaled.from_raw(raw) == min(max(openjaus, lo), hi)


@pytest.mark.parametrize("kind", ["short", "integer"])
def test_negative_raws_reencode_one_step_toward_zero(kind: str) -> None:
    """With OpenJAUS's pair, raw n < 0 decodes to n * scale, which re-encodes to n + 1."""
    scaled = ScaledInt(kind, -100.0, 100.0)  # type: ignore[arg-type]
    for raw in (-1, -2, -327, -16384, -32765):
        assert scaled.to_raw(scaled.from_raw(raw)) == raw + 1
    for raw in (0, 1, 327, 16384, 32767):
        assert scaled.to_raw(scaled.from_raw(raw)) == raw


def test_short_is_exhaustively_characterised() -> None:
    """Every int16 raw on the wrench range: the round trip of the docs, and the clamp only
    where no encoder goes (-32768, -32767)."""
    for raw in range(-32768, 32768):
        value = PERCENT.from_raw(raw)
        assert -100.0 <= value <= 100.0
        again = PERCENT.to_raw(value)
        if raw < -32766:
            assert value == -100.0 and again == -32766
        else:
            assert again == (raw + 1 if raw < 0 else raw)


# --------------------------------------------------------------------------- header


def test_header_every_field_in_its_bits() -> None:
    header = Header(
        destination=JausId(0x11, 0x22, 0x33, 0x44),
        source=JausId(0x55, 0x66, 0x77, 0x88),
        priority=12,
        ack_nak=2,
        service_connection=True,
        version=2,
        sequence=0xBEEF,
    )
    wire = encode(SetComponentAuthority(authority=9, header=header))
    assert wire[0] == 12 | 2 << 4 | 1 << 6  # priority, ack/nak, service connection
    assert wire[1] == 2
    assert wire[2:4] == b"\x01\x00"
    assert wire[4:8] == bytes([0x44, 0x33, 0x22, 0x11])  # instance, component, node, subsystem
    assert wire[8:12] == bytes([0x88, 0x77, 0x66, 0x55])
    assert wire[12:14] == struct.pack("<H", 1)  # size 1, data flag 0
    assert wire[14:16] == struct.pack("<H", 0xBEEF)
    assert decode(wire).header == header


def test_experimental_flag_is_bit_7() -> None:
    assert encode(ReportVehicleMode())[0] & 0x80
    assert not encode(ReportComponentStatus())[0] & 0x80


def test_jaus_id_text() -> None:
    assert JausId.parse("1.1.33.1") == JausId(1, 1, 33, 1) == xgv_id(XgvComponent.PRIMITIVE_DRIVER)
    assert str(JausId(2, 2, 4, 1)) == "2.2.4.1"
    for bad in ("1.1.33", "1.1.33.256", "a.b.c.d", "1..1.1", ""):
        with pytest.raises(ValueError):
            JausId.parse(bad)
    assert JausId(1, 255, 33, 1).matches(JausId(1, 7, 33, 1))
    assert not JausId(1, 1, 33, 1).matches(JausId(1, 1, 10, 1))


# --------------------------------------------------------------------------- every payload

STAMP = JausTimestamp(day=21, hour=13, minute=45, second=30, millisecond=250)
STAMP_RAW = 250 | 30 << 10 | 45 << 16 | 13 << 22 | 21 << 27
WRENCH = dict(zip(
    [f"propulsive_{a}_{x}_pct" for a in ("linear", "rotational") for x in "xyz"]
    + [f"resistive_{a}_{x}_pct" for a in ("linear", "rotational") for x in "xyz"],
    [-100.0, -37.5, -0.2, 0.2, 63.1, 100.0, 0.0, 12.5, 25.0, 50.0, 99.9, 100.0],
    strict=True,
))  # fmt: skip
WRENCH_RAWS = [ref(v, -100, 100, "short") for v in list(WRENCH.values())[:6]] + [
    ref(v, 0, 100, "byte") for v in list(WRENCH.values())[6:]
]
VELOCITY = (1.5, -2.25, 0.1, 0.3, 0.5, -0.25, 1.0, 0.2)
POSE_ANGLES = (0.1, -0.2, 3.0, 0.05)


def velocity_payload() -> bytes:
    raws = [ref(v, -65.534, 65.534, "integer") for v in VELOCITY[:3]]
    raws.append(ref(VELOCITY[3], 0, 100, "uinteger"))
    raws += [ref(v, -32.767, 32.767, "short") for v in VELOCITY[4:7]]
    raws.append(ref(VELOCITY[7], 0, PI, "ushort"))
    return struct.pack("<H3iI3hHI", 0x1FF, *raws, STAMP_RAW)


def pose_payload(first: list[int]) -> bytes:
    attitude = [ref(v, -PI, PI, "short") for v in POSE_ANGLES[:3]]
    return struct.pack(
        "<H3iI3hHI",
        0x1FF,
        *first,
        ref(2.5, 0, 100, "uinteger"),
        *attitude,
        ref(POSE_ANGLES[3], 0, PI, "ushort"),
        STAMP_RAW,
    )


def motion_raws(speed: float, accel: float, curvature: float, rate: float, ms: int) -> list[int]:
    return [
        ref(speed, -65.535, 65.535, "ushort"),
        ref(accel, 0, 100, "ushort"),
        ref(math.atan(curvature), -PI / 2, PI / 2, "ushort"),
        ref(rate, 0, 10, "ushort"),
        ms,
    ]


CASES: list[tuple[Message, int, bool, bytes]] = [
    (SetComponentAuthority(authority=7), 0x0001, False, b"\x07"),
    (Shutdown(), 0x0002, False, b""),
    (Standby(), 0x0003, False, b""),
    (Resume(), 0x0004, False, b""),
    (Reset(), 0x0005, False, b""),
    (SetEmergency(emergency_code=1), 0x0006, False, b"\x01\x00"),
    (ClearEmergency(emergency_code=1), 0x0007, False, b"\x01\x00"),
    (
        CreateServiceConnection(command_code=0x4002, rate_hz=1092.0, presence_vector=0xDEADBEEF),
        0x0008, False, struct.pack("<HHI", 0x4002, 0xFFFF, 0xDEADBEEF),
    ),
    (
        ConfirmServiceConnection(command_code=0x4404, instance_id=3, rate_hz=25.0, response=4),
        0x0009, False, struct.pack("<HBHB", 0x4404, 3, ref(25.0, 0, 1092, "ushort"), 4),
    ),
    (ActivateServiceConnection(command_code=0x4404, instance_id=3), 0x000A, False, b"\x04\x44\x03"),
    (SuspendServiceConnection(command_code=0x4404, instance_id=3), 0x000B, False, b"\x04\x44\x03"),
    (TerminateServiceConnection(command_code=0x4404, instance_id=3), 0x000C, False, b"\x04\x44\x03"),
    (RequestComponentControl(authority=6), 0x000D, False, b"\x06"),
    (ReleaseComponentControl(), 0x000E, False, b""),
    (ConfirmComponentControl(response=2), 0x000F, False, b"\x02"),
    (RejectComponentControl(), 0x0010, False, b""),
    (QueryComponentStatus(), 0x2002, False, b""),
    (
        ReportComponentStatus(primary_status=5, secondary_status=1 << 16 | 1 << 28),
        0x4002, False, struct.pack("<BI", 5, 1 << 16 | 1 << 28),
    ),
    (QueryComponentControl(), 0x200D, False, b""),
    (
        ReportComponentControl(controller=JausId(2, 3, 4, 5), authority=6),
        0x400D, False, bytes([2, 3, 4, 5, 6]),
    ),
    (QueryHeartbeatPulse(), 0x2202, False, b""),
    (ReportHeartbeatPulse(), 0x4202, False, b""),
    (SetWrenchEffort(**WRENCH), 0x0405, False, struct.pack("<H6h6B", 0xFFF, *WRENCH_RAWS)),
    (
        ReportWrenchEffort(propulsive_rotational_z_pct=-12.0, resistive_linear_z_pct=3.0),
        0x4405, False,
        struct.pack("<Hhb", 0x120, ref(-12.0, -100, 100, "short"), ref(3.0, 0, 100, "byte")),
    ),
    (QueryWrenchEffort(presence_vector=0x61), 0x2405, False, b"\x61\x00"),
    (SetDiscreteDevices(gear=2), 0x0406, False, b"\x04\x02"),
    (
        ReportDiscreteDevices(propulsion_flags=0x81, parking_horn_flags=3, gear=129, transfer_case=7),
        0x4406, False, bytes([0x0F, 0x81, 3, 129, 7]),
    ),
    (QueryDiscreteDevices(presence_vector=0x0F), 0x2406, False, b"\x0f"),
    (
        ReportVelocityState(**dict(zip(
            ["velocity_x_mps", "velocity_y_mps", "velocity_z_mps", "velocity_rms_mps",
             "roll_rate_radps", "pitch_rate_radps", "yaw_rate_radps", "rate_rms_radps"],
            VELOCITY, strict=True)), timestamp=STAMP),
        0x4404, False, velocity_payload(),
    ),
    (QueryVelocityState(), 0x2404, False, b"\xff\x01"),
    (
        ReportGlobalPose(latitude_deg=37.2, longitude_deg=-80.4, elevation_m=600.0,
                         position_rms_m=2.5, roll_rad=0.1, pitch_rad=-0.2, yaw_rad=3.0,
                         attitude_rms_rad=0.05, timestamp=STAMP),
        0x4402, False,
        pose_payload([ref(37.2, -90, 90, "integer"), ref(-80.4, -180, 180, "integer"),
                      ref(600.0, -10000, 35000, "integer")]),
    ),
    (QueryGlobalPose(presence_vector=0x3), 0x2402, False, b"\x03\x00"),
    (
        ReportLocalPose(x_m=-1234.5, y_m=99999.0, z_m=-3.0, position_rms_m=2.5, roll_rad=0.1,
                        pitch_rad=-0.2, yaw_rad=3.0, attitude_rms_rad=0.05, timestamp=STAMP),
        0x4403, False,
        pose_payload([ref(-1234.5, -100000, 100000, "integer"),
                      ref(99999.0, -100000, 100000, "integer"),
                      ref(-3.0, -10000, 35000, "integer")]),
    ),
    (QueryLocalPose(), 0x2403, False, b"\xff\x01"),
    (
        SetMotionProfile(motions=(Motion(-3.0, 1.5, -0.1, 0.5, 0.4), Motion(2.0, 0.5, 0.2, 1.0, 1.25))),
        0xE328, True,
        struct.pack("<BB10H", 1, 2, *motion_raws(-3.0, 1.5, -0.1, 0.5, 400),
                    *motion_raws(2.0, 0.5, 0.2, 1.0, 1250)),
    ),
    (
        ReportVehicleMode(control_mode=2, ready_mode=2, safety_mode=8, partial_mode_overrides=1,
                          safety_devices=0x0412),
        0xE456, True, struct.pack("<5BH", 0, 2, 2, 8, 1, 0x0412),
    ),
    (
        ReportCurvature(curvature_1pm=0.05, timestamp=STAMP),
        0xE455, True,
        struct.pack("<BHI", 1, ref(math.atan(0.05), -PI / 2, PI / 2, "ushort"), STAMP_RAW),
    ),
    (
        ReportWheelsSpeed(right_front_mps=1.0, left_front_mps=2.0, right_rear_mps=-3.0,
                          left_rear_mps=0.0, timestamp=STAMP),
        0xE42E, True,
        struct.pack("<B4HI", 0, *(ref(v, -65.535, 65.535, "ushort") for v in (1, 2, -3, 0)),
                    STAMP_RAW),
    ),
    (
        SetSignals(turn_signal=1, horn=Horn(1, 10, 20)),
        0xE322, True, bytes([0, 0b011, 1, 1, 10, 20]),
    ),
    (
        ReportSignals(lights=Lights(2 | 8, 5, 6)),
        0xE445, True, bytes([0, 0b100, 10, 5, 6]),
    ),
    (
        ReportErrorCount(counts=(1, -2, 2**31 - 1)),
        0xE451, True, bytes([0, 0, 3]) + struct.pack("<3i", 1, -2, 2**31 - 1),
    ),
    (QueryComponentAuthority(), 0x2001, False, b""),
    (ReportComponentAuthority(authority=9), 0x4001, False, b"\x09"),
    (QueryIdentification(query_field=3), 0x2B00, False, b"\x03"),
    (
        ReportIdentification(query_type=2, authority=0, type=10001, identification="XGV"),
        0x4B00, False, struct.pack("<BBH", 2, 0, 10001) + b"XGV" + bytes(77),
    ),
    (QueryConfiguration(query_field=2), 0x2B01, False, b"\x02"),
    (
        ReportConfiguration(nodes=(ConfigurationNode(1, ((1, 1), (33, 1))),)),
        0x4B01, False, bytes([1, 1, 2, 1, 1, 33, 1]),
    ),
    (QueryServices(), 0x2B03, False, b""),
    (
        ReportServices(services=(Service(0, ((0x0001, 0),), ((0x4202, 0),)),)),
        0x4B03, False, bytes([1, 0, 0, 1, 1, 0, 0, 0, 0, 0, 1, 2, 0x42, 0, 0, 0, 0]),
    ),
]  # fmt: skip


def test_every_message_type_has_a_case() -> None:
    assert {type(m) for m, *_ in CASES} == set(message_types())


@pytest.mark.parametrize(("message", "code", "experimental", "payload"), CASES,
                         ids=[m.name for m, *_ in CASES])  # fmt: skip
def test_payload_matches_reference(
    message: Message, code: int, experimental: bool, payload: bytes
) -> None:
    wire = encode(message)
    assert wire[16:] == payload
    assert struct.unpack_from("<H", wire, 2)[0] == code
    assert bool(wire[0] & 0x80) == experimental
    assert struct.unpack_from("<H", wire, 12)[0] == len(payload)
    again = decode(wire)
    assert type(again) is type(message)
    assert decode(encode(message)) == again


def test_scaled_fields_decode_close_to_what_was_sent() -> None:
    again = decode(encode(SetWrenchEffort(**WRENCH)))
    for name, value in WRENCH.items():
        assert getattr(again, name) == pytest.approx(
            value, abs=1.5 * 200 / 65534 if "propulsive" in name else 0.5 * 100 / 255
        )
    pose = decode(encode(CASES[32][0]))
    assert isinstance(pose, ReportLocalPose)
    assert pose.x_m == pytest.approx(-1234.5, abs=1e-4)
    assert pose.timestamp == STAMP
    curvature = decode(encode(ReportCurvature(curvature_1pm=0.05)))
    assert isinstance(curvature, ReportCurvature)
    assert curvature.curvature_1pm == pytest.approx(0.05, abs=1e-4)


def test_wrong_experimental_flag_is_a_different_message() -> None:
    wire = bytearray(encode(RequestComponentControl()))
    wire[0] |= 0x80
    unknown = decode(bytes(wire))
    assert unknown.name == "unknown" and unknown.code == 0x000D and unknown.experimental
    assert encode(unknown) == bytes(wire)


def test_codes_are_unique() -> None:
    keys = [(cls.experimental, cls.code) for cls in message_types()]
    assert len(keys) == len(set(keys))


def test_decode_rejects_payload_not_matching_layout() -> None:
    wire = bytearray(encode(SetWrenchEffort.xgv(throttle_pct=10)))
    wire[16] = 0x03  # presence now promises two int16 fields; only one follows
    with pytest.raises(JausDecodeError, match="presence vector"):
        decode(bytes(wire))


def test_discrete_device_bytes_have_named_bits() -> None:
    """Issue 19: the propulsion byte read as a number; its bits are named (reference §5)."""
    message = decode(encode(SetDiscreteDevices(propulsion_flags=0x91, parking_horn_flags=0xFF,
                                               gear=130)))
    fields = message.fields_dict()
    assert fields["propulsion"] == {
        "main_power": True, "main_fuel": False, "auxiliary_fuel": False,
        "auxiliary_power": False, "starter": True, "cold_start": False, "auto_start": False,
        "auto_shutdown": True}
    assert fields["parking_horn"] == {"parking_brake": True, "horn": True}
    assert fields["gear_name"] == "reverse" and fields["propulsion_flags"] == 0x91
    assert message.propulsion & Propulsion.STARTER  # type: ignore[attr-defined, operator]
    assert [gear_name(g) for g in (0, 1, 127, 128, 129, 255)] == [
        "park", "forward", "forward", "neutral", "reverse", "reverse"]
