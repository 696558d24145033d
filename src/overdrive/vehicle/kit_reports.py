"""Reports a CAN kit sends, checked for a second sender and for speeds no vehicle can have. Sans-IO.

CAN frames carry no sender: any node on the bus can send a kit's report id, and PACMod 3's v3
reports carry no counter. A forged or replayed VEHICLE_SPEED_RPT (speed 0 while moving) made the
stack's dead reckoning fall behind and a 10 m MOVE end at 23-44 m by the kit's own odometry (red
team, 2026-11-26). ``ReportGuard`` catches what a second sender cannot hide:

- **rate**: one id arriving more often than the kit sends it (more than ``RATE_MARGIN`` times its
  period's count in a ``RATE_WINDOW_S`` window, plus ``RATE_SLACK_FRAMES``): two senders;
- **jumps**: a speed that changes faster than any vehicle can (``MAX_ACCEL_MPS2`` over the time
  since the last report, at least one report period, plus ``SPEED_QUANTUM_MPS``).

Either is a conflict the client treats as a fault it detected (the vehicle is braked to a stop,
engaged, then let go; only the operator engages again). A forger that copies the kit's rate and
stays within the physics is not caught: CAN has no authentication (docs/pacmod3.md).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Final

RATE_WINDOW_S: Final = 0.25
"""The window the rate is judged over: ~7 reports at 30 Hz, so a forger at the kit's own rate
doubles the count within a quarter second."""
RATE_MARGIN: Final = 1.5
"""A kit's report jitter (a late frame and the next one close behind) stays well under 1.5x."""
RATE_SLACK_FRAMES: Final = 2
"""Frames read in one drain after a stall of the reader carry stamps bunched together."""
MAX_ACCEL_MPS2: Final = 15.0
"""About 1.5 g: beyond any tyre's grip (overdrive's ellipse keeps to under 1 g), so a speed
report implying more is not the vehicle's."""
SPEED_QUANTUM_MPS: Final = 0.1
"""VEHICLE_SPEED_RPT resolves 0.01 m/s; a tenth absorbs a sensor's step and rounding."""


class ReportGuard:
    """Per report id: arrival rate and (for speeds) physical plausibility."""

    def __init__(self, period_s: float) -> None:
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"report period {period_s!r}: a positive number of seconds")
        self.period_s = period_s
        self.max_frames = math.floor(RATE_MARGIN * RATE_WINDOW_S / period_s) + RATE_SLACK_FRAMES
        self._arrivals: dict[int, deque[float]] = {}
        self._speed: tuple[float, float] | None = None   # (speed_mps, stamp_s) last taken
        self.conflict: str | None = None                  # the first conflict seen (latched)
        self.too_fast = 0
        self.jumps = 0

    def arrived(self, frame_id: int, stamp_s: float) -> bool:
        """Count a report of ``frame_id`` at ``stamp_s``; False when the id now arrives too
        often (a second sender)."""
        times = self._arrivals.setdefault(frame_id, deque())
        times.append(stamp_s)
        while times and times[0] < stamp_s - RATE_WINDOW_S:
            times.popleft()
        if len(times) <= self.max_frames:
            return True
        self.too_fast += 1
        self._latch(f"report 0x{frame_id:X} arrives {len(times)} times in "
                    f"{RATE_WINDOW_S:g} s (the kit sends at most {self.max_frames}): "
                    f"a second sender on the bus")
        return False

    def speed_plausible(self, speed_mps: float, stamp_s: float) -> bool:
        """Whether ``speed_mps`` can follow the last speed taken; the last speed is kept on a
        refusal, so a forged frame between two true ones is refused, the next true one taken."""
        if self._speed is not None:
            last_mps, last_s = self._speed
            dt_s = max(stamp_s - last_s, self.period_s)
            if abs(speed_mps - last_mps) > MAX_ACCEL_MPS2 * dt_s + SPEED_QUANTUM_MPS:
                self.jumps += 1
                self._latch(f"speed report {speed_mps:.2f} m/s after {last_mps:.2f} m/s "
                            f"{stamp_s - last_s:.3f} s earlier: beyond {MAX_ACCEL_MPS2:g} m/s^2, "
                            f"not this vehicle's")
                return False
        self._speed = (speed_mps, stamp_s)
        return True

    def _latch(self, reason: str) -> None:
        if self.conflict is None:
            self.conflict = reason

    def clear(self) -> None:
        """The operator's engage: start judging afresh."""
        self.conflict = None
        self._arrivals.clear()
