"""kit-sim hands each frame to the kit at its bus time; a frame too old to act on (stamped more
than ``STAMP_TRUST_S`` before the read, or more than the command timeout before the kit's last
step) is dropped and counted, never acted on as new. Driven through ``KitSimServer._take`` on
python-can's virtual bus with chosen stamps; judged from the kit's own enable state."""

from __future__ import annotations

import os

import pytest

from overdrive.kits.pacmod3 import Pacmod3Codec
from overdrive.run.kit_sim import STAMP_TRUST_S, KitSimServer
from overdrive.runtime.can_edge import resolve_can_config
from overdrive.vehicle.pacmod3_kit import COMMAND_TIMEOUT_S
from tests.kits.kit_driver import drive_stream

CODEC = Pacmod3Codec("v3")
WALL0_S = 1.8e9


def server(name: str) -> KitSimServer:
    s = KitSimServer(resolve_can_config(interface="virtual", channel=f"{name}-{os.getpid()}"))
    s._wall0 = WALL0_S
    return s


def engage(s: KitSimServer, read_s: float, age_s: float) -> None:
    """The disable then enable frames, all stamped ``age_s`` before ``read_s``."""
    stamp = WALL0_S + read_s - age_s
    off = [(stamp - 0.002, CODEC.encode(m)) for m in drive_stream(brake=0.5, enable=False)(0)]
    on = [(stamp, CODEC.encode(m)) for m in drive_stream(brake=0.5)(0)]
    s._take(off + on, read_s)


@pytest.mark.parametrize("age_s", [0.0, 0.05, STAMP_TRUST_S - 0.01])
def test_a_frame_stamped_within_the_window_acts_at_its_bus_time(age_s: float) -> None:
    s = server("kit-fresh")
    try:
        read_s = STAMP_TRUST_S + 0.5
        engage(s, read_s, age_s)
        assert s.stale_frames == 0
        assert "brake" in s.kit.truth(read_s).enabled
        assert s._last_arrival_s == pytest.approx(read_s - age_s)
    finally:
        s.close()


@pytest.mark.parametrize("age_s", [STAMP_TRUST_S + 0.01, 2.0, 30.0])
def test_a_frame_stamped_older_than_the_window_is_dropped_and_counted(age_s: float) -> None:
    s = server("kit-stale")
    try:
        read_s = 40.0
        engage(s, read_s, age_s)
        assert s.stale_frames == 8
        assert s.kit.truth(read_s).enabled == ()
    finally:
        s.close()


@pytest.mark.parametrize(("behind_s", "dropped"), [(COMMAND_TIMEOUT_S - 0.01, False),
                                                   (COMMAND_TIMEOUT_S + 0.01, True)])
def test_a_frame_from_before_the_kit_timed_out_is_dropped(behind_s, dropped) -> None:
    s = server("kit-behind")
    try:
        s.now_s = 5.0   # the kit last stepped at 5 s: it judged its timeout up to then
        engage(s, 5.0, behind_s)
        assert s.stale_frames == (8 if dropped else 0)
        assert ("brake" in s.kit.truth(5.0).enabled) is not dropped
    finally:
        s.close()
