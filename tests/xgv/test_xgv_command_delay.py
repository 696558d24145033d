"""A JAUS link delayed towards the vehicle only (lock-step, ``interface: jaus``, real UDP on
loopback): the XGV's reports stay fresh, so their age sees nothing, yet every command acts late.
Found: delayed 0.5 s one way in wrench mode, 9.17 m/s on an 8 m/s MOVE and 0.09 m past its end,
seen by the run's judge only; the control queries' round trip, timed from the oldest unanswered
one, read 100 ms.

The client now measures the round trip with tagged probes (``RoundTrips``: each Query Velocity
State's presence vector is its tag, so each answer is matched to its own probe). Judged from
ground truth (the simulated XGV's own state): no overrun, no speed above the MOVE's limit, no
motion after the stop until a new command; loss alone never reads as a delay.
"""

from __future__ import annotations

import itertools
from typing import Any

import msgspec
import pytest

from overdrive.jaus import JausId, QueryVelocityState, ReportVelocityState, encode_datagram
from overdrive.jaus.messages import POSE_ALL
from overdrive.run.compose import build_servers, lockstep_nodes
from overdrive.run.sim import run_scenario
from overdrive.vehicle.link_time import (
    PROBE_PERIOD_S,
    PROBE_TAGS,
    PROBE_UNARMED_PERIOD_S,
    PROBE_WINDOW_S,
    RoundTrips,
    presence_vector,
)
from overdrive.vehicle.xgv import jaus_timestamp
from overdrive.vehicle.xgv_client import AGE_DISTANCE_M, ROUND_TRIP_DEGRADED_S, ROUND_TRIP_STOP_S
from tests.xgv.test_xgv_link_loss import (
    LIMIT_MPS,
    MOVE_M,
    SPEED_TOLERANCE_MPS,
    codes,
    run,
    scenario,
    truth,
)
from tests.xgv.test_xgv_plain_profile import ME, VSS, controlling, deliver, sent

AT_CRUISE_S = 8.0          # the vehicle holds 8 m/s from ~6.5 s
AT_REST_MPS = 0.01
MOVED_AFTER_REST_M = 0.05
STEP_S = 0.01              # one lock-step period: the round trip of a prompt answer


def towards_vehicle(delay_s: float, at_s: float = AT_CRUISE_S) -> dict[str, Any]:
    return {"at_s": at_s, "delay": {"channel": "jaus", "for_s": 30, "delay_s": delay_s,
                                    "direction": "to_vehicle"}}


def loss(fraction: float) -> dict[str, Any]:
    return {"at_s": 1.0, "loss": {"channel": "jaus", "for_s": 30, "fraction": fraction}}


def assert_judged_safe(trace: list[dict[str, Any]], summary: dict[str, Any]) -> None:
    """No overrun, no speed above the limit; once at rest after a stop nobody asked for,
    nothing moves again (no new command is sent)."""
    t, x, v = truth(trace)
    assert max(x) <= MOVE_M, max(x)
    assert max(v) <= LIMIT_MPS + SPEED_TOLERANCE_MPS, max(v)
    interrupted = [e["t_s"] for e in summary["events"] if e["kind"] == "interrupted"]
    if interrupted:
        rest = next(i for i, ti in enumerate(t) if ti > interrupted[0] and v[i] < AT_REST_MPS)
        assert max(x[rest:]) - x[rest] < MOVED_AFTER_REST_M, (t[rest], x[rest], max(x[rest:]))


# ----------------------------------------------------------------------------- whole runs

@pytest.mark.variants   # `make test`: the thresholds' edges and one case in four of the rest
@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
@pytest.mark.parametrize("delay_s", [
    0.03, 0.05, pytest.param(0.1, marks=pytest.mark.variant_edge),
    pytest.param(0.11, marks=pytest.mark.variant_edge), 0.12, 0.2, 0.23,
    pytest.param(0.26, marks=pytest.mark.variant_edge), 0.3,
    pytest.param(0.5, marks=pytest.mark.variant_edge), 1.0, 2.0])
