"""overdrive: a drive-by-wire motion-control stack.

Planner -> move server -> driving module -> speed server and steering -> vehicle
(simulated in-process, or a ByWire XGV over JAUS 3.3).
"""

__version__ = "0.1.0"
