"""The plain JAUS profile after its review (issue 19): the local frame against an exact
ECEF -> ENU computation, fixes claiming too poor an accuracy, the speed check's averaged
bound at ojVehicleSim's 1 m rms, Query Component Control, and control taken away mid-drive.
Lock-step runs are judged from the simulated vehicle's ground truth (trace, judge) and what
the vehicle itself holds (its PD's controller), never from the client's view of itself."""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Callable
from typing import Any

import msgspec
import pytest

from overdrive.jaus import (
    ComponentStatus,
    JausId,
    QueryComponentControl,
    ReleaseComponentControl,
    ReportComponentControl,
    ReportComponentStatus,
    ReportGlobalPose,
    ReportVelocityState,
    RequestComponentControl,
    Resume,
    SetWrenchEffort,
    encode_datagram,
)
from overdrive.messages import PedalCommand, Topic, VehicleStatus
from overdrive.run.compose import build_servers, lockstep_nodes
from overdrive.run.sim import run_scenario
from overdrive.vehicle.plain_jaus import (
    MAX_ABS_LATITUDE_DEG,
    MAX_POSITION_RMS_M,
    REPORT_SKEW_S,
    SPEED_CHECK_BLOCK_S,
    SPEED_CHECK_SIGMAS,
    STATUS_TIMEOUT_S,
    WGS84_A_M,
    WGS84_E2,
    LocalFrame,
    PoseRefused,
    SpeedCheck,
    local_radii_m,
)
from overdrive.vehicle.xgv_client import (
    CONTROL_QUERIES_UNANSWERED,
    CONTROL_QUERY_PERIOD_S,
    XgvClient,
)
from tests.conftest import PRESET_NAMES
from tests.xgv.test_xgv_plain_profile import ME, PD, controlling, deliver, fix, ready, report, sent

MOVE_M = 12.0                 # openjaus-wrench-drive.yaml's move
OJ_RMS_M = 1.0                # ojVehicleSim's claimed position rms (its gpos.c)
OTHER = JausId(1, 5, 1, 1)    # another controller, with a higher authority than ours (6)


# ---------------------------------------------------------------- the local frame vs ENU

def _ecef_m(lat_deg: float, lon_deg: float) -> tuple[float, float, float]:
    """WGS-84 geodetic (on the ellipsoid) to earth-centred earth-fixed."""
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * math.sin(lat) ** 2)
    return (n * math.cos(lat) * math.cos(lon), n * math.cos(lat) * math.sin(lon),
            n * (1.0 - WGS84_E2) * math.sin(lat))


def _enu_m(lat0: float, lon0: float, lat: float, lon: float) -> tuple[float, float]:
    """East, north of (lat, lon) in the tangent plane at (lat0, lon0): ECEF -> ENU."""
    x0, y0, z0 = _ecef_m(lat0, lon0)
    x, y, z = _ecef_m(lat, lon)
    dx, dy, dz = x - x0, y - y0, z - z0
    la, lo = math.radians(lat0), math.radians(lon0)
    east = -math.sin(lo) * dx + math.cos(lo) * dy
    north = (-math.sin(la) * math.cos(lo) * dx - math.sin(la) * math.sin(lo) * dy
             + math.cos(la) * dz)
    return east, north


def _geodetic(lat0: float, lon0: float, east_m: float, north_m: float) -> tuple[float, float]:
    """The point at (east, north) of the ENU frame (Newton on ``_enu_m``, from a sphere's guess:
    independent of the projection under test)."""
    lat = lat0 + math.degrees(north_m / WGS84_A_M)
    lon = lon0 + math.degrees(east_m / (WGS84_A_M * math.cos(math.radians(lat0))))
    for _ in range(8):
        e, n = _enu_m(lat0, lon0, lat, lon)
        step = 1e-6
        e_lat, n_lat = _enu_m(lat0, lon0, lat + step, lon)
        e_lon, n_lon = _enu_m(lat0, lon0, lat, lon + step)
        a, b = (e_lat - e) / step, (e_lon - e) / step
        c, d = (n_lat - n) / step, (n_lon - n) / step
        det = a * d - b * c
        re, rn = east_m - e, north_m - n
        lat += (d * re - b * rn) / det
        lon += (-c * re + a * rn) / det
    return lat, lon


