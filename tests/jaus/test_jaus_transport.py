"""JudpEndpoint on real loopback sockets (ephemeral ports, every socket closed by fixtures)."""

from __future__ import annotations

import queue
import socket
import time
from collections.abc import Iterator

import pytest

from overdrive.jaus import (
    DEFAULT_CLIENT_ID,
    XGV_MOTION_PROFILE_DRIVER,
    XGV_PRIMITIVE_DRIVER,
    ConfirmComponentControl,
    ControlResponse,
    JausId,
    ReportHeartbeatPulse,
    ReportVelocityState,
    RequestComponentControl,
    SetWrenchEffort,
    encode_datagram,
)
from overdrive.runtime.jaus_endpoint import JudpEndpoint, Received

TIMEOUT_S = 2.0


@pytest.fixture
def xgv() -> Iterator[JudpEndpoint]:
    with JudpEndpoint("127.0.0.1", 0) as endpoint:
        yield endpoint


@pytest.fixture
def client(xgv: JudpEndpoint) -> Iterator[JudpEndpoint]:
    with JudpEndpoint("127.0.0.1", 0, default_peer=xgv.address) as endpoint:
        yield endpoint


def drain(inbox: queue.Queue[Received], count: int) -> list[Received]:
    return [inbox.get(timeout=TIMEOUT_S) for _ in range(count)]


def wait_for(condition, timeout_s: float = TIMEOUT_S) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.005)


def test_request_and_confirm_component_control(xgv: JudpEndpoint, client: JudpEndpoint) -> None:
    def primitive_driver(received: Received) -> None:
        if isinstance(received.message, RequestComponentControl):
            xgv.reply(received, ConfirmComponentControl(response=ControlResponse.ACCEPTED))

    xgv.register(XGV_PRIMITIVE_DRIVER, primitive_driver)
    inbox = client.subscribe(DEFAULT_CLIENT_ID)

    sent = client.send(RequestComponentControl(authority=6))

    reply = inbox.get(timeout=TIMEOUT_S)
    assert isinstance(reply.message, ConfirmComponentControl)
    assert reply.message.response == ControlResponse.ACCEPTED
    assert reply.message.header.source == XGV_PRIMITIVE_DRIVER
    assert reply.message.header.destination == DEFAULT_CLIENT_ID
    assert reply.sender == xgv.address
    assert sent.header.destination == XGV_PRIMITIVE_DRIVER
    assert sent.header.sequence == 0


def test_wrench_effort_stream_keeps_order_and_sequence(
    xgv: JudpEndpoint, client: JudpEndpoint
) -> None:
    inbox = xgv.subscribe(XGV_PRIMITIVE_DRIVER)
    throttles = [float(i) for i in range(60)]
    for throttle in throttles:
        client.send(
            SetWrenchEffort.xgv(throttle_pct=throttle, steering_pct=-throttle / 2, brake_pct=0)
        )
    received = drain(inbox, len(throttles))
    messages = [r.message for r in received]
    assert all(isinstance(m, SetWrenchEffort) for m in messages)
    assert [m.header.sequence for m in messages] == list(range(len(throttles)))
    for message, throttle in zip(messages, throttles, strict=True):
        assert message.throttle_pct == pytest.approx(throttle, abs=0.0046)  # type: ignore[attr-defined]
        assert message.steering_pct == pytest.approx(-throttle / 2, abs=0.0046)  # type: ignore[attr-defined]
    assert xgv.stats.decode_errors == 0


def test_send_many_sends_one_message_per_datagram(
    xgv: JudpEndpoint, client: JudpEndpoint
) -> None:
    """OpenJAUS reads only the first message of a datagram: one each unless asked to pack."""
    inbox = xgv.subscribe(XGV_PRIMITIVE_DRIVER)
    sent = client.send_many([SetWrenchEffort.xgv(throttle_pct=float(i)) for i in range(5)])
    assert client.stats.datagrams_sent == 5
    assert [r.message.header.sequence for r in drain(inbox, 5)] == [s.header.sequence for s in sent]
    packed = client.send_many([SetWrenchEffort.xgv(throttle_pct=1.0)] * 5, packed=True)
    assert client.stats.datagrams_sent == 6
    assert [r.message.header.sequence for r in drain(inbox, 5)] == [s.header.sequence for s in packed]


