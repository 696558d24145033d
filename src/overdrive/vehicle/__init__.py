"""overdrive.vehicle: the vehicles the stack drives, as sans-IO objects: the physics (``plant``),
the simulated vehicle as a node (``sim_node``), the XGV's modes (``modes``), the simulated XGV
(``xgv``), the stack's JAUS client (``xgv_client``) and a plain JAUS 3.3 vehicle profile
(``plain_jaus``), and the link's time from its reports' stamps (``link_time``). Bytes in and
out, time passed in: the sockets are in ``runtime``.

Layer 4 (beside ``servers``, which it does not import). May import ``safety``, ``dynamics``,
``messages`` and the codecs. Must not import ``servers``, ``bus`` or anything above.
"""
