"""The simulated XGV, sans-IO: access control, status, service connections, modes, loops."""

from __future__ import annotations

import random

import msgspec
import pytest

from overdrive.jaus import (
    ActivateServiceConnection,
    ConfirmComponentControl,
    ConfirmServiceConnection,
    ControlResponse,
    CreateServiceConnection,
    Gear,
    JausId,
    Propulsion,
    QueryComponentControl,
    QueryComponentStatus,
    QueryHeartbeatPulse,
    QueryLocalPose,
    QueryVelocityState,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportComponentControl,
    ReportComponentStatus,
    ReportHeartbeatPulse,
    ReportLocalPose,
    ReportVehicleMode,
    ReportVelocityState,
    RequestComponentControl,
    Resume,
    ServiceConnectionResponse,
    SetDiscreteDevices,
    SetEmergency,
    SetMotionProfile,
    SetWrenchEffort,
    Standby,
    SuspendServiceConnection,
    TerminateServiceConnection,
    XgvSecondaryStatus,
    encode_datagram,
)
from overdrive.messages import SafetyDevices
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv import gear_codes, gear_from_code, jaus_timestamp
from tests.xgv.xgv_helpers import CLIENT, MPD, NM, OTHER, Peer, make_sim


def controlled(ready: bool = True) -> tuple[Peer, Peer]:
    sim = make_sim(ready=ready)
    mail: dict = {}
    client = Peer(sim, CLIENT, ("127.0.0.1", 40000), mail)
    other = Peer(sim, OTHER, ("127.0.0.2", 3794), mail)
    replies = client.send(RequestComponentControl(authority=6), Resume())
    assert [type(m) for m in replies] == [ConfirmComponentControl]
    assert replies[0].response == ControlResponse.ACCEPTED
    return client, other


def drive(client: Peer, throttle_pct: float, steps: int, brake_pct: float = 0.0) -> None:
    for _ in range(steps):
        client.send(SetWrenchEffort.xgv(throttle_pct=throttle_pct, steering_pct=0.0,
                                        brake_pct=brake_pct))
        client.step()


# --------------------------------------------------------------------------- access control

def test_control_is_exclusive_and_commands_from_others_are_ignored() -> None:
    client, other = controlled()
    assert client.sim.mode.safety_mode == "drive-by-wire"
    refused = other.send(RequestComponentControl(authority=6))
    assert refused[0].response == ControlResponse.NOT_ACCEPTED
    ignored = client.sim.stats.ignored_no_control
    other.send(SetWrenchEffort.xgv(throttle_pct=100.0, steering_pct=50.0, brake_pct=0.0),
               Standby(), ReleaseComponentControl())
    assert client.sim.stats.ignored_no_control == ignored + 3
    assert client.sim.actuation.throttle_pct == 0.0
    assert client.sim.mode.ready_mode == "ready"


def test_higher_authority_takes_control_and_the_loser_is_told() -> None:
    client, other = controlled()
    taken = other.send(RequestComponentControl(authority=7))
    assert taken[0].response == ControlResponse.ACCEPTED
    assert client.of(RejectComponentControl)
    assert client.sim.pd.controller == OTHER
    assert client.sim.mode.ready_mode == "software-pause"    # the new controller must Resume
    report = other.send(QueryComponentControl())[0]
    assert isinstance(report, ReportComponentControl)
    assert (report.controller, report.authority) == (OTHER, 7)


def test_release_gives_software_pause_and_a_reject() -> None:
    client, _ = controlled()
    replies = client.send(ReleaseComponentControl())
    assert isinstance(replies[0], RejectComponentControl)
    client.step()
    assert client.sim.mode.control_mode == "software-pause"
    assert client.sim.mode.safety_mode == "software-pause"
    assert client.sim.core.mode == "software-pause"


def test_component_status_and_emergency() -> None:
    client, other = controlled()
    status = client.send(QueryComponentStatus())[0]
    assert isinstance(status, ReportComponentStatus) and status.primary_status == 1   # ready
    assert status.secondary_status & XgvSecondaryStatus.COMPUTER_SPEED
    other.send(SetEmergency())                       # anyone may raise an emergency
    assert client.sim.pd.status == 5
    assert client.sim.mode.safety_mode == "software-pause"
    client.send(Resume())                            # not out of an emergency
    assert client.sim.pd.status == 5


