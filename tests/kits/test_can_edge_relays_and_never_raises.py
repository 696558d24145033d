"""The CAN edge, judged through python-can's own interfaces: the loopback socketcand hub relays
every frame to every other client unchanged and never to its sender; malformed input and a
client that stops reading never stall the bus; python-can's configuration lookup is honoured
key by key with each key's source named; frames leave at least 500 us apart; bus errors are
counted and returned, never raised."""

from __future__ import annotations

import itertools
import socket
import time

import pytest

import can
from overdrive.kits.frames import CanFrame
from overdrive.runtime.can_edge import (
    MIN_FRAME_GAP_S,
    CanConfigError,
    CanPort,
    resolve_can_config,
)
from overdrive.runtime.can_hub import MAX_BACKLOG_BYTES, CanHub

FRAMES = (
    CanFrame(arbitration_id=0x100, data=bytes(range(8))),
    CanFrame(arbitration_id=0x104, data=b""),
    CanFrame(arbitration_id=0x7FF, data=b"\xff"),
    CanFrame(arbitration_id=0x000, data=b"\x00\x80"),
    CanFrame(arbitration_id=0x1ABCDEF0, data=b"\x01\x02\x03", is_extended=True),
)


def _python_can_client(hub: CanHub, channel: str = "can0") -> can.BusABC:
    return can.Bus(interface="socketcand", host="127.0.0.1", port=hub.port, channel=channel,
                   tcp_tune=True)


def _drain(bus: can.BusABC, n: int, timeout_s: float = 5.0) -> list[can.Message]:
    out: list[can.Message] = []
    end = time.monotonic() + timeout_s
    while len(out) < n and time.monotonic() < end:
        message = bus.recv(timeout=0.05)
        if message is not None:
            out.append(message)
    return out


@pytest.fixture
def hub():
    with CanHub(port=0) as running:
        yield running


def test_every_frame_reaches_every_other_python_can_client_unchanged_and_never_its_sender(hub):
    sender, a, b = (_python_can_client(hub) for _ in range(3))
    try:
        for frame in FRAMES:
            sender.send(can.Message(arbitration_id=frame.arbitration_id, data=frame.data,
                                    is_extended_id=frame.is_extended))
        for receiver in (a, b):
            got = _drain(receiver, len(FRAMES))
            assert [(m.arbitration_id, bytes(m.data), m.is_extended_id) for m in got] == [
                (f.arbitration_id, f.data, f.is_extended) for f in FRAMES]
        assert sender.recv(timeout=0.2) is None
        assert hub.relayed == len(FRAMES) and hub.malformed == 0
    finally:
        for bus in (sender, a, b):
            bus.shutdown()


def test_frames_stay_on_their_channel(hub):
    sender, same, other = (_python_can_client(hub, c) for c in ("can0", "can0", "can1"))
    try:
        sender.send(can.Message(arbitration_id=0x10, data=b"\x01"))
        assert len(_drain(same, 1)) == 1
        assert other.recv(timeout=0.3) is None
    finally:
        for bus in (sender, same, other):
            bus.shutdown()


@pytest.mark.parametrize("garbage", [
    "< send 800 1 00 >",                 # an 11-bit id above 0x7FF
    "< send 100 9 0 1 2 3 4 5 6 7 8 >",  # 9 bytes
    "< send 100 2 01 >",                 # fewer bytes than the length says
    "< send 100 1 100 >",                # a byte above 0xFF
    "< send zz 1 00 >",
    "< frame 100 1.0 00 >",              # a server's word from a client
    "<" + "x" * 500,                     # no end
])
def test_a_malformed_command_is_counted_and_never_relayed(hub, garbage):
    receiver = _python_can_client(hub)
    raw = socket.create_connection(("127.0.0.1", hub.port))
    try:
        assert raw.recv(64) == b"< hi >"
        raw.sendall(b"< open can0 >")
        assert raw.recv(64) == b"< ok >"
        raw.sendall(b"< rawmode >")
        assert raw.recv(64) == b"< ok >"
        raw.sendall(garbage.encode())
        raw.sendall(b"< send 123 1 7 >")      # a good frame after it still gets through
        got = _drain(receiver, 1)
        assert [(m.arbitration_id, bytes(m.data)) for m in got] == [(0x123, b"\x07")]
        assert receiver.recv(timeout=0.2) is None
        assert hub.malformed >= 1
    finally:
        raw.close()
        receiver.shutdown()


def test_a_client_that_stops_reading_never_stalls_the_bus(hub):
    """A stopped process (SIGSTOP) keeps its TCP connection but reads nothing: the hub queues a
    bounded backlog for it and drops the rest; the other clients keep every frame."""
    stuck = socket.create_connection(("127.0.0.1", hub.port))
    stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stuck.recv(64)
    stuck.sendall(b"< open can0 >")
    stuck.recv(64)
    stuck.sendall(b"< rawmode >")
    stuck.recv(64)
    time.sleep(0.05)
    for client in hub._clients.values():   # the kernel's buffers small, so the hub's own fills
        client.sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    sender, receiver = _python_can_client(hub), _python_can_client(hub)
    n = 2 * MAX_BACKLOG_BYTES // 40     # twice what the backlog holds (~40 characters a frame)
    try:
        got = 0
        for i in range(n):
            sender.send(can.Message(arbitration_id=0x200, data=i.to_bytes(4, "big")))
            got += len(_drain(receiver, 1, timeout_s=0.0)) if i % 64 else 0
        got += len(_drain(receiver, n - got, timeout_s=20.0))
        assert got == n
        assert hub.overflowed > 0
    finally:
        stuck.close()
        sender.shutdown()
        receiver.shutdown()