def _residual_bound_m(lat0: float, distance_m: float) -> float:
    """The projection's stated error (module docstring): 0.6 d^2 tan|lat0| / N, plus 1 mm."""
    return 0.6 * distance_m ** 2 * math.tan(math.radians(abs(lat0))) / local_radii_m(lat0)[1] \
        + 0.001


@pytest.mark.parametrize("lat0", [0.0, 37.2136, -37.2136, 52.0, 60.0, 80.0, -80.0,
                                  MAX_ABS_LATITUDE_DEG - 0.01])
@pytest.mark.parametrize("distance_m", [10.0, 100.0, 1000.0])
def test_the_local_frame_matches_ecef_to_enu_within_the_stated_error(lat0: float,
                                                                      distance_m: float) -> None:
    """Found: the projection used the equatorial radius for north too, 0.30 % short at 37 deg
    (3 m in 1 km, claimed 'under 1 mm'). With WGS-84's radii at the origin's latitude the
    error against the exact tangent plane is the stated 0.6 d^2 tan|lat0| / N (67 mm at 1 km
    at 37 deg), and a run's distances (10 m, 100 m) are right to the millimetre."""
    lon0 = -80.4376
    worst_m = 0.0
    for k in range(16):
        bearing = 2.0 * math.pi * k / 16
        east, north = distance_m * math.sin(bearing), distance_m * math.cos(bearing)
        lat, lon = _geodetic(lat0, lon0, east, north)
        assert _enu_m(lat0, lon0, lat, lon) == pytest.approx((east, north), abs=1e-6)
        frame = LocalFrame()
        frame.project(ReportGlobalPose(latitude_deg=lat0, longitude_deg=lon0, yaw_rad=0.0), 0.0)
        pose = frame.project(ReportGlobalPose(latitude_deg=lat, longitude_deg=lon, yaw_rad=0.0),
                             100.0)
        worst_m = max(worst_m, math.hypot(pose.x_m - north, pose.y_m - east))
    assert worst_m <= _residual_bound_m(lat0, distance_m), worst_m
    if distance_m <= 100.0:
        assert worst_m <= 0.01      # a run's scale: under 1 cm up to 84 deg


def test_the_stated_error_is_not_loose() -> None:
    """The docstring's figures are the real ones, not a wide margin: 37 deg, 1 km."""
    lat, lon = _geodetic(37.2136, -80.4376, 1000.0 * math.sin(1.0), 1000.0 * math.cos(1.0))
    frame = LocalFrame()
    frame.project(ReportGlobalPose(latitude_deg=37.2136, longitude_deg=-80.4376, yaw_rad=0.0), 0.0)
    pose = frame.project(ReportGlobalPose(latitude_deg=lat, longitude_deg=lon, yaw_rad=0.0), 100.0)
    error_m = math.hypot(pose.x_m - 1000.0 * math.cos(1.0), pose.y_m - 1000.0 * math.sin(1.0))
    assert 0.01 < error_m < 0.07


# ---------------------------------------------------------------- claimed accuracy

@pytest.mark.parametrize(("rms_m", "refused"), [
    (MAX_POSITION_RMS_M - 0.01, False), (MAX_POSITION_RMS_M, False),
    (MAX_POSITION_RMS_M + 0.01, True), (10.0, True), (100.0, True), (math.inf, False)])
