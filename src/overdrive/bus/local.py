"""In-process publish/subscribe bus for the lock-step runtime.

Delivery is synchronous and ordered: a message published during a tick is in every
subscriber's inbox at once, so a node stepped later in the same tick sees it. A channel model
(scenario fault injection: drop, loss, delay, duplicate, reorder) may sit between publisher and
subscribers, so no node knows about faults.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol

Envelope = tuple[str, Any]
Inbox = list[Envelope]
Tap = Callable[[str, Any], None]


class Stamped(tuple):
    """An inbox envelope ``(topic, msg)`` that also carries ``sent_s``, its send time.

    It unpacks and compares like the pair, so nodes that ignore send times see no difference.
    ``sent_s`` is on the clock of the receiving node's ``now_s`` (the wall-clock runtime converts
    it, from ``sender``'s clock: docs/multiprocess.md, "Clocks across machines"); the lock-step
    runtime delivers plain pairs, sent in the tick that reads them.
    """

    sent_s: float
    sender: str

    def __new__(cls, topic: str, msg: Any, sent_s: float, sender: str = "") -> Stamped:
        self = super().__new__(cls, (topic, msg))
        self.sent_s = sent_s
        self.sender = sender
        return self


def sent_time_s(envelope: Envelope, now_s: float) -> float:
    """When ``envelope`` was sent on ``now_s``'s clock: its stamp, or ``now_s`` without one."""
    sent_s = getattr(envelope, "sent_s", now_s)
    return sent_s if math.isfinite(sent_s) else now_s


class ChannelModel(Protocol):
    def route(self, topic: str, msg: Any) -> Sequence[Any]:
        """Messages to deliver now for this publication: ``()`` drops, ``(m, m)`` duplicates."""
        ...

    def due(self) -> Sequence[Envelope]:
        """Held messages (delayed, reordered) to deliver now; called once per tick."""
        ...


class LocalBus:
    def __init__(self) -> None:
        self._subscribers: dict[str, list[Inbox]] = {}
        self._taps: list[Tap] = []
        self._delivered_taps: dict[str, list[Tap]] = {}
        self.channel: ChannelModel | None = None

    def subscribe(self, topics: Sequence[str]) -> Inbox:
        """Return a new inbox that receives every message published on ``topics``."""
        inbox: Inbox = []
        for topic in topics:
            self._subscribers.setdefault(topic, []).append(inbox)
        return inbox

    def tap(self, observer: Tap) -> None:
        """Observe every published message (recording); taps see messages before channel faults."""
        self._taps.append(observer)

    def tap_delivered(self, observer: Tap, topics: Sequence[str]) -> None:
        """Observe the messages on ``topics`` as the channel delivers them (after drops, delays,
        duplication and reordering): what a subscriber actually received."""
        for topic in topics:
            self._delivered_taps.setdefault(topic, []).append(observer)

    def _deliver(self, topic: str, msg: Any) -> None:
        for tap in self._delivered_taps.get(topic, ()):
            tap(topic, msg)
        envelope = (topic, msg)
        for inbox in self._subscribers.get(topic, ()):
            inbox.append(envelope)

    def publish(self, topic: str, msg: Any) -> None:
        self.publish_all(((topic, msg),))

    def publish_all(self, outputs: Iterable[Envelope]) -> None:
        """``publish`` each ``(topic, msg)`` in order (a node's outputs: one call per step)."""
        taps = self._taps
        subscribers = self._subscribers
        channel = self.channel
        delivered_taps = self._delivered_taps
        for topic, msg in outputs:
            for tap in taps:
                tap(topic, msg)
            if topic in delivered_taps:
                for routed in (channel.route(topic, msg) if channel is not None else (msg,)):
                    self._deliver(topic, routed)
                continue
            inboxes = subscribers.get(topic)
            if channel is None:
                if inboxes:
                    envelope = (topic, msg)
                    for inbox in inboxes:
                        inbox.append(envelope)
                continue
            for routed in channel.route(topic, msg):
                if inboxes:
                    envelope = (topic, routed)
                    for inbox in inboxes:
                        inbox.append(envelope)

    def pump(self) -> None:
        """Deliver held messages that are due; the runtime calls it at the start of each tick."""
        if self.channel is not None:
            for topic, msg in self.channel.due():
                self._deliver(topic, msg)
