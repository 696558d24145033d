"""The driving module as the speed server's client: request sequencing and gear choice."""

from __future__ import annotations

import math

import pytest

from overdrive.messages import AdvanceAuthorization, DriveMode, MaxSpeed, Topic
from overdrive.scenario.vehicles import PRESETS
from overdrive.servers.driving import (
    REQUEST_TOWARD,
    SPEED_STATES,
    DrivingConfig,
    DrivingModule,
    Request,
    client_request,
    wants_low_gear,
)
from overdrive.servers.speed_table import REQUESTABLE
from tests.servers.driving_harness import outputs, sensors

PRESET_NAMES = tuple(PRESETS)


def test_table_covers_every_target_and_state_and_requests_only_requestable():
    assert set(REQUEST_TOWARD) == set(REQUESTABLE)
    for row in REQUEST_TOWARD.values():
        assert set(row) == set(SPEED_STATES)
        assert all(r is None or r in REQUESTABLE for r in row.values())


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_seed_sequence_from_parked_to_run(name):
    p = PRESETS[name]
    g = p.drive_gear
    assert client_request("run", "parked", p.park_gear, g, True, None).state == "paused"
    last = Request("paused", p.park_gear)
    assert client_request("run", "starting", "neutral", g, True, last) == last   # wait
    # issue 31 item 9: out of paused, run is asked at once (one runwait: paused -> runwait ->
    # shifting -> run); the seed's "request idle" first, then run, waited twice
    assert client_request("run", "paused", "neutral", g, True, last) == Request("run", g)
    assert client_request("run", "runwait", "neutral", g, True, Request("run", g)) == \
        Request("run", g)
    assert client_request("idle", "paused", "neutral", g, True, last) == Request("idle", g)
    assert client_request("run", "idle", "neutral", g, True, None) == Request("idle", g)  # shift
    assert client_request("run", "idle", g, g, True, None) == Request("run", g)
    assert client_request("run", "run", g, g, True, None) == Request("run", g, drive=True)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_gear_change_stops_then_goes_through_idle(name):
    p = PRESETS[name]
    g, r = p.drive_gear, p.reverse_gear
    moving = client_request("run", "run", g, r, False, None)
    assert moving == Request("run", g)                 # speed 0 in the current gear
    assert client_request("run", "run", g, r, True, None) == Request("idle", g)
    assert client_request("run", "idle", g, r, True, None) == Request("idle", r)
    assert client_request("run", "idle", r, r, True, None) == Request("run", r)


def test_stop_before_pause_or_park():
    assert client_request("paused", "run", "high", "high", False, None) == Request("run", "high")
    assert client_request("paused", "run", "high", "high", True, None).state == "paused"
    assert client_request("parked", "run", "high", "high", True, None).state == "paused"
    assert client_request("parked", "paused", "neutral", "high", True, None).state == "parked"
    assert client_request("idle", "run", "high", "high", True, None) == Request("idle", "high")


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_low_gear_hysteresis(name):
    p = PRESETS[name]
    cfg = DrivingConfig()
    low_max = p.gear(p.low_gear).max_speed_mps
    enter = min(cfg.low_gear_enter_fraction * low_max, cfg.low_gear_max_limit_mps)
    leave = min(cfg.low_gear_exit_fraction * low_max, cfg.low_gear_exit_limit_mps)
    assert wants_low_gear(p, False, enter, False, 0.0, cfg)
    assert not wants_low_gear(p, False, math.nextafter(enter, 99), False, 0.0, cfg)
    assert wants_low_gear(p, True, leave, False, 0.0, cfg)          # stays in low up to exit
    assert not wants_low_gear(p, True, math.nextafter(leave, 99), False, 0.0, cfg)
    assert wants_low_gear(p, False, math.inf, True, 0.0, cfg)       # slippery
    assert not wants_low_gear(p, False, 0.0, False, 0.0, cfg)       # a hold keeps the gear
    assert wants_low_gear(p, True, 0.0, False, 0.0, cfg)
    steep = 0.5 * p.max_pitch_rad
    assert wants_low_gear(p, False, math.inf, False, -steep, cfg)   # steep, either way
    assert not wants_low_gear(p, False, math.inf, False, 0.99 * steep, cfg)
    assert wants_low_gear(p, True, math.inf, False, 0.71 * steep, cfg)
    assert not wants_low_gear(p, True, math.inf, False, 0.69 * steep, cfg)


def _run_node(node, p, seconds, t0=0.0, msgs_at=None, every=(), **sensor_kw):
    spss = []
    for i in range(round(seconds / 0.01)):
        t = t0 + i * 0.01
        extra = (msgs_at or {}).get(i, []) + list(every)
        out = node.step(t, sensors(p, **sensor_kw) + extra)
        spss += outputs(out, Topic.SET_SPEED)
    return spss


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_low_limit_shifts_only_when_stopped_and_waiting(name):
    p = PRESETS[name]
    node = DrivingModule(p)
    low_limit = min(0.4 * p.gear(p.low_gear).max_speed_mps, 2.5)
    limit = [(Topic.MAX_SPEED, MaxSpeed(source="map", speed_mps=low_limit))]
    auth = [(Topic.ADVANCE, AdvanceAuthorization(source="l", distance_m=50.0))]
    # authorized to move: no shift, the vehicle drives in its gear
    spss = _run_node(node, p, 2.0, msgs_at={0: auth}, every=limit)
    assert all(s.gear == p.drive_gear and s.state == "run" for s in spss)
    assert spss[-1].speed_mps > 0.0
    # nothing left to do (authorization used up), stopped: worth shifting to low
    spss = _run_node(node, p, 2.0, t0=2.0, every=limit, odometer_m=50.0)
    assert spss[-1] == spss[-1].__class__(speed_mps=0.0, accel_mps2=spss[-1].accel_mps2,
                                          gear=p.drive_gear, state="idle")
    spss = _run_node(node, p, 0.5, t0=4.0, every=limit, odometer_m=50.0, state="idle",
                     gear=p.drive_gear)
    assert spss[-1].state == "idle" and spss[-1].gear == p.low_gear


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_reverse_mode_requests_the_reverse_gear(name):
    p = PRESETS[name]
    node = DrivingModule(p)
    mode = [(Topic.DRIVE_MODE, DriveMode(state="run", direction="reverse"))]
    spss = _run_node(node, p, 0.3, msgs_at={0: mode})
    assert spss[-1].state == "idle" and spss[-1].gear == p.drive_gear and spss[-1].speed_mps == 0
    spss = _run_node(node, p, 0.3, t0=0.3, state="idle")
    assert spss[-1].gear == p.reverse_gear and spss[-1].state == "idle"
    spss = _run_node(node, p, 0.3, t0=0.6, state="idle", gear=p.reverse_gear)
    assert spss[-1].gear == p.reverse_gear and spss[-1].state == "run"


def test_first_spss_waits_one_period_for_the_speed_state():
    p = PRESETS["ranger-6x6"]
    node = DrivingModule(p)
    assert not outputs(node.step(0.0, []), Topic.SET_SPEED)
    out = []
    for i in range(1, 11):
        out += outputs(node.step(i * 0.01, []), Topic.SET_SPEED)
    assert len(out) == 1 and out[0].state == "run" and out[0].speed_mps == 0.0
