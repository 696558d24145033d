"""The stack's side of a ByWire XGV: a JAUS 3.3 client standing where ``VehicleSim`` stands. Sans-IO.

``XgvClient`` turns the stack's actuator commands into JAUS commands and the XGV's reports into
the stack's sensor messages. It never touches a socket or a clock: ``receive(datagram, now_s)``
takes what arrived, ``sensor_outputs(now_s)`` gives the bus messages to publish, and
``command_datagrams(now_s)`` the datagrams to send (``overdrive.runtime.xgv_link`` does the I/O).

Sequence (reference §7): Query Heartbeat Pulse until the XGV answers; then Create Service
Connection for Report Vehicle Mode (Node Manager) and the vehicle's reports (Primitive Driver),
and Request Component Control of the Primitive Driver (``control="wrench"``) or the Motion
Profile Driver (``"motion-profile"``), retried every ``retry_s``; once confirmed, Resume (again
whenever the vehicle mode says the ready mode is paused); then every call:

- wrench: Set Wrench Effort (throttle = the speed server's throttle, brake, steering) to the PD;
- motion profile: Set Motion Profile to the MPD: the driving module's SPSS speed (signed by the
  speed server's gear) and acceleration once the speed server is in ``run`` and not e-stopped,
  else speed 0 (at ``ESTOP_DECEL_MPS2`` when the speed server is e-stopped); the curvature of
  the driving module's steering command;
- Set Discrete Devices (gear, engine, parking brake, horn of the speed server's powertrain
  command) on every change and every ``discrete_refresh_s``, to the component it controls.

The stack sees the XGV through ``VehicleStatus`` (safety mode from Report Vehicle Mode, actual
efforts from Report Wrench Effort, gear and engine from Report Discrete Devices), ``GpsIns``
(Local Pose + Velocity State; the odometer integrates the velocity), ``Imu`` (acceleration
differentiated from the velocity, lateral from the yaw rate), ``WheelSpeed`` (Report Wheels
Speed). Safety: every safety mode but drive-by-wire pauses the stack (the move server caps its
speed at 0, the speed server holds the brakes as ``computer_speed`` is false); in e-stop
disable the XGV stops the engine, which the speed server takes as a stall (a fault). When the
XGV's heartbeat is missing for ``heartbeat_timeout_s`` the client reports a fault and stops
publishing sensors, so the speed server's sensor watchdog latches an emergency stop. Commands
that do not reach the XGV while its reports still do (a link cut one way) are read from its
reports: in motion profile its speed falling away from the commanded motion (``FollowCheck``,
its motion lapsed), in either mode its error pause (its own command timeout); these, and a
control we held being lost, are unasked stops latched until a runwait (``_unasked_stop``), and
without control the XGV profile reports a software pause (docs/xgv.md, "A link cut one way").

``profile="plain"`` reads a plain JAUS 3.3 vehicle (OpenJAUS's ojVehicleSim) instead:
safety mode from the PD's Report Component Status, pose from Report Global Pose on a local
tangent plane (refused fixes never move the pose; none for 0.25 s: no ``GpsIns``), speed from
Velocity State, no Set Discrete Devices; see ``vehicle.plain_jaus`` and docs/xgv.md.
"""

from __future__ import annotations

import math
from typing import Any, Final, Literal

import msgspec

from overdrive.dynamics.control import first_order_lag
from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams
from overdrive.jaus import (
    DEFAULT_CLIENT_ID,
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
    Message,
    Propulsion,
    QueryComponentControl,
    QueryConfiguration,
    QueryField,
    QueryHeartbeatPulse,
    QueryIdentification,
    QueryServices,
    QueryVelocityState,
    ReadyMode,
    RejectComponentControl,
    ReleaseComponentControl,
    ReportComponentControl,
    ReportComponentStatus,
    ReportConfiguration,
    ReportDiscreteDevices,
    ReportGlobalPose,
    ReportHeartbeatPulse,
    ReportIdentification,
    ReportLocalPose,
    ReportServices,
    ReportVehicleMode,
    ReportVelocityState,
    ReportWheelsSpeed,
    ReportWrenchEffort,
    RequestComponentControl,
    Resume,
    Service,
    ServiceConnectionResponse,
    SetDiscreteDevices,
    SetMotionProfile,
    SetWrenchEffort,
    TerminateServiceConnection,
    XgvComponent,
    decode_datagram,
    message_type,
    safety_mode_name,
)
from overdrive.jaus.judp import datagrams
from overdrive.messages import (
    GpsIns,
    Imu,
    MaxSpeed,
    Notice,
    PedalCommand,
    PowertrainCommand,
    SetSpeed,
    SpeedState,
    Topic,
    Truth,
    VehicleStatus,
    WheelSpeed,
)
from overdrive.safety.gate import GateLimits, gate_pedals
from overdrive.vehicle.link_time import (
    GAP_S,
    RECEIVER_STALL_S,
    LinkTime,
    RoundTrips,
    SourceClock,
    presence_vector,
    stamp_s,
)
from overdrive.vehicle.modes import SAFETY_MODES, computer_axes
from overdrive.vehicle.plain_jaus import (
    STATUS_TIMEOUT_S,
    JausProfile,
    JausSensor,
    LocalFrame,
    PoseRefused,
    SpeedCheck,
    safety_mode_from_status,
)
from overdrive.vehicle.xgv import PEER_TIMEOUT_S, gear_codes, gear_from_code

ESTOP_DECEL_MPS2: Final = 9.0        # speed server e-stopped: stop at the strongest preset brake
DEFAULT_DECEL_MPS2: Final = 2.5      # not in run and no SPSS rate known: a pause-like stop
MIN_ACCEL_MPS2: Final = 0.05         # Set Motion Profile needs a positive acceleration (xgv.py)
SHIFT_MARGIN_S: Final = 3.0          # a commanded gear not reported after shift time + this: not shifting
ODOMETER_GAP_S: Final = GAP_S       # reports missing longer than this (a lost link, not jitter):
                                     # odometer from the poses either side of the gap
AGE_DEGRADED_S: Final = 0.05         # reports older than this (five 10 ms periods; loopback and
                                     # a vehicle LAN take 1-20 ms): the link is degraded, slower
AGE_STOP_S: Final = 0.125            # older than this: a fault and an unasked stop, latched (the
                                     # wrench speed loop held a limit to 0.01 m/s at 110 ms of
                                     # delay each way, overshot it by 0.5 m/s at 160 ms)
ROUND_TRIP_DEGRADED_S: Final = 2 * AGE_DEGRADED_S   # a round trip longer than this: degraded,
ROUND_TRIP_STOP_S: Final = 2 * AGE_STOP_S   # and an unasked stop (round trips are judged as
                                     # two ages: a delay towards the vehicle only is bounded as
                                     # one both ways; 0.3 s towards it: 8.37 m/s on an 8 m/s
                                     # MOVE in wrench, 0.2 s: 8.22 m/s, measured)
PROBES_UNMATCHED: Final = 10         # answers to probes with the speed in them (and none to a
                                     # tag): the vehicle does not answer tags, said once
AGE_DISTANCE_M: Final = 0.4          # degraded: max speed = this / age, so the stack never sees
                                     # the vehicle further behind than this (8 m/s at 50 ms)
AGE_HOLD_S: Final = 1.0              # the degraded limit follows the oldest age of the last second
LINK_SOURCE: Final = "xgv-link"      # MaxSpeed source of the degraded-link limit
LINK_FAULTS: Final = ("xgv_stall", "xgv_report_gap", "xgv_report_age", "xgv_round_trip",
                      "xgv_link_degraded", "xgv_not_following", "xgv_error_pause")
