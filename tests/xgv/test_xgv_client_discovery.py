"""The client as its own node manager (issue 19): it says it is alive to the XGV's node
manager and answers the discovery an OpenJAUS node manager runs, so OpenJAUS keeps it (and its
control) in its system tree. Sans-IO: datagrams in, datagrams out."""

from __future__ import annotations

from overdrive.jaus import (
    ConfirmComponentControl,
    JausId,
    QueryConfiguration,
    QueryField,
    QueryHeartbeatPulse,
    QueryIdentification,
    QueryServices,
    RejectComponentControl,
    ReportConfiguration,
    ReportHeartbeatPulse,
    ReportIdentification,
    ReportServices,
    RequestComponentControl,
    decode_datagram,
    encode_datagram,
)
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv_client import (
    NM_HEARTBEAT_PERIOD_S,
    REGISTRATION_GRACE_S,
    XgvClient,
    XgvClientConfig,
)

ME = JausId(1, 2, 4, 1)
MY_NM = JausId(1, 2, 1, 1)
XGV_NM = JausId(1, 1, 1, 1)
PD = JausId(1, 1, 33, 1)


def sent(client: XgvClient, now_s: float) -> list:
    return [m for d in client.command_datagrams(now_s) for m in decode_datagram(d)]


def deliver(client: XgvClient, message: object, source: JausId, destination: JausId,
            now_s: float) -> None:
    framed = message.with_header(source=source, destination=destination)  # type: ignore[attr-defined]
    client.receive(encode_datagram(framed), now_s)


def test_heartbeats_as_its_node_manager_and_answers_discovery() -> None:
    client = XgvClient(PRESETS["escape-hybrid"])
    beats = [m for t in range(0, 30) for m in sent(client, t * 0.1)
             if isinstance(m, ReportHeartbeatPulse)]
    assert len(beats) == round(3.0 / NM_HEARTBEAT_PERIOD_S)
    assert {(b.header.source, b.header.destination) for b in beats} == {(MY_NM, XGV_NM)}
    # what OpenJAUS's node manager asks, in its order
    deliver(client, QueryIdentification(query_field=QueryField.NODE), XGV_NM, MY_NM, 3.0)
    deliver(client, QueryConfiguration(query_field=QueryField.NODE), XGV_NM, MY_NM, 3.0)
    deliver(client, QueryIdentification(query_field=QueryField.COMPONENT), XGV_NM, ME, 3.0)
    deliver(client, QueryServices(), XGV_NM, ME, 3.0)
    deliver(client, QueryHeartbeatPulse(), XGV_NM, MY_NM, 3.0)
    answers = [m for m in sent(client, 3.0) if not isinstance(m, RequestComponentControl)]
    node, config, component, services, beat = answers[:5]
    assert isinstance(node, ReportIdentification) and node.query_type == 3
    assert node.header.source == MY_NM and node.header.destination == XGV_NM
    assert isinstance(config, ReportConfiguration)
    assert config.nodes[0].node == 2 and (4, 1) in config.nodes[0].components
    assert isinstance(component, ReportIdentification) and component.header.source == ME
    assert "client" in component.identification
    assert isinstance(services, ReportServices) and services.header.source == ME
    assert isinstance(beat, ReportHeartbeatPulse) and client.registered


def test_a_reject_before_openjaus_knows_us_is_retried_quietly() -> None:
    client = XgvClient(PRESETS["escape-hybrid"])
    deliver(client, ReportHeartbeatPulse(), XGV_NM, JausId(1, 255, 1, 1), 0.0)  # broadcast
    assert client.link_up
    deliver(client, ConfirmComponentControl(response=0), PD, ME, 0.1)
    deliver(client, RejectComponentControl(), PD, ME, 0.11)
    assert not client.control and client.notices == []
    assert any(isinstance(m, RequestComponentControl) for m in sent(client, 0.12))
    # after the grace, or once registered, a Reject is a fault as before
    deliver(client, ConfirmComponentControl(response=0), PD, ME, REGISTRATION_GRACE_S)
    deliver(client, RejectComponentControl(), PD, ME, REGISTRATION_GRACE_S + 0.01)
    assert [n.code for n in client.notices] == ["xgv_control", "command_timeout"]   # latched


def test_without_the_node_manager_role_nothing_is_answered() -> None:
    client = XgvClient(PRESETS["escape-hybrid"], XgvClientConfig(node_manager=False))
    assert not any(isinstance(m, ReportHeartbeatPulse) for m in sent(client, 0.0))
    deliver(client, QueryConfiguration(), XGV_NM, MY_NM, 0.0)
    assert client.stats.foreign == 1 and not client.registered


def test_serves_its_status_to_a_component_that_watches_its_controller() -> None:
    """OpenJAUS's Primitive Driver asks its controller for Report Component Status at 5 Hz and
    brakes at 80 % when the reports stop (ojVehicleSim pd.c)."""
    from overdrive.jaus import (
        ConfirmServiceConnection,
        CreateServiceConnection,
        ReportComponentStatus,
        TerminateServiceConnection,
    )

    client = XgvClient(PRESETS["escape-hybrid"])
    deliver(client, CreateServiceConnection(command_code=0x4002, rate_hz=5.0), PD, ME, 0.0)
    deliver(client, CreateServiceConnection(command_code=0x4404, rate_hz=5.0), PD, ME, 0.0)
    got = [m for t in range(100) for m in sent(client, t * 0.01)]
    confirms = [m for m in got if isinstance(m, ConfirmServiceConnection)]
    assert [(c.command_code, c.response) for c in confirms] == [(0x4002, 0), (0x4404, 2)]
    statuses = [m for m in got if isinstance(m, ReportComponentStatus)]
    assert len(statuses) == 5 and all(s.header.service_connection for s in statuses)
    assert {s.primary_status for s in statuses} == {1} and statuses[0].header.destination == PD
    deliver(client, TerminateServiceConnection(command_code=0x4002, instance_id=1), PD, ME, 1.0)
    assert not any(isinstance(m, ReportComponentStatus) for m in sent(client, 2.0))
