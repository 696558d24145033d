"""overdrive.runtime: how nodes are stepped and connected to the world: the lock-step runtime
(``lockstep``: one simulated clock), the wall-clock runtime (``wall``), the edges that own
sockets (``udp``: the one place a UDP socket is opened; ``xgv_link``: the JAUS link's datagrams
and nodes; ``jaus_endpoint``: the JUDP/UDP endpoint; ``link_proxy``: the UDP fault proxy)
and the supervision of a multi-process run
(``ports``: listener ports; ``scheduling``: priority; ``processes``: stopping them;
``supervision``: liveness ticks and who is hung, a pure judgement). The only
layer that reads a clock or opens a socket for the stack's nodes.

Layer 6. May import ``bus``, ``vehicle``, ``servers``, ``safety``, ``dynamics``, ``messages``
and the codecs. Must not import ``scenario``, ``observe``, ``run`` or ``cli``.
"""