"""Fault codes of time the reports cannot account for, a degraded link, or commands the XGV
does not execute: a run with one fails unless its scenario expects it (no silent pass;
``run.sim.make_summary``)."""
# Commands not getting through (docs/xgv.md, "A link cut one way"): the XGV's reports show it
# ignoring what it is commanded.
FOLLOW_MARGIN_MPS: Final = 0.3       # motion profile: within this below the commanded speed the
                                     # XGV follows (the judge's speed tolerance)
FOLLOW_FALL_MPS: Final = 1.0         # below that, its speed falling this far from its highest
                                     # (or to rest, from under this) is a stop nobody asked for:
                                     # its motion lapsed (400 ms without Set Motion Profile; it
                                     # then stops at 2.5 m/s^2: found 0.96 s into a cut at
                                     # 7.7 m/s). Healthy runs never fell at all below the
                                     # margin (0.00 m/s: 1-15 m/s, curves, +-8 % grade, 5-50 %
                                     # loss, reverse; measured)
FOLLOW_REST_MPS: Final = 0.05        # at rest (the simulated MPD's standstill, xgv.STOPPED_MPS)
FOLLOW_REST_REPORTS: Final = 30      # after it moved, at rest this many Velocity States in a row
                                     # (0.3 s at 100 Hz) against a command to move (above the
                                     # rest speed) is not following, however slow the command:
                                     # under the margin a lapsed motion at 0.2-0.3 m/s stopped
                                     # and the old MOVE drove on unseen (red team, measured)
ERROR_PAUSE_BIT: Final = 1 << 7      # Report Vehicle Mode safety devices: error pause (the
                                     # XGV's own 0.5 s wrench command timeout, or its error)
POSE_NOISE_SIGMAS: Final = 3.0       # position noise allowance on that chord
MIN_CURVATURE_SPEED_MPS: Final = 0.1  # below this the yaw rate says nothing about the curvature

ControlKind = Literal["wrench", "motion-profile"]
NM_HEARTBEAT_PERIOD_S: Final = 0.5   # OpenJAUS's node manager takes one discovery step per
                                     # heartbeat it hears (3 to register a node): half the
                                     # reference §2 period, so it knows us within ~1.5 s
REGISTRATION_GRACE_S: Final = 3.0    # a Reject this soon after the link came up, before the
                                     # XGV asked our configuration, is OpenJAUS not knowing us
                                     # yet: retried quietly (seen: confirm, reject ~10 ms later)
REGISTRATION_SETTLE_S: Final = NM_HEARTBEAT_PERIOD_S   # and just after it asked, before
                                     # our answer reached its system tree (seen: a Reject
                                     # 30 ms in, after the query): one of our heartbeat periods
# Loss tolerance (docs/xgv.md, "A lossy link"). Loss model: each datagram lost independently
# with probability p; design point p = LOSS_DESIGN = 5 %, a false trip (no loss of link or of
# control, only lost datagrams) below FALSE_TRIP_PER_HOUR_BOUND per hour at that point
# (``false_trips_per_hour``; tests/xgv/test_xgv_link_loss.py holds the constants to it).
LOSS_DESIGN: Final = 0.05
FALSE_TRIP_PER_HOUR_BOUND: Final = 1e-4
HEARTBEAT_PERIOD_S: Final = 1.0      # reference §2: the XGV's unprompted heartbeat, ~1 Hz
HEARTBEATS_MISSED: Final = 4         # this many periods without one (and half a period of
                                     # jitter) is a lost link: p^4 = 6e-6 per period at 5 %,
                                     # 0.02 false trips an hour from the 1 Hz heartbeat alone,
                                     # so an overdue heartbeat is also asked for (below)
HEARTBEAT_TIMEOUT_S: Final = (HEARTBEATS_MISSED + 0.5) * HEARTBEAT_PERIOD_S   # 4.5 s: under
                                     # the simulated XGV's 5 s peer timeout (xgv.PEER_TIMEOUT_S),
                                     # so the client forgets the session before the XGV does
HEARTBEAT_QUERY_AFTER_S: Final = 1.25 * HEARTBEAT_PERIOD_S   # a heartbeat this late is asked
HEARTBEAT_QUERY_PERIOD_S: Final = 0.25   # for (Query Heartbeat Pulse) every this; any answer
                                     # counts: 13 more chances before the timeout at 4.5 s
CONTROL_QUERY_PERIOD_S: Final = 0.2  # Query Component Control while we hold control: a lost
                                     # Reject is found within this and one answer
CONTROL_QUERIES_UNANSWERED: Final = 20  # this many in a row unanswered (4 s, under the
                                     # heartbeat's 4.5 s): control lost. A query is answered
                                     # with (1-p)^2: at 5 % 20 lost in a row is 6e-21 (3 at
                                     # 1 Hz, as before, tripped 3 times an hour); another
                                     # controller is named by the first answer that arrives
TIME_EPS_S: Final = 1e-6             # float noise in times summed from 10 ms ticks: a query
                                     # due at 0.6000000001 goes out at 0.6, not a tick late
MAX_WATCHERS: Final = 4              # components watching our status (the PD, the MPD)
CLIENT_NAME: Final = "overdrive XGV client"   # Report Identification texts (ours)
NODE_NAME: Final = "overdrive"


CLIENT_SERVICE: Final = Service(
    0,   # core (OpenJAUS CORE_MESSAGE_SUPPORT): what a controlling client takes and sends
    inputs=tuple((code, 0) for code in (0x0009, 0x000F, 0x0010, 0x2202, 0x2B00, 0x2B01, 0x2B03,
                                        0x4202)),
    outputs=tuple((code, 0) for code in (0x0004, 0x0008, 0x000D, 0x000E, 0x0405, 0x0406, 0x2202)))


def _every_field(code: int) -> int:
    """The presence vector asking for every field of a report (0 when it has none): OpenJAUS
    honours 0 literally and sends empty reports (issue 19)."""
    cls = message_type(code, code >= EXPERIMENTAL_CODES)
    layout = getattr(cls, "layout", None)
    return getattr(layout, "valid_bits", 0)


EXPERIMENTAL_CODES: Final = 0xE000   # reference §6: TORC's experimental codes are 0xE___


_ONE_SOURCE: Final = (ReportVelocityState.code, ReportGlobalPose.code)   # plain: taken only
                                     # from the sensor asked (``wanted``), never another one


