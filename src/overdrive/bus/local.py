"""In-process publish/subscribe bus for the lock-step runtime.

Delivery is synchronous and ordered: a message published during a tick is in every
subscriber's inbox at once, so a node stepped later in the same tick sees it. Channel faults
(scenario ``drop`` events, and later delay/duplicate/reorder) are applied here, between
publisher and subscribers, so no node knows about them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Envelope = tuple[str, Any]
Inbox = list[Envelope]
Tap = Callable[[str, Any], None]
ChannelFilter = Callable[[str, Any], bool]


class LocalBus:
    def __init__(self) -> None:
        self._subscribers: dict[str, list[Inbox]] = {}
        self._taps: list[Tap] = []
        self.filter: ChannelFilter | None = None
        """Called as ``filter(topic, msg)`` before delivery; False drops the message."""
        self.dropped = 0

    def subscribe(self, topics: tuple[str, ...] | list[str]) -> Inbox:
        """Return a new inbox that receives every message published on ``topics``."""
        inbox: Inbox = []
        for topic in topics:
            self._subscribers.setdefault(topic, []).append(inbox)
        return inbox

    def tap(self, observer: Tap) -> None:
        """Observe every published message (recording); taps see messages before channel faults."""
        self._taps.append(observer)

    def publish(self, topic: str, msg: Any) -> None:
        for tap in self._taps:
            tap(topic, msg)
        if self.filter is not None and not self.filter(topic, msg):
            self.dropped += 1
            return
        envelope = (topic, msg)
        for inbox in self._subscribers.get(topic, ()):
            inbox.append(envelope)