def test_fixes_claiming_too_poor_an_accuracy_are_refused(rms_m: float, refused: bool) -> None:
    """Just inside / just outside MAX_POSITION_RMS_M (an infinite rms is not a valid claim:
    taken as unknown, ojVehicleSim's 1 m, as a missing one)."""
    frame = LocalFrame()
    frame.project(fix(), 0.0)
    if refused:
        with pytest.raises(PoseRefused, match="too inaccurate"):
            frame.project(fix(0.1, position_rms_m=rms_m), 0.01)
    else:
        assert frame.project(fix(0.1, position_rms_m=rms_m), 0.01).position_rms_m \
            <= MAX_POSITION_RMS_M


@pytest.mark.parametrize("jump_m", [30.0, 500.0])
def test_a_first_fix_claiming_a_huge_rms_is_no_origin_and_no_jump_passes(jump_m: float) -> None:
    frame = LocalFrame()
    with pytest.raises(PoseRefused, match="too inaccurate"):
        frame.project(fix(position_rms_m=50.0), 0.0)
    assert frame.origin is None
    frame.project(fix(), 0.1)
    with pytest.raises(PoseRefused):   # at the cap the bound is 6 sqrt 2 x 3 = 25 m at dt 0
        frame.project(fix(jump_m, position_rms_m=MAX_POSITION_RMS_M), 0.12)


def test_the_odometer_across_a_gap_takes_no_discount_from_a_claimed_rms() -> None:
    """Found: across a report gap the odometer took the chord less 3 sqrt 2 x the fix's own
    rms (xgv_client._odometer), so a fix claiming 100 m rms zeroed 400 m of travel."""
    client = controlling()
    report(client, 0.1, pose=fix(), speed_mps=0.0)
    deliver(client, fix(20.0, position_rms_m=100.0), JausId(1, 1, 38, 1), 1.0)   # refused
    report(client, 1.01, pose=fix(20.5), speed_mps=0.0)                          # a good one
    assert client.odometer_m == pytest.approx(20.5 - 3.0 * math.sqrt(2.0) * 1.0, abs=0.05)


Hook = Callable[[Any, Any, float], Any]


def hooked_run(name: str, preset: str, hook: Hook) -> Any:
    """``name`` against the simulated XGV read as a plain vehicle, every report it sends
    rewritten by ``hook(simulator, report, now_s)``."""
    scenario = ready(name, preset)
    nodes = lockstep_nodes(scenario, build_servers(scenario, over_jaus=True), profile="plain")
    simulator = nodes[0].simulator
    original = simulator._report

    def rewritten(cid: int, code: int, presence: int, now_s: float) -> Any:
        message = original(cid, code, presence, now_s)
        return message if message is None else hook(simulator, message, now_s)

    simulator._report = rewritten
    return run_scenario(scenario, None, keep_trace=True, nodes=nodes, plot=False)


def noisy(rms_m: float, seed: int) -> Callable[[Any, Any, float], Any]:
    """Global Pose with white noise of ``rms_m`` on each axis (more than a 2-D rms of
    ``rms_m``), claiming ``rms_m``."""
    rng = random.Random(seed)

    def add_noise(simulator: Any, m: Any, now_s: float) -> Any:
        if not isinstance(m, ReportGlobalPose):
            return m
        lat0 = simulator.origin_deg[0]
        meridian_m, prime_vertical_m = local_radii_m(lat0)
        return msgspec.structs.replace(
            m, position_rms_m=rms_m,
            latitude_deg=m.latitude_deg + math.degrees(rng.gauss(0.0, rms_m) / meridian_m),
            longitude_deg=m.longitude_deg + math.degrees(
                rng.gauss(0.0, rms_m) / (prime_vertical_m * math.cos(math.radians(lat0)))))
    return add_noise


def judged(summary: dict) -> list[str]:
    return [v for v in summary["violations"] if not v.startswith("expect")]