class XgvClientConfig(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """Addresses, rates and timeouts of the client; defaults are reference §7's."""

    control: ControlKind = "wrench"
    client_id: JausId = DEFAULT_CLIENT_ID
    xgv_subsystem: int = 1
    xgv_node: int = 1
    authority: int = 6                    # reference §7: "authority 6"
    report_rate_hz: float = 100.0         # service connections: the stack's 10 ms period
    heartbeat_timeout_s: float = HEARTBEAT_TIMEOUT_S   # no heartbeat this long: link lost
                                          # (above HEARTBEAT_QUERY_AFTER_S, under the XGV's
                                          # peer timeout xgv.PEER_TIMEOUT_S)
    retry_s: float = 0.5                  # requests and queries not answered are repeated
    discrete_refresh_s: float = 0.5       # Set Discrete Devices repeated (a lost one heals)
    motion_duration_s: float = 0.4        # reference §6: "clients send 400 ms and refresh it"
    accel_filter_s: float = 0.0           # on the differentiated velocity (wall clock: ~0.05)
    profile: JausProfile = "xgv"         # "plain": a JAUS 3.3 vehicle without the XGV's own
                                          # reports (vehicle.plain_jaus, docs/xgv.md)
    velocity_component: int | None = None  # None: the profile's (XGV: the PD; plain: 42)
    pose_component: int | None = None      # None: the profile's (XGV: the PD; plain: 38)
    publish_truth: bool = False           # overdrive drive: the run's trace from the reports
    limits: GateLimits | None = None      # who may command (default: VehicleSim's sources)
    pack_datagrams: bool = False          # several messages per datagram: only for peers that
                                          # read them all (OpenJAUS keeps the first only)
    node_manager: bool = True             # be our node's node manager (docs/xgv.md): OpenJAUS
                                          # keeps a controller only if its system tree has it

    def __post_init__(self) -> None:
        for name in ("heartbeat_timeout_s", "retry_s", "discrete_refresh_s", "report_rate_hz",
                     "motion_duration_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"XgvClientConfig.{name}: a finite number above 0, got {value!r}")
        if self.heartbeat_timeout_s <= HEARTBEAT_QUERY_AFTER_S:
            raise ValueError(f"XgvClientConfig.heartbeat_timeout_s: above "
                             f"{HEARTBEAT_QUERY_AFTER_S} s (an overdue heartbeat is asked for "
                             f"then), got {self.heartbeat_timeout_s!r}")
        if self.heartbeat_timeout_s >= PEER_TIMEOUT_S:
            raise ValueError(f"XgvClientConfig.heartbeat_timeout_s: under the XGV's "
                             f"{PEER_TIMEOUT_S} s peer timeout (xgv.PEER_TIMEOUT_S: the client "
                             f"must drop the session before the XGV forgets it), got "
                             f"{self.heartbeat_timeout_s!r}")


def false_trips_per_hour(loss: float, timeout_s: float = HEARTBEAT_TIMEOUT_S) -> dict[str, float]:
    """Expected false trips an hour of the heartbeat and control-query timeouts when each
    datagram is lost independently with probability ``loss`` and nothing else goes wrong
    (the loss model of the constants above).

    heartbeat: every unprompted heartbeat of the ``timeout_s`` window after the last one
    received lost, and every overdue query (from ``HEARTBEAT_QUERY_AFTER_S``, answered by
    ``timeout_s``) or its answer lost; one window starts per heartbeat received. control:
    ``CONTROL_QUERIES_UNANSWERED`` queries in a row lost either way, one run starting per
    query answered."""
    if not (0.0 <= loss <= 1.0):
        raise ValueError(f"loss: a fraction in [0, 1], got {loss!r}")
    round_trip_lost = 1.0 - (1.0 - loss) ** 2
    beats = math.floor(timeout_s / HEARTBEAT_PERIOD_S)
    queries = math.floor((timeout_s - HEARTBEAT_QUERY_AFTER_S) / HEARTBEAT_QUERY_PERIOD_S)
    per_window = loss ** beats * round_trip_lost ** queries
    received_per_hour = 3600.0 / HEARTBEAT_PERIOD_S * (1.0 - loss)
    control = (3600.0 / CONTROL_QUERY_PERIOD_S * (1.0 - round_trip_lost)
               * round_trip_lost ** CONTROL_QUERIES_UNANSWERED)
    return {"heartbeat": received_per_hour * per_window, "control": control}


class FollowCheck:
    """Motion profile: is the XGV slowing against its command? (Pure; fed each Velocity State
    with the speed commanded then.) While its speed is within ``FOLLOW_MARGIN_MPS`` below the
    command (or above it: asked to slow) it follows; otherwise the highest speed since is kept,
    and a fall of ``FOLLOW_FALL_MPS`` from it, or to rest from under that, is returned as the
    reason: the XGV is not executing the commanded motion (a link cut towards it: its motion
    lapsed and it stops by itself)."""

    def __init__(self) -> None:
        self.peak_mps: float | None = None   # highest speed since it last followed
        self.moved = False                   # moved since the command became non-zero
        self.at_rest = 0                     # reports in a row at rest since it moved

    def reset(self) -> None:
        self.peak_mps = None
        self.moved = False
        self.at_rest = 0

    def check(self, commanded_mps: float, reported_mps: float) -> str | None:
        if not (math.isfinite(commanded_mps) and math.isfinite(reported_mps)) \
                or commanded_mps == 0.0:
            self.reset()
            return None
        direction = 1.0 if commanded_mps > 0.0 else -1.0
        speed_mps = direction * reported_mps          # along the commanded direction
        if speed_mps > FOLLOW_REST_MPS:
            self.moved, self.at_rest = True, 0
        elif self.moved and abs(commanded_mps) > FOLLOW_REST_MPS:
            self.at_rest += 1
            if self.at_rest >= FOLLOW_REST_REPORTS:
                self.reset()
                return (f"the XGV stands against its command: at rest for "
                        f"{FOLLOW_REST_REPORTS} reports, commanded {abs(commanded_mps):.2f} m/s: "
                        f"its motion lapsed (Set Motion Profile not reaching it)")
        if abs(commanded_mps) <= speed_mps + FOLLOW_MARGIN_MPS:
            self.peak_mps = speed_mps
            return None
        peak = speed_mps if self.peak_mps is None else max(self.peak_mps, speed_mps)
        self.peak_mps = peak
        fall = peak - speed_mps
        if peak > FOLLOW_REST_MPS and fall > min(FOLLOW_FALL_MPS, peak - FOLLOW_REST_MPS):
            self.peak_mps = None
            return (f"the XGV slows against its command: {speed_mps:.2f} m/s, down from "
                    f"{peak:.2f}, commanded {abs(commanded_mps):.2f}: its motion lapsed "
                    f"(Set Motion Profile not reaching it)")
        return None


class ClientStats:
    __slots__ = ("datagrams", "foreign", "malformed", "messages", "rejected_commands",
                 "rejected_reports")

    def __init__(self) -> None:
        for name in self.__slots__:
            setattr(self, name, 0)

    def __repr__(self) -> str:
        return "ClientStats(" + ", ".join(f"{k}={getattr(self, k)}" for k in self.__slots__) + ")"


class XgvClient:
    """JAUS client logic for one XGV (see the module docstring)."""

    def __init__(self, params: VehicleParams, config: XgvClientConfig | None = None,
                 name: str = "xgv-client") -> None:
        self.params = params
        self.config = cfg = config or XgvClientConfig()
        self.name = name
        self.limits = cfg.limits or GateLimits(
            steer_rate_pct_per_s=100.0 * params.steer_rate_rps / params.max_steer_rad)
        self.gear_code = gear_codes(params)

        def xgv(component: int) -> JausId:
            return JausId(cfg.xgv_subsystem, cfg.xgv_node, int(component), 1)

        self.node_manager = xgv(XgvComponent.NODE_MANAGER)
        self.pd = xgv(XgvComponent.PRIMITIVE_DRIVER)
        self.mpd = xgv(XgvComponent.MOTION_PROFILE_DRIVER)
        self.target = self.pd if cfg.control == "wrench" else self.mpd
        self.plain = cfg.profile == "plain"
        if self.plain and cfg.control != "wrench":
            raise ValueError("a plain JAUS vehicle has no Motion Profile Driver: control wrench")
        if self.plain:   # vehicle.plain_jaus: status, Global Pose and Velocity State only
            self.wanted: dict[int, JausId] = {
                ReportComponentStatus.code: self.pd,
                ReportVelocityState.code: xgv(cfg.velocity_component
                                              or JausSensor.VELOCITY_STATE),
                ReportGlobalPose.code: xgv(cfg.pose_component or JausSensor.GLOBAL_POSE),
            }
        else:
            self.wanted = {
                ReportVehicleMode.code: self.node_manager,
                ReportVelocityState.code: xgv(cfg.velocity_component
                                              or XgvComponent.PRIMITIVE_DRIVER),
                ReportLocalPose.code: xgv(cfg.pose_component or XgvComponent.PRIMITIVE_DRIVER),
                ReportWrenchEffort.code: self.pd,
                ReportDiscreteDevices.code: self.pd,
                ReportWheelsSpeed.code: self.pd,
            }
        self.frame = LocalFrame()
        self.speed_check = SpeedCheck()
        self.speed_implausible = False   # plain: latched; no sensors, so the watchdog e-stops
        self.pd_status: int | None = None      # plain: the PD's primary status, and when
        self.pd_status_s = -math.inf
        self.pose_s = -math.inf                # plain: when a Global Pose was last accepted
        self.checked_pose_s = -math.inf        # and the last one the speed check took
        self.pose_refused: str | None = None   # why the fixes since then were refused
        self.stats = ClientStats()
        # discovery: our node's node manager (component 1, instance 1)
        self.own_node_manager = JausId(cfg.client_id.subsystem, cfg.client_id.node, 1, 1)
        self.replies: list[Message] = []
        self.next_nm_heartbeat_s = -math.inf
        self.registered = False        # the XGV asked our node's configuration
        self.registered_s = -math.inf  # when it first asked
        self.status_watchers: dict[JausId, list[float]] = {}   # id -> [period, next due]
        self.link_up_s: float | None = None
        # link and control
        self.heartbeat_s: float | None = None
        self.link_up = False
        self.control = False
        self.control_asked = False   # a Request Component Control not yet answered
        self.control_queries = 0     # Query Component Control sent since the last Report
        self.next_control_query_s = -math.inf
        self.next_query_s = -math.inf
        self.next_heartbeat_query_s = -math.inf   # an overdue heartbeat is asked for
        self.next_request_s = -math.inf
        self.next_resume_s = -math.inf
        self.next_create_s: dict[int, float] = dict.fromkeys(self.wanted, -math.inf)
        self.connections: dict[int, int] = {}      # report code -> instance id
        self._sequences: dict[tuple[Any, ...], int] = {}
        self.notices: list[Notice] = []
        self._told: set[str] = set()
        # inputs from the stack
        self.pedals = PedalCommand(throttle_pct=0.0, brake_pct=100.0, source="xgv-client")
        self.steer_pct = 0.0
        self.powertrain: PowertrainCommand | None = None
        self.spss: SetSpeed | None = None
        self.speed_state: SpeedState | None = None
        self.sent_discrete: tuple[int, int, int] | None = None
        self.next_discrete_s = -math.inf
        self.gear_cmd: str | None = None
        self.gear_cmd_s = 0.0
        # reports
        self.mode: ReportVehicleMode | None = None
        self.wrench: ReportWrenchEffort | None = None
        self.discrete: ReportDiscreteDevices | None = None
        self.velocity: ReportVelocityState | None = None
        self.pose: ReportLocalPose | None = None
        self.wheels: ReportWheelsSpeed | None = None
        self.fresh = False
        self.velocity_s: float | None = None
        self.speed_mps = 0.0
        self.accel_mps2 = 0.0
        self.odometer_m = 0.0
        self.odometer_at: tuple[float, float] | None = None
        self.step_m = 0.0          # distance and time since the last published odometer
        self.step_s = 0.0
        self.curvature_1pm = 0.0
        self.engine = "running" if self.plain else "off"   # plain: reports none (start: ready)
        self.start_failed = False
        # time from the source (vehicle.link_time, docs/xgv.md "Time from the source")
        self.link_time = LinkTime()
        self.round_trips = RoundTrips()   # tagged probes: the delay towards the vehicle too
        self.round_trip_s: float | None = None
        self.velocity_clock = SourceClock()
        self.velocity_source_s: float | None = None   # the last velocity report's stamp
        self.gap_in_step = False        # a stamp gap beyond ODOMETER_GAP_S since the last publish
        self.report_age_s: float | None = None   # the newest velocity report's age (upper bound)
        self.degraded_age_s = 0.0       # the oldest age of the last AGE_HOLD_S
        self.degraded_s = -math.inf
        self.limit_sent = False         # once a link limit was sent it is kept fresh (it lapses
                                        # to a hold otherwise, driving.SpeedLimits)
        self.timeout_latched = False    # the vehicle's command timeout: brakes until a runwait
        self.follow = FollowCheck()     # motion profile: the XGV slowing against its command
        self.control_query_s = -math.inf   # when the oldest unanswered control query was sent
        self.read_s = 0.0               # when the datagram being taken was read
        self.sensor_step_s: float | None = None   # when sensor_outputs last ran

    # ------------------------------------------------------------------ wire in

    def receive(self, data: bytes, now_s: float, read_s: float | None = None) -> None:
        """Take one datagram from the XGV; malformed or foreign ones are counted and dropped.
        ``read_s``: when it was read, on any steady clock (default ``now_s``); the reports'
        ages are measured on it."""
        self.read_s = now_s if read_s is None else read_s
        self.stats.datagrams += 1
        try:
            messages = decode_datagram(data)
        except JausDecodeError:
            self.stats.malformed += 1
            return
        cfg = self.config
        for m in messages:
            self.stats.messages += 1
            h = m.header
            to_us = h.destination.matches(cfg.client_id) or (
                cfg.node_manager and h.destination.matches(self.own_node_manager))
            if (not to_us or h.source.subsystem != cfg.xgv_subsystem
                    or h.source.node != cfg.xgv_node):
                self.stats.foreign += 1
                continue
            if isinstance(m, QueryIdentification | QueryConfiguration | QueryServices
                          | QueryHeartbeatPulse):
                self._answer(m, now_s)
                continue
            if isinstance(m, CreateServiceConnection | TerminateServiceConnection):
                self._status_connection(m, now_s)
                continue
            if h.service_connection:
                self.link_time.sequence(h.source, m.code, h.sequence)
            self._take(m, h.source, now_s)

    def _answer(self, m: Message, now_s: float) -> None:
        """Discovery, as OpenJAUS's node manager asks it of a node (docs/xgv.md)."""
        h = m.header
        me = self.config.client_id
        asked = me if h.destination == me else self.own_node_manager
        answer: Message | None = None
        if isinstance(m, QueryHeartbeatPulse):
            answer = ReportHeartbeatPulse()
        elif isinstance(m, QueryIdentification) and m.query_field in (QueryField.NODE,
                                                                       QueryField.COMPONENT):
            text = CLIENT_NAME if m.query_field == QueryField.COMPONENT and asked == me \
                else NODE_NAME
            answer = ReportIdentification(query_type=m.query_field, identification=text)
        elif isinstance(m, QueryConfiguration):
            if not self.registered:
                self.registered, self.registered_s = True, now_s
            answer = ReportConfiguration(nodes=(ConfigurationNode(me.node, (
                (1, 1), (me.component, me.instance))),))
            asked = self.own_node_manager
        elif isinstance(m, QueryServices):
            answer = ReportServices(services=(CLIENT_SERVICE,))
        if answer is None:
            self.stats.foreign += 1
            return
        self.replies.append(self._to(answer, h.source, source=asked))

    def _status_connection(self, m: Message, now_s: float) -> None:
        """A controlled component watching its controller (OpenJAUS's Primitive Driver asks
        Report Component Status at 5 Hz and brakes when it stops): served at the asked rate."""
        source = m.header.source
        if isinstance(m, TerminateServiceConnection):
            self.status_watchers.pop(source, None)
            return
        assert isinstance(m, CreateServiceConnection)
        ok = (m.command_code == ReportComponentStatus.code and m.rate_hz > 0.0
              and (source in self.status_watchers or len(self.status_watchers) < MAX_WATCHERS))
        rate = min(m.rate_hz, self.config.report_rate_hz) if ok else 0.0
        if ok:
            self.status_watchers[source] = [1.0 / rate, now_s]
        self.replies.append(self._to(ConfirmServiceConnection(
            command_code=m.command_code, instance_id=1 if ok else 0, rate_hz=rate,
            response=ServiceConnectionResponse.CREATED if ok
            else ServiceConnectionResponse.COMPONENT_NOT_CAPABLE), source,
            service_connection=True))

    def _take(self, m: Message, source: JausId, now_s: float) -> None:
        if self.plain and m.code in _ONE_SOURCE and source != self.wanted[m.code]:
            self.stats.foreign += 1   # the speed or pose of another (or a spoofed) component
            return
        if isinstance(m, ReportHeartbeatPulse):
            self.heartbeat_s = now_s
            if not self.link_up:
                self.link_up = True
                self.link_up_s = now_s
                self._told.discard("heartbeat")
        elif isinstance(m, ConfirmComponentControl) and source == self.target:
            if not self.control_asked:   # a duplicate or a late copy: no control from it
                self.stats.foreign += 1
                return
            self.control_asked = False
            self.control = m.response == ControlResponse.ACCEPTED
            if self.control:
                self.next_resume_s = -math.inf
                self.control_queries = 0
                self.next_control_query_s = now_s + CONTROL_QUERY_PERIOD_S
                self._told.discard("control")   # a later loss is a new onset
            else:
                self._notice("control", f"{self.target} refused control (response {m.response})")
        elif isinstance(m, ReportComponentControl) and source == self.target:
            if self.control_queries >= 1:
                # timed from the oldest query still out: the answer's own round trip or longer
                # (an upper bound, the safe side of an age), at any delay up to the 4 s the
                # queries are given, not only under one query period
                self.link_time.round_trip(now_s - self.control_query_s)
            self.control_queries = 0
            if self.control and m.controller != self.config.client_id:
                self._control_lost(f"{self.target} reports {m.controller} in control")
        elif isinstance(m, RejectComponentControl) and source == self.target:
            self.control_asked = False
            if self._not_known_yet(now_s):
                self.control = False           # retried at once, without a fault
                self.next_request_s = now_s
                return
            if self.control:
                self._control_lost(f"{self.target} took control away (Reject Component Control)")
            self.control = False
        elif isinstance(m, ConfirmServiceConnection):
            if m.response == ServiceConnectionResponse.CREATED:
                self.connections[m.command_code] = m.instance_id
            else:
                self._notice(f"connection-{m.command_code}", f"service connection 0x"
                             f"{m.command_code:04X} refused (response {m.response})")
        elif isinstance(m, ReportVehicleMode):
            self.mode = m
            if self.control and (m.safety_devices or 0) & ERROR_PAUSE_BIT:
                self._unasked_stop("error_pause", "the XGV reports an error pause (safety "
                                   "devices bit 7): its own command timeout (our commands do "
                                   "not reach it) or an internal error")
        elif isinstance(m, ReportWrenchEffort):
            self.wrench = m
        elif isinstance(m, ReportDiscreteDevices):
            self._discrete_report(m)
        elif isinstance(m, ReportVelocityState):
            if (not m.header.service_connection and m.velocity_x_mps is None
                    and source == self.wanted[ReportVelocityState.code]):
                # an answer to a probe (its presence vector is the tag), never a speed sample
                round_trip_s = self.round_trips.answer(presence_vector(m), now_s)
                if round_trip_s is not None:   # exact: bounds the fastest delivery too
                    self.link_time.round_trip(round_trip_s)
                return
            if source == self.wanted[ReportVelocityState.code] and m.velocity_x_mps is not None:
                if m.header.service_connection:
                    self.round_trips.support(presence_vector(m))   # the fields it does send
                elif self.round_trips.probes:
                    self._unmatched_answer()
            self._velocity_report(m, now_s)
        elif isinstance(m, ReportLocalPose) and not self.plain:
            self.pose = m
        elif isinstance(m, ReportGlobalPose) and self.plain:
            try:
                self.pose = self.frame.project(m, now_s)
            except PoseRefused as exc:   # never used: the stack keeps the last good pose
                self.stats.rejected_reports += 1
                self.pose_refused = str(exc)   # a fault once it costs the stack its position
            else:
                self._told.discard("pose")
                self.pose_refused = None
                self.pose_s = now_s
        elif isinstance(m, ReportComponentStatus) and source == self.pd:
            self.pd_status, self.pd_status_s = m.primary_status, now_s
        elif isinstance(m, ReportWheelsSpeed):
            self.wheels = m

    def _not_known_yet(self, now_s: float) -> bool:
        settling = self.registered and now_s - self.registered_s < REGISTRATION_SETTLE_S
        return (self.config.node_manager and (not self.registered or settling)
                and self.link_up_s is not None and now_s - self.link_up_s < REGISTRATION_GRACE_S)

    def _discrete_report(self, m: ReportDiscreteDevices) -> None:
        self.discrete = m
        if m.propulsion_flags is not None:
            flags = m.propulsion_flags
            engine = ("cranking" if flags & Propulsion.STARTER
                      else "running" if flags & Propulsion.MAIN_POWER else "off")
            if engine == "cranking":
                self.start_failed = False
            elif self.engine == "cranking" and engine == "off":
                self.start_failed = True
            self.engine = engine

    def _velocity_report(self, m: ReportVelocityState, now_s: float) -> None:
        """Speed, acceleration and distance between reports, timed by the reports' own stamps
        (arrival only for a vehicle that stamps none), so reports read late count in full."""
        if m.velocity_x_mps is None:
            return
        v = m.velocity_x_mps
        raw_s = stamp_s(m.timestamp)
        dt = 0.0
        if raw_s is not None:
            source_s = self.velocity_clock.advance(raw_s)
            if self.velocity_source_s is not None:
                dt = source_s - self.velocity_source_s
                if -ODOMETER_GAP_S <= dt <= 0.0:
                    return   # a repeated or reordered (older) report: the newer one stands
                if dt < 0.0:   # the XGV's clock went back (restarted): nothing to count from
                    self._unasked_stop("report_gap", f"Velocity State stamped {-dt:.3f} s "
                                                     f"before the last one: its clock stepped")
                    self.gap_in_step = True
                    self.link_time.reset()   # ages measured afresh on the new clock
                    dt = 0.0
            age_s = self.link_time.arrival(raw_s, self.read_s)
            self.velocity_source_s = source_s
            self.report_age_s = age_s
        elif self.velocity_s is not None:
            dt = now_s - self.velocity_s
        if dt > 0.0:
            self.accel_mps2 = first_order_lag((v - self.speed_mps) / dt, self.accel_mps2,
                                              self.config.accel_filter_s, dt)
            self.step_m += 0.5 * (abs(v) + abs(self.speed_mps)) * dt
            self.step_s += dt
            if dt > ODOMETER_GAP_S:
                self.gap_in_step = True
                if raw_s is not None:
                    self._unasked_stop("report_gap", f"no Velocity State stamped for "
                                                     f"{dt:.3f} s: motion in between unknown")
        self.velocity_s, self.speed_mps = now_s, v
        yaw = m.yaw_rate_radps
        if yaw is not None and abs(v) >= MIN_CURVATURE_SPEED_MPS:
            self.curvature_1pm = yaw / v
        self.velocity = m
        self.fresh = True

    def _unmatched_answer(self) -> None:
        """An answer to a probe holding fields it did not ask (the speed): the vehicle ignores
        a query's presence vector, so the round trip cannot be measured. Said once (a fault
        notice that does not fail the run: the vehicle is as safe as before the probes)."""
        trips = self.round_trips
        trips.unmatched += 1
        if trips.unmatched >= PROBES_UNMATCHED and trips.answered == 0:
            self._notice("round_trip_unmeasured", f"{trips.unmatched} answers to tagged "
                         f"probes held fields not asked: the vehicle ignores a query's presence "
                         f"vector, so a delay towards it is not measured (docs/xgv.md)")

    def _unasked_stop(self, key: str, reason: str) -> None:
        """Time the reports cannot account for, or commands the XGV does not execute: a fault,
        and the vehicle's command timeout (brakes, ``VehicleStatus.command_timeout``, so the
        speed server e-stops and the move server discards the command) until the stack
        restarts through a runwait."""
        self._notice(key, reason)
        self._latch(reason)

    def _control_lost(self, reason: str) -> None:
        """Control we held is gone: a fault, no more commands, and the stop latched (the XGV
        pauses; when control comes back nothing drives the old command on)."""
        self._notice("control", reason)
        self._latch(reason)
        self.control = False
        self.round_trips.reset()   # probes out now may never be answered to us

    def _latch(self, reason: str) -> None:
        """The vehicle's command timeout, latched until a runwait (``_unasked_stop``)."""
        if not self.timeout_latched:
            self.timeout_latched = True
            self.notices.append(Notice(kind="estop", source=self.name, code="command_timeout",
                                       reason=f"{reason}: full brake until the stack restarts "
                                              f"through a runwait"))

    def _notice(self, key: str, reason: str) -> None:
        if key not in self._told:
            self._told.add(key)
            self.notices.append(Notice(kind="fault", source=self.name, code=f"xgv_{key}",
                                       reason=reason))

    # ------------------------------------------------------------------ stack side

    def take_inputs(self, inbox: Any) -> list[tuple[str, Any]]:
        """The stack's commands; those from sources without control are rejected (as VehicleSim)."""
        lim = self.limits
        out: list[tuple[str, Any]] = []
        for topic, msg in inbox:
            if topic == Topic.PEDALS:
                if self._allowed(msg, lim.pedal_sources, out):
                    self.pedals = msg
            elif topic == Topic.STEER:
                if self._allowed(msg, lim.steer_sources, out) and math.isfinite(msg.steer_pct):
                    self.steer_pct = min(max(msg.steer_pct, -100.0), 100.0)
            elif topic == Topic.POWERTRAIN:
                if self._allowed(msg, lim.powertrain_sources, out):
                    self.powertrain = msg
            elif topic == Topic.SET_SPEED and isinstance(msg, SetSpeed):
                self.spss = msg
            elif topic == Topic.SPEED_STATE and isinstance(msg, SpeedState):
                self.speed_state = msg
                if self.timeout_latched and msg.state == "runwait" and not self._too_old():
                    self.timeout_latched = False   # the stack's deliberate restart
                    for key in ("stall", "report_gap", "report_age", "round_trip",
                                "not_following", "error_pause"):
                        self._told.discard(key)
        return out

    def _allowed(self, msg: Any, sources: frozenset[str], out: list) -> bool:
        if getattr(msg, "source", None) in sources:
            return True
        self.stats.rejected_commands += 1
        out.append((Topic.NOTICE, Notice(kind="rejected", source=self.name, code="no_control",
                                         reason=f"{type(msg).__name__} from {msg.source!r}")))
        return False

    def sensor_outputs(self, now_s: float) -> list[tuple[str, Any]]:
        """Bus messages for what arrived since the last call (nothing while the link is down)."""
        cfg = self.config
        out: list[tuple[str, Any]] = []
        last, self.sensor_step_s = self.sensor_step_s, now_s
        if last is not None and now_s - last > RECEIVER_STALL_S and self.control:
            # we were not stepped: the vehicle went that long without fresh commands
            self.link_time.stalls += 1
            self._unasked_stop("stall", f"the client was not stepped for {now_s - last:.3f} s "
                                        f"(bound {RECEIVER_STALL_S:.3f} s)")
        if (self.link_up and self.heartbeat_s is not None
                and now_s - self.heartbeat_s > cfg.heartbeat_timeout_s):
            self.link_up = False
            reason = f"no heartbeat from the XGV for {cfg.heartbeat_timeout_s} s"
            if self.control:
                self._latch(reason)
            self.control = False
            self.connections.clear()
            self.link_time.reset()   # the XGV may come back on another clock
            self.round_trips.reset()
            self._notice("heartbeat", reason)
        if self.pose_refused is not None and now_s - self.pose_s > ODOMETER_GAP_S:
            # refused fixes cost the stack its position: a fault. One refused fix among good
            # ones is only counted (ojVehicleSim sends one now and then: a use-after-free race
            # between its vehicle and Global Pose threads, vehicleSim.c / gpos.c)
            self._notice("pose", self.pose_refused)
        out.extend((Topic.NOTICE, n) for n in self.notices)
        self.notices.clear()
        fresh, self.fresh = self.fresh, False
        known = (self.pd_status is not None if self.plain
                 else self.mode is not None and self.discrete is not None)
        if not (fresh and self.link_up and known) or self.speed_implausible:
            return out
        self._age_check(now_s, out)
        if cfg.control == "motion-profile":
            self._follow_check()
            out.extend((Topic.NOTICE, n) for n in self.notices)
            self.notices.clear()
        out.append((Topic.VEHICLE_STATUS, self.plain_status(now_s) if self.plain
                    else self.vehicle_status(now_s)))
        v = self.speed_mps
        pose = self.pose
        if self.plain and now_s - self.pose_s > ODOMETER_GAP_S:
            pose = None   # refused or missing fixes: no stale position (the move server stops)
        self._odometer(pose)
        if (self.plain and pose is not None and self.pose_s != self.checked_pose_s
                and self._speed_reads_low(now_s, pose, out)):
            return out
        pitch = (pose.pitch_rad or 0.0) if pose is not None else 0.0
        roll = (pose.roll_rad or 0.0) if pose is not None else 0.0
        yaw_rate = (self.velocity.yaw_rate_radps or 0.0) if self.velocity is not None else 0.0
        if self.wheels is not None:
            w = self.wheels
            wheel = (w.right_front_mps + w.left_front_mps + w.right_rear_mps + w.left_rear_mps) / 4.0
        else:
            wheel = v
        out.append((Topic.WHEEL_SPEED, WheelSpeed(speed_mps=wheel)))
        if pose is not None:
            out.append((Topic.GPS_INS, GpsIns(
                x_m=pose.x_m or 0.0, y_m=-(pose.y_m or 0.0), heading_rad=-(pose.yaw_rad or 0.0),
                speed_mps=v, pitch_rad=pitch, roll_rad=roll, odometer_m=self.odometer_m,
                position_sigma_m=pose.position_rms_m)))   # the vehicle's own rms, if it says
        out.append((Topic.IMU, Imu(
            accel_x_mps2=self.accel_mps2 + G_MPS2 * math.sin(pitch),
            accel_y_mps2=-v * yaw_rate, accel_z_mps2=G_MPS2 * math.cos(pitch),
            yaw_rate_rps=-yaw_rate)))
        if cfg.publish_truth and pose is not None:
            out.append((Topic.TRUTH, Truth(
                x_m=pose.x_m or 0.0, y_m=-(pose.y_m or 0.0), heading_rad=-(pose.yaw_rad or 0.0),
                speed_mps=v, accel_mps2=self.accel_mps2, lat_accel_mps2=v * yaw_rate,
                curvature_1pm=self.curvature_1pm, pitch_rad=pitch, roll_rad=roll,
                odometer_m=self.odometer_m, slip=False, contact=False)))
        return out

    def _follow_check(self) -> None:
        """Motion profile: the XGV slowing against the motion commanded is an unasked stop
        (``FollowCheck``), checked while we hold control in drive-by-wire."""
        manual_speed = bool(self.mode is not None and self.mode.partial_mode_overrides & 2)
        driving = (self.control and not self.timeout_latched and not manual_speed
                   and self.safety_mode() == "drive-by-wire")   # the computer has the speed
        commanded_mps = self.motion_command()[0] if driving else 0.0
        reason = self.follow.check(commanded_mps, self.speed_mps)
        if reason is not None:
            self._unasked_stop("not_following", reason)

    def _too_old(self) -> bool:
        """Reports too old, or commands acting too late, for a runwait to release the stop."""
        return ((self.report_age_s is not None and self.report_age_s > AGE_STOP_S)
                or (self.round_trip_s is not None and self.round_trip_s > ROUND_TRIP_STOP_S))

    def _age_check(self, now_s: float, out: list[tuple[str, Any]]) -> None:
        """The newest report's age and the round trip of the probes (as an age: half of it):
        beyond ``AGE_DEGRADED_S`` the link is degraded (a fault once per onset, and a max speed
        of ``AGE_DISTANCE_M`` per second of age); beyond ``AGE_STOP_S`` an unasked stop,
        latched (``_unasked_stop``). Probes unanswered say nothing (lost, or a cut the other
        checks see); a probe answered late is a delay."""
        round_trip_s = self.round_trip_s = (self.round_trips.round_trip_s(now_s) if self.control
                                            else None)
        if self.report_age_s is None and round_trip_s is None:
            return   # unstamped reports (OpenJAUS's) and no probe answered: nothing to judge
        age_s = self.report_age_s or 0.0
        if age_s > AGE_STOP_S:
            self._unasked_stop("report_age", f"Velocity State up to {age_s * 1000:.0f} ms old "
                                             f"(bound {AGE_STOP_S * 1000:.0f} ms; the shortest "
                                             f"round trip counts in full, as the split of a "
                                             f"delay between the two ways is unknown)")
        if round_trip_s is not None and round_trip_s > ROUND_TRIP_STOP_S:
            self._unasked_stop("round_trip", f"probes answered {round_trip_s * 1000:.0f} ms "
                                             f"after they were sent (bound "
                                             f"{ROUND_TRIP_STOP_S * 1000:.0f} ms): commands act "
                                             f"that late")
        why = f"Velocity State {age_s * 1000:.0f} ms old"
        if round_trip_s is not None and round_trip_s / 2.0 > age_s:
            age_s, why = round_trip_s / 2.0, f"probes answered in {round_trip_s * 1000:.0f} ms"
        if age_s > AGE_DEGRADED_S:
            if now_s - self.degraded_s > AGE_HOLD_S:
                self._told.discard("link_degraded")   # a new onset
                self.degraded_age_s = 0.0
            self._notice("link_degraded", f"{why} (bound {AGE_DEGRADED_S * 1000:.0f} ms each "
                                          f"way): max speed lowered")
            self.degraded_age_s = max(self.degraded_age_s, age_s)
            self.degraded_s = now_s
        elif now_s - self.degraded_s > AGE_HOLD_S:
            self.degraded_age_s = 0.0
        out.extend((Topic.NOTICE, n) for n in self.notices)
        self.notices.clear()
        if self.timeout_latched:
            return   # stopping: the stop supersedes a lower limit (one the vehicle could not
                     # meet while its commands still act late: a false judge alarm)
        if self.degraded_age_s > 0.0:
            self.limit_sent = True
            limit = AGE_DISTANCE_M / self.degraded_age_s
        elif self.limit_sent:
            limit = max(g.max_speed_mps for g in self.params.gears)   # kept fresh, no limit
        else:
            return
        out.append((Topic.MAX_SPEED, MaxSpeed(source=LINK_SOURCE, speed_mps=limit,
                                              issued_s=now_s)))

    def _speed_reads_low(self, now_s: float, pose: ReportLocalPose,
                         out: list[tuple[str, Any]]) -> bool:
        """Plain: Velocity State checked against the Global Pose (``SpeedCheck``); once it
        reads low, a fault and no more sensors (the speed server's watchdog e-stops), as a
        lost heartbeat."""
        self.checked_pose_s = self.pose_s   # each fix once (the check averages fixes)
        reason = self.speed_check.check(now_s, pose.x_m or 0.0, pose.y_m or 0.0,
                                        self.odometer_m, pose.position_rms_m or 0.0,
                                        self.speed_mps)
        if reason is None:
            return False
        self.speed_implausible = True
        self._notice("speed", reason)
        out.extend((Topic.NOTICE, n) for n in self.notices)
        self.notices.clear()
        return True

    def _odometer(self, pose: ReportLocalPose | None) -> None:
        """Path length: the velocity integrated, or across a gap in the reports (a lost link)
        the straight line between the poses either side of it."""
        here = (pose.x_m or 0.0, pose.y_m or 0.0) if pose is not None else None
        if self.gap_in_step and here is not None and self.odometer_at is not None:
            # the chord, less what the position noise alone could make of it (the velocity
            # either side says nothing about what happened in between); both are lower bounds
            # of the path, so the longer is taken
            noise = POSE_NOISE_SIGMAS * math.sqrt(2.0) * ((pose.position_rms_m or 0.0)
                                                           if pose is not None else 0.0)
            chord = math.hypot(here[0] - self.odometer_at[0], here[1] - self.odometer_at[1])
            self.odometer_m += max(0.0, chord - noise, self.step_m)
        else:
            self.odometer_m += self.step_m
        self.step_m = self.step_s = 0.0
        self.gap_in_step = False
        self.odometer_at = here

    def safety_mode(self) -> str:
        """The contract's name of the reported safety mode; unknown values pause."""
        if self.mode is None:
            return "inactive"
        name = safety_mode_name(self.mode.safety_mode)
        if self.mode.safety_mode == 0:
            return "inactive"
        return name if name in SAFETY_MODES else "software-pause"

    def plain_status(self, now_s: float) -> VehicleStatus:
        """A plain JAUS vehicle's status: mode from the PD's component status (stale after
        ``STATUS_TIMEOUT_S``: unknown); it reports no gear, engine or actuator positions, so
        it is taken as ready in its drive gear (``overdrive drive --profile plain`` needs
        ``start: ready``) and its efforts as the ones last commanded."""
        p = self.params
        status = self.pd_status if now_s - self.pd_status_s <= STATUS_TIMEOUT_S else None
        mode = safety_mode_from_status(status, self.control)
        computer_steering, computer_speed = computer_axes(mode, "full")
        throttle, brake, _ = gate_pedals(self.pedals.throttle_pct, self.pedals.brake_pct)
        return VehicleStatus(
            gear=p.drive_gear, shifting=False, engine="running",
            engine_rpm=self._rpm(p.drive_gear),
            start_failed=False, traction_control=False, steer_pct=self.steer_pct,
            throttle_pct=throttle, brake_pct=brake, safety_mode=mode,
            computer_speed=computer_speed, computer_steering=computer_steering,
            command_timeout=self.timeout_latched)

    def vehicle_status(self, now_s: float) -> VehicleStatus:
        """The XGV's status; drive-by-wire only while we hold control (else a software pause,
        as the plain profile's ``safety_mode_from_status``)."""
        p = self.params
        mode = self.safety_mode()
        if mode == "drive-by-wire" and not self.control:
            mode = "software-pause"
        overrides = self.mode.partial_mode_overrides if self.mode is not None else 0
        partial = ("manual-steering" if overrides & 1 else "manual-speed" if overrides & 2
                   else "full")
        computer_steering, computer_speed = computer_axes(mode, partial)
        d = self.discrete
        gear = gear_from_code(p, d.gear) if d is not None and d.gear is not None else None
        gear = gear or p.park_gear
        shifting = (self.gear_cmd is not None and self.gear_cmd != gear
                    and now_s - self.gear_cmd_s < p.shift_time_s + SHIFT_MARGIN_S)
        w = self.wrench
        return VehicleStatus(
            gear=gear, shifting=shifting, engine=self.engine,  # type: ignore[arg-type]
            engine_rpm=self._rpm(gear), start_failed=self.start_failed, traction_control=False,
            steer_pct=(w.steering_pct or 0.0) if w is not None else 0.0,
            throttle_pct=(w.throttle_pct or 0.0) if w is not None else 0.0,
            brake_pct=(w.brake_pct or 0.0) if w is not None else 0.0,
            safety_mode=mode, computer_speed=computer_speed, computer_steering=computer_steering,
            command_timeout=self.timeout_latched)

    def _rpm(self, gear_name: str) -> float:
        """Engine speed estimated from the speed in gear (JAUS 3.3 reports none)."""
        p = self.params
        if self.engine != "running":
            return 0.0
        gear = p.gear(gear_name)
        if gear.direction == 0 or gear.max_speed_mps <= 0.0:
            return p.idle_rpm
        return p.idle_rpm + (p.redline_rpm - p.idle_rpm) * min(abs(self.speed_mps)
                                                               / gear.max_speed_mps, 1.0)

    # ------------------------------------------------------------------ wire out

    def command_datagrams(self, now_s: float) -> list[bytes]:
        """What to send now: the connection sequence, then the stream of commands."""
        cfg = self.config
        messages, self.replies = self.replies, []
        if cfg.node_manager and now_s >= self.next_nm_heartbeat_s:
            messages.append(self._to(ReportHeartbeatPulse(), self.node_manager,
                                     source=self.own_node_manager))
            self.next_nm_heartbeat_s = now_s + NM_HEARTBEAT_PERIOD_S
        for watcher, due in self.status_watchers.items():
            if now_s >= due[1]:
                messages.append(self._to(ReportComponentStatus(
                    primary_status=ComponentStatus.READY), watcher, service_connection=True))
                due[1] = max(due[1] + due[0], now_s)
        if not self.link_up:
            if now_s >= self.next_query_s:
                messages.append(self._to(QueryHeartbeatPulse(), self.node_manager))
                self.next_query_s = now_s + cfg.retry_s
        else:
            for code, component in self.wanted.items():
                if code not in self.connections and now_s >= self.next_create_s[code]:
                    messages.append(self._to(CreateServiceConnection(
                        command_code=code, rate_hz=cfg.report_rate_hz,
                        presence_vector=_every_field(code)), component,
                        service_connection=True))
                    self.next_create_s[code] = now_s + cfg.retry_s
            if (self.heartbeat_s is not None and now_s >= self.next_heartbeat_query_s - TIME_EPS_S
                    and now_s - self.heartbeat_s >= HEARTBEAT_QUERY_AFTER_S):
                messages.append(self._to(QueryHeartbeatPulse(), self.node_manager))
                self.next_heartbeat_query_s = now_s + HEARTBEAT_QUERY_PERIOD_S
            if self.control and now_s >= self.next_control_query_s - TIME_EPS_S:
                messages.extend(self._query_control(now_s))
            tag = self.round_trips.probe(now_s) if self.control else None
            if tag is not None:
                messages.append(self._to(QueryVelocityState(presence_vector=tag),
                                         self.wanted[ReportVelocityState.code]))
            if not self.control and now_s >= self.next_request_s:
                messages.append(self._to(RequestComponentControl(authority=cfg.authority),
                                         self.target))
                self.control_asked = True
                self.next_request_s = now_s + cfg.retry_s
        if self.control:
            paused = (self.pd_status == ComponentStatus.STANDBY
                      and now_s - self.pd_status_s <= STATUS_TIMEOUT_S if self.plain
                      else self.mode is None or self.mode.ready_mode != ReadyMode.READY)
            if paused and now_s >= self.next_resume_s:
                messages.append(self._to(Resume(), self.target))
                self.next_resume_s = now_s + cfg.retry_s
            discrete = None if self.plain else self._discrete_command(now_s)
            if discrete is not None:
                messages.append(discrete)
            messages.append(self._wrench() if cfg.control == "wrench" else self._motion())
        try:
            return datagrams(messages, cfg.pack_datagrams)
        except JausEncodeError:   # cannot happen with validated inputs; never crash the stack
            self._notice("encode", "a command could not be encoded")
            return []

    def _query_control(self, now_s: float) -> list[Message]:
        """Query Component Control once a period while we hold control (a lost Reject would
        leave us believing it); ``CONTROL_QUERIES_UNANSWERED`` unanswered: control lost."""
        if self.control_queries >= CONTROL_QUERIES_UNANSWERED:
            self._control_lost(f"{self.target} answered none of {self.control_queries} "
                               f"Query Component Control: control taken as lost")
            self.control_queries = 0
            return []
        if self.control_queries == 0:
            self.control_query_s = now_s
        self.control_queries += 1
        self.next_control_query_s = now_s + CONTROL_QUERY_PERIOD_S
        return [self._to(QueryComponentControl(), self.target)]

    def release(self) -> list[bytes]:
        """Datagrams giving control back (the XGV then pauses)."""
        if not self.control:
            return []
        self.control = False
        return datagrams([self._to(ReleaseComponentControl(), self.target)])

    def _wrench(self) -> SetWrenchEffort:
        throttle, brake, _ = gate_pedals(self.pedals.throttle_pct, self.pedals.brake_pct)
        if self.timeout_latched:
            throttle, brake = 0.0, 100.0
        return self._to(SetWrenchEffort.xgv(throttle_pct=throttle, steering_pct=self.steer_pct,
                                            brake_pct=brake), self.pd)

    def motion_command(self) -> tuple[float, float, float]:
        """(signed speed, acceleration, curvature) for Set Motion Profile from the stack's intent."""
        p = self.params
        ss, spss = self.speed_state, self.spss
        curvature = math.tan(self.steer_pct / 100.0 * p.max_steer_rad) / p.wheelbase_m
        driving = (ss is not None and ss.state == "run" and not ss.estop and spss is not None
                   and spss.state == "run" and spss.fault == 0 and ss.gear in p.gear_names
                   and math.isfinite(spss.speed_mps) and math.isfinite(spss.accel_mps2))
        if driving and not self.timeout_latched:
            assert ss is not None and spss is not None
            direction = p.gear(ss.gear).direction
            speed = direction * min(max(spss.speed_mps, 0.0), 65.0)
            accel = min(max(spss.accel_mps2, MIN_ACCEL_MPS2), 100.0)
            return speed, accel, curvature
        if self.timeout_latched or (ss is not None and ss.estop):
            return 0.0, ESTOP_DECEL_MPS2, curvature
        accel = DEFAULT_DECEL_MPS2
        if spss is not None and math.isfinite(spss.accel_mps2) and spss.accel_mps2 > 0.0:
            accel = min(spss.accel_mps2, 100.0)
        return 0.0, accel, curvature

    def _motion(self) -> SetMotionProfile:
        p = self.params
        speed, accel, curvature = self.motion_command()
        rate = min(p.steer_rate_rps / p.wheelbase_m, 10.0)   # the steering's own curvature rate
        return self._to(SetMotionProfile.single(
            speed_mps=speed, max_accel_mps2=accel, curvature_1pm=curvature,
            curvature_rate_1pms=rate, duration_s=self.config.motion_duration_s), self.mpd)

    def _discrete_command(self, now_s: float) -> SetDiscreteDevices | None:
        pt = self.powertrain
        if pt is None or pt.gear not in self.gear_code:
            return None
        engine = int(Propulsion.MAIN_POWER) if pt.engine_on else 0
        if pt.engine_on and self.engine != "running":
            engine |= int(Propulsion.STARTER)
        wanted = (engine, int(pt.park_brake) | int(pt.horn) << 1, self.gear_code[pt.gear])
        if wanted == self.sent_discrete and now_s < self.next_discrete_s:
            return None
        if pt.gear != self.gear_cmd:
            self.gear_cmd, self.gear_cmd_s = pt.gear, now_s
        self.sent_discrete = wanted
        self.next_discrete_s = now_s + self.config.discrete_refresh_s
        return self._to(SetDiscreteDevices(propulsion_flags=wanted[0], parking_horn_flags=wanted[1],
                                           gear=wanted[2]), self.target)

    def _to(self, message: Message, destination: JausId, *, service_connection: bool = False,
            source: JausId | None = None) -> Any:
        source = source or self.config.client_id
        key: tuple[Any, ...] = (source, destination, message.code) if service_connection \
            else (source, destination)
        sequence = self._sequences.get(key, 0)
        self._sequences[key] = (sequence + 1) % 0x10000
        return msgspec.structs.replace(message, header=Header(
            destination=destination, source=source, service_connection=service_connection,
            sequence=sequence))


__all__ = ["LINK_FAULTS", "XgvClient", "XgvClientConfig", "false_trips_per_hour"]
