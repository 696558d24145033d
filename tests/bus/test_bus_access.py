"""The shipped locked-down Zenoh config: authenticated users may publish only what they own."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from overdrive.bus.zenoh_bus import PUBLISHERS, ZenohBus, session_config
from overdrive.launch import free_port
from overdrive.messages import SetSpeed, Topic, VehicleStatus

ROOT = Path(__file__).resolve().parents[2]
LOCKED = ROOT / "config" / "zenoh-locked-down.json5"
USERS = dict(line.split(":", 1) for line in
             (ROOT / "config" / "zenoh-users.example.txt").read_text().split())
SPSS = SetSpeed(speed_mps=1.0, accel_mps2=1.0, gear="drive", state="run")


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


def _delivered(listener: ZenohBus, dialler: ZenohBus, topic: str, msg, window_s: float = 1.5) -> bool:
    inbox = listener.subscribe([topic])
    deadline = time.monotonic() + window_s
    while time.monotonic() < deadline:
        dialler.publish(topic, msg)
        time.sleep(0.02)
        if inbox.drain():
            return True
    return False


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
    dialler = _open("driving", "wrong", connect=[endpoint])
    try:
        assert not _delivered(listener, dialler, Topic.SET_SPEED, SPSS, window_s=1.0)
        assert listener.session.info.peers_zid() == []
    finally:
        dialler.close()
