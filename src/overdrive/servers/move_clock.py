"""The planner's clock as the move server sees it: when, on this server's clock, a command was
issued (rules: docs/move-server.md, "The planner's clock").

A planner stamps ``MoveCommand.issued_s`` on its own clock. It may also echo the newest
``MoveStatus`` it received: the server's stamp ``status_sent_s`` and its own receipt time
``status_received_s``. The command's stamp bounds the offset (this clock minus the planner's)
from above, the echo from below (``servers.clock_offset``); the command counts from the
**earliest plausible** issue time, ``issued_s + lo_s``, never later than its arrival. Anchoring
early can only bring the end closer: the worst-case error is ``speed x (hi_s - lo_s)``, short
of the end, never past it (0.08 m at 8 m/s for a 10 ms round trip).

``planner_machine``:

- ``same`` (default): the planner runs on this machine's clock, the offset is 0 and a stamp is
  taken as it is (a stamp up to ``SKEW_S`` ahead, step phase, as now); a planner that echoes is
  placed at the earlier of its stamp and ``issued_s + lo_s``. When what it sends proves
  otherwise (its bounds exclude 0 by more than ``SKEW_S``), the measurement wins: the stamp is
  corrected as for ``separate``; without an echo a stamp further ahead is refused.
- ``separate``: the planner runs on another machine. No command that starts or extends motion is
  taken until the offset is measured (both directions) and within tolerance: the vehicle stays
  where it is (parked, if it was).

Beyond ``MAX_CLOCK_OFFSET_S`` or ``MAX_CLOCK_UNCERTAINTY_S`` a command that needs its time is
refused (code ``clock``) with the reason; refusals in a row raise a fault notice. Pure.
"""

from __future__ import annotations

import math
from typing import Literal

from overdrive.messages import ClockEstimate, MoveCommand
from overdrive.servers.anchoring import SKEW_S
from overdrive.servers.clock_offset import (
    MAX_CLOCK_OFFSET_S,
    MAX_CLOCK_UNCERTAINTY_S,
    ClockOffset,
    OffsetEstimate,
)

PlannerMachine = Literal["same", "separate"]

FAULT_AFTER_REFUSALS = 2
"""Time refusals in a row that make a fault (one can be a clock's step being re-measured)."""

REPORT_CHANGE_S = 0.001
"""A new ``ClockEstimate`` is published when a bound moves by more than this (1 ms)."""


