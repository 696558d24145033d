"""Hostile frames never move the emulated kit's actuators: random ids and bytes (wrong lengths,
unknown ids, report ids, extended ids), and random bytes on the command ids themselves. Every
such frame is counted or decoded; none crashes the kit; an actuator moves only under a command
the kit accepted after a DISABLE -> ENABLE edge of that system's own enable bit, checked
against an independent decode of the same frames."""

from __future__ import annotations

from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from overdrive.kits.frames import CanFrame, KitDecodeError
from overdrive.kits.pacmod3 import AccelCmd, BrakeCmd, ShiftCmd, SteeringCmd
from tests.kits.kit_driver import lexus_kit

KIT = lexus_kit()
COMMAND_IDS = {KIT.codec.frame_id(c): c for c in (AccelCmd, BrakeCmd, SteeringCmd, ShiftCmd)}


def not_a_command(frame_id: int, length: int) -> bool:
    return frame_id not in COMMAND_IDS or length != 8


frames = st.builds(
    lambda i, data, ext: CanFrame(arbitration_id=i if not ext else i | 0x800, data=data,
                                  is_extended=ext),
    st.integers(0, 0x7FF), st.binary(min_size=0, max_size=8), st.booleans())


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(frames, min_size=1, max_size=60))
def test_frames_that_are_not_commands_never_enable_or_move(batch: list[CanFrame]) -> None:
    kit = lexus_kit("v14")
    t = 0.0
    for frame in batch:
        if not frame.is_extended and frame.arbitration_id in COMMAND_IDS and len(frame.data) == 8:
            continue   # a well-formed command: the next test's business
        kit.receive(frame, t)
        t += 0.01
        kit.step(t)
    truth = kit.truth(t)
    assert truth.enabled == () and truth.odometer_m == 0.0 and truth.throttle == 0.0
    assert truth.gear == "park" and truth.road_wheel_rad == 0.0
    assert sum(kit.bad_frames.values()) + sum(kit.frames_seen.values()) == sum(
        1 for f in batch if f.is_extended or f.arbitration_id not in COMMAND_IDS
        or len(f.data) != 8)


command_frames = st.builds(lambda i, data: CanFrame(arbitration_id=i, data=data),
                           st.sampled_from(sorted(COMMAND_IDS)), st.binary(min_size=8, max_size=8))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(command_frames, min_size=1, max_size=80))
@example([CanFrame(arbitration_id=0x128, data=b"\x00\x08" + bytes(6))])   # SHIFT_CMD gear 8: the
# codec raised a bare ValueError from its Gear conversion (now KitDecodeError), crashing the kit
def test_random_command_bytes_move_an_actuator_only_after_an_accepted_edge(
        batch: list[CanFrame]) -> None:
    kit = lexus_kit()
    oracle_prev: dict[type, bool | None] = dict.fromkeys(COMMAND_IDS.values())
    edged: set[type] = set()
    t = 0.0
    for frame in batch:
        try:
            msg = kit.codec.decode(frame)
        except KitDecodeError:
            msg = None
        refused_before = sum(kit.bad_frames.values())
        kit.receive(frame, t)
        if msg is not None and sum(kit.bad_frames.values()) == refused_before:
            cls = type(msg)
            if oracle_prev[cls] is False and msg.enable:
                edged.add(cls)
            oracle_prev[cls] = msg.enable
        t += 0.01
        kit.step(t)
        truth = kit.truth(t)
        if AccelCmd not in edged:
            assert truth.throttle == 0.0
        if BrakeCmd not in edged:
            assert truth.brake == 0.0
        if SteeringCmd not in edged:
            assert truth.road_wheel_rad == 0.0
        if ShiftCmd not in edged:
            assert truth.gear == "park"
    names = {AccelCmd: "accel", BrakeCmd: "brake", SteeringCmd: "steering", ShiftCmd: "shift"}
    assert {s for s, _ in kit.events.enable_edges} <= {names[c] for c in edged}
