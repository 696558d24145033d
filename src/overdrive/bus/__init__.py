"""Message buses: publish/subscribe by topic. ``LocalBus`` is the in-process default."""

from overdrive.bus.local import Inbox, LocalBus

__all__ = ["Inbox", "LocalBus"]
