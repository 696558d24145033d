"""Channel fault injection for scenarios: drop, loss, delay, duplicate and reorder on a channel.

A ``ChannelFaults`` is the bus's channel model. Each scenario fault opens a window on a
channel (a group of topics); a message published inside the window is dropped, dropped with
probability ``fraction`` (``loss``: each message independently, drawn from a generator seeded
with the run's seed, so a run repeats exactly), held for ``delay_s``, delivered twice, or
swapped with the next message on the same topic. The clock is the runner's: it sets ``now_s``
before every tick.
"""

from __future__ import annotations

import random
from collections.abc import Sequence
from typing import Any

from overdrive.messages import Topic

EPS_S = 1e-9

CHANNEL_TOPICS: dict[str, tuple[str, ...]] = {
    "set_speed": (Topic.SET_SPEED,),
    "steering": (Topic.STEER,),
    "pedals": (Topic.PEDALS,),
    "radar": (Topic.RADAR,),
    "gps": (Topic.GPS_INS,),
    "imu": (Topic.IMU,),
    "wheel_speed": (Topic.WHEEL_SPEED,),
    "speed_state": (Topic.SPEED_STATE,),
    "move": (Topic.MOVE_COMMAND,),
    "advance": (Topic.ADVANCE,),
    "max_speed": (Topic.MAX_SPEED,),
    "jaus": (),                       # the JAUS link: applied by the XGV transport
}
"""Scenario channel names -> bus topics."""

FAULT_KINDS = ("drop", "loss", "delay", "duplicate", "reorder")


class Window:
    __slots__ = ("delay_s", "end_s", "fraction", "kind", "start_s")

    def __init__(self, kind: str, start_s: float, end_s: float, delay_s: float = 0.0,
                 fraction: float = 1.0) -> None:
        if kind not in FAULT_KINDS:
            raise ValueError(f"channel fault kind: one of {FAULT_KINDS}, got {kind!r}")
        if not 0.0 <= fraction <= 1.0:   # also refuses NaN
            raise ValueError(f"loss fraction: in [0, 1], got {fraction!r}")
        self.kind, self.start_s, self.end_s, self.delay_s = kind, start_s, end_s, delay_s
        self.fraction = fraction

    def open_at(self, now_s: float) -> bool:
        return self.start_s - EPS_S <= now_s < self.end_s - EPS_S


class ChannelFaults:
    def __init__(self, windows: dict[str, list[Window]] | None = None, seed: int = 0) -> None:
        self.now_s = 0.0
        self.rng = random.Random(seed)   # loss draws only: other kinds never consume it
        self.windows: dict[str, list[Window]] = windows or {}
        self.held: list[tuple[float, int, str, Any]] = []   # (release time, order, topic, msg)
        self.reorder_slot: dict[str, tuple[Any, float]] = {}   # topic -> (held message, window end)
        self.counts = dict.fromkeys(FAULT_KINDS, 0)
        self._order = 0

    def add(self, channel: str, kind: str, start_s: float, for_s: float, delay_s: float = 0.0,
            fraction: float = 1.0) -> None:
        for topic in CHANNEL_TOPICS[channel]:
            self.windows.setdefault(topic, []).append(
                Window(kind, start_s, start_s + for_s, delay_s, fraction))

    def route(self, topic: str, msg: Any) -> Sequence[Any]:
        """What becomes of ``msg`` on ``topic`` now. Windows open together compose as a real
        link's faults do: a drop or a loss first (each loss window draws, in the order the
        windows were opened), then the first duplicate or reorder, then every delay (added)
        on what that gives out."""
        windows = self.windows.get(topic)
        if windows:
            open_now = [w for w in windows if w.open_at(self.now_s)]
            if open_now:
                return self._compose(open_now, topic, msg)
        if self.reorder_slot:   # a message held back for a swap: it goes out after this one
            held = self.reorder_slot.pop(topic, None)
            if held is not None:
                return (msg, held[0])
        return (msg,)

    def _compose(self, windows: list[Window], topic: str, msg: Any) -> Sequence[Any]:
        for window in windows:
            if window.kind == "drop":
                self.counts["drop"] += 1
                return ()
            if window.kind == "loss" and self._apply(window, topic, msg) == ():
                return ()
        rest = [w for w in windows if w.kind in ("duplicate", "reorder")]
        out = self._apply(rest[0], topic, msg) if rest else (msg,)
        delay_s = sum(w.delay_s for w in windows if w.kind == "delay")
        if delay_s <= 0.0:
            return out
        for message in out:   # what the duplicate or the swap gives out, held for the delay
            self.counts["delay"] += 1
            self._order += 1
            self.held.append((self.now_s + delay_s, self._order, topic, message))
        return ()

    def _apply(self, window: Window, topic: str, msg: Any) -> Sequence[Any]:
        if window.kind == "loss":
            if self.rng.random() >= window.fraction:
                return (msg,)
            self.counts["loss"] += 1
            return ()
        self.counts[window.kind] += 1
        if window.kind == "drop":
            return ()
        if window.kind == "duplicate":
            return (msg, msg)
        if window.kind == "delay":
            self._order += 1
            self.held.append((self.now_s + window.delay_s, self._order, topic, msg))
            return ()
        held = self.reorder_slot.pop(topic, None)      # reorder: swap with the next message
        if held is None:
            self.reorder_slot[topic] = (msg, window.end_s)
            return ()
        return (msg, held[0])

    def due(self) -> list[tuple[str, Any]]:
        """Held messages to deliver now: delays that ran out, and a message held for a swap
        whose window closed with nothing after it (it is late, never lost)."""
        released = [(topic, held[0]) for topic, held in self.reorder_slot.items()
                    if held[1] <= self.now_s + EPS_S]
        for topic, _ in released:
            del self.reorder_slot[topic]
        if not self.held:
            return released
        ready = sorted(h for h in self.held if h[0] <= self.now_s + EPS_S)
        if ready:
            self.held = [h for h in self.held if h[0] > self.now_s + EPS_S]
        return released + [(topic, msg) for _, _, topic, msg in ready]