def test_explicit_flags_win_and_every_key_names_its_source(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    (tmp_path / "can.conf").write_text(
        "[default]\ninterface = virtual\nchannel = from_file\nbitrate = 250000\n"
        "[lab]\nchannel = lab_file\n")
    monkeypatch.setenv("CAN_CHANNEL", "from_env")
    for key in ("CAN_INTERFACE", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(key, raising=False)
    config = resolve_can_config()
    assert (config.interface, config.channel, config.options["bitrate"]) == (
        "virtual", "from_env", 250000)
    assert config.sources["channel"] == "environment"
    conf = tmp_path / "can.conf"
    assert config.sources["interface"] == config.sources["bitrate"] == f"config file {conf} [default]"
    flagged = resolve_can_config(channel="from_flag", bitrate=500000)
    assert (flagged.channel, flagged.options["bitrate"]) == ("from_flag", 500000)
    assert flagged.sources["channel"] == flagged.sources["bitrate"] == "flag"
    monkeypatch.delenv("CAN_CHANNEL")
    assert resolve_can_config(context="lab").channel == "lab_file"
    assert f"bitrate = 250000 (config file {conf} [default])" in resolve_can_config().describe()


def test_can_config_json_in_the_environment_supplies_socketcand_host_and_port(monkeypatch,
                                                                             tmp_path):
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.setenv("CAN_INTERFACE", "socketcand")
    monkeypatch.setenv("CAN_CHANNEL", "can0")
    monkeypatch.setenv("CAN_CONFIG", '{"host": "127.0.0.1", "port": 29999}')
    config = resolve_can_config()
    assert config.options["host"] == "127.0.0.1" and config.options["port"] == 29999
    assert config.bus_kwargs()["tcp_tune"] is True


@pytest.mark.parametrize(("kwargs", "problem"), [
    ({"interface": "no-such-kit", "channel": "x"}, "interface"),
    ({"interface": "virtual"}, "channel"),
    ({"channel": "x"}, "interface"),
])
def test_a_configuration_python_can_cannot_open_is_refused_by_name(monkeypatch, tmp_path,
                                                                   kwargs, problem):
    monkeypatch.setenv("HOME", str(tmp_path))
    for key in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(key, raising=False)
    with pytest.raises(CanConfigError, match=problem):
        resolve_can_config(**kwargs)


def test_no_hub_at_the_address_is_said_at_once():
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    start = time.monotonic()
    with pytest.raises(CanConfigError, match=f"no socketcand server at 127.0.0.1:{port}"):
        CanPort(resolve_can_config("socketcand", "can0", host="127.0.0.1", port=port))
    assert time.monotonic() - start < 5.0


def test_frames_leave_at_least_500_us_apart_across_calls():
    """Judged by the edge's own monotonic clock around each send: only a lower bound, which
    load cannot break."""
    sent_at: list[float] = []
    port = CanPort(resolve_can_config("virtual", "gap-test"))
    real_send = port.bus.send

    def timed(message, timeout=None):
        sent_at.append(time.monotonic())
        return real_send(message, timeout=timeout)

    port.bus.send = timed
    try:
        for _ in range(5):
            assert port.send(FRAMES[:4], 0.0) == []
        gaps = [b - a for a, b in itertools.pairwise(sent_at)]
        assert len(gaps) == 19 and min(gaps) >= MIN_FRAME_GAP_S
    finally:
        port.close()


class _FailingBus:
    def __init__(self, error: Exception) -> None:
        self.error = error

    def send(self, message, timeout=None):
        raise self.error

    def recv(self, timeout=None):
        raise self.error

    def shutdown(self):
        raise can.CanOperationError("already down")


@pytest.mark.parametrize("error", [
    can.CanOperationError("bus-off"),
    can.CanOperationError("no acknowledgement"),
    can.CanOperationError("Transmit buffer full"),
    BrokenPipeError(32, "Broken pipe"),
])
def test_a_bus_error_is_counted_and_returned_never_raised(error):
    port = CanPort(resolve_can_config("virtual", "err-test"))
    port.bus.shutdown()
    port.bus = _FailingBus(error)
    problems = port.send(FRAMES[:2], 1.0)
    assert len(problems) == 2 and port.errors.send_failures == 2
    assert port.receive() == [] and port.errors.receive_failures == 1
    assert port.traffic() is None           # nothing left the edge, nothing is logged as sent
    port.close()


def test_error_remote_and_fd_frames_are_counted_never_passed_on():
    port = CanPort(resolve_can_config("virtual", "odd-frames"))
    peer = can.Bus(interface="virtual", channel="odd-frames")
    try:
        peer.send(can.Message(arbitration_id=0x10, is_error_frame=True))
        peer.send(can.Message(arbitration_id=0x10, is_remote_frame=True, dlc=2))
        peer.send(can.Message(arbitration_id=0x10, data=bytes(12), is_fd=True))
        peer.send(can.Message(arbitration_id=0x10, data=b"\x01"))
        time.sleep(0.05)
        got = port.receive(0.2)
        assert [f.data for _, f in got] == [b"\x01"]
        assert port.errors.error_frames == 1 and port.errors.malformed == 2
        traffic = port.traffic()
        assert traffic is not None and [r.direction for r in traffic.frames] == ["rx"]
    finally:
        peer.shutdown()
        port.close()