def faults(summary: dict) -> list[tuple[str, float]]:
    return [(e.get("code"), e.get("t_s")) for e in summary["events"] if e["kind"] == "fault"]


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("rms_m", [MAX_POSITION_RMS_M + 0.5, 100.0])
def test_fixes_degrading_beyond_the_cap_mid_drive_stop_the_vehicle(preset: str,
                                                                   rms_m: float) -> None:
    def degraded(simulator: Any, m: Any, now_s: float) -> Any:
        if isinstance(m, ReportGlobalPose) and now_s >= 3.0:
            return msgspec.structs.replace(m, position_rms_m=rms_m)
        return m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, degraded)
    assert judged(result.summary) == []
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert result.summary["odometer_m"] < MOVE_M - 1.0     # stopped short of the move
    assert [c for c, _ in faults(result.summary)][:1] == ["xgv_pose"]


# ---------------------------------------------------------------- the speed check's bound

@pytest.mark.parametrize("rms_m", [0.02, 1.0, MAX_POSITION_RMS_M])
@pytest.mark.parametrize(("margin", "caught"), [(-0.001, False), (0.001, True)])
@pytest.mark.parametrize("n", [1, 10, 50])
def test_the_averaged_bound(rms_m: float, margin: float, caught: bool, n: int) -> None:
    """Just inside / just outside (0.1 %): a completed block of 50 still fixes, then ``n`` fixes
    ``d`` further on with an odometer that says 0 m: the block's mean is caught beyond
    SPEED_CHECK_SIGMAS x rms sqrt(1/50 + 1/n) (1.3 m at 1 m rms and n = 50, against 8.5 m
    for a single pair before), never inside it."""
    check = SpeedCheck()
    for i in range(50):
        assert check.check(i * 0.01, 0.0, 0.0, 0.0, rms_m, 0.0) is None
    allowed_m = SPEED_CHECK_SIGMAS * rms_m * math.sqrt(1.0 / 50 + 1.0 / n)
    reasons = [check.check(SPEED_CHECK_BLOCK_S + i * 0.01, allowed_m * (1.0 + margin), 0.0, 0.0,
                           rms_m, 0.0) for i in range(n)]
    assert (reasons[-1] is not None) is caught
    assert all(r is None for r in reasons[:-1])


@pytest.mark.parametrize("speed_mps", [0.0, 2.5])
def test_the_skew_allowance_is_at_the_later_speed(speed_mps: float) -> None:
    """The odometer integrates the velocity reports as they come, so it lags the pose by up
    to REPORT_SKEW_S: the later fix's speed times that is allowed (a block driven at 2.5 m/s
    then a fix reading 0 gets none: a speed reading low is not excused by the one before)."""
    check = SpeedCheck()
    for i in range(50):
        check.check(i * 0.01, 0.0, 0.0, 0.0, 0.02, 2.5 - speed_mps)
    base_m = SPEED_CHECK_SIGMAS * 0.02 * math.sqrt(1.0 / 50 + 1.0) + speed_mps * REPORT_SKEW_S
    assert check.check(0.5, base_m - 0.01, 0.0, 0.0, 0.02, speed_mps) is None
    assert check.check(0.51, base_m + 0.01, 0.0, 0.0, 0.02, speed_mps) is not None


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("name", ["openjaus-wrench-drive.yaml", "move-curve.yaml"])
@pytest.mark.parametrize("seed", range(3))
def test_healthy_drives_with_1m_noise_raise_no_speed_fault(preset: str, name: str,
                                                          seed: int) -> None:
    """No false alarm: ojVehicleSim's 1 m rms as white noise on each axis (harder than its
    claim). Offline, 150 such runs (seeds 0-24, both presets, straight, long straight and
    curve) peaked at 5.2 sigma against the bound's 6.5."""
    result = hooked_run(name, preset, noisy(OJ_RMS_M, seed))
    assert faults(result.summary) == []
    assert judged(result.summary) == []
    assert result.summary["odometer_m"] > 10.0


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("scale", [0.0, 0.5])
@pytest.mark.parametrize("seed", range(2))
def test_a_low_speed_at_1m_rms_is_caught_before_the_move_is_driven(preset: str, scale: float,
                                                                  seed: int) -> None:
    """Found: at ojVehicleSim's 1 m rms the single-pair bound (8.5 m) caught a Velocity State
    reading 0 or half the truth from t=2 s only at 4.1-6.4 s, after 13.9-20.6 m of the 12 m
    move at up to 7.7 m/s. Averaged blocks catch it 0.7-1.7 s after the fault with 1 m of
    real noise: 3.2-8.7 m driven (ground truth), up to 5.0 m/s. Still over the speed limit
    for a moment (the strict xfail in test_xgv_plain_redteam.py)."""
    base = noisy(OJ_RMS_M, seed)

    def low(simulator: Any, m: Any, now_s: float) -> Any:
        m = base(simulator, m, now_s)
        if isinstance(m, ReportVelocityState) and now_s >= 2.0:
            return msgspec.structs.replace(m, velocity_x_mps=scale * m.velocity_x_mps)
        return m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, low)
    caught = faults(result.summary)
    # the client's speed check, or first the stack's own plausibility check (issue 16: a
    # Velocity State of 0 while the pose moves is a frozen wheel speed, fault 1102)
    assert caught[0][0] in ("xgv_speed", "1102") and caught[0][1] <= 2.0 + 2.0, caught
    assert result.summary["odometer_m"] <= MOVE_M - 2.0, result.summary["odometer_m"]
    assert max(float(r["speed_mps"]) for r in result.trace) <= 5.5
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert any(e["kind"] == "estop" for e in result.summary["events"])