def test_routing_by_destination_and_broadcast(xgv: JudpEndpoint, client: JudpEndpoint) -> None:
    pd_inbox = xgv.subscribe(XGV_PRIMITIVE_DRIVER)
    mpd_inbox = xgv.subscribe(XGV_MOTION_PROFILE_DRIVER)
    client.send(ReportHeartbeatPulse(), destination=JausId(1, 1, 255, 1), source=DEFAULT_CLIENT_ID)
    assert isinstance(pd_inbox.get(timeout=TIMEOUT_S).message, ReportHeartbeatPulse)
    assert isinstance(mpd_inbox.get(timeout=TIMEOUT_S).message, ReportHeartbeatPulse)

    client.send(RequestComponentControl(), destination=XGV_MOTION_PROFILE_DRIVER)
    assert isinstance(mpd_inbox.get(timeout=TIMEOUT_S).message, RequestComponentControl)
    client.send(RequestComponentControl(), destination=JausId(9, 9, 9, 9))
    wait_for(lambda: xgv.stats.unroutable == 1)
    assert pd_inbox.empty()


def test_sequences_per_destination_and_service_connection(client: JudpEndpoint) -> None:
    to_pd = [client.address_message(RequestComponentControl()) for _ in range(3)]
    to_mpd = client.address_message(
        RequestComponentControl(), destination=XGV_MOTION_PROFILE_DRIVER
    )
    report = ReportVelocityState(velocity_x_mps=1.0)
    stream = [
        client.address_message(report, destination=DEFAULT_CLIENT_ID, source=XGV_PRIMITIVE_DRIVER,
                               service_connection=True)
        for _ in range(2)
    ]  # fmt: skip
    other_stream = client.address_message(
        ReportHeartbeatPulse(),
        destination=DEFAULT_CLIENT_ID,
        source=XGV_PRIMITIVE_DRIVER,
        service_connection=True,
    )
    assert [m.header.sequence for m in to_pd] == [0, 1, 2]
    assert to_mpd.header.sequence == 0
    assert [m.header.sequence for m in stream] == [0, 1]
    assert all(m.header.service_connection for m in stream)
    assert other_stream.header.sequence == 0
    assert client.address_message(RequestComponentControl(), sequence=77).header.sequence == 77


def test_sequence_wraps_at_16_bits(client: JudpEndpoint) -> None:
    for _ in range(0x10000):
        client.next_sequence(DEFAULT_CLIENT_ID, XGV_PRIMITIVE_DRIVER, 0x0405, False)
    assert client.next_sequence(DEFAULT_CLIENT_ID, XGV_PRIMITIVE_DRIVER, 0x0405, False) == 0


def test_garbage_and_failing_handlers_do_not_stop_the_endpoint(
    xgv: JudpEndpoint, client: JudpEndpoint
) -> None:
    def broken(received: Received) -> None:
        raise RuntimeError("handler bug")

    xgv.register(XGV_PRIMITIVE_DRIVER, broken)
    inbox = xgv.subscribe(XGV_PRIMITIVE_DRIVER)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as raw:
        raw.sendto(b"\x01\x00\x00\x00\x30garbage", xgv.address)
        raw.sendto(b"", xgv.address)
        raw.sendto(encode_datagram(RequestComponentControl()), xgv.address)
    assert isinstance(inbox.get(timeout=TIMEOUT_S).message, RequestComponentControl)
    assert xgv.stats.decode_errors == 2
    assert xgv.stats.handler_errors == 1


def test_replies_go_to_the_learned_address(xgv: JudpEndpoint, client: JudpEndpoint) -> None:
    inbox = xgv.subscribe(XGV_PRIMITIVE_DRIVER)
    client.send(RequestComponentControl())
    inbox.get(timeout=TIMEOUT_S)
    assert xgv.peer(DEFAULT_CLIENT_ID) == client.address


def test_reply_port_override() -> None:
    with JudpEndpoint("127.0.0.1", 0, reply_port=3794) as server:
        server.dispatch(encode_datagram(RequestComponentControl()), ("127.0.0.9", 5555))
        assert server.peer(DEFAULT_CLIENT_ID) == ("127.0.0.9", 3794)


def test_unknown_destination_without_peer_raises() -> None:
    with JudpEndpoint("127.0.0.1", 0) as lonely, pytest.raises(LookupError):
        lonely.send(RequestComponentControl())


def test_close_is_idempotent_and_closes_the_socket() -> None:
    endpoint = JudpEndpoint("127.0.0.1", 0).start()
    endpoint.close()
    endpoint.close()
    assert endpoint._sock.fileno() == -1


def test_reply_to_a_broadcast_needs_a_source(xgv: JudpEndpoint) -> None:
    asked = RequestComponentControl().with_header(destination=JausId(1, 1, 255, 1))
    with pytest.raises(ValueError, match="broadcast"):
        xgv.reply(Received(asked, ("127.0.0.1", 9)), ConfirmComponentControl())