def test_a_delay_towards_the_vehicle_is_slowed_then_stopped_never_overrun_nor_over_the_limit(
        control: str, delay_s: float) -> None:
    """Delayed from 8 s at cruise: a round trip beyond 100 ms (50 ms as an age) lowers the
    max speed, beyond 250 ms is an unasked stop, latched; the run fails on the link fault."""
    result, _, trace = run([towards_vehicle(delay_s)], control=control)
    summary = result.summary
    assert_judged_safe(trace, summary)
    round_trip_s = delay_s   # a delayed datagram is read in the step it is due: no period more
    faults = codes(summary, "fault")
    assert ("xgv_round_trip" in faults) == (round_trip_s > ROUND_TRIP_STOP_S)
    assert ("xgv_link_degraded" in faults) == (round_trip_s > ROUND_TRIP_DEGRADED_S + 1e-9)
    stopped = bool(codes(summary, "interrupted"))
    assert stopped == (round_trip_s > ROUND_TRIP_STOP_S)
    probes = summary["link"]["probes"]
    assert probes["round_trip_ms"]["max"] == pytest.approx(1000.0 * round_trip_s, abs=0.5)
    if ROUND_TRIP_DEGRADED_S < round_trip_s <= ROUND_TRIP_STOP_S:   # slower: 0.8 m per s
        t, _, v = truth(trace)
        late = [vi for ti, vi in zip(t, v, strict=True) if ti > AT_CRUISE_S + 3.0]
        assert max(late) <= 2 * AGE_DISTANCE_M / round_trip_s + SPEED_TOLERANCE_MPS
    if round_trip_s > ROUND_TRIP_DEGRADED_S:
        assert result.exit_code == 1   # no silent pass
    else:
        assert summary["violations"] == [] and result.exit_code == 0
        _, x, _ = truth(trace)
        assert x[-1] > MOVE_M - 1.0   # and the MOVE completes


@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
@pytest.mark.parametrize("fraction", [0.05, 0.2, 0.5])
def test_loss_alone_never_reads_as_a_delay(control: str, fraction: float) -> None:
    """Each datagram lost with probability ``fraction`` both ways: the answers that arrive are
    matched to their own probes, so every round trip is one period and nothing is slowed."""
    result, _, trace = run([loss(fraction)], control=control)
    summary = result.summary
    assert_judged_safe(trace, summary)
    faults = codes(summary, "fault")
    assert "xgv_round_trip" not in faults and "xgv_link_degraded" not in faults
    if fraction == 0.05:
        assert faults == [] and summary["violations"] == []
    probes = summary["link"]["probes"]
    assert probes["answered"] < probes["sent"]
    assert probes["round_trip_ms"]["max"] == pytest.approx(1000.0 * STEP_S)


@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
@pytest.mark.parametrize("delay_s", [0.1, 0.3, 0.5])
def test_a_delay_in_heavy_loss_is_measured_exactly_and_acted_on(
        control: str, delay_s: float) -> None:
    """50 % loss both ways and a delay towards the vehicle: loss and delay compose (a real
    link's), and the round trip read is the delay's, not the loss's."""
    result, _, trace = run([loss(0.5), towards_vehicle(delay_s)], control=control)
    summary = result.summary
    assert_judged_safe(trace, summary)
    assert summary["link"]["probes"]["round_trip_ms"]["max"] == pytest.approx(
        1000.0 * delay_s, abs=0.5)
    assert ("xgv_round_trip" in codes(summary, "fault")) == (delay_s > ROUND_TRIP_STOP_S)


