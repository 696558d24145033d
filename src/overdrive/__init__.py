"""overdrive: a drive-by-wire motion-control stack.

Planner -> move server -> driving module -> speed server and steering -> vehicle
(simulated in-process, a ByWire XGV over JAUS 3.3, a CAN drive-by-wire kit).

The package is layered; each folder imports only from layers below it (``LAYERS``, top
first; folders on one layer do not import each other). ``tests/test_import_layers.py`` holds the
code to it and ``docs/architecture.md`` is generated from it.
"""

__version__ = "0.1.0"

LAYERS: tuple[tuple[str, ...], ...] = (
    ("cli",),
    ("run",),
    ("observe",),
    ("scenario",),
    ("runtime",),
    ("bus",),
    ("vehicle", "servers"),
    ("safety",),
    ("dynamics",),
    ("messages", "jaus", "kits", "fuzzing"),
)
"""Top to bottom. A name is a folder (``overdrive/<name>/``) or, on the bottom layer, a module
(``messages``, ``fuzzing``); the protocol codecs (``jaus``, later the CAN kits and ROS 2 CDR)
sit at the bottom, socket-free."""
