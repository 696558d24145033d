"""PACMod 3 byte layouts written out by hand, for checking the codec against something that is
not cantools reading a DBC: v3.4.0 from the DBC text (``as_pacmod_v3.4.0.dbc``: Motorola byte
order, a signal's start bit is its most significant bit, byte ``b`` bit ``k`` is bit ``8b+k``),
v14 from pacmod3_common's generated C (``src/autogen/pacmod12.c``, ``Pack_*_pacmod12``).

Each ``pack_*`` takes raw integers (before scaling) and returns the frame's bytes; each
``unpack_*`` takes bytes and returns the raw integers.
"""

from __future__ import annotations

ACCEL_CMD_ID = 0x100
BRAKE_CMD_ID = 0x104
SHIFT_CMD_ID = 0x128
STEERING_CMD_ID = 0x12C
GLOBAL_RPT_ID = 0x10
ACCEL_RPT_ID = 0x200
BRAKE_RPT_ID = 0x204
SHIFT_RPT_ID = 0x228
STEERING_RPT_ID = 0x22C
VEHICLE_SPEED_RPT_ID = 0x400
WHEEL_SPEED_RPT_ID = 0x407
YAW_RATE_RPT_ID = 0x40D
GLOBAL_CMD_ID = 0x80
SUPERVISORY_CTRL_ID = 0x81

V3_LENGTH = 8
"""Every message of as_pacmod_v3.4.0.dbc is 8 bytes (``BO_ ... : 8``)."""
V14_LENGTH = {ACCEL_CMD_ID: 3, BRAKE_CMD_ID: 3, STEERING_CMD_ID: 5, SHIFT_CMD_ID: 2,
              GLOBAL_CMD_ID: 2, SUPERVISORY_CTRL_ID: 2, SHIFT_RPT_ID: 4,
              VEHICLE_SPEED_RPT_ID: 3, YAW_RATE_RPT_ID: 2, GLOBAL_RPT_ID: 8, ACCEL_RPT_ID: 8,
              BRAKE_RPT_ID: 8, STEERING_RPT_ID: 8, WHEEL_SPEED_RPT_ID: 8}
"""pacmod12.h: ``#define <MESSAGE>_DLC``."""


def u16(raw: int) -> bytes:
    """A 16-bit value big-endian (Motorola): two's complement for a negative one."""
    return (raw & 0xFFFF).to_bytes(2, "big")


def s16(data: bytes, at: int) -> int:
    value = int.from_bytes(data[at:at + 2], "big")
    return value - 0x10000 if value & 0x8000 else value


def uint16(data: bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 2], "big")


def flags(*bits: int) -> int:
    """Bits 0, 1, 2, ... of byte 0 from a sequence of 0/1."""
    return sum((b & 1) << i for i, b in enumerate(bits))


def pad(data: bytes, length: int) -> bytes:
    return data + bytes(length - len(data))


# ----------------------------------------------------------------- system commands

def pack_pedal_cmd(enable: int, ignore: int, clear_override: int, clear_faults: int,
                   ratio_raw: int, length: int = V3_LENGTH) -> bytes:
    """ACCEL_CMD / BRAKE_CMD: flags in byte 0 (v3: CLEAR_FAULTS bit 3; v14: none), the ratio at
    0.001 per bit in bytes 1-2 (start bit 15, 16 bits)."""
    return pad(bytes([flags(enable, ignore, clear_override, clear_faults)]) + u16(ratio_raw),
               length)


def pack_steering_cmd(enable: int, ignore: int, clear_override: int, clear_faults: int,
                      position_raw: int, rate_raw: int, length: int = V3_LENGTH) -> bytes:
    """STEERING_CMD: POSITION signed in bytes 1-2, ROTATION_RATE unsigned in bytes 3-4, both
    0.001 per bit."""
    return pad(bytes([flags(enable, ignore, clear_override, clear_faults)]) + u16(position_raw)
               + u16(rate_raw), length)


def pack_shift_cmd(enable: int, ignore: int, clear_override: int, clear_faults: int,
                   gear: int, length: int = V3_LENGTH) -> bytes:
    """SHIFT_CMD: the gear in byte 1 (start bit 15, 8 bits)."""
    return pad(bytes([flags(enable, ignore, clear_override, clear_faults), gear & 0xFF]), length)


