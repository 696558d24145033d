"""The planner's clock as the move server sees it: when, on this server's clock, a command was
issued (rules: docs/move-server.md, "The planner's clock").

A planner stamps ``MoveCommand.issued_s`` on its own clock and echoes the newest ``MoveStatus``
it received: the server's stamp ``status_sent_s`` and its own receipt time
``status_received_s``. The command was issued ``issued_s - status_received_s`` (the planner's
dwell) after the status arrived, so after it was sent: its **earliest plausible issue time** on
this clock is ``status_sent_s + dwell`` (less the drift allowance over the dwell). That bound
comes from the command alone: it survives a clock step before the echoed status was received, a
restart on another machine and drift beyond the allowance. The command counts from there (never
later than its arrival): its end can only come closer, by at most ``speed x`` the command's own
round trip (0.08 m at 8 m/s for 10 ms), never further.

The stamps and echoes of the planner's session also bound its offset over time
(``servers.clock_offset``): those bounds decide the tolerance: an offset certainly beyond
``MAX_CLOCK_OFFSET_S`` either way is refused, and on another machine bounds wider than
``MAX_CLOCK_UNCERTAINTY_S``. A new session starts them again (a restarted planner may be on
another machine).

``planner_machine``:

- ``same`` (default): one clock. A command without an echo is taken at its stamp (one up to
  ``SKEW_S`` ahead, step phase, at its arrival; further ahead refused: that clock is not this
  one); with an echo, at the earlier of its stamp and its earliest plausible time, unless the
  session's bounds exclude 0 by more than ``SKEW_S`` (the measurement wins: not one clock).
- ``separate``: another machine. A command that needs its time must carry an echo, and the
  session's bounds must be within tolerance; until then the vehicle stays where it is.

A clock that steps *between* receiving the echoed status and stamping the command cannot be told
from a command that was late on the way: it is placed late by up to the smaller of the step and
its transit time. Planners stamp with a clock that never steps (docs/move-server.md). Refusals
say why (code ``clock``); out of tolerance, or twice in a row otherwise, they raise a fault. Pure.
"""

from __future__ import annotations

from collections import deque
from typing import Literal, get_args

