"""E-stop disable cuts the engine as the vehicle is configured (issue 31 item 5). Seed 000:
in e-stop disable "the XGV will apply 100% braking effort to stop the vehicle. It will also
shut off the engine (if configured to do so)". The vehicle file's ``estop_engine_cut``: never,
standstill (the default: moving, the engine keeps the power steering and the brake assist;
cut once stopped, or at once when the throttle does not close) or always. On both presets the
e-stop still stops the vehicle at full brake; the engine is judged from the plant's report."""

from __future__ import annotations

import pytest

from overdrive.dynamics.vehicle_params import VehicleSpecError, with_overrides
from overdrive.messages import PedalCommand, SafetyDevices, Topic
from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.plant import ActuatorFaults
from overdrive.vehicle.sim_node import FAULTS_TOPIC, VehicleSim, World
from tests.conftest import PRESET_NAMES

ON_S = 9.0
STOPPED_MPS = 0.05
CUT_S = 0.05          # the engine reported off within this of its cause (a few 10 ms ticks)


def estop_run(preset: str, cut: str, extra: list[dict] = ()):
    data = {"name": "estop-engine", "vehicle": {"preset": preset, "estop_engine_cut": cut},
            "start": "ready", "seed": 1, "duration_s": ON_S + 5.0,
            "events": [{"at_s": 0.5, "move": {"distance_m": 120, "maxspeed_mps": 8,
                                              "curvature_1pm": 0}},
                       *extra, {"at_s": ON_S, "safestop": "stop"}]}
    return run_scenario(parse_scenario(data), None, plot=False, record_mcap=False)


def first_time(rows, predicate) -> float | None:
    return next((float(r["t_s"]) for r in rows if predicate(r)), None)


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("cut", ["never", "standstill", "always"])
def test_the_estop_stops_the_vehicle_and_cuts_the_engine_as_configured(preset: str,
                                                                      cut: str) -> None:
    result = estop_run(preset, cut)
    rows = [r for r in result.trace if float(r["t_s"]) >= ON_S]
    v0 = float(rows[0]["speed_mps"])
    stopped_s = first_time(rows, lambda r: abs(float(r["speed_mps"])) < STOPPED_MPS)
    assert v0 > 7.0 and stopped_s is not None
    assert v0 / (stopped_s - ON_S) >= 0.6 * PRESETS[preset].max_brake_decel_mps2   # full brake
    assert abs(float(result.trace[-1]["speed_mps"])) < STOPPED_MPS
    off_s = first_time(rows, lambda r: r["engine"] == "off")
    if cut == "never":
        assert off_s is None
    elif cut == "always":
        assert off_s is not None and off_s <= ON_S + CUT_S
    else:
        assert off_s is not None and stopped_s - CUT_S <= off_s <= stopped_s + 0.5
    assert result.summary["violations"] == []


def drive_vehicle(preset: str, throttle_pct: float, stuck: bool) -> tuple[float, float | None]:
    """The simulated vehicle alone: ``throttle_pct`` to 8 m/s, the throttle stuck there (or
    not), then e-stop disable at ``ON_S`` while the controller keeps asking that throttle.
    Returns (the speed at the e-stop, when the engine went off; None if it did not in 2 s)."""
    sim = VehicleSim(PRESETS[preset], World(), seed=1, ready=True)
    t_s, step_s, v_on, off_s, sent = 0.0, 0.01, 0.0, None, False
    pedals = (Topic.PEDALS, PedalCommand(throttle_pct=throttle_pct, brake_pct=0.0, source="speed"))
    while t_s < ON_S + 2.0:
        inbox = [pedals]
        if sim.plant.speed_mps >= 8.0 and not sent:
            inbox.append((FAULTS_TOPIC, ActuatorFaults(throttle_stuck=stuck)))
            sent = True
        if abs(t_s - ON_S) < step_s / 2:
            v_on = sim.plant.speed_mps
            inbox.append((Topic.SAFETY, SafetyDevices(safestop="stop")))
        sim.step(t_s, inbox)
        if t_s > ON_S and off_s is None and sim.plant.engine == "off":
            off_s = t_s
        t_s = round(t_s + step_s, 6)
    return v_on, off_s


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("stuck", [False, True])
def test_a_throttle_that_does_not_close_has_the_engine_cut_while_moving(preset: str,
                                                                        stuck: bool) -> None:
    """``standstill`` keeps a running engine while moving, unless the throttle stays open
    (stuck) 0.5 s into the e-stop: an engine driving against the brake is cut then."""
    v_on, off_s = drive_vehicle(preset, 60.0, stuck)
    assert v_on >= 7.0
    assert off_s is not None
    if stuck:
        assert ON_S + 0.5 - CUT_S <= off_s <= ON_S + 0.5 + CUT_S
    else:
        assert off_s > ON_S + 0.5 + CUT_S   # kept while moving: cut once it stood


@pytest.mark.parametrize("value", ["sometimes", "", "Standstill", 1, True, None, 2.5])
def test_an_unknown_engine_cut_setting_is_refused_by_name(value) -> None:
    with pytest.raises(VehicleSpecError) as err:
        with_overrides(PRESETS["escape-hybrid"], {"estop_engine_cut": value})
    assert err.value.field == "estop_engine_cut"
