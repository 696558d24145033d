"""``overdrive kit-sim pacmod3``: the emulated PACMod 3 kit on a CAN bus, in wall-clock time.

The runtime edge of ``vehicle.pacmod3_kit.Pacmod3Kit``: one ``CanPort`` (the only bus owner,
``runtime.can_edge``), every frame handed to the kit as it arrives, the vehicle stepped every
``PERIOD_S`` of wall-clock time and the reports the kit has due sent. This loop reads the clock;
the kit never does. With a scenario, its vehicle, seed and world are used and its world,
safety-device (a manual override: the safety driver brakes and holds the wheel) and actuator
fault events are played at their times; ``--fault`` adds the kit's own faults (override,
report silence, stuck actuator). Both run on the scenario clock, which starts with the first
frame received, so a stack started a little later sees them when the scenario says.

On exit (SIGINT, SIGTERM, ``--duration``) it writes the kit's summary as JSON (``--summary``):
ground truth, odometer, frames seen, enable edges, timeouts, overrides, the last command frame
per system, bad frames by reason, and the bus's own counts, so a test judges a drive from the
kit's own odometry.

A frame's time on the kit's clock is when it reached the bus (python-can's time stamp,
``runtime.can_edge.bus_arrival_s``), not when this loop read it: a kit-sim starved of CPU (``make
test-under-load``) must not time out a stack whose frames were on time, as hardware would not.
A frame too old to act on is dropped and counted (``stale_frames``), never taken as read now:
stamped more than ``STAMP_TRUST_S`` before the read, or more than the kit's command timeout
before the kit's last step (the kit already judged that time: a real kit, acting on each frame
as it arrives, would have timed it out).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Final, TextIO

import msgspec

from overdrive.kits.pacmod3 import Dialect
from overdrive.messages import SIM_FAULTS_TOPIC, SIM_WORLD_TOPIC, Topic
from overdrive.runtime.can_edge import CanConfig, CanConfigError, CanPort, bus_arrival_s
from overdrive.scenario.player import ScenarioPlayer, world_from_spec
from overdrive.scenario.schema import Scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_kit import COMMAND_TIMEOUT_S, KitFault, Pacmod3Kit
from overdrive.vehicle.plant import ActuatorFaults

PERIOD_S: Final = 0.01
"""The vehicle's step, as in the lock-step runs and xgv-sim."""
DEFAULT_VEHICLE: Final = "lexus-rx450h"
"""The PACMod default (issue 32): Lexus RX 450h, wheelbase 2.79 m."""
TRUTH_HEADER: Final = "t_s,scenario_s,x_m,y_m,speed_mps,odometer_m"
STAMP_TRUST_S: Final = 1.0
"""A frame's bus time stamp (python-can's, the wall clock of the hub or interface that received
it) is its arrival time when it is at most this old and not in the future (``STAMP_FUTURE_S``
of slack): a kit-sim starved of CPU (tests stall it 0.3 s) then judges
the command timeout by when frames reached the bus, as the kit's hardware would. Older: dropped
and counted (before, it was taken as read now: a stale command acted on as new). Later (a
clock step): taken as read."""


def parse_fault(text: str) -> KitFault:
    """``KIND:SYSTEM:START[:END[:VALUE]]`` -> a ``KitFault`` on the scenario clock, e.g.
    ``override:brake:5:7:0.4`` (brake pedal at 40 % from 5 s to 7 s), ``silence::3:4``,
    ``stuck:steering:2``. Raises ValueError naming what is wrong."""
    parts = text.split(":")
    if not 3 <= len(parts) <= 5:
        raise ValueError(f"{text!r}: expected KIND:SYSTEM:START[:END[:VALUE]]")
    kind, system = parts[0], parts[1] or None
    try:
        start = float(parts[2])
        end = float(parts[3]) if len(parts) > 3 and parts[3] else None
        value = float(parts[4]) if len(parts) > 4 else 0.0
    except ValueError:
        raise ValueError(f"{text!r}: START, END and VALUE are numbers") from None
    try:
        return msgspec.convert({"kind": kind, "system": system, "start_s": start, "end_s": end,
                                "value": value}, KitFault)
    except (msgspec.ValidationError, ValueError) as e:
        raise ValueError(f"{text!r}: {e}") from None


