"""The SPSS watchdog timed from the SPSS send time (issue 20), on a simulated clock.

Across processes an SPSS arrives after a hop and is read at the next step; the watchdog must
still stop the vehicle 200 ms + one period after the last SPSS *sent*.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from overdrive.bus.local import Stamped
from overdrive.messages import Topic
from overdrive.servers.speed import CLOCK_SKEW_MAX_S
from tests.servers.test_speed_server import PERIOD_S, Rig, spss

TIMEOUT_S = 0.2   # seed 001


def _drive(rig: Rig, hop_s: float, stamp=lambda sent_s: sent_s) -> tuple[float, float]:
    """Drive 3 s with SPSS every 100 ms, each read ``hop_s`` after it was sent (stamped with
    ``stamp(sent)``); then silence. Returns (last SPSS sent, first step with the e-stop)."""
    request = spss("run", 3.0, 1.0)
    sends = [round(0.1 * i, 6) for i in range(30)]
    pending: list[float] = []
    last_sent = estop = None
    for tick in range(600):
        now = rig.now_s
        if sends and sends[0] <= now + 1e-9:
            pending.append(sends.pop(0))
        arrived = [s for s in pending if s + hop_s <= now + 1e-9]
        pending = [s for s in pending if s + hop_s > now + 1e-9]
        inbox = rig.vehicle.sensors() + [Stamped(Topic.SET_SPEED, request, stamp(s)) for s in arrived]
        if arrived:
            last_sent = arrived[-1]
        out = rig.server.step(now, inbox)
        rig.vehicle.command(out)
        rig.vehicle.advance(PERIOD_S)
        rig.tick_count = tick + 1
        if any(t == Topic.NOTICE and m.kind == "estop" for t, m in out):
            estop = now
            break
    assert last_sent is not None and estop is not None
    return last_sent, estop


@pytest.mark.parametrize("hop_s", [0.0, 0.004, 0.013, 0.05])
def test_estop_within_200_ms_plus_one_period_of_the_last_spss_sent(hop_s: float) -> None:
    last_sent, estop = _drive(Rig("ranger-6x6", state="run", gear="high"), hop_s)
    assert TIMEOUT_S - 1e-9 <= estop - last_sent <= TIMEOUT_S + PERIOD_S + 1e-9, (last_sent, estop)


def test_stamps_from_the_future_are_timed_from_receipt() -> None:
    """A sender whose clock runs ahead cannot extend the watchdog (clock-skew attack)."""
    last_sent, estop = _drive(Rig("ranger-6x6", state="run", gear="high"), 0.013,
                              stamp=lambda s: s + 5.0)
    received = last_sent + 0.013
    assert TIMEOUT_S - 1e-9 <= estop - received <= TIMEOUT_S + PERIOD_S + 1e-9


def test_stamps_from_a_clock_behind_stop_early_never_late() -> None:
    last_sent, estop = _drive(Rig("ranger-6x6", state="run", gear="high"), 0.0,
                              stamp=lambda s: s - 0.15)
    assert estop - last_sent <= TIMEOUT_S + PERIOD_S + 1e-9


@settings(max_examples=60, deadline=None)
@given(lead_s=st.floats(min_value=-1.0, max_value=1.0))
def test_the_watchdog_never_runs_later_than_receipt_timing(lead_s: float) -> None:
    """Whatever the stamp, the e-stop is no later than timing from receipt would give."""
    last_sent, estop = _drive(Rig("ranger-6x6", state="run", gear="high"), 0.02,
                              stamp=lambda s: s + lead_s)
    assert estop - (last_sent + 0.02) <= TIMEOUT_S + PERIOD_S + CLOCK_SKEW_MAX_S + 1e-9
