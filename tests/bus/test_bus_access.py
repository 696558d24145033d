"""The shipped locked-down Zenoh config: authenticated users may publish only what they own."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from overdrive.bus.zenoh_bus import PUBLISHERS, ZenohBus, session_config
from overdrive.messages import Notice, SetSpeed, Topic, VehicleStatus
from overdrive.runtime.ports import free_port
from tests.bus.waits import wait_for

ROOT = Path(__file__).resolve().parents[2]
LOCKED = ROOT / "config" / "zenoh-locked-down.json5"
USERS = dict(line.split(":", 1) for line in
             (ROOT / "config" / "zenoh-users.example.txt").read_text().split())
pytestmark = pytest.mark.wallclock   # real sessions: run serially (Makefile)

SPSS = SetSpeed(speed_mps=1.0, accel_mps2=1.0, gear="drive", state="run")
MARKER = Notice(kind="note", source="test", reason="link probe")
LAST = Notice(kind="note", source="test", reason="last")
LINK_TIMEOUT_S = 30.0   # a link comes up in ~0.1 s idle; a loaded 2-core host can take seconds


def _open(user: str, password: str, *, listen=(), connect=()) -> ZenohBus:
    config = session_config(listen=listen, connect=connect, base_file=LOCKED, user=user,
                            password=password)
    config.insert_json5("transport/auth/usrpwd/dictionary_file",
                        json.dumps(str(ROOT / "config" / "zenoh-users.example.txt")))
    # the bus policy is off here: only Zenoh's access control is under test
    return ZenohBus(zenoh.open(config), sender=user, publishers=None, own_session=True)


@pytest.fixture
def speed_node() -> Iterator[tuple[ZenohBus, str]]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    bus = _open("speed", USERS["speed"], listen=[endpoint])
    try:
        yield bus, endpoint
    finally:
        bus.close()


def _delivered(listener: ZenohBus, dialler: ZenohBus, topic: str, msg) -> bool:
    """Did ``msg`` on ``topic`` reach the listener? Decided by a marker sent after it, not a timer.

    The dialler first sends markers (on ``events``, which every user may write) until one
    arrives: the link is up. Then it sends ``msg`` ten times followed by a last marker on the
    same reliable, ordered link; once that marker is in, ``msg`` is either in too or was denied.
    """
    inbox, markers = listener.subscribe([topic]), listener.subscribe([Topic.NOTICE])

    def marker_in() -> bool:
        dialler.publish(Topic.NOTICE, MARKER)
        return bool(markers.drain())

    assert wait_for(marker_in, LINK_TIMEOUT_S), "no link: the dialler's marker never arrived"
    for _ in range(10):
        dialler.publish(topic, msg)
    dialler.publish(Topic.NOTICE, LAST)
    assert wait_for(lambda: any(m == LAST for _, m in markers.drain()), LINK_TIMEOUT_S)
    return bool(inbox.drain())


@pytest.mark.parametrize(("user", "topic", "msg", "allowed"), [
    ("driving", Topic.SET_SPEED, SPSS, True),
    ("planner", Topic.SET_SPEED, SPSS, False),
    ("observer", Topic.SET_SPEED, SPSS, False),
    ("vehicle", Topic.VEHICLE_STATUS, None, True),
    ("driving", Topic.VEHICLE_STATUS, None, False),
])
def test_users_may_publish_only_the_keys_they_own(speed_node, user, topic, msg, allowed) -> None:
    listener, endpoint = speed_node
    msg = msg or VehicleStatus(gear="drive", shifting=False, engine="running", engine_rpm=800.0,
                               start_failed=False, traction_control=False, steer_pct=0.0,
                               throttle_pct=0.0, brake_pct=0.0, safety_mode="drive-by-wire")
    dialler = _open(user, USERS[user], connect=[endpoint])
    try:
        assert _delivered(listener, dialler, topic, msg) is allowed
        assert (user in PUBLISHERS[topic]) is allowed, "config and bus policy agree"
    finally:
        dialler.close()


def test_a_wrong_password_gets_no_link(speed_node) -> None:
    listener, endpoint = speed_node
    good = _open("driving", USERS["driving"], connect=[endpoint])
    dialler = _open("driving", "wrong", connect=[endpoint])
    try:   # the right password links within the timeout; the wrong one meanwhile gets nothing
        assert wait_for(lambda: len(listener.session.info.peers_zid()) == 1, LINK_TIMEOUT_S)
        assert dialler.session.info.peers_zid() == []
        assert [str(z) for z in listener.session.info.peers_zid()] == [str(good.session.info.zid())]
    finally:
        dialler.close()
        good.close()
