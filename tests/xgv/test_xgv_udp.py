"""The simulated XGV as an external user sees it: a JAUS client on a real UDP socket (loopback).

The XGV (``overdrive xgv-sim``'s server) runs in wall-clock time on a thread, bound to an
ephemeral port; the clients are ``JudpEndpoint``s on other ephemeral ports, one of them on
127.0.0.2. Every socket is closed by the fixtures.
"""

from __future__ import annotations

import queue
import time
from collections.abc import Callable, Iterator

import pytest

from overdrive.jaus import (
    ConfirmComponentControl,
    ConfirmServiceConnection,
    ControlResponse,
    CreateServiceConnection,
    JausId,
    QueryHeartbeatPulse,
    QueryVelocityState,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportHeartbeatPulse,
    ReportVehicleMode,
    ReportVelocityState,
    RequestComponentControl,
    Resume,
    ServiceConnectionResponse,
    SetWrenchEffort,
)
from overdrive.messages import SafetyDevices
from overdrive.run.xgv_sim import XgvServer
from overdrive.runtime.jaus_endpoint import JudpEndpoint, Received
from tests.xgv.xgv_helpers import ready_scenario, serving

TIMEOUT_S = 3.0
PD = JausId(1, 1, 33, 1)
NM = JausId(1, 1, 1, 1)
ME = JausId(1, 2, 4, 1)
INTRUDER = JausId(1, 3, 4, 1)


@pytest.fixture
def xgv() -> Iterator[XgvServer]:
    with serving(XgvServer("127.0.0.1", 0, ready_scenario())) as server:
        yield server


@pytest.fixture
def client(xgv: XgvServer) -> Iterator[JudpEndpoint]:
    with JudpEndpoint("127.0.0.1", 0, default_peer=xgv.address) as endpoint:
        yield endpoint


@pytest.fixture
def intruder(xgv: XgvServer) -> Iterator[JudpEndpoint]:
    with JudpEndpoint("127.0.0.2", 0, default_peer=xgv.address) as endpoint:
        yield endpoint


def wait_for(inbox: queue.Queue[Received], want: Callable[[object], bool],
              timeout_s: float = TIMEOUT_S) -> object:
    deadline = time.monotonic() + timeout_s
    while True:
        remaining = deadline - time.monotonic()
        assert remaining > 0, "no matching message in time"
        message = inbox.get(timeout=remaining).message
        if want(message):
            return message


def drive_for(client: JudpEndpoint, seconds: float, throttle_pct: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        client.send(SetWrenchEffort.xgv(throttle_pct=throttle_pct, steering_pct=0.0,
                                        brake_pct=0.0), destination=PD, source=ME)
        time.sleep(0.02)


def speed(client: JudpEndpoint, inbox: queue.Queue[Received]) -> float:
    client.send(QueryVelocityState(), destination=PD, source=ME)
    report = wait_for(inbox, lambda m: isinstance(m, ReportVelocityState))
    assert isinstance(report, ReportVelocityState) and report.velocity_x_mps is not None
    return report.velocity_x_mps


def test_an_external_client_drives_the_xgv(xgv: XgvServer, client: JudpEndpoint,
                                           intruder: JudpEndpoint) -> None:
    inbox = client.subscribe(ME)
    modes: queue.Queue[ReportVehicleMode] = queue.Queue()
    client.register(ME, lambda r: modes.put(r.message)
                    if isinstance(r.message, ReportVehicleMode) else None)
    others = intruder.subscribe(INTRUDER)

    # clients wait for the heartbeat, take control of the Primitive Driver, Resume (ref. §7)
    client.send(QueryHeartbeatPulse(), destination=NM, source=ME)
    wait_for(inbox, lambda m: isinstance(m, ReportHeartbeatPulse))
    client.send(RequestComponentControl(authority=6), destination=PD, source=ME)
    confirm = wait_for(inbox, lambda m: isinstance(m, ConfirmComponentControl))
    assert confirm.response == ControlResponse.ACCEPTED  # type: ignore[attr-defined]
    client.send(Resume(), destination=PD, source=ME)
    client.send(CreateServiceConnection(command_code=0xE456, rate_hz=20.0), destination=NM,
                source=ME)
    created = wait_for(inbox, lambda m: isinstance(m, ConfirmServiceConnection))
    assert created.response == ServiceConnectionResponse.CREATED  # type: ignore[attr-defined]
    drive_for(client, 0.1, 0.0)

    def mode_now() -> ReportVehicleMode:
        while True:          # the latest report that arrives after this call
            try:
                modes.get_nowait()
            except queue.Empty:
                break
        return modes.get(timeout=TIMEOUT_S)

    first = mode_now()
    assert first.header.service_connection and first.header.source == NM
    assert (first.control_mode, first.ready_mode, first.safety_mode) == (2, 2, 1)

    drive_for(client, 0.8, 35.0)
    assert speed(client, inbox) > 0.4

    # a second client, on another loopback address, holds no control: ignored and counted
    ignored = xgv.simulator.stats.ignored_no_control
    intruder.send(RequestComponentControl(authority=6), destination=PD, source=INTRUDER)
    refused = wait_for(others, lambda m: isinstance(m, ConfirmComponentControl))
    assert refused.response == ControlResponse.NOT_ACCEPTED  # type: ignore[attr-defined]
    intruder.send(SetWrenchEffort.xgv(throttle_pct=0.0, steering_pct=0.0, brake_pct=100.0),
                  destination=PD, source=INTRUDER)
    deadline = time.monotonic() + TIMEOUT_S
    while xgv.simulator.stats.ignored_no_control == ignored:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert xgv.simulator.pd.controller == ME

    # SafeStop pause: safety mode 8, the vehicle brakes to a stop although throttle keeps coming
    xgv.simulator.set_devices(SafetyDevices(safestop="pause"))
    drive_for(client, 0.2, 35.0)
    paused = mode_now()
    assert paused.safety_mode == 8 and paused.safety_devices & 0b10
    drive_for(client, 1.0, 35.0)
    assert abs(speed(client, inbox)) < 0.05

    # SafeStop run: drive-by-wire again; releasing control gives software pause
    xgv.simulator.set_devices(SafetyDevices())
    drive_for(client, 0.1, 0.0)
    assert mode_now().safety_mode == 1
    client.send(ReleaseComponentControl(), destination=PD, source=ME)
    wait_for(inbox, lambda m: isinstance(m, RejectComponentControl))
    released = mode_now()
    assert (released.control_mode, released.safety_mode) == (1, 2)