@pytest.mark.parametrize("control", ["wrench", "motion-profile"])
def test_after_the_stop_a_new_move_stays_held_while_the_delay_lasts(control: str) -> None:
    """A runwait does not release the vehicle's command timeout while commands still act too
    late (as for reports too old): the new MOVE is not driven and the stop is reported once,
    not once a step; after the delay ends the next MOVE drives."""
    events = [{"at_s": AT_CRUISE_S, "delay": {"channel": "jaus", "for_s": 6.0, "delay_s": 0.3,
                                              "direction": "to_vehicle"}},
              {"at_s": 11.0, "move": {"distance_m": 5, "maxspeed_mps": 3, "curvature_1pm": 0}},
              {"at_s": 16.0, "move": {"distance_m": 5, "maxspeed_mps": 3, "curvature_1pm": 0}}]
    result, _, trace = run(events, control=control, duration_s=24.0)
    t, x, _ = truth(trace)
    held = [xi for ti, xi in zip(t, x, strict=True) if 10.0 <= ti <= 14.0]
    assert max(held) - min(held) < MOVED_AFTER_REST_M           # the MOVE of 11 s not driven
    estops = [e for e in result.summary["events"]
              if e["kind"] == "estop" and e.get("code") == "command_timeout"]
    assert len(estops) <= 3, len(estops)
    assert x[-1] > max(held) + 1.0                              # after it ends, it drives


def test_a_plain_vehicle_with_unstamped_reports_is_judged_by_its_round_trip() -> None:
    """OpenJAUS's Velocity State carries no time stamp, so its age is unknown; the probes still
    measure the round trip and a delay towards it stops the vehicle (plain profile)."""
    sc = scenario([towards_vehicle(0.3)], control="wrench")
    nodes = lockstep_nodes(sc, build_servers(sc, over_jaus=True), profile="plain")
    simulator = nodes[0].simulator
    original = simulator._report

    def unstamped(cid: int, code: int, presence: int, now_s: float) -> Any:
        message = original(cid, code, presence, now_s)
        if isinstance(message, ReportVelocityState):
            return msgspec.structs.replace(message, timestamp=None)
        return message

    simulator._report = unstamped
    result = run_scenario(sc, None, keep_trace=True, nodes=nodes, plot=False)
    summary = result.summary
    assert summary["link"]["latency_ms"]["samples"] == 0           # no age: unstamped
    assert summary["link"]["probes"]["round_trip_ms"]["max"] == pytest.approx(300.0, abs=0.5)
    assert "xgv_round_trip" in codes(summary, "fault")
    assert_judged_safe(result.trace, summary)


def test_a_delay_from_the_start_is_measured_not_aliased() -> None:
    """A link delayed 14 s towards the vehicle from the start, longer than the tags take to come
    round at the armed rate (12.75 s): until the vehicle first answers, probes go out at the
    unarmed rate (tags round after 25.5 s), so the first answer reads the delay's 14 s. Sent
    at the armed rate from the start, the same answer would name a probe 1.25 s old."""
    trips = streaming()
    sent = {}
    now_s = 0.0
    while now_s < 14.0:
        tag = trips.probe(now_s)
        if tag is not None:
            sent.setdefault(tag, now_s)
        now_s = round(now_s + STEP_S, 6)
    first = min(sent, key=sent.__getitem__)
    assert trips.answer(first, 14.0) == pytest.approx(14.0)
    assert PROBE_UNARMED_PERIOD_S * len(PROBE_TAGS) > 14.0 > PROBE_PERIOD_S * len(PROBE_TAGS)


def test_the_acceleration_to_the_limit_under_a_long_delay_is_stopped_within_the_stated_bound(
        ) -> None:
    """The residual (docs/xgv.md, "A delay towards the vehicle"): delayed 0.5 s while still
    accelerating to the limit (5.5 s, 7.4 m/s), nothing the stack sends arrives for 0.5 s
    and the XGV holds the last effort; the stop acts another 0.5 s later. The vehicle gains
    up to the acceleration held times twice the delay but stops latched, never past the end."""
    result, _, trace = run([towards_vehicle(0.5, at_s=5.5)], control="wrench")
    t, x, v = truth(trace)
    assert max(x) <= MOVE_M
    assert max(v) <= LIMIT_MPS + 0.7            # measured 8.66 m/s (2026-11-26)
    assert "xgv_round_trip" in codes(result.summary, "fault")
    assert codes(result.summary, "interrupted") == ["command_timeout"]
    rest = next(i for i, ti in enumerate(t) if ti > 6.0 and v[i] < AT_REST_MPS)
    assert max(x[rest:]) - x[rest] < MOVED_AFTER_REST_M