class PlannerClock:
    """Offset bounds to the planner's clock and the issue time of its commands."""

    __slots__ = ("_reported", "fault_reason", "machine", "offset", "out_of_tolerance", "refusals",
                 "refusals_in_row", "worst_uncertainty_s")

    def __init__(self, machine: PlannerMachine = "same") -> None:
        self.machine = machine
        self.offset = ClockOffset()
        self.refusals = 0                 # commands refused for time reasons, whole run
        self.refusals_in_row = 0
        self.fault_reason = ""            # set while time refusals persist
        self.worst_uncertainty_s = 0.0
        self.out_of_tolerance = False     # the last issue_time's bounds were out of tolerance
        self._reported: OffsetEstimate | None = None

    def observe(self, now_s: float, cmd: MoveCommand) -> str:
        """Take the command's stamp and echo as samples; why the echo is malformed, or ""."""
        sent, received = cmd.status_sent_s, cmd.status_received_s
        if (sent is None) != (received is None):
            return "status_sent_s and status_received_s come together (an echo of one MoveStatus)"
        if sent is not None and received is not None:
            if not (math.isfinite(sent) and math.isfinite(received)):
                return f"echo ({sent!r}, {received!r}) is not finite"
            if sent > now_s + 1e-9:
                return (f"status_sent_s {sent:.3f} is later than this server's now "
                        f"({now_s:.3f}): not a MoveStatus it sent")
            self.offset.echoed(sent, received)
        if cmd.issued_s is not None:
            self.offset.received(now_s, cmd.issued_s)
        return ""

    def issue_time(self, issued_s: float, now_s: float) -> tuple[float | None, str]:
        """The earliest plausible time, on this clock, at which ``issued_s`` was stamped (never
        after ``now_s``), or (None, why) when the planner's clock is unknown or out of
        tolerance."""
        est = self.offset.estimate(now_s)
        self.out_of_tolerance = est is not None and (
            abs(est.offset_s) > MAX_CLOCK_OFFSET_S or est.uncertainty_s > MAX_CLOCK_UNCERTAINTY_S)
        if est is not None:
            self.worst_uncertainty_s = max(self.worst_uncertainty_s, est.uncertainty_s)
        if est is None:
            if self.machine == "separate":
                if self.offset.upper_only or not self.offset.resets:
                    return None, ("the planner's clock offset is not measured yet: echo the newest "
                                  "MoveStatus (status_sent_s, status_received_s) in commands")
                return None, ("the planner's clock stepped: its stamps and echoes contradict "
                              "each other until re-measured")
            if issued_s > now_s + SKEW_S:
                return None, (f"issued at t={issued_s:.3f} s on the planner's clock, "
                              f"{issued_s - now_s:.3f} s ahead of this server's (t={now_s:.3f} s): "
                              "its clock is not this machine's; echo MoveStatus stamps (the "
                              "offset is then measured) or synchronise the clocks")
            return min(issued_s, now_s), ""
        if abs(est.offset_s) > MAX_CLOCK_OFFSET_S:
            return None, (f"the planner's clock is {-est.offset_s:+.3f} s from this server's "
                          f"(+-{0.5 * est.uncertainty_s:.3f} s), beyond {MAX_CLOCK_OFFSET_S} s: "
                          "synchronise the clocks (docs/multiprocess.md)")
        if est.uncertainty_s > MAX_CLOCK_UNCERTAINTY_S:
            return None, (f"the planner's clock offset is known only within "
                          f"{est.uncertainty_s:.3f} s (round trip), more than "
                          f"{MAX_CLOCK_UNCERTAINTY_S} s")
        lo_s = est.lo_s
        if self.machine == "same" and lo_s - SKEW_S <= 0.0 <= est.hi_s + SKEW_S:
            lo_s = min(lo_s, 0.0)    # one clock, as configured: never later than the stamp
        return min(issued_s + lo_s, now_s), ""

    def refused(self, why: str) -> bool:
        """A command refused for ``why`` (time): True when this refusal makes the fault: at
        once when the clocks are out of tolerance (that does not pass), else when refusals
        persist (a step being re-measured, an echo still missing)."""
        self.refusals += 1
        self.refusals_in_row += 1
        if ((self.out_of_tolerance or self.refusals_in_row >= FAULT_AFTER_REFUSALS)
                and not self.fault_reason):
            self.fault_reason = why
            return True
        return False

    def placed(self) -> None:
        """A command's time was placed: time refusals no longer persist."""
        self.refusals_in_row = 0
        self.fault_reason = ""

    def report(self, now_s: float) -> ClockEstimate | None:
        """A ``ClockEstimate`` when the bounds moved by more than ``REPORT_CHANGE_S`` since the
        last one (or refusals changed), else None."""
        est = self.offset.estimate(now_s)
        last = self._reported
        if est is None or (last is not None and abs(est.lo_s - last.lo_s) <= REPORT_CHANGE_S
                           and abs(est.hi_s - last.hi_s) <= REPORT_CHANGE_S):
            return None
        self._reported = est
        return ClockEstimate(peer="planner", offset_s=est.offset_s, lo_s=est.lo_s,
                             hi_s=est.hi_s, uncertainty_s=est.uncertainty_s,
                             worst_uncertainty_s=self.worst_uncertainty_s,
                             refusals=self.refusals, resets=self.offset.resets)


__all__ = ["FAULT_AFTER_REFUSALS", "PlannerClock", "PlannerMachine"]
