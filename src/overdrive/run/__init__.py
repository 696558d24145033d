"""overdrive.run: the runners. Each composes nodes for one way of running the stack and drives
it to the end: ``sim`` (lock-step, in process), ``sweep`` (many sims), ``replay`` (a run.mcap
again), ``launch`` (one process per node over Zenoh), ``drive`` (the stack against an XGV over
JAUS/UDP), ``xgv_sim`` (a simulated XGV serving JAUS), ``move_sim`` (``move-server -s``), and
``docs`` (documents generated from the code). ``compose`` builds the node lists they share.

Layer 9. May import ``observe``, ``scenario``, ``runtime``, ``bus``, ``vehicle``, ``servers``,
``safety``, ``dynamics``, ``messages`` and the codecs. Must not import ``cli``.
"""
