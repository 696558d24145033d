"""overdrive.scenario: the scenario file: its schema and validation (``schema``), hostile-input
safe YAML/JSON reading (``safe_yaml``), the vehicle files and the shipped presets read from them
(``vehicles``), the player that turns events into bus messages (``player``) and the
expectations (``expect``). Channel faults are the bus's (``overdrive.bus.faults``).

Layer 7. May import ``runtime``, ``bus``, ``vehicle``, ``servers``, ``safety``, ``dynamics``,
``messages``. Must not import ``observe``, ``run`` or ``cli``.
"""