# ----------------------------------------------------------------- v14 global commands

def pack_global_cmd(clear_faults: int, sanity_check_required: int, clear_overrides: int,
                    counter: int, complement: int) -> bytes:
    """Pack_GLOBAL_CMD_pacmod12: d0 = CLEAR_FAULTS | SANITY_CHECK_REQUIRED << 1 |
    CLEAR_OVERRIDES << 2; d1 = COUNTER | COMPLEMENT << 4."""
    return bytes([flags(clear_faults, sanity_check_required, clear_overrides),
                  (counter & 0xF) | (complement & 0xF) << 4])


def pack_supervisory_ctrl(enable: int, counter: int, complement: int) -> bytes:
    """Pack_SUPERVISORY_CTRL_pacmod12: d0 = ENABLE; d1 = COUNTER | COMPLEMENT << 4."""
    return bytes([enable & 1, (counter & 0xF) | (complement & 0xF) << 4])


# ----------------------------------------------------------------- reports

def pack_global_rpt(bits: tuple[int, ...], config_fault: int, read_errors: int,
                    supervisory_enable_required: int = 0) -> bytes:
    """GLOBAL_RPT: byte 0 bits 0-7 (ENABLED, OVERRIDE_ACTIVE, USR_CAN_TIMEOUT, STR_CAN_TIMEOUT,
    BRK_CAN_TIMEOUT, SUBSYSTEM_TIMEOUT, VEH_CAN_TIMEOUT, FAULT_ACTIVE); byte 1 bit 7
    CONFIG_FAULT_ACTIVE (start bit 15), bit 6 SUPERVISORY_ENABLE_REQUIRED (v14); bytes 6-7
    USR_CAN_READ_ERRORS (start bit 55)."""
    return (bytes([flags(*bits), (config_fault & 1) << 7 | (supervisory_enable_required & 1) << 6])
            + bytes(4) + u16(read_errors))


def pack_system_rpt(bits: tuple[int, ...], manual_raw: int, commanded_raw: int,
                    output_raw: int) -> bytes:
    """ACCEL_RPT / BRAKE_RPT / STEERING_RPT: byte 0 status bits (ENABLED, OVERRIDE_ACTIVE,
    COMMAND_OUTPUT_FAULT, INPUT_OUTPUT_FAULT, OUTPUT_REPORTED_FAULT, PACMOD_FAULT,
    VEHICLE_FAULT, and in v14 COMMAND_TIMEOUT), then three 16-bit values in bytes 1-2, 3-4, 5-6."""
    return (bytes([flags(*bits)]) + u16(manual_raw) + u16(commanded_raw) + u16(output_raw)
            + bytes(1))


def pack_shift_rpt(bits: tuple[int, ...], manual: int, commanded: int, output: int,
                   length: int = V3_LENGTH) -> bytes:
    """SHIFT_RPT: status byte, then the three gears in bytes 1, 2, 3."""
    return pad(bytes([flags(*bits), manual, commanded, output]), length)


def pack_vehicle_speed_rpt(speed_raw: int, valid: int, length: int = V3_LENGTH) -> bytes:
    """VEHICLE_SPEED_RPT: speed signed at 0.01 m/s in bytes 0-1 (start bit 7), VALID byte 2
    bit 0 (bit 16)."""
    return pad(u16(speed_raw) + bytes([valid & 1]), length)


def pack_wheel_speed_rpt(fl_raw: int, fr_raw: int, rl_raw: int, rr_raw: int) -> bytes:
    """WHEEL_SPEED_RPT: four 16-bit speeds at 0.01 rad/s in bytes 0-1, 2-3, 4-5, 6-7."""
    return u16(fl_raw) + u16(fr_raw) + u16(rl_raw) + u16(rr_raw)


def pack_yaw_rate_rpt(yaw_raw: int, length: int = V3_LENGTH) -> bytes:
    """YAW_RATE_RPT: signed at 0.01 rad/s in bytes 0-1."""
    return pad(u16(yaw_raw), length)
