"""A healthy service brake must never be declared failed (which latches an e-stop and a
takeover request for good) because the GPS/INS speed is noisy while the wheel speed and the IMU
agree the vehicle stands still. Judged from ground truth: the simulated vehicle never moves."""

from __future__ import annotations

from typing import Any

import pytest

from overdrive.run.sim import run_scenario
from overdrive.scenario.schema import parse_scenario
from tests.conftest import PRESET_NAMES

BRAKE_LOST_CODES = ("1133", "1134", "1136")


def run(preset: str, sigma: float) -> Any:
    """A MOVE on a vehicle whose GPS/INS position (m) and speed (m/s) get Gaussian noise of
    ``sigma`` (the position steps stop it before it moves: the vehicle holds on its brake)."""
    data = {"name": "gps-noise", "vehicle": preset, "start": "ready", "duration_s": 30,
            "events": [
                {"at_s": 0.2, "sensor": {"name": "gps", "fault": "noise", "for_s": 29.5,
                                         "sigma": sigma}},
                {"at_s": 0.5, "move": {"distance_m": 40, "maxspeed_mps": 2.5,
                                       "curvature_1pm": 0}}]}
    return run_scenario(parse_scenario(data), None)


def check_no_brake_alarm(result: Any) -> None:
    peak = max(abs(float(r["speed_mps"])) for r in result.trace)
    assert peak < 0.01, f"the vehicle moved ({peak} m/s): not the case this file pins"
    faults = [(e["code"], e["t_s"]) for e in result.summary["events"]
              if e["kind"] == "fault" and str(e.get("code")) in BRAKE_LOST_CODES]
    assert not faults, faults
    assert not result.nodes["speed"].takeover


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("sigma", [0.1, 0.2])
def test_gps_noise_on_a_standing_vehicle_raises_no_brake_fault(preset: str, sigma: float) -> None:
    """The reference: up to 0.2 m/s of GPS/INS speed noise, no brake alarm."""
    check_no_brake_alarm(run(preset, sigma))


@pytest.mark.parametrize("preset", PRESET_NAMES)
@pytest.mark.parametrize("sigma", [0.3])
def test_gps_speed_noise_on_a_standing_vehicle_is_no_brake_failure(preset: str,
                                                                   sigma: float) -> None:
    """Measured (2026-11-26, this file), both presets: sigma 0.3 (the GPS/INS position step
    check, 1105, stops the MOVE at once; the truth speed stays 0.000 throughout): 1134 "brake
    gives 22 %" at 7.34 s, 1136 "16 %" at 8.40 s, e-stop and takeover latched. Sigma 0.1-0.2:
    none. Suspected cause: ``PedalMonitor``'s brake response samples whenever the speed server's
    speed (GPS/INS-led) exceeds ``min_speed_mps``, with no check that the wheel speed and the
    IMU agree the vehicle is moving."""
    check_no_brake_alarm(run(preset, sigma))