from overdrive.messages import ClockEstimate, MoveCommand
from overdrive.servers.anchoring import SKEW_S
from overdrive.servers.clock_offset import (
    DRIFT_RATE,
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

STATUS_STAMPS_KEPT = 500
"""``MoveStatus.sent_s`` stamps remembered (5 s at the 100 Hz status rate): an echo must name
one of them, so a planner cannot echo a stamp this server never sent."""

SAME_INSTANT_S = 1e-9
"""Float rounding of one instant (times compared on one clock)."""


def earliest_issue_s(cmd: MoveCommand) -> float | None:
    """``cmd``'s earliest plausible issue time on the server's clock from its own echo, or None
    without one: the echoed status was sent at ``status_sent_s``, the planner issued the
    command ``issued_s - status_received_s`` after receiving it (widened by the drift
    allowance over that time)."""
    sent, received, issued = cmd.status_sent_s, cmd.status_received_s, cmd.issued_s
    if sent is None or received is None or issued is None:
        return None
    dwell_s = issued - received
    return sent + dwell_s - DRIFT_RATE * abs(dwell_s)


class PlannerClock:
    """Offset bounds to the planner's clock and the issue time of its commands."""

    __slots__ = ("_reported", "_stamps", "_stamps_set", "fault_reason", "machine", "offset",
                 "out_of_tolerance", "refusals", "refusals_in_row", "resets",
                 "worst_uncertainty_s")

    def __init__(self, machine: PlannerMachine = "same") -> None:
        if machine not in get_args(PlannerMachine):
            raise ValueError(f"planner_machine: {machine!r} is not one of "
                             f"{', '.join(get_args(PlannerMachine))}")
        self.machine = machine
        self._stamps: deque[float] = deque()
        self._stamps_set: set[float] = set()
        self.offset = ClockOffset()
        self.refusals = 0                 # commands refused for time reasons, whole run
        self.refusals_in_row = 0
        self.resets = 0                   # bounds crossed (a step), summed over sessions
        self.fault_reason = ""            # set while time refusals persist
        self.worst_uncertainty_s = 0.0
        self.out_of_tolerance = False     # the last issue_time's bounds were out of tolerance
        self._reported: tuple[OffsetEstimate | None, int, int] | None = None

    def status_sent(self, sent_s: float) -> None:
        """This server sent a ``MoveStatus`` stamped ``sent_s``: an echo may name it."""
        self._stamps.append(sent_s)
        self._stamps_set.add(sent_s)
        if len(self._stamps) > STATUS_STAMPS_KEPT:
            self._stamps_set.discard(self._stamps.popleft())

    def new_session(self) -> None:
        """A new planner session: its clock may be another machine's; measure it again."""
        self.resets += self.offset.resets
        self.offset = ClockOffset()
        self._reported = None

    def echo_problem(self, now_s: float, cmd: MoveCommand) -> str:
        """Why ``cmd``'s echo cannot be one of this server's statuses, or "" (the fields' types
        and finiteness are checked with the command: ``move_feasibility.invalid_reason``)."""
        sent, received = cmd.status_sent_s, cmd.status_received_s
        if (sent is None) != (received is None):
            return "status_sent_s and status_received_s come together (an echo of one MoveStatus)"
        if sent is None or received is None:
            return ""
        if sent not in self._stamps_set:
            return (f"status_sent_s {sent:.6f} is not a MoveStatus this server sent in the last "
                    f"{STATUS_STAMPS_KEPT} (echo the newest status received, as it came)")
        if cmd.issued_s is not None and cmd.issued_s < received - SAME_INSTANT_S:
            return (f"issued_s {cmd.issued_s:.6f} is before status_received_s {received:.6f} "
                    "(both on the planner's clock): the echo is not of a status received "
                    "before the command")
        return ""

    def observe(self, now_s: float, cmd: MoveCommand) -> None:
        """Take a current-session command's stamp and echo as bounds on the offset. When they
        cross the older bounds (which are then dropped), the command's own pair starts them
        again: it is consistent by itself, so the tolerance is judged on it."""
        resets = self.offset.resets
        for _ in range(2):
            if cmd.status_sent_s is not None and cmd.status_received_s is not None:
                self.offset.echoed(cmd.status_sent_s, cmd.status_received_s)
            if cmd.issued_s is not None:
                self.offset.received(now_s, cmd.issued_s)
            if self.offset.resets == resets:
                return

    def placed_s(self, cmd: MoveCommand, now_s: float) -> float | None:
        """Where ``cmd``'s stamp falls on this clock, tolerance aside (for ordering sessions):
        its earliest plausible issue time, or on the same machine its stamp; None if neither."""
        earliest = earliest_issue_s(cmd)
        if earliest is not None:
            return min(earliest, now_s)
        if self.machine == "same" and cmd.issued_s is not None:
            return min(cmd.issued_s, now_s)
        return None

    def issue_time(self, cmd: MoveCommand, now_s: float) -> tuple[float | None, str]:
        """The earliest plausible time, on this clock, at which ``cmd`` (with ``issued_s``) was
        issued (never after ``now_s``), or (None, why) when the planner's clock is unknown or
        out of tolerance."""
        issued_s = cmd.issued_s
        assert issued_s is not None
        est = self.offset.estimate(now_s)
        self.out_of_tolerance = False
        if est is not None:
            self.worst_uncertainty_s = max(self.worst_uncertainty_s, est.uncertainty_s)
            if est.lo_s > MAX_CLOCK_OFFSET_S or est.hi_s < -MAX_CLOCK_OFFSET_S:
                self.out_of_tolerance = True
                return None, (f"the planner's clock is {-est.offset_s:+.3f} s from this "
                              f"server's (+-{0.5 * est.uncertainty_s:.3f} s), beyond "
                              f"{MAX_CLOCK_OFFSET_S} s: synchronise the clocks "
                              "(docs/multiprocess.md)")
            if self.machine == "separate" and est.uncertainty_s > MAX_CLOCK_UNCERTAINTY_S:
                self.out_of_tolerance = True
                return None, (f"the planner's clock offset is known only within "
                              f"{est.uncertainty_s:.3f} s (round trip), more than "
                              f"{MAX_CLOCK_UNCERTAINTY_S} s")
        earliest = earliest_issue_s(cmd)
        if earliest is not None:
            if self.machine == "same" and (est is None or est.lo_s - SKEW_S <= 0.0
                                           <= est.hi_s + SKEW_S):
                earliest = min(earliest, issued_s)   # one clock, as configured
            return min(earliest, now_s), ""
        if self.machine == "separate":
            return None, ("the planner is on another machine and this command echoes no "
                          "MoveStatus (status_sent_s, status_received_s): its stamp cannot be "
                          "placed on this clock")
        if issued_s > now_s + SKEW_S:
            return None, (f"issued at t={issued_s:.3f} s on the planner's clock, "
                          f"{issued_s - now_s:.3f} s ahead of this server's (t={now_s:.3f} s): "
                          "its clock is not this machine's; echo MoveStatus stamps (the "
                          "offset is then measured) or synchronise the clocks")
        upper = self.offset.upper_s(now_s)
        if self.offset.contradicted or (upper is not None and upper < -SKEW_S):
            return None, ("the planner's stamps show its clock is not this machine's (ahead "
                          "by more than the step phase, or stepped): echo MoveStatus stamps or "
                          "synchronise the clocks")
        return min(issued_s, now_s), ""

    def refused(self, why: str) -> bool:
        """A command refused for ``why`` (time): True when this refusal makes the fault: at
        once when the clocks are out of tolerance (that does not pass), else when refusals
        persist (an echo still missing, a clock ahead)."""
        self.refusals += 1
        self.refusals_in_row += 1
        if self.out_of_tolerance or self.refusals_in_row >= FAULT_AFTER_REFUSALS:
            first = not self.fault_reason
            self.fault_reason = why       # the latest reason, for MoveStatus
            return first
        return False

    def placed(self) -> None:
        """A command's time was placed (or a MOVE / REVERSE taken without a stamp): time
        refusals no longer persist."""
        self.refusals_in_row = 0
        self.fault_reason = ""

    def report(self, now_s: float) -> ClockEstimate | None:
        """A ``ClockEstimate`` when the bounds moved by more than ``REPORT_CHANGE_S``, became
        known or unknown, or the refusals or resets changed since the last one; else None."""
        est = self.offset.estimate(now_s)
        resets = self.resets + self.offset.resets
        last = self._reported
        if last is not None:
            last_est, last_refusals, last_resets = last
            same_bounds = (est is None and last_est is None) or (
                est is not None and last_est is not None
                and abs(est.lo_s - last_est.lo_s) <= REPORT_CHANGE_S
                and abs(est.hi_s - last_est.hi_s) <= REPORT_CHANGE_S)
            if same_bounds and (last_refusals, last_resets) == (self.refusals, resets):
                return None
        elif est is None and not self.refusals:
            return None
        self._reported = (est, self.refusals, resets)
        if est is None:
            return ClockEstimate(peer="planner", worst_uncertainty_s=self.worst_uncertainty_s,
                                 refusals=self.refusals, resets=resets)
        return ClockEstimate(peer="planner", offset_s=est.offset_s, lo_s=est.lo_s,
                             hi_s=est.hi_s, uncertainty_s=est.uncertainty_s,
                             worst_uncertainty_s=self.worst_uncertainty_s,
                             refusals=self.refusals, resets=resets)


__all__ = ["FAULT_AFTER_REFUSALS", "PlannerClock", "PlannerMachine", "earliest_issue_s"]