# ----------------------------------------------------------------------------- the probes

EVERY_FIELD = 0x1FF   # a stream of Velocity State with all nine fields (the simulated XGV's)


def streaming(presence: int = EVERY_FIELD) -> RoundTrips:
    """Probes towards a vehicle whose Velocity State stream carries ``presence``."""
    trips = RoundTrips()
    trips.support(presence)
    return trips


def test_tags_ask_only_for_fields_the_vehicle_streams_and_too_few_mean_no_probes() -> None:
    """A vehicle answers with the fields asked that it has: tags come from the fields its own
    stream carries, so an answer is exactly its tag; with fewer than six such fields besides
    the speed (tags would come round within 3.2 s) it is not probed; before its stream is
    known, nothing is sent; a stream that changes its fields starts the probes afresh."""
    assert RoundTrips().probe(0.0) is None
    no_stamp = streaming(EVERY_FIELD & ~0x100)
    tags = {no_stamp.probe(i * PROBE_UNARMED_PERIOD_S) for i in range(300)}
    assert len(tags) == 127 and all(tag & 0x100 == 0 for tag in tags)
    assert streaming(0x141).probe(0.0) is None            # speed, yaw rate, stamp only
    trips = streaming()
    tag = trips.probe(0.0)
    assert tag is not None
    trips.support(EVERY_FIELD & ~0x100)
    assert trips.answer(tag, 0.01) is None                 # forgotten: the stream changed

def test_every_tag_leaves_out_the_speed_and_differs_from_the_stream() -> None:
    """An answer is never taken for a speed sample (bit 0, velocity x, is never asked) and
    never for a streamed report (which asks every field); tags are distinct."""
    assert len(set(PROBE_TAGS)) == len(PROBE_TAGS) == 255
    assert all(tag & 1 == 0 and 0 < tag <= 0x1FF and tag != POSE_ALL for tag in PROBE_TAGS)


def test_an_answer_is_matched_to_its_own_probe_whatever_was_lost_before_it() -> None:
    """Nine probes in ten lost: each answer that arrives reads its own probe's round trip,
    never the time since the oldest unanswered one."""
    trips = streaming()
    now_s, count = 0.0, 0
    while count < 200:
        tag = trips.probe(now_s)
        if tag is not None:
            count += 1
            if count % 10 == 0:
                assert trips.answer(tag, now_s + 0.004) == pytest.approx(0.004)
        now_s += STEP_S
    assert trips.round_trip_s(now_s) == pytest.approx(0.004)
    assert trips.answered == 20 and trips.probes == 200


def test_probes_go_out_slowly_until_answered_then_every_period() -> None:
    trips = streaming()
    times = [i * STEP_S for i in range(100)]
    sent = [t for t in times if trips.probe(t) is not None]
    assert sent[1] - sent[0] == pytest.approx(PROBE_UNARMED_PERIOD_S)
    tag = trips.probe(1.0)
    assert tag is not None and trips.answer(tag, 1.005) == pytest.approx(0.005)
    later = [t for t in (1.0 + i * STEP_S for i in range(1, 50)) if trips.probe(t) is not None]
    assert later[0] == pytest.approx(1.01)   # at once: it answers
    assert all(b - a == pytest.approx(PROBE_PERIOD_S) for a, b in itertools.pairwise(later))


def test_a_vehicle_that_never_answers_is_unmeasured_never_faulted() -> None:
    trips = streaming()
    for i in range(1000):
        trips.probe(i * STEP_S)
    assert trips.round_trip_s(10.0) is None and trips.report()["round_trip_ms"] is None


@pytest.mark.parametrize("case", ["unknown", "repeated", "before_sent"])
def test_an_answer_to_no_probe_of_ours_is_ignored(case: str) -> None:
    """A tag never sent, an answer delivered twice, or one stamped on our clock before its
    probe went out (impossible): not a round trip."""
    trips = streaming()
    tag = trips.probe(1.0)
    assert tag is not None
    if case == "unknown":
        assert trips.answer(PROBE_TAGS[-1], 1.01) is None
    elif case == "repeated":
        assert trips.answer(tag, 1.01) is not None
        assert trips.answer(tag, 1.02) is None
    else:
        assert trips.answer(tag, 0.99) is None
    assert trips.answered == (1 if case == "repeated" else 0)


