"""overdrive.bus: message buses, publish/subscribe by topic. ``LocalBus`` (``local``) is the
in-process default; ``zenoh_bus`` carries the same messages between processes and machines
(``wire``: the frames, ``access``: who may publish what, ``tool_gate``: the relay for tools);
``faults`` is the channel model that drops, loses, delays, duplicates or reorders a channel's
messages; ``link_faults`` decides the same for datagrams on a real link (``overdrive link-proxy``).

Layer 5. May import ``messages`` (and the codecs); it needs nothing of the layers between.
Must not import ``runtime``, ``scenario`` or anything above: it knows topics, not nodes.
"""

from overdrive.bus.local import Inbox, LocalBus

__all__ = ["Inbox", "LocalBus"]
