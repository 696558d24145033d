"""The simulated ByWire XGV: its JAUS 3.3 components around the simulated vehicle. Sans-IO.

``XgvSimulator`` is the XGV controller (reference §7: subsystem 1, node 1) seen from the wire:

- Node Manager (1): heartbeat (Report Heartbeat Pulse about once a second to every client it
  has heard from), Report Vehicle Mode (0xE456) over service connections;
- Motion Profile Driver (10): Set Motion Profile, tracked by its own speed and curvature
  controllers; when controlled it takes control of the Primitive Driver itself (seed 000);
- Signals Driver (11), Error Manager (12, Report Error Count of the simulator's counters);
- Primitive Driver (33): Set Wrench Effort, Set Discrete Devices (gear, engine, parking
  brake, horn), and the reports of the vehicle's state;
- velocity and pose sensors, answered at the Primitive Driver (the codec's default source)
  and at the JAUS 3.3 sensor ids 38 (global pose), 41 (local pose), 42 (velocity state).

Access control: a component is controlled by one client at a time; a request of higher
authority takes it (the loser gets Reject Component Control); commands from anyone else are
ignored and counted. Component status, service connections and queries follow reference §4.
Each client id is bound to the UDP address it first spoke from; messages claiming it from
elsewhere are dropped and counted, and a peer silent for ``PEER_TIMEOUT_S`` loses its
connections and control (issue 18, docs/xgv.md). Discovery queries (Identification,
Configuration, Services, Component Authority) are answered as an OpenJAUS node manager expects.
The vehicle itself is ``VehicleSim`` (gate, seed-000 safety behaviour, plant, sensors),
driven by the commands of whoever holds the Primitive Driver; its safety mode includes the
control/ready-mode software pause (``VehicleSim.software_ready``).

Frames: JAUS's vehicle frame is x forward, y right, z down, so positive curvature, yaw rate
and steering effort turn right, as in the stack (no sign change). Local Pose is x along the
stack's +x, y to its right (-y), yaw clockwise (-heading). Global Pose is a flat-earth
projection of the local pose at ``origin_deg`` with local +x pointing north (WGS-84 radii at
the origin: the exact inverse of ``plain_jaus.LocalFrame``).

Nothing here reads a clock or touches a socket: ``receive(datagram, sender, now_s)`` and
``step(now_s)`` return the datagrams to send as ``(bytes, address)``. See docs/xgv.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, Final

import msgspec

from overdrive.dynamics.control import Pid, PidGains, rate_limit
from overdrive.dynamics.speed_control import LongitudinalController, gains_for
from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.jaus import (
    ActivateServiceConnection,
    ClearEmergency,
    ComponentStatus,
    ConfigurationNode,
    ConfirmComponentControl,
    ConfirmServiceConnection,
    ControlResponse,
    CreateServiceConnection,
    Header,
    JausDecodeError,
    JausEncodeError,
    JausId,
    JausTimestamp,
    Message,
    Propulsion,
    QueryComponentAuthority,
    QueryComponentControl,
    QueryComponentStatus,
    QueryConfiguration,
    QueryDiscreteDevices,
    QueryField,
    QueryGlobalPose,
    QueryHeartbeatPulse,
    QueryIdentification,
    QueryLocalPose,
    QueryServices,
    QueryVelocityState,
    QueryWrenchEffort,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportComponentAuthority,
    ReportComponentControl,
    ReportComponentStatus,
    ReportConfiguration,
    ReportCurvature,
    ReportDiscreteDevices,
    ReportErrorCount,
    ReportGlobalPose,
    ReportHeartbeatPulse,
    ReportIdentification,
    ReportLocalPose,
    ReportServices,
    ReportSignals,
    ReportVehicleMode,
    ReportVelocityState,
    ReportWheelsSpeed,
    ReportWrenchEffort,
    RequestComponentControl,
    Reset,
    Resume,
    Service,
    ServiceConnectionResponse,
    SetComponentAuthority,
    SetDiscreteDevices,
    SetEmergency,
    SetMotionProfile,
    SetSignals,
    SetWrenchEffort,
    Shutdown,
    Standby,
    SuspendServiceConnection,
    TerminateServiceConnection,
    XgvComponent,
    XgvSecondaryStatus,
)
from overdrive.jaus.judp import datagrams, decode_messages, split
from overdrive.jaus.messages import LINK_STATUS_SHIFT
from overdrive.jaus.multipacket import Reassembler
from overdrive.messages import SafetyDevices, Topic
from overdrive.safety.gate import GateLimits
from overdrive.vehicle.modes import (
    CONTROL_MODE_CODE,
    LINK_CODE,
    MPD_ID,
    READY_MODE_CODE,
    SAFETY_MODE_CODE,
    ModeInputs,
    VehicleMode,
    compute_modes,
    computer_axes,
    control_mode,
    partial_override_bits,
    safety_device_bits,
)
from overdrive.vehicle.plain_jaus import local_radii_m
from overdrive.vehicle.plant import World
from overdrive.vehicle.sim_node import FAULTS_TOPIC, VehicleSim

Address = tuple[str, int]
Outgoing = list[tuple[bytes, Address]]

HEARTBEAT_PERIOD_S: Final = 1.0        # reference §2: Report Heartbeat Pulse "at about 1 Hz"
MAX_REPORT_RATE_HZ: Final = 100.0      # the simulator steps at 100 Hz: faster is granted at this
STEP_TOLERANCE_S: Final = 0.005        # half the 10 ms step (xgv_sim.PERIOD_S): a report due
                                       # within it goes out in this step
COMMAND_TIMEOUT_S: Final = 0.5         # wrench mode: no Set Wrench Effort for this long -> error pause
                                       # (a dead client must not leave the throttle open; our choice);
                                       # 50 periods of the client's 100 Hz: no false trip at any
                                       # loss up to 50 % (p^50; docs/xgv.md, "A lossy link")
MPD_HOLD_BRAKE_PCT: Final = 50.0       # MPD at a standstill: seed 000's 50 % holding brake
SPEED_DEADBAND_MPS: Final = 0.005     # a few steps of the u16 speed field (0.002 m/s, reference §6)
CURVATURE_DEADBAND_1PM: Final = 1e-4  # two steps of the u16 atan(curvature) field (reference §6)
FULL_BRAKE_FRACTION: Final = 0.99     # a stop at >= this x the preset's full-brake decel: 100 %
STOPPED_MPS: Final = 0.05              # MPD standstill (plant shift threshold, as the driving module)
CURVATURE_TRIM_MIN_MPS: Final = 1.0    # curvature trim only where yaw rate / speed is meaningful
MAX_PEERS: Final = 64                  # per-source state bound (issue 18): a real setup has a
                                       # handful of client ids; more are refused and counted
MAX_CONNECTIONS: Final = 256           # all service connections (instance ids are one byte)
MAX_MESSAGES_PER_DATAGRAM: Final = 8  # reference §2: "one public XGV client packs up to 5";
                                       # the rest of a longer datagram is dropped (``excess``):
                                       # 200 messages in one datagram cost 200 dispatches
MAX_CONNECTIONS_PER_PEER: Final = 16   # one client: the overdrive client opens 6, ojcmpt 3
PEER_TIMEOUT_S: Final = 5.0            # a peer silent this long (5 heartbeat periods, reference
                                       # §2) loses its service connections and control, and its
                                       # id is free to come back from another address (500 of
                                       # the client's 100 Hz datagrams: loss never trips it; the
                                       # client's own heartbeat timeout, 4.5 s, is shorter)
ORIGIN_DEG: Final = (37.2296, -80.4139)  # Global Pose datum (Blacksburg, VA); any point works
POSITION_RMS_M: Final = 0.02           # reported accuracy: the preset's RTK-grade GPS noise
ATTITUDE_RMS_RAD: Final = 0.002
DAYS_IN_TIMESTAMP: Final = 31          # reference §5: day of month, 1..31

GLOBAL_POSE_SENSOR: Final = 38         # JAUS 3.3 component ids of the standard sensors
LOCAL_POSE_SENSOR: Final = 41
VELOCITY_STATE_SENSOR: Final = 42

QUERY_REPORT: Final = {
    QueryComponentStatus.code: ReportComponentStatus.code,
    QueryComponentControl.code: ReportComponentControl.code,
    QueryHeartbeatPulse.code: ReportHeartbeatPulse.code,
    QueryWrenchEffort.code: ReportWrenchEffort.code,
    QueryDiscreteDevices.code: ReportDiscreteDevices.code,
    QueryVelocityState.code: ReportVelocityState.code,
    QueryGlobalPose.code: ReportGlobalPose.code,
    QueryLocalPose.code: ReportLocalPose.code,
}
"""Query code -> the report it is answered with (reference §4-5)."""

_STATUS, _CONTROL, _HEARTBEAT = 0x4002, 0x400D, 0x4202
_WRENCH, _DISCRETE, _VELOCITY, _GLOBAL, _LOCAL = 0x4405, 0x4406, 0x4404, 0x4402, 0x4403
_MODE, _CURVATURE, _WHEELS, _SIGNALS, _ERRORS = 0xE456, 0xE455, 0xE42E, 0xE445, 0xE451
_PD_REPORTS: Final = frozenset({_STATUS, _CONTROL, _HEARTBEAT, _WRENCH, _DISCRETE, _VELOCITY,
                                _GLOBAL, _LOCAL, _WHEELS})
REPORTS: Final[dict[int, frozenset[int]]] = {
    XgvComponent.NODE_MANAGER: frozenset({_STATUS, _HEARTBEAT, _MODE}),
    XgvComponent.MOTION_PROFILE_DRIVER: frozenset({_STATUS, _CONTROL, _HEARTBEAT, _CURVATURE}),
    XgvComponent.SIGNALS_DRIVER: frozenset({_STATUS, _CONTROL, _HEARTBEAT, _SIGNALS}),
    XgvComponent.ERROR_MANAGER: frozenset({_STATUS, _HEARTBEAT, _ERRORS}),
    XgvComponent.PRIMITIVE_DRIVER: _PD_REPORTS,
    GLOBAL_POSE_SENSOR: frozenset({_STATUS, _HEARTBEAT, _GLOBAL}),
    LOCAL_POSE_SENSOR: frozenset({_STATUS, _HEARTBEAT, _LOCAL}),
    VELOCITY_STATE_SENSOR: frozenset({_STATUS, _HEARTBEAT, _VELOCITY}),
}
"""The reports each component gives, on query and over service connections."""

CONTROLLABLE: Final = frozenset({XgvComponent.PRIMITIVE_DRIVER, XgvComponent.MOTION_PROFILE_DRIVER,
                                 XgvComponent.SIGNALS_DRIVER})
# Discovery (issue 19): what an OpenJAUS node manager asks of every component it finds. The
# names are ours; types and authority are 0 as OpenJAUS's own node manager reports them.
SUBSYSTEM_IDENTIFICATION: Final = "overdrive xgv-sim (ByWire XGV)"
NODE_IDENTIFICATION: Final = "XGV controller"
COMPONENT_IDENTIFICATION: Final = {
    XgvComponent.NODE_MANAGER: "Node Manager", XgvComponent.MOTION_PROFILE_DRIVER:
    "Motion Profile Driver", XgvComponent.SIGNALS_DRIVER: "Signals Driver",
    XgvComponent.ERROR_MANAGER: "Error Manager", XgvComponent.PRIMITIVE_DRIVER: "Primitive Driver",
    GLOBAL_POSE_SENSOR: "Global Pose Sensor", LOCAL_POSE_SENSOR: "Local Pose Sensor",
    VELOCITY_STATE_SENSOR: "Velocity State Sensor"}
CORE_SERVICE: Final = 0   # OpenJAUS jausService.h CORE_MESSAGE_SUPPORT
CORE_INPUTS: Final = (0x0001, 0x0002, 0x0003, 0x0004, 0x0005, 0x0006, 0x0007, 0x0008, 0x0009,
                      0x000A, 0x000B, 0x000C, 0x000D, 0x000E, 0x000F, 0x0010, 0x2001, 0x2002,
                      0x200D, 0x2202)   # reference §4 core messages taken by every component
CORE_OUTPUTS: Final = (0x0009, 0x000F, 0x0010, 0x4001, 0x4002, 0x400D, 0x4202)
COMMANDS: Final[dict[int, tuple[tuple[int, int], ...]]] = {
    XgvComponent.PRIMITIVE_DRIVER: ((0x0405, 0x0FFF), (0x0406, 0x0F)),   # §5, defined bits
    XgvComponent.MOTION_PROFILE_DRIVER: ((0xE328, 0), (0x0406, 0x0F)),  # §6, relayed devices
    XgvComponent.SIGNALS_DRIVER: ((0xE322, 0x07),)}
PRESENCE_BITS: Final = {_WRENCH: 0x0FFF, _DISCRETE: 0x0F, _VELOCITY: 0x01FF, _GLOBAL: 0x01FF,
                        _LOCAL: 0x01FF}
_STATUS_NAME: Final = {ComponentStatus.READY: "ready", ComponentStatus.STANDBY: "standby",
                       ComponentStatus.INITIALIZE: "initialize", ComponentStatus.SHUTDOWN: "shutdown",
                       ComponentStatus.FAILURE: "failure", ComponentStatus.EMERGENCY: "emergency"}


# --------------------------------------------------------------------------- gears

def gear_codes(params: VehicleParams) -> dict[str, int]:
    """Set/Report Discrete Devices gear byte per gear of the preset (reference §5).

    Park-type gears 0, neutral 128, reverse 129 and up, forward 1-127: the low gear 1 and the
    drive gear 2 (the XGV's numbers), other forward gears from 3.
    """
    codes: dict[str, int] = {}
    forward, reverse = 3, 129
    for gear in params.gears:
        if gear.direction == 0:
            codes[gear.name] = 0 if gear.holds else 128
        elif gear.direction < 0:
            codes[gear.name], reverse = reverse, reverse + 1
        elif gear.name == params.low_gear:
            codes[gear.name] = 1
        elif gear.name == params.drive_gear:
            codes[gear.name] = 2
        else:
            codes[gear.name], forward = forward, forward + 1
    return codes


def gear_from_code(params: VehicleParams, code: int) -> str | None:
    """The preset's gear for a gear byte; any 129-255 is the first reverse gear; else None."""
    for name, value in gear_codes(params).items():
        if value == code:
            return name
    if 129 <= code <= 255:
        return params.reverse_gear
    return None


def jaus_timestamp(now_s: float) -> JausTimestamp:
    """Reference §5 timestamp of a time in seconds since the simulator started (day 1 first)."""
    ms_total = int(max(now_s, 0.0) * 1000.0)
    seconds, ms = divmod(ms_total, 1000)
    minutes, second = divmod(seconds, 60)
    hours, minute = divmod(minutes, 60)
    days, hour = divmod(hours, 24)
    return JausTimestamp(days % DAYS_IN_TIMESTAMP + 1, hour, minute, second, ms)


# --------------------------------------------------------------------------- state records

class XgvStats:
    """Counters; the Error Manager reports them (Report Error Count, in this order)."""

    FIELDS = ("malformed", "ignored_no_control", "unsupported", "invalid", "unroutable",
              "datagrams", "messages", "spoofed", "peers_refused", "expired", "excess")

    def __init__(self) -> None:
        for name in self.FIELDS:
            setattr(self, name, 0)

    def as_dict(self) -> dict[str, int]:
        return {name: getattr(self, name) for name in self.FIELDS}

    def __repr__(self) -> str:
        return f"XgvStats({self.as_dict()})"


@dataclass
class Component:
    jaus_id: JausId
    controller: JausId | None = None
    controller_authority: int = 0
    authority: int = 0                       # Set Component Authority: the bar for requests
    status: int = ComponentStatus.STANDBY

    @property
    def status_name(self) -> str:
        return _STATUS_NAME[ComponentStatus(self.status)]


@dataclass
class PeerBinding:
    """Where a client id talks from, and when it was last heard (issue 18)."""

    address: Address
    last_heard_s: float


@dataclass
class Connection:
    client: JausId
    address: Address
    component: int
    code: int
    instance: int
    rate_hz: float
    presence: int
    active: bool = True
    next_s: float = -math.inf
    sequence: int = 0


@dataclass
class Actuation:
    """What the Primitive Driver executes (from its controller, or from the MPD's loops)."""

    throttle_pct: float = 0.0
    brake_pct: float = 100.0
    steer_pct: float = 0.0
    gear: str = "park"
    engine_on: bool = False
    park_brake: bool = True
    horn: bool = False
    last_wrench_s: float | None = None


@dataclass
class MotionPlan:
    motions: tuple[Any, ...] = ()
    start_s: float = 0.0
    signals: dict[str, Any] = field(default_factory=dict)


class XgvSimulator:
    """The XGV controller as a sans-IO object (see the module docstring)."""

    def __init__(self, params: VehicleParams, world: World | None = None, seed: int = 1, *,
                 ready: bool = False, subsystem: int = 1, node: int = 1,
                 command_timeout_s: float | None = COMMAND_TIMEOUT_S,
                 origin_deg: tuple[float, float] = ORIGIN_DEG,
                 pack_datagrams: bool = False) -> None:
        self.params = params
        self.pack_datagrams = pack_datagrams   # one message per datagram unless asked (judp)
        self.subsystem, self.node = subsystem, node
        self.core = VehicleSim(params, world or World(), seed, ready=ready, limits=GateLimits(
            steer_rate_pct_per_s=100.0 * params.steer_rate_rps / params.max_steer_rad,
            pedal_sources=frozenset({"xgv"}), steer_sources=frozenset({"xgv"}),
            powertrain_sources=frozenset({"xgv"})))
        self.command_timeout_s = command_timeout_s
        self.origin_deg = origin_deg
        self.gear_code = gear_codes(params)
        self.components: dict[int, Component] = {
            int(c): Component(JausId(subsystem, node, int(c), 1)) for c in REPORTS}
        self.actuation = Actuation(brake_pct=0.0 if ready else 100.0,
                                   gear=params.drive_gear if ready else params.park_gear,
                                   engine_on=ready, park_brake=not ready)
        self.plan = MotionPlan()
        self.devices = SafetyDevices()
        self.stats = XgvStats()
        self.peers: dict[JausId, PeerBinding] = {}
        self.connections: list[Connection] = []
        self.reassembler = Reassembler()   # multi-packet messages (none of the XGV's needs it)
        self._instances: dict[tuple[int, int], int] = {}
        self._sequences: dict[tuple[JausId, JausId], int] = {}
        self.next_heartbeat_s = 0.0
        self.last_step_s: float | None = None
        self.latest: dict[str, Any] = {}         # the core's last sensor messages, by topic
        self.effective_devices = self.devices
        self.mode: VehicleMode = self._modes()
        # the MPD's own loops
        self.speed_loop = LongitudinalController(params, gains_for(params), MPD_HOLD_BRAKE_PCT)
        self.curvature_trim = Pid(PidGains(kp=0.0, ki=10.0, output_min=-10.0, output_max=10.0,
                                           tracking_time_s=0.5))
        self.curvature_ref_1pm = 0.0
        self.mpd_active = False

    # ------------------------------------------------------------------ physical inputs

    def set_devices(self, devices: SafetyDevices) -> None:
        """The safety devices changed (SafeStop, overrides, door, e-stop, errors, LCD)."""
        self.devices = devices

    def set_world(self, world: World) -> None:
        self.core.plant.world = world

    def apply_fault(self, fault: Any) -> None:
        """A scenario fault for the vehicle (as VehicleSim takes them on ``sim/faults``)."""
        self.core._receive([(FAULTS_TOPIC, fault)], [])

    # ------------------------------------------------------------------ modes

    @property
    def pd(self) -> Component:
        return self.components[XgvComponent.PRIMITIVE_DRIVER]

    @property
    def mpd(self) -> Component:
        return self.components[XgvComponent.MOTION_PROFILE_DRIVER]

    def _controller_key(self, comp: Component) -> str | None:
        if comp.controller is None:
            return None
        return MPD_ID if comp.controller == self.mpd.jaus_id else str(comp.controller)

    def _devices_at(self, now_s: float, control: str) -> SafetyDevices:
        """The devices plus the simulator's own error: a wrench-mode command timeout."""
        stale = (self.command_timeout_s is not None and control == "wrench-efforts"
                 and (self.actuation.last_wrench_s is None
                      or now_s - self.actuation.last_wrench_s > self.command_timeout_s))
        if stale and not self.devices.internal_error:
            return msgspec.structs.replace(self.devices, internal_error=True)
        return self.devices

    def _modes(self, now_s: float = 0.0) -> VehicleMode:
        pd_key, mpd_key = self._controller_key(self.pd), self._controller_key(self.mpd)
        self.effective_devices = self._devices_at(now_s, control_mode(pd_key, mpd_key))
        self.mode = compute_modes(ModeInputs(
            pd_controller=pd_key, mpd_controller=mpd_key,
            pd_status=self.pd.status_name, mpd_status=self.mpd.status_name,  # type: ignore[arg-type]
            devices=self.effective_devices))
        return self.mode

    # ------------------------------------------------------------------ wire in

    def receive(self, data: bytes, sender: Address, now_s: float) -> Outgoing:
        """Handle one datagram from ``sender``; returns the replies to send."""
        self.stats.datagrams += 1
        try:
            raws = split(data)
            if len(raws) > MAX_MESSAGES_PER_DATAGRAM:
                self.stats.excess += len(raws) - MAX_MESSAGES_PER_DATAGRAM
                raws = raws[:MAX_MESSAGES_PER_DATAGRAM]
            messages = decode_messages(raws, self.reassembler, now_s, sender)
        except JausDecodeError:
            self.stats.malformed += 1
            return []
        out: list[tuple[Message, Address]] = []
        for message in messages:
            self.stats.messages += 1
            self._dispatch(message, sender, now_s, out)
        self._take_pd_for_mpd(out)
        self._modes(now_s)
        return self._pack(out)

    def _dispatch(self, message: Message, sender: Address, now_s: float,
                  out: list[tuple[Message, Address]]) -> None:
        header = message.header
        dst, src = header.destination, header.source
        if not src.is_valid or src.is_broadcast or not dst.is_valid:
            self.stats.invalid += 1
            return
        if dst.subsystem not in (self.subsystem, 255) or dst.node not in (self.node, 255):
            self.stats.unroutable += 1
            return
        targets = [(cid, c) for cid, c in self.components.items() if dst.matches(c.jaus_id)]
        if not targets:
            self.stats.unroutable += 1
            return
        if not self._admit_peer(src, sender, now_s):
            return
        for cid, comp in targets:
            self._handle(cid, comp, message, src, sender, now_s, out)

    # ------------------------------------------------------------------ peers (issue 18)

    def _admit_peer(self, src: JausId, sender: Address, now_s: float) -> bool:
        """Bind ``src`` to ``sender`` on first contact; False (counted) when ``src`` is bound to
        another address and still alive, or when the peer table is full of live peers.

        The binding (id -> address) is what reports, heartbeats and Reject Component Control
        go to; it changes only after the peer has been silent for ``PEER_TIMEOUT_S``, by which
        time its control and service connections are gone (``_expire``).
        """
        peer = self.peers.get(src)
        if peer is not None and peer.address != sender:
            if now_s - peer.last_heard_s < PEER_TIMEOUT_S:
                self.stats.spoofed += 1
                return False
            self._drop_peer(src)
            peer = None
        if peer is None:
            if len(self.peers) >= MAX_PEERS:
                self._expire(now_s)
            if len(self.peers) >= MAX_PEERS:
                self.stats.peers_refused += 1
                return False
            peer = self.peers[src] = PeerBinding(sender, now_s)
        peer.last_heard_s = now_s
        return True

    def trusted_addresses(self) -> set[Address]:
        """The addresses of peers that control a component or hold a service connection (the
        runtime edge serves them first under load). One pass, whatever the number of senders."""
        holders = {c.controller for c in self.components.values()}
        holders.update(conn.client for conn in self.connections)
        return {peer.address for client, peer in self.peers.items() if client in holders}

    def _holds_session(self, client: JausId) -> bool:
        return (any(c.controller == client for c in self.components.values())
                or any(conn.client == client for conn in self.connections))

    def _drop_peer(self, client: JausId) -> None:
        """Forget ``client``: its service connections end and it loses control (a pause)."""
        self.peers.pop(client, None)
        before = len(self.connections)
        self.connections = [conn for conn in self.connections if conn.client != client]
        self.stats.expired += before - len(self.connections)
        for cid, comp in self.components.items():
            if comp.controller == client:
                self._release(cid, comp)

    def _expire(self, now_s: float) -> None:
        """Drop every peer silent for ``PEER_TIMEOUT_S`` (documented in docs/xgv.md)."""
        for client in [c for c, p in self.peers.items()
                       if now_s - p.last_heard_s >= PEER_TIMEOUT_S]:
            self._drop_peer(client)

    def _handle(self, cid: int, comp: Component, m: Message, src: JausId, sender: Address,
                now_s: float, out: list[tuple[Message, Address]]) -> None:
        reply = out.append
        controlled_by_sender = comp.controller == src
        if isinstance(m, RequestComponentControl):
            if cid not in CONTROLLABLE:
                reply((self._to(ConfirmComponentControl(response=ControlResponse.NOT_SUPPORTED),
                                comp, src), sender))
            else:
                self._request_control(comp, src, m.authority, sender, now_s, out)
        elif isinstance(m, ReleaseComponentControl):
            if cid in CONTROLLABLE and controlled_by_sender:
                self._release(cid, comp)
                reply((self._to(RejectComponentControl(), comp, src), sender))
            else:
                self.stats.ignored_no_control += 1
        elif isinstance(m, QueryHeartbeatPulse | QueryComponentStatus | QueryComponentControl
                        | QueryWrenchEffort | QueryDiscreteDevices | QueryVelocityState
                        | QueryGlobalPose | QueryLocalPose):
            code = QUERY_REPORT[m.code]
            presence = getattr(m, "presence_vector", 0)
            report = self._report(cid, code, presence, now_s) if code in REPORTS[cid] else None
            if report is None:
                self.stats.unsupported += 1
            else:
                reply((self._to(report, comp, src), sender))
        elif isinstance(m, QueryIdentification | QueryConfiguration | QueryServices
                        | QueryComponentAuthority):
            answer = self._discovery(cid, comp, m)
            if answer is None:
                self.stats.unsupported += 1
            else:
                reply((self._to(answer, comp, src), sender))
        elif isinstance(m, CreateServiceConnection):
            reply((self._to(self._create(cid, comp, m, src, sender), comp, src,
                            service_connection=True), sender))
        elif isinstance(m, ActivateServiceConnection | SuspendServiceConnection
                        | TerminateServiceConnection):
            self._change_connection(cid, m, src)
        elif isinstance(m, SetEmergency):
            if comp.status != ComponentStatus.EMERGENCY:
                comp.status = ComponentStatus.EMERGENCY
            if cid == XgvComponent.MOTION_PROFILE_DRIVER and self.pd.controller == comp.jaus_id:
                self.pd.status = ComponentStatus.EMERGENCY
        elif isinstance(m, ClearEmergency):
            if comp.status == ComponentStatus.EMERGENCY:
                comp.status = ComponentStatus.STANDBY
            if (cid == XgvComponent.MOTION_PROFILE_DRIVER and self.pd.controller == comp.jaus_id
                    and self.pd.status == ComponentStatus.EMERGENCY):
                self.pd.status = ComponentStatus.STANDBY
        elif isinstance(m, ReportHeartbeatPulse):
            pass        # a client's node manager saying it is alive (docs/xgv.md): noted above
        elif cid not in CONTROLLABLE:
            self.stats.unsupported += 1
        elif not controlled_by_sender:
            self.stats.ignored_no_control += 1
        elif isinstance(m, Resume | Standby | Shutdown | Reset):
            self._set_status(cid, comp, m)
        elif isinstance(m, SetComponentAuthority):
            comp.authority = m.authority
        elif isinstance(m, SetWrenchEffort) and cid == XgvComponent.PRIMITIVE_DRIVER:
            self._wrench(m, now_s)
        elif isinstance(m, SetDiscreteDevices) and cid in (XgvComponent.PRIMITIVE_DRIVER,
                                                            XgvComponent.MOTION_PROFILE_DRIVER):
            # the MPD relays its controller's discrete devices to the PD it controls
            if cid == XgvComponent.PRIMITIVE_DRIVER or self.pd.controller == comp.jaus_id:
                self._discrete(m)
            else:
                self.stats.ignored_no_control += 1
        elif isinstance(m, SetMotionProfile) and cid == XgvComponent.MOTION_PROFILE_DRIVER:
            self._motion_profile(m, now_s)
        elif isinstance(m, SetSignals) and cid == XgvComponent.SIGNALS_DRIVER:
            self.plan.signals = {k: v for k, v in m.fields_dict().items() if k != "version"}
        else:
            self.stats.unsupported += 1

    # ------------------------------------------------------------------ discovery

    def _discovery(self, cid: int, comp: Component, m: Message) -> Message | None:
        """Answers to what an OpenJAUS node manager asks (issue 19); None: not ours to answer."""
        node_manager = cid == XgvComponent.NODE_MANAGER
        if isinstance(m, QueryComponentAuthority):
            return ReportComponentAuthority(authority=comp.authority)
        if isinstance(m, QueryServices):
            core = Service(CORE_SERVICE, tuple((c, 0) for c in CORE_INPUTS),
                           tuple((c, 0) for c in CORE_OUTPUTS))
            reports = sorted(REPORTS[cid] - {_STATUS, _CONTROL, _HEARTBEAT})
            own = Service(cid, COMMANDS.get(cid, ()) + tuple(
                (code & 0x0FFF | 0x2000 if code < 0xE000 else code, PRESENCE_BITS.get(code, 0))
                for code in reports if code < 0xE000),
                tuple((code, PRESENCE_BITS.get(code, 0)) for code in reports))
            return ReportServices(services=(core, own))
        if isinstance(m, QueryConfiguration):
            if not node_manager or m.query_field not in (QueryField.SUBSYSTEM, QueryField.NODE):
                return None
            components = tuple((c, 1) for c in sorted(self.components))
            return ReportConfiguration(nodes=(ConfigurationNode(self.node, components),))
        assert isinstance(m, QueryIdentification)
        names = {QueryField.SUBSYSTEM: SUBSYSTEM_IDENTIFICATION,
                 QueryField.NODE: NODE_IDENTIFICATION}
        if m.query_field == QueryField.COMPONENT:
            text = COMPONENT_IDENTIFICATION[cid]
        elif node_manager and m.query_field in names:
            text = names[QueryField(m.query_field)]
        else:
            return None
        return ReportIdentification(query_type=m.query_field, identification=text)

    # ------------------------------------------------------------------ access control

    def _request_control(self, comp: Component, src: JausId, authority: int, sender: Address,
                         now_s: float, out: list[tuple[Message, Address]]) -> None:
        if comp.controller == src:
            comp.controller_authority = authority
            accepted = True
        elif authority < comp.authority:
            accepted = False
        elif comp.controller is None:
            accepted = True
        elif authority > comp.controller_authority:
            self._lose_control(comp, out)
            accepted = True
        else:
            accepted = False
        if accepted and comp.controller != src:
            comp.controller, comp.controller_authority = src, authority
            if comp.status == ComponentStatus.READY:
                comp.status = ComponentStatus.STANDBY   # a new controller must Resume
            if comp is self.pd:
                self.actuation.last_wrench_s = now_s     # the command timeout starts now
        response = ControlResponse.ACCEPTED if accepted else ControlResponse.NOT_ACCEPTED
        out.append((self._to(ConfirmComponentControl(response=response), comp, src), sender))

    def _lose_control(self, comp: Component, out: list[tuple[Message, Address]]) -> None:
        """``comp``'s controller loses it to a higher authority: tell it (Reject)."""
        old = comp.controller
        if old is None:
            return
        if old == self.mpd.jaus_id:
            self.mpd_active = False
        else:
            peer = self.peers.get(old)
            if peer is not None:
                out.append((self._to(RejectComponentControl(), comp, old), peer.address))
        if comp is self.mpd and self.pd.controller == self.mpd.jaus_id:
            self._free(self.pd)

    def _free(self, comp: Component) -> None:
        comp.controller, comp.controller_authority = None, 0
        if comp.status == ComponentStatus.READY:
            comp.status = ComponentStatus.STANDBY
        if comp is self.pd:
            self.actuation.throttle_pct = 0.0

    def _release(self, cid: int, comp: Component) -> None:
        self._free(comp)
        if cid == XgvComponent.MOTION_PROFILE_DRIVER and self.pd.controller == comp.jaus_id:
            self._free(self.pd)

    def _take_pd_for_mpd(self, out: list[tuple[Message, Address]]) -> None:
        """Seed 000: a controlled MPD requests control of the PD (with its controller's authority)."""
        mpd, pd = self.mpd, self.pd
        if mpd.controller is None or pd.controller == mpd.jaus_id:
            return
        authority = mpd.controller_authority
        if pd.controller is None or (authority > pd.controller_authority
                                     and authority >= pd.authority):
            self._lose_control(pd, out)
            pd.controller, pd.controller_authority = mpd.jaus_id, authority
            pd.status = mpd.status if mpd.status == ComponentStatus.READY else ComponentStatus.STANDBY

    def _set_status(self, cid: int, comp: Component, m: Message) -> None:
        targets = [comp]
        if cid == XgvComponent.MOTION_PROFILE_DRIVER and self.pd.controller == comp.jaus_id:
            targets.append(self.pd)       # the MPD resumes / pauses the PD it controls
        for c in targets:
            if isinstance(m, Resume):
                if c.status in (ComponentStatus.STANDBY, ComponentStatus.READY):
                    c.status = ComponentStatus.READY
            elif isinstance(m, Standby):
                if c.status in (ComponentStatus.STANDBY, ComponentStatus.READY):
                    c.status = ComponentStatus.STANDBY
            elif isinstance(m, Shutdown):
                c.status = ComponentStatus.SHUTDOWN
            else:  # Reset: reinitialised, waiting for Resume
                c.status = ComponentStatus.STANDBY

    # ------------------------------------------------------------------ commands

    def _wrench(self, m: SetWrenchEffort, now_s: float) -> None:
        a = self.actuation
        if m.throttle_pct is not None:
            a.throttle_pct = m.throttle_pct
        if m.brake_pct is not None:
            a.brake_pct = m.brake_pct
        if m.steering_pct is not None:
            a.steer_pct = m.steering_pct
        a.last_wrench_s = now_s

    def _discrete(self, m: SetDiscreteDevices) -> None:
        a = self.actuation
        if m.gear is not None:
            gear = gear_from_code(self.params, m.gear)
            if gear is None:
                self.stats.invalid += 1
            else:
                a.gear = gear
        if m.propulsion_flags is not None:
            a.engine_on = bool(m.propulsion_flags & (Propulsion.MAIN_POWER | Propulsion.STARTER))
        if m.parking_horn_flags is not None:
            a.park_brake = bool(m.parking_horn_flags & 1)
            a.horn = bool(m.parking_horn_flags & 2)

    def _motion_profile(self, m: SetMotionProfile, now_s: float) -> None:
        if m.version != 1 or not m.motions or any(
                mo.max_accel_mps2 <= 0.0 or mo.duration_s <= 0.0 for mo in m.motions):
            self.stats.invalid += 1
            return
        self.plan.motions, self.plan.start_s = tuple(m.motions), now_s

    def current_motion(self, now_s: float) -> Any | None:
        """The motion in force at ``now_s``, or None once the profile has lapsed."""
        t = now_s - self.plan.start_s
        for motion in self.plan.motions:
            if t < motion.duration_s - 1e-9:
                return motion
            t -= motion.duration_s
        return None

    # ------------------------------------------------------------------ service connections

    def _create(self, cid: int, comp: Component, m: CreateServiceConnection, src: JausId,
                sender: Address) -> ConfirmServiceConnection:
        def confirm(response: int, instance: int = 0, rate: float = 0.0) -> ConfirmServiceConnection:
            return ConfirmServiceConnection(command_code=m.command_code, instance_id=instance,
                                            rate_hz=rate, response=response)

        if m.command_code not in REPORTS[cid]:
            return confirm(ServiceConnectionResponse.NOT_SUPPORTED)
        if not m.rate_hz > 0.0:
            return confirm(ServiceConnectionResponse.INVALID_PARAMETER)
        rate = min(m.rate_hz, MAX_REPORT_RATE_HZ)
        for conn in self.connections:   # the same client asking again: update, same instance
            if conn.client == src and conn.component == cid and conn.code == m.command_code:
                conn.rate_hz, conn.presence, conn.address, conn.active = (
                    rate, m.presence_vector, sender, True)
                return confirm(ServiceConnectionResponse.CREATED, conn.instance, rate)
        if (len(self.connections) >= MAX_CONNECTIONS
                or sum(conn.client == src for conn in self.connections) >= MAX_CONNECTIONS_PER_PEER):
            return confirm(ServiceConnectionResponse.REFUSED)
        key = (cid, m.command_code)
        instance = self._instances.get(key, 0) % 255 + 1
        self._instances[key] = instance
        self.connections.append(Connection(src, sender, cid, m.command_code, instance, rate,
                                           m.presence_vector))
        return confirm(ServiceConnectionResponse.CREATED, instance, rate)

    def _change_connection(self, cid: int, m: Any, src: JausId) -> None:
        for conn in self.connections:
            if (conn.client == src and conn.component == cid and conn.code == m.command_code
                    and conn.instance == m.instance_id):
                if isinstance(m, TerminateServiceConnection):
                    self.connections.remove(conn)
                else:
                    conn.active = isinstance(m, ActivateServiceConnection)
                return
        self.stats.invalid += 1

    # ------------------------------------------------------------------ step

    def step(self, now_s: float) -> Outgoing:
        """Advance the vehicle to ``now_s``; returns the reports and heartbeats now due."""
        dt_s = 0.0 if self.last_step_s is None else max(0.0, now_s - self.last_step_s)
        self.last_step_s = now_s
        out: list[tuple[Message, Address]] = []
        self._expire(now_s)
        self._take_pd_for_mpd(out)
        mode = self._modes(now_s)
        if mode.control_mode == "motion-profiles":
            self._motion_loops(dt_s, now_s)
        else:
            self.mpd_active = False
        core, a = self.core, self.actuation
        core.devices = self.effective_devices
        core.software_ready = mode.control_mode != "software-pause" and mode.ready_mode == "ready"
        core.throttle_pct, core.brake_pct, core.steer_pct = a.throttle_pct, a.brake_pct, a.steer_pct
        core.gear_cmd, core.engine_on, core.park_brake = a.gear, a.engine_on, a.park_brake
        for topic, msg in core.step(now_s, ()):
            self.latest[topic] = msg
        for conn in self.connections:
            period = 1.0 / conn.rate_hz
            if conn.active and now_s >= conn.next_s - STEP_TOLERANCE_S:
                report = self._report(conn.component, conn.code, conn.presence, now_s)
                if report is not None:
                    header = Header(destination=conn.client,
                                    source=self.components[conn.component].jaus_id,
                                    service_connection=True, sequence=conn.sequence)
                    conn.sequence = (conn.sequence + 1) % 0x10000
                    out.append((msgspec.structs.replace(report, header=header), conn.address))
                # the schedule advances by whole periods, so the mean rate is the confirmed
                # one (10 Hz was 12.5 Hz when counted from now_s); the first report or a stall
                # (re)starts it from now
                conn.next_s += period
                if conn.next_s < now_s:
                    conn.next_s = now_s + period
        if now_s >= self.next_heartbeat_s - 1e-9:
            self.next_heartbeat_s = now_s + HEARTBEAT_PERIOD_S
            nm = self.components[XgvComponent.NODE_MANAGER]
            for client, peer in self.peers.items():
                out.append((self._to(ReportHeartbeatPulse(), nm, client), peer.address))
        return self._pack(out)

    def _motion_loops(self, dt_s: float, now_s: float) -> None:
        """The MPD's speed and curvature controllers write the PD's efforts."""
        p, plant, a = self.params, self.core.plant, self.actuation
        if not self.mpd_active:
            self.mpd_active = True
            self.curvature_ref_1pm = plant.curvature_1pm
            self.curvature_trim.reset()
            self.speed_loop.reset(abs(plant.speed_mps), 0.0, a.brake_pct)
        motion = self.current_motion(now_s)
        if motion is None:
            # a lapsed motion profile stops like a pause (seed 000): the vehicle's pause rate
            desired, accel = 0.0, p.pause_decel_mps2
            curvature, rate = self.curvature_ref_1pm, 0.0
        else:
            desired, accel = motion.speed_mps, motion.max_accel_mps2
            curvature, rate = motion.curvature_1pm, motion.curvature_rate_1pms
        if abs(desired) < SPEED_DEADBAND_MPS:
            desired = 0.0       # the u16 speed field cannot carry 0 exactly (0x7FFF is -0.001)
        gear = p.gear(plant.gear)
        stopped = abs(plant.speed_mps) < STOPPED_MPS
        wanted = 0 if desired == 0.0 else (1 if desired > 0.0 else -1)
        if wanted and gear.direction != wanted and stopped and plant.shift_target is None:
            a.gear = p.drive_gear if wanted > 0 else p.reverse_gear   # the closed loop shifts
        direction = gear.direction
        if direction == 0 or plant.shift_target is not None:
            self.speed_loop.reset(0.0, 0.0, MPD_HOLD_BRAKE_PCT)
            a.throttle_pct, a.brake_pct = 0.0, MPD_HOLD_BRAKE_PCT
        elif desired == 0.0 and accel >= FULL_BRAKE_FRACTION * p.max_brake_decel_mps2:
            # a stop asked harder than the brakes can give: all of them (the stack's e-stop)
            self.speed_loop.reset(0.0, 0.0, 100.0)
            a.throttle_pct, a.brake_pct = 0.0, 100.0
        else:
            target = abs(desired) if wanted == direction else 0.0
            result = self.speed_loop.step(
                dt_s, min(target, gear.max_speed_mps * 0.9), accel, direction * plant.speed_mps,
                direction * plant.accel_mps2, direction * math.sin(plant.pitch_rad), gear, stopped)
            a.throttle_pct, a.brake_pct = result.throttle_pct, result.brake_pct
        if not math.isfinite(curvature):
            curvature = self.curvature_ref_1pm
        elif abs(curvature) < CURVATURE_DEADBAND_1PM:
            curvature = 0.0     # nor 0 in atan(curvature) (one step is 4.8e-5 1/m)
        limit = p.max_curvature_1pm
        curvature = min(max(curvature, -limit), limit)
        self.curvature_ref_1pm = (rate_limit(curvature, self.curvature_ref_1pm, rate, dt_s)
                                  if rate > 0.0 else curvature)
        trim = 0.0
        if abs(plant.speed_mps) >= CURVATURE_TRIM_MIN_MPS and dt_s > 0.0:
            trim = self.curvature_trim.update(self.curvature_ref_1pm * 100.0,
                                              plant.curvature_1pm * 100.0, dt_s)
        a.steer_pct = math.atan(self.curvature_ref_1pm * p.wheelbase_m) / p.max_steer_rad * 100.0 + trim
        a.last_wrench_s = now_s

    # ------------------------------------------------------------------ reports

    def secondary_status(self) -> int:
        d = self.devices
        steering, speed = computer_axes(self.mode.safety_mode, d.partial_mode)
        bits = (
            (XgvSecondaryStatus.MANUAL_OVERRIDE if d.manual_override else 0)
            | (XgvSecondaryStatus.SAFESTOP_PAUSE if d.safestop == "pause" else 0)
            | (XgvSecondaryStatus.SAFESTOP_STOP if d.safestop == "stop" else 0)
            | LINK_CODE[d.safestop_link] << LINK_STATUS_SHIFT
            | (XgvSecondaryStatus.EXTERNAL_ESTOP if d.estop_button else 0)
            | (XgvSecondaryStatus.COMPUTER_STEERING if steering else 0)
            | (XgvSecondaryStatus.COMPUTER_SPEED if speed else 0)
            | (XgvSecondaryStatus.DOOR_PAUSE if d.door_open else 0)
            | (XgvSecondaryStatus.ERROR_PAUSE if d.internal_error else 0)
            | (XgvSecondaryStatus.EMERGENCY_MANUAL_OVERRIDE if d.emergency_manual_override else 0)
            | (XgvSecondaryStatus.STEERING_NEEDS_INIT if d.steering_needs_init else 0)
            | (XgvSecondaryStatus.STEERING_INIT_NEEDS_USER_INPUT if d.steering_awaiting_user else 0))
        return int(bits)

    def vehicle_mode(self) -> ReportVehicleMode:
        """Report Vehicle Mode (0xE456) as the Node Manager sends it now."""
        mode = self.mode
        devices = self.effective_devices
        return ReportVehicleMode(
            control_mode=CONTROL_MODE_CODE[mode.control_mode],
            ready_mode=READY_MODE_CODE[mode.ready_mode],
            safety_mode=SAFETY_MODE_CODE[mode.safety_mode],
            partial_mode_overrides=partial_override_bits(mode),
            safety_devices=safety_device_bits(devices))

    def _report(self, cid: int, code: int, presence: int, now_s: float) -> Message | None:
        plant = self.core.plant
        comp = self.components[cid]
        if code == _STATUS:
            return ReportComponentStatus(primary_status=comp.status,
                                         secondary_status=self.secondary_status())
        if code == _CONTROL:
            return ReportComponentControl(controller=comp.controller or JausId(0, 0, 0, 0),
                                          authority=comp.controller_authority)
        if code == _HEARTBEAT:
            return ReportHeartbeatPulse()
        if code == _MODE:
            return self.vehicle_mode()
        stamp = jaus_timestamp(now_s)
        if code == _WRENCH:
            values = {"propulsive_linear_x_pct": 100.0 * plant.throttle,
                      "propulsive_rotational_z_pct": 100.0 * plant.road_wheel_rad
                      / self.params.max_steer_rad,
                      "resistive_linear_x_pct": 100.0 * plant.brake}
            return _present(ReportWrenchEffort, values, presence or 0x0061)
        if code == _DISCRETE:
            propulsion = ((Propulsion.MAIN_POWER if plant.engine == "running" else 0)
                          | (Propulsion.STARTER if plant.engine == "cranking" else 0))
            values = {"propulsion_flags": int(propulsion),
                      "parking_horn_flags": int(plant.park_brake) | int(self.actuation.horn) << 1,
                      "gear": self.gear_code.get(plant.gear, 128), "transfer_case": 0}
            return _present(ReportDiscreteDevices, values, presence or 0x07)
        if code == _VELOCITY:
            v = plant.speed_mps
            values = {"velocity_x_mps": v, "velocity_y_mps": 0.0, "velocity_z_mps": 0.0,
                      "velocity_rms_mps": 0.0, "roll_rate_radps": 0.0, "pitch_rate_radps": 0.0,
                      "yaw_rate_radps": v * plant.curvature_1pm, "rate_rms_radps": 0.0,
                      "timestamp": stamp}
            return _present(ReportVelocityState, values, presence or 0x0141)
        if code in (_LOCAL, _GLOBAL):
            gps = self.latest.get(Topic.GPS_INS)
            x, y = (gps.x_m, gps.y_m) if gps is not None else (plant.x_m, plant.y_m)
            attitude = {"position_rms_m": POSITION_RMS_M, "roll_rad": plant.roll_rad,
                        "pitch_rad": plant.pitch_rad, "yaw_rad": -plant.heading_rad,
                        "attitude_rms_rad": ATTITUDE_RMS_RAD, "timestamp": stamp}
            if code == _LOCAL:
                return _present(ReportLocalPose, {"x_m": x, "y_m": -y, "z_m": 0.0, **attitude},
                                presence or 0x01F3)
            lat0, lon0 = self.origin_deg
            meridian_m, prime_vertical_m = local_radii_m(lat0)   # plain_jaus's projection
            lat = lat0 + math.degrees(x / meridian_m)
            lon = lon0 + math.degrees(-y / (prime_vertical_m * math.cos(math.radians(lat0))))
            return _present(ReportGlobalPose, {"latitude_deg": lat, "longitude_deg": lon,
                                               "elevation_m": 0.0, **attitude}, presence or 0x01F3)
        if code == _WHEELS:
            wheel = self.latest.get(Topic.WHEEL_SPEED)
            w = wheel.speed_mps if wheel is not None else plant.wheel_speed_mps
            return ReportWheelsSpeed(right_front_mps=w, left_front_mps=w, right_rear_mps=w,
                                     left_rear_mps=w, timestamp=stamp)
        if code == _CURVATURE:
            return ReportCurvature(curvature_1pm=plant.curvature_1pm, timestamp=stamp)
        if code == _SIGNALS:
            return ReportSignals(**self.plan.signals)
        if code == _ERRORS:
            return ReportErrorCount(counts=tuple(min(v, 0x7FFFFFFF)
                                                 for v in self.stats.as_dict().values()))
        return None

    # ------------------------------------------------------------------ wire out

    def _to(self, message: Message, comp: Component, destination: JausId, *,
            service_connection: bool = False) -> Message:
        """``message`` from ``comp`` to ``destination`` with the stream's next sequence number."""
        key = (comp.jaus_id, destination)
        sequence = self._sequences.get(key, 0)
        self._sequences[key] = (sequence + 1) % 0x10000
        return msgspec.structs.replace(message, header=Header(
            destination=destination, source=comp.jaus_id, service_connection=service_connection,
            sequence=sequence))

    def _pack(self, out: Iterable[tuple[Message, Address]]) -> Outgoing:
        """The datagrams for ``out``: one message each (judp), or packed per address."""
        batches: list[tuple[Address, list[Message]]] = []
        if self.pack_datagrams:
            by_address: dict[Address, list[Message]] = {}
            for message, address in out:
                by_address.setdefault(address, []).append(message)
            batches = [(address, messages) for address, messages in by_address.items()]
        else:
            batches = [(address, [message]) for message, address in out]
        outgoing: Outgoing = []
        for address, messages in batches:
            try:
                outgoing.extend((d, address) for d in datagrams(messages, self.pack_datagrams))
            except JausEncodeError:
                self.stats.invalid += 1
        return outgoing

    # ------------------------------------------------------------------ views

    @property
    def gate_interventions(self) -> dict[str, int]:
        return self.core.gate_interventions


def _present(cls: type[Message], values: dict[str, Any], presence: int) -> Message:
    """A presence-vector report holding the fields whose bit is set in ``presence``."""
    names = [f for f in cls.__struct_fields__ if f != "header"]
    return cls(**{name: values.get(name) for bit, name in enumerate(names) if presence >> bit & 1})


__all__ = ["REPORTS", "XgvSimulator", "XgvStats", "gear_codes", "gear_from_code", "jaus_timestamp"]
