"""PID: tracking, anti-windup, derivative on measurement, output limits."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from overdrive.dynamics.control import Pid, PidGains, first_order_lag


def test_pi_drives_first_order_plant_to_setpoint() -> None:
    pid = Pid(PidGains(kp=2.0, ki=4.0, output_min=-10, output_max=10))
    y = 0.0
    for _ in range(2000):
        u = pid.update(1.0, y, 0.01)
        y = first_order_lag(u, y, 0.2, 0.01)
    assert abs(y - 1.0) < 1e-3


def test_back_calculation_limits_windup() -> None:
    gains = PidGains(kp=1.0, ki=5.0, output_min=0.0, output_max=1.0)
    pid = Pid(gains)
    for _ in range(1000):  # long saturation: setpoint far out of reach
        pid.update(100.0, 0.0, 0.01)
    # after the error reverses the output must leave saturation within a few steps
    outputs = [pid.update(0.0, 100.0, 0.01) for _ in range(20)]
    assert outputs[-1] == 0.0
    naive_integral = 5.0 * 100.0 * 10.0
    assert abs(pid.integral) < naive_integral / 10


@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=50))
def test_output_within_limits_and_rate(measurements: list[float]) -> None:
    pid = Pid(PidGains(kp=3.0, ki=1.0, kd=0.1, output_min=-5, output_max=5, output_rate_per_s=100))
    last = 0.0
    for m in measurements:
        out = pid.update(0.0, m, 0.01)
        assert -5.0 <= out <= 5.0
        assert abs(out - last) <= 100 * 0.01 + 1e-9
        last = out


def test_no_derivative_kick_on_setpoint_step() -> None:
    pid = Pid(PidGains(kp=0.0, kd=1.0, output_min=-100, output_max=100))
    pid.update(0.0, 0.0, 0.01)
    assert pid.update(50.0, 0.0, 0.01) == 0.0