# --------------------------------------------------------------------------- wire robustness

@pytest.mark.parametrize("seed", range(3))
def test_malformed_datagrams_are_counted_never_fatal(seed: int) -> None:
    client, _ = controlled()
    rng = random.Random(seed)
    good = encode_datagram(SetWrenchEffort.xgv(throttle_pct=10.0, steering_pct=0.0,
                                               brake_pct=0.0).with_header(source=CLIENT))
    sim = client.sim
    for _ in range(300):
        data = bytearray(good)
        for _ in range(rng.randint(1, 4)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        data = data[:rng.randint(0, len(data))] if rng.random() < 0.3 else data
        sim.receive(bytes(data), ("127.0.0.1", 40000), 0.0)
        sim.step(0.0)
    assert sim.stats.malformed > 0
    assert sim.stats.datagrams == 300 + 1


# --------------------------------------------------------------------------- service connections

def test_service_connection_lifecycle_for_vehicle_mode() -> None:
    client, _ = controlled()
    confirm = client.send(CreateServiceConnection(command_code=0xE456, rate_hz=50.0), to=NM,
                          service=True)[0]
    assert isinstance(confirm, ConfirmServiceConnection)
    assert confirm.response == ServiceConnectionResponse.CREATED
    assert confirm.header.service_connection
    reports = [m for m in client.step(10) if isinstance(m, ReportVehicleMode)]
    assert len(reports) == 5                                   # 50 Hz over 0.1 s
    assert [r.header.sequence for r in reports] == list(range(5))
    assert all(r.header.service_connection and r.header.source == NM for r in reports)
    assert (reports[0].control_mode, reports[0].ready_mode, reports[0].safety_mode) == (2, 2, 1)
    key = {"command_code": 0xE456, "instance_id": confirm.instance_id}
    client.send(SuspendServiceConnection(**key), to=NM, service=True)
    assert not any(isinstance(m, ReportVehicleMode) for m in client.step(10))
    client.send(ActivateServiceConnection(**key), to=NM, service=True)
    assert any(isinstance(m, ReportVehicleMode) for m in client.step(10))
    client.send(TerminateServiceConnection(**key), to=NM, service=True)
    assert not any(isinstance(m, ReportVehicleMode) for m in client.step(10))


def test_unsupported_connection_is_refused() -> None:
    client, _ = controlled()
    confirm = client.send(CreateServiceConnection(command_code=0x4405, rate_hz=10.0), to=NM,
                          service=True)[0]
    assert confirm.response == ServiceConnectionResponse.NOT_SUPPORTED


def test_heartbeat_about_once_a_second_to_every_client() -> None:
    client, other = controlled()
    other.send(QueryHeartbeatPulse(), to=NM)
    assert other.of(ReportHeartbeatPulse)
    client.step(300)
    beats = [m for m in client.inbox if isinstance(m, ReportHeartbeatPulse)]
    assert 3 <= len(beats) <= 4
    assert len(other.of(ReportHeartbeatPulse)) >= 3


# --------------------------------------------------------------------------- driving

def test_wrench_efforts_move_the_vehicle_and_queries_report_it() -> None:
    client, _ = controlled()
    drive(client, 30.0, 200)
    velocity = client.send(QueryVelocityState())[0]
    assert isinstance(velocity, ReportVelocityState)
    assert velocity.velocity_x_mps == pytest.approx(client.sim.core.plant.speed_mps, abs=1e-6)
    assert velocity.velocity_x_mps > 1.0
    pose = client.send(QueryLocalPose())[0]
    assert isinstance(pose, ReportLocalPose) and pose.x_m > 1.0


def test_safestop_pause_brakes_to_a_stop_and_reports_mode_8() -> None:
    client, _ = controlled()
    client.send(CreateServiceConnection(command_code=0xE456, rate_hz=100.0), to=NM, service=True)
    drive(client, 40.0, 300)
    assert client.sim.core.plant.speed_mps > 2.0
    client.sim.set_devices(SafetyDevices(safestop="pause"))
    drive(client, 40.0, 400)                                   # throttle keeps coming: ignored
    mode = [m for m in client.inbox if isinstance(m, ReportVehicleMode)][-1]
    assert mode.safety_mode == 8 and mode.safety_devices & 0b10
    assert abs(client.sim.core.plant.speed_mps) < 0.01
    assert client.sim.core.plant.brake == pytest.approx(0.5, abs=0.02)   # 50 % hold


def test_wrench_command_timeout_is_an_error_pause() -> None:
    client, _ = controlled()
    drive(client, 20.0, 10)
    client.step(60)
    assert client.sim.mode.safety_mode == "software-pause"
    assert client.sim.vehicle_mode().safety_devices & 0x80        # errors detected
    drive(client, 0.0, 2)
    assert client.sim.mode.safety_mode == "drive-by-wire"


def test_discrete_devices_shift_and_start() -> None:
    client, _ = controlled(ready=False)
    client.send(SetDiscreteDevices(propulsion_flags=Propulsion.MAIN_POWER | Propulsion.STARTER,
                                   parking_horn_flags=0, gear=Gear.NEUTRAL))
    drive(client, 0.0, 200, brake_pct=50.0)
    plant = client.sim.core.plant
    assert plant.engine == "running" and plant.gear == "neutral" and not plant.park_brake
    client.send(SetDiscreteDevices(gear=2))
    drive(client, 0.0, 100, brake_pct=50.0)
    assert plant.gear == "drive"
    client.send(SetDiscreteDevices(gear=77))                  # not a gear of the Escape
    assert client.sim.stats.invalid == 1


def test_motion_profile_mpd_takes_the_pd_tracks_and_lapses_to_a_stop() -> None:
    sim = make_sim()
    client = Peer(sim)
    client.send(RequestComponentControl(authority=6), Resume(), to=MPD)
    assert sim.pd.controller == MPD and sim.mode.control_mode == "motion-profiles"
    assert sim.mode.ready_mode == "ready" and sim.mode.safety_mode == "drive-by-wire"
    ignored = sim.stats.ignored_no_control
    client.send(SetWrenchEffort.xgv(throttle_pct=80.0, steering_pct=0.0, brake_pct=0.0))
    assert sim.stats.ignored_no_control == ignored + 1         # the PD belongs to the MPD
    for _ in range(600):
        client.send(SetMotionProfile.single(speed_mps=4.0, max_accel_mps2=1.5,
                                            curvature_1pm=-0.02), to=MPD)
        client.step()
    plant = sim.core.plant
    assert plant.speed_mps == pytest.approx(4.0, abs=0.15)
    assert plant.curvature_1pm == pytest.approx(-0.02, abs=0.002)
    client.step(int(4.0 / sim.params.pause_decel_mps2 / 0.01) + 150)   # no refresh: it lapses
    assert abs(plant.speed_mps) < 0.01


def test_estop_disable_overrides_everything() -> None:
    client, _ = controlled()
    drive(client, 40.0, 200)
    client.sim.set_devices(SafetyDevices(estop_button=True))
    drive(client, 40.0, 100)
    assert client.sim.mode.safety_mode == "estop-disable"
    assert client.sim.core.plant.brake > 0.99 and client.sim.core.plant.engine == "off"


# --------------------------------------------------------------------------- helpers

def test_gear_codes_round_trip_for_every_preset() -> None:
    for params in PRESETS.values():
        codes = gear_codes(params)
        assert len(set(codes.values())) == len(codes)
        for name, code in codes.items():
            assert gear_from_code(params, code) == name
    escape = gear_codes(PRESETS["escape-hybrid"])
    assert escape == {"park": 0, "reverse": 129, "neutral": 128, "drive": 2, "low": 1}
    assert gear_from_code(PRESETS["escape-hybrid"], 200) == "reverse"


def test_timestamp_fields() -> None:
    stamp = jaus_timestamp(3723.456)
    assert (stamp.day, stamp.hour, stamp.minute, stamp.second, stamp.millisecond) == (1, 1, 2, 3, 456)
    assert msgspec.structs.astuple(jaus_timestamp(0.0)) == (1, 0, 0, 0, 0)


def test_one_message_per_datagram_unless_packing_is_asked() -> None:
    """OpenJAUS receivers keep only a datagram's first message (issue 19): never pack by default."""
    from overdrive.jaus import CreateServiceConnection, ReportVelocityState, ReportWrenchEffort
    from overdrive.jaus.judp import split

    for packed in (False, True):
        sim = make_sim(pack_datagrams=packed)
        peer = Peer(sim)
        for code in (ReportVelocityState.code, ReportWrenchEffort.code, 0x4002):
            peer.send(CreateServiceConnection(command_code=code, rate_hz=100.0), service=True)
        sizes = [len(split(data)) for data, _ in sim.step(0.0)]
        assert sum(sizes) >= 3
        assert (max(sizes) > 1) if packed else sizes == [1] * len(sizes)


@pytest.mark.parametrize("rate_hz", [1.0, 5.0, 10.0, 12.5, 20.0, 33.0, 50.0, 100.0])
def test_service_connection_reports_at_the_confirmed_rate(rate_hz: float) -> None:
    """Issue 19: 10 Hz came out at 12.5 Hz. Over 10 s the count is the rate's, within one."""
    from overdrive.jaus import (
        ConfirmServiceConnection,
        CreateServiceConnection,
        ReportVelocityState,
    )

    sim = make_sim()
    peer = Peer(sim)
    peer.send(CreateServiceConnection(command_code=ReportVelocityState.code, rate_hz=rate_hz),
              service=True)
    confirmed = peer.of(ConfirmServiceConnection)[-1].rate_hz
    got = []
    for _ in range(10):    # a live client: heard from every second (PEER_TIMEOUT_S)
        got += peer.step(100)
        peer.send(QueryHeartbeatPulse(), to=NM)
    count = sum(isinstance(m, ReportVelocityState) for m in got)
    assert abs(count - 10.0 * confirmed) <= 1.0, (count, confirmed)


def test_discovery_queries_are_answered_as_openjaus_expects() -> None:
    """An OpenJAUS node manager asks Identification, Configuration and Services (issue 19)."""
    from overdrive.jaus import (
        QueryConfiguration,
        QueryField,
        QueryIdentification,
        QueryServices,
        ReportConfiguration,
        ReportIdentification,
        ReportServices,
        encode,
    )

    sim = make_sim()
    peer = Peer(sim)
    (subsystem,) = peer.send(QueryIdentification(query_field=QueryField.SUBSYSTEM), to=NM)
    (node,) = peer.send(QueryIdentification(query_field=QueryField.NODE), to=NM)
    (component,) = peer.send(QueryIdentification(query_field=QueryField.COMPONENT))
    assert isinstance(subsystem, ReportIdentification) and subsystem.query_type == 2
    assert subsystem.header.source == NM and subsystem.header.destination == CLIENT
    assert "XGV" in subsystem.identification
    assert node.query_type == 3 and component.identification == "Primitive Driver"
    (config,) = peer.send(QueryConfiguration(query_field=QueryField.SUBSYSTEM), to=NM)
    assert isinstance(config, ReportConfiguration)
    assert [n.node for n in config.nodes] == [1]
    assert (33, 1) in config.nodes[0].components and (1, 1) in config.nodes[0].components
    (services,) = peer.send(QueryServices())
    assert isinstance(services, ReportServices)
    assert [s.type for s in services.services] == [0, 33]
    assert (0x0405, 0x0FFF) in services.services[1].inputs
    assert (0x4405, 0x0FFF) in services.services[1].outputs
    assert all(encode(m) for m in (subsystem, node, component, config, services))
    # a node-level query at a component that is not the node manager is not answered
    assert peer.send(QueryConfiguration(query_field=QueryField.SUBSYSTEM)) == []
    assert sim.stats.unsupported == 1


# --------------------------------------------------------------------------- peers

def test_an_id_is_bound_to_its_address_and_spoofs_are_dropped() -> None:
    from overdrive.jaus import (
        CreateServiceConnection,
        ReleaseComponentControl,
        RequestComponentControl,
        SetWrenchEffort,
        TerminateServiceConnection,
    )

    sim = make_sim()
    mail: dict = {}
    real = Peer(sim, CLIENT, ("127.0.0.1", 40000), mail)
    spoof = Peer(sim, CLIENT, ("127.0.0.1", 40001), mail)   # same id, another port
    real.send(RequestComponentControl(authority=6))
    real.send(CreateServiceConnection(command_code=0x4404, rate_hz=50.0), service=True)
    attacks = [SetWrenchEffort.xgv(throttle_pct=95.9), ReleaseComponentControl(),
               TerminateServiceConnection(command_code=0x4404, instance_id=1),
               CreateServiceConnection(command_code=0x4404, rate_hz=100.0), QueryHeartbeatPulse()]
    for attack in attacks:
        assert spoof.send(attack) == []
    assert sim.stats.spoofed == len(attacks)
    assert sim.pd.controller == CLIENT and sim.actuation.throttle_pct == 0.0
    assert [(c.client, c.address) for c in sim.connections] == [(CLIENT, real.address)]
    assert sim.peers[CLIENT].address == real.address
    real.step(20)
    assert mail[spoof.address] == []                       # nothing redirected


def test_silent_peers_expire_and_free_their_id_and_state() -> None:
    from overdrive.jaus import CreateServiceConnection, RequestComponentControl
    from overdrive.vehicle.xgv import MAX_PEERS, PEER_TIMEOUT_S

    sim = make_sim()
    mail: dict = {}
    first = Peer(sim, CLIENT, ("127.0.0.1", 40000), mail)
    first.send(RequestComponentControl(authority=6))
    first.send(CreateServiceConnection(command_code=0x4404, rate_hz=10.0), service=True)
    fakes = [Peer(sim, JausId(1, 9, 5 + i, 1), ("127.0.0.1", 41000 + i), mail)
             for i in range(MAX_PEERS + 10)]
    for fake in fakes:
        fake.send(QueryHeartbeatPulse(), to=NM)
    assert len(sim.peers) == MAX_PEERS and sim.stats.peers_refused == 11
    first.step(int(PEER_TIMEOUT_S / 0.01) + 1)            # everyone silent for 5 s
    assert sim.peers == {} and sim.connections == [] and sim.pd.controller is None
    assert sim.stats.expired == 1
    again = Peer(sim, CLIENT, ("127.0.0.1", 40002), mail)  # the id, from a new port
    again.now_s = first.now_s
    assert again.send(RequestComponentControl(authority=6))
    assert sim.pd.controller == CLIENT and sim.peers[CLIENT].address == again.address


def test_connections_per_peer_are_bounded() -> None:
    from overdrive.jaus import ConfirmServiceConnection, CreateServiceConnection
    from overdrive.vehicle.xgv import MAX_CONNECTIONS_PER_PEER, REPORTS

    sim = make_sim()
    peer = Peer(sim)
    codes = [(cid, code) for cid, codes in REPORTS.items() for code in sorted(codes)]
    for cid, code in codes:
        peer.send(CreateServiceConnection(command_code=code, rate_hz=1.0),
                  to=JausId(1, 1, int(cid), 1), service=True)
    responses = [m.response for m in peer.of(ConfirmServiceConnection)]
    assert len(codes) > MAX_CONNECTIONS_PER_PEER
    assert responses.count(ServiceConnectionResponse.CREATED) == MAX_CONNECTIONS_PER_PEER
    assert len(sim.connections) == MAX_CONNECTIONS_PER_PEER


def test_a_datagram_packed_with_messages_costs_at_most_eight_dispatches() -> None:
    """Found: 200 queries in one 4 kB datagram were 200 dispatches (and replies)."""
    from overdrive.jaus import Header, encode_datagram
    from overdrive.vehicle.xgv import MAX_MESSAGES_PER_DATAGRAM

    sim = make_sim()
    query = QueryHeartbeatPulse(header=Header(destination=NM, source=CLIENT))
    datagram = encode_datagram([query] * 200)
    replies = sim.receive(datagram, ("127.0.0.1", 40000), 0.0)
    assert len(replies) == MAX_MESSAGES_PER_DATAGRAM == 8
    assert sim.stats.excess == 192 and sim.stats.messages == 8