def test_one_late_answer_is_not_a_delay_the_shortest_of_the_window_is() -> None:
    """A host hiccup delays one answer 400 ms among prompt ones: the round trip read stays the
    prompt one throughout; only when every answer of the window is late is the link delayed."""
    trips = streaming()
    tag = trips.probe(0.0)
    assert tag is not None
    trips.answer(tag, STEP_S)
    late_tag, late_s, read = None, 0.0, []
    for i in range(1, 100):
        now_s = i * PROBE_PERIOD_S
        tag = trips.probe(now_s)
        assert tag is not None
        if i == 50:
            late_tag, late_s = tag, now_s
        else:
            trips.answer(tag, now_s + STEP_S)
        if late_tag is not None and now_s >= late_s + 0.4:
            trips.answer(late_tag, now_s)
            late_tag = None
        read.append(trips.round_trip_s(now_s + STEP_S))
    assert all(r == pytest.approx(STEP_S) for r in read)
    end = 100 + int(PROBE_WINDOW_S / PROBE_PERIOD_S) + 2
    for i in range(100, end):   # now every answer 0.3 s late
        tag = trips.probe(i * PROBE_PERIOD_S)
        assert tag is not None
        trips.answer(tag, i * PROBE_PERIOD_S + 0.3)
    assert trips.round_trip_s((end - 1) * PROBE_PERIOD_S + 0.3) == pytest.approx(0.3)


def answer_for(tag: int) -> ReportVelocityState:
    """A report holding exactly the fields of ``tag`` (as a vehicle answers the probe)."""
    names = ReportVelocityState.layout.names
    values: dict[str, Any] = {name: 0.0 for bit, name in enumerate(names) if tag >> bit & 1}
    if "timestamp" in values:
        values["timestamp"] = jaus_timestamp(1.0)
    return ReportVelocityState(**values)


def test_the_client_probes_the_velocity_component_and_takes_only_its_answers() -> None:
    """Over the encoded wire (plain profile): the probe is a Query Velocity State to the
    velocity sensor with a tag; its answer from that sensor is a round trip, the same report
    from a stranger or on a service connection is not."""
    client = controlling()
    stream = ReportVelocityState(velocity_x_mps=1.0, velocity_y_mps=0.0, velocity_z_mps=0.0,
                                 velocity_rms_mps=0.0, roll_rate_radps=0.0, pitch_rate_radps=0.0,
                                 yaw_rate_radps=0.0, rate_rms_radps=0.0)   # OpenJAUS: no stamp
    client.receive(encode_datagram(stream.with_header(source=VSS, destination=ME,
                                                      service_connection=True)), 9.99)
    probes = [m for m in sent(client, 10.0) if isinstance(m, QueryVelocityState)]
    assert len(probes) == 1 and probes[0].presence_vector in PROBE_TAGS
    assert probes[0].header.destination == VSS
    tag = probes[0].presence_vector
    deliver(client, answer_for(tag), JausId(VSS.subsystem, VSS.node, 99, 1), 10.005)
    framed = answer_for(tag).with_header(source=VSS, destination=ME, service_connection=True)
    client.receive(encode_datagram(framed), 10.005)
    assert client.round_trips.answered == 0
    deliver(client, answer_for(tag), VSS, 10.005)
    assert client.round_trips.answered == 1
    assert client.round_trips.round_trip_s(10.005) == pytest.approx(0.005)


def test_the_presence_vector_of_a_report_is_the_bits_of_its_fields() -> None:
    assert presence_vector(ReportVelocityState(velocity_x_mps=1.0)) == 0x1
    assert presence_vector(ReportVelocityState(velocity_y_mps=0.0, yaw_rate_radps=0.0)) == 0x42
    assert all(presence_vector(answer_for(tag)) == tag for tag in PROBE_TAGS)