# ---------------------------------------------------------------- Query Component Control

def throttling(client: XgvClient) -> XgvClient:
    client.take_inputs([(Topic.PEDALS, PedalCommand(source="speed", throttle_pct=40.0,
                                                    brake_pct=0.0))])
    return client


def drive(client: XgvClient, start_s: float, end_s: float,
          answer: Callable[[float], JausId | None] | None = None) -> list[Any]:
    """Step the client every 10 ms with healthy reports; each Query Component Control is
    answered with a Report naming ``answer(t)`` (None: no answer). What it sent."""
    out: list[Any] = []
    t = start_s
    while t < end_s - 1e-9:
        report(client, t, pose=fix(), speed_mps=0.0)
        messages = sent(client, t)
        out.extend((t, m) for m in messages)
        if answer is not None and any(isinstance(m, QueryComponentControl) for m in messages):
            controller = answer(t)
            if controller is not None:
                deliver(client, ReportComponentControl(controller=controller, authority=6),
                        PD, t + 0.005)
        t = round(t + 0.01, 6)
    return out


def mode(client: XgvClient, now_s: float) -> str:
    status = dict(report(client, now_s, pose=fix(), speed_mps=0.0))[Topic.VEHICLE_STATUS]
    assert isinstance(status, VehicleStatus)
    return status.safety_mode


def test_control_is_queried_about_once_a_second_while_held() -> None:
    client = throttling(controlling())
    out = drive(client, 0.1, 5.05, answer=lambda t: ME)
    queries = [t for t, m in out if isinstance(m, QueryComponentControl)]
    assert len(queries) == 5 and all(m.header.destination == PD for _, m in out
                                     if isinstance(m, QueryComponentControl))
    gaps = [b - a for a, b in itertools.pairwise(queries)]
    assert all(g == pytest.approx(CONTROL_QUERY_PERIOD_S, abs=0.011) for g in gaps)
    assert mode(client, 5.06) == "drive-by-wire"


