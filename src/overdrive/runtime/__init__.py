"""overdrive.runtime: how nodes are stepped and connected to the world: the lock-step runtime
(``lockstep``: one simulated clock), the wall-clock runtime (``wall``), and the edges that own
sockets (``jaus_endpoint``: the JUDP/UDP endpoint). The only layer that reads a clock or opens a
socket for the stack's nodes.

Layer 6. May import ``bus``, ``vehicle``, ``servers``, ``safety``, ``dynamics``, ``messages``
and the codecs. Must not import ``scenario``, ``observe``, ``run`` or ``cli``.
"""