class KitSimServer:
    """The kit behind a CAN port; ``serve()`` runs until ``stop()`` or ``duration_s``."""

    def __init__(self, config: CanConfig, *, scenario: Scenario | None = None,
                 vehicle: Any = None, dialect: Dialect = "v3",
                 faults: tuple[KitFault, ...] = ()) -> None:
        params = vehicle if vehicle is not None else (
            scenario.vehicle if scenario is not None else KIT_VEHICLES[DEFAULT_VEHICLE])
        spec = scenario.spec if scenario is not None else None
        self.kit = Pacmod3Kit(params, world_from_spec(spec.world) if spec is not None else None,
                              spec.seed if spec is not None else 1, dialect=dialect)
        self.player = ScenarioPlayer(scenario) if scenario is not None else None
        self.pending_faults = faults          # on the scenario clock, injected at its start
        self.port = CanPort(config)
        self.config = config
        self._stop = threading.Event()
        self.scenario_start_s: float | None = None
        self.now_s = 0.0
        self.reports_sent = 0
        self.bus_problems: list[str] = []
        self.ignored_events: dict[str, int] = {}
        self._wall0 = 0.0
        self._last_arrival_s = 0.0
        self.stale_frames = 0                 # stamped older than the command timeout: dropped

    def stop(self) -> None:
        self._stop.set()

    def close(self) -> None:
        self.port.close()

    def __enter__(self) -> KitSimServer:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def serve(self, duration_s: float | None = None,
              clock: Callable[[], float] = time.monotonic, truth: TextIO | None = None,
              wall_clock: Callable[[], float] = time.time) -> None:
        """Hand arriving frames to the kit, step it every ``PERIOD_S``, send its reports."""
        kit, port = self.kit, self.port
        start = clock()
        self._wall0 = wall_clock() - (clock() - start)   # the wall-clock time of kit time 0
        tick = 0
        while not self._stop.is_set():
            now = clock() - start
            if duration_s is not None and now >= duration_s:
                break
            next_tick_s = tick * PERIOD_S
            if now < next_tick_s:
                batch = port.receive(timeout_s=next_tick_s - now)
                self._take(batch, clock() - start)
                continue
            # the step's time is read first, then everything that arrived is drained: a stall
            # anywhere in between cannot make frames already on the bus look late
            self._take(port.receive(timeout_s=0.0), now)
            self.now_s = now
            if self.player is not None and self.scenario_start_s is not None:
                self._play(now - self.scenario_start_s)
            kit.step(now)
            frames = kit.report_frames(now)
            if frames:
                problems = port.send(frames, now)
                self.reports_sent += len(frames) - len(problems)
                self.bus_problems.extend(problems[: max(0, 20 - len(self.bus_problems))])
            if truth is not None:
                self._write_truth(truth, now)
            tick = max(tick + 1, int(now / PERIOD_S))

    def _take(self, batch: list[tuple[float, Any]], read_s: float) -> None:
        """Hand ``batch`` (python-can stamps and frames, read at ``read_s``) to the kit."""
        for stamp, frame in batch:
            arrived = self._arrival_s(stamp, read_s)
            if arrived is None:
                self.stale_frames += 1
                continue
            if self.scenario_start_s is None:
                self._start_scenario(arrived)
            self.kit.receive(frame, arrived)

    def _arrival_s(self, stamp: float, read_s: float) -> float | None:
        """A frame's arrival on the kit's clock (``STAMP_TRUST_S``), never before the previous
        frame's; None: too old to act on."""
        t = bus_arrival_s(stamp, self._wall0, read_s, self._last_arrival_s, STAMP_TRUST_S)
        if t is None or t < self.now_s - COMMAND_TIMEOUT_S:
            return None
        self._last_arrival_s = t
        return t

    def _start_scenario(self, now_s: float) -> None:
        self.scenario_start_s = now_s
        for f in self.pending_faults:
            self.kit.inject(msgspec.structs.replace(
                f, start_s=f.start_s + now_s,
                end_s=None if f.end_s is None else f.end_s + now_s))

    def _play(self, scenario_s: float) -> None:
        assert self.player is not None
        if scenario_s > self.player.scenario.spec.duration_s:
            return
        for topic, msg in self.player.step(scenario_s, ()):
            if topic == Topic.SAFETY:
                self.kit.set_devices(msg)
            elif topic == SIM_WORLD_TOPIC:
                self.kit.set_world(msg)
            elif topic == SIM_FAULTS_TOPIC and isinstance(msg, ActuatorFaults):
                self.kit.apply_actuator_faults(msg)
            else:   # sensor faults, commands for a stack: not the kit's
                name = type(msg).__name__
                self.ignored_events[name] = self.ignored_events.get(name, 0) + 1

    def _write_truth(self, out: TextIO, now_s: float) -> None:
        t = self.kit.truth(now_s)
        scenario_s = "" if self.scenario_start_s is None else f"{now_s - self.scenario_start_s:.4f}"
        out.write(f"{now_s:.4f},{scenario_s},{t.x_m:.4f},{t.y_m:.4f},{t.speed_mps:.4f},"
                  f"{t.odometer_m:.4f}\n")

    def summary(self) -> dict[str, Any]:
        """The kit's summary and the bus's counts (times on this process's clock from start;
        ``scenario_start_s`` converts them to the scenario clock)."""
        out = self.kit.summary(self.now_s)
        out.update({
            "scenario_start_s": self.scenario_start_s, "duration_s": self.now_s,
            "can": self.config.to_json(), "frames_received": self.port.received,
            "reports_sent": self.reports_sent, "stale_frames": self.stale_frames,
            "bus_errors": self.port.errors.as_dict(),
            "bus_problems": self.bus_problems, "ignored_scenario_events": self.ignored_events,
        })
        return out


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    """The summary as JSON, written whole (a temporary file renamed over the target)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    tmp.replace(path)


__all__ = ["DEFAULT_VEHICLE", "TRUTH_HEADER", "CanConfigError", "KitSimServer", "parse_fault",
           "write_summary"]