@pytest.mark.parametrize(("offset_s", "lost"), [(-0.1, False), (0.1, True)])
def test_queries_left_unanswered_mean_control_lost(offset_s: float, lost: bool) -> None:
    """Found: a lost Reject Component Control left the client believing it held control,
    sending throttle and telling the stack drive-by-wire. Now: the PD answers none of
    CONTROL_QUERIES_UNANSWERED queries (one a second) by the time the next is due: control
    lost, a fault, no throttle, a software pause (the stack stops), and control is asked
    for again. Just before that time: still in control."""
    client = throttling(controlling())
    answered = {"n": 0}

    def answer(t: float) -> JausId | None:
        answered["n"] += 1
        return ME if answered["n"] == 1 else None   # the first answered, then silence

    answered_s = CONTROL_QUERY_PERIOD_S     # the first query: a period after the Confirm at 0
    end_s = answered_s + (CONTROL_QUERIES_UNANSWERED + 1) * CONTROL_QUERY_PERIOD_S + offset_s
    out = drive(client, 0.1, end_s + 0.05, answer)
    late = [m for t, m in out if t >= end_s - abs(offset_s) - 1e-6]
    wrench = [m for m in late if isinstance(m, SetWrenchEffort)]
    if lost:
        assert mode(client, end_s + 0.06) == "software-pause"
        assert not wrench
        assert any(isinstance(m, RequestComponentControl) for m in late)
    else:
        assert mode(client, end_s + 0.06) == "drive-by-wire"
        assert wrench and wrench[-1].propulsive_linear_x_pct == pytest.approx(40.0, abs=0.01)


@pytest.mark.parametrize("controller", [OTHER, JausId(0, 0, 0, 0)])
def test_a_query_answered_with_another_controller_stops_the_throttle(controller: JausId) -> None:
    """A lost Reject, then the answer to our query names someone else (or nobody: OpenJAUS
    reports 0.0.0.0 for a PD with no controller): lost at once, a fault."""
    client = throttling(controlling())
    out = drive(client, 0.1, 2.2, answer=lambda t: ME if t < 1.5 else controller)
    after = [m for t, m in out if t > 2.12]
    assert not [m for m in after if isinstance(m, SetWrenchEffort)]
    assert mode(client, 2.21) == "software-pause"


# ---------------------------------------------------------------- control taken mid-drive

def takeover_run(preset: str, take_s: float, release_s: float, *, reject_lost: bool) -> Any:
    """openjaus-wrench-drive.yaml (plain) where another client with a higher authority takes
    the PD at ``take_s`` (its Reject to us lost or not) and releases it at ``release_s``."""
    scenario = ready("openjaus-wrench-drive.yaml", preset)
    nodes = lockstep_nodes(scenario, build_servers(scenario, over_jaus=True), profile="plain")
    sim_node = nodes[0]
    simulator, link = sim_node.simulator, sim_node.link
    step = sim_node.step
    done: set[str] = set()
    other_address = ("127.0.0.9", 3794)

    def from_other(message: Any, now_s: float) -> None:
        data = encode_datagram([message.with_header(source=OTHER, destination=PD)])
        for reply, address in simulator.receive(data, other_address, now_s):
            if address != other_address and not reject_lost:
                link.send("xgv", reply, now_s, to=address)   # the Reject reaches us

    def stepped(now_s: float, inbox: Any) -> Any:
        if now_s >= take_s and "take" not in done:
            done.add("take")
            from_other(RequestComponentControl(authority=7), now_s)
            simulator.pd.status = ComponentStatus.READY     # the other Resumed it
        if now_s >= release_s and "release" not in done:
            done.add("release")
            from_other(ReleaseComponentControl(), now_s)
        return step(now_s, inbox)

    sim_node.step = stepped   # type: ignore[method-assign]
    scenario = msgspec.structs.replace(scenario, spec=msgspec.structs.replace(
        scenario.spec, duration_s=14.0))
    result = run_scenario(scenario, None, keep_trace=True, nodes=nodes, plot=False)
    return result, simulator


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("reject_lost", [False, True])
@pytest.mark.parametrize("take_s", [3.0, 4.5])
def test_control_taken_mid_drive_then_released_does_not_resume_the_move(
        preset: str, reject_lost: bool, take_s: float) -> None:
    """Control taken by another controller mid-move (its Reject delivered, or lost: then
    found by Query Component Control within CONTROL_QUERIES_UNANSWERED periods) and released
    2 s later: the client takes control back (the PD's own controller is us again at the
    end), but the stack does not drive the old move on by itself (the move server takes the
    pause as an interruption and discards it): the vehicle stays stopped (ground truth)."""
    release_s = take_s + 2.0 + (CONTROL_QUERY_PERIOD_S if reject_lost else 0.0)
    result, simulator = takeover_run(preset, take_s, release_s, reject_lost=reject_lost)
    summary = result.summary
    codes = faults(summary)
    assert codes and codes[0][0] == "xgv_control", codes
    assert codes[0][1] <= take_s + (2.0 * CONTROL_QUERY_PERIOD_S if reject_lost else 0.1)
    assert simulator.pd.controller == ME           # control is back at the end
    after = [r for r in result.trace if float(r["t_s"]) >= release_s]
    assert after and max(float(r["speed_mps"]) for r in after) < 0.05
    odometer_at_release = float(after[0]["odometer_m"])
    assert float(result.trace[-1]["odometer_m"]) == pytest.approx(odometer_at_release, abs=0.05)
    assert odometer_at_release < MOVE_M - 1.0      # the move was not finished before
    assert judged(summary) == []


# ---------------------------------------------------------------- a stale status

@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("silent_s", [3.0, 4.0])
def test_a_status_that_stops_coming_stops_the_vehicle_soon(preset: str, silent_s: float) -> None:
    """Found: the PD's last READY stayed drive-by-wire for 1.5 s (the heartbeat timeout), so a
    PD whose status stream stopped mid-move was driven 4.1-4.2 m further. Now STATUS_TIMEOUT_S
    (0.5 s): 1.7-1.8 m from the last status to standstill (ground truth), no violation."""
    def silent(simulator: Any, m: Any, now_s: float) -> Any:
        return None if isinstance(m, ReportComponentStatus) and now_s >= silent_s else m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, silent)
    at = next(r for r in result.trace if float(r["t_s"]) >= silent_s)
    assert result.summary["odometer_m"] - float(at["odometer_m"]) <= 2.5
    assert float(result.trace[-1]["speed_mps"]) < 0.05
    assert judged(result.summary) == []


@pytest.mark.parametrize(("age_s", "resumes"), [(STATUS_TIMEOUT_S - 0.05, True),
                                                (STATUS_TIMEOUT_S + 0.05, False)])
def test_no_resume_on_a_stale_standby(age_s: float, resumes: bool) -> None:
    """Found: a STANDBY last heard 1.5 s ago still drew a Resume every 0.5 s; a PD whose
    state is unknown is not resumed."""
    client = controlling()
    report(client, 0.1, pose=fix(), status=ComponentStatus.STANDBY)
    assert any(isinstance(m, Resume) for m in sent(client, 0.1))      # the first Resume
    deliver(client, ReportComponentStatus(primary_status=ComponentStatus.STANDBY), PD, 0.2)
    # the next is due 0.5 s after the first (retry_s): asked at 0.65 / 0.75
    assert any(isinstance(m, Resume) for m in sent(client, 0.2 + age_s)) is resumes


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("at_s", [3.0, 5.5])
def test_an_isolated_garbage_fix_is_counted_not_a_fault(preset: str, at_s: float) -> None:
    """Found in the interop drive (about one in four): ojVehicleSim now and then sends one
    Global Pose of lat 90, lon 180 (a use-after-free race between its vehicle and Global Pose
    threads); the fault it raised failed a healthy drive. Refused and counted, it never moves
    the pose, and the drive ends as without it."""
    def garbage(simulator: Any, m: Any, now_s: float) -> Any:
        if isinstance(m, ReportGlobalPose) and at_s <= now_s < at_s + 0.01:
            return msgspec.structs.replace(m, latitude_deg=90.0, longitude_deg=180.0)
        return m

    result = hooked_run("openjaus-wrench-drive.yaml", preset, garbage)
    assert faults(result.summary) == []
    assert judged(result.summary) == []
    assert result.summary["odometer_m"] == pytest.approx(MOVE_M, abs=0.5)
    assert float(result.trace[-1]["speed_mps"]) < 0.05
