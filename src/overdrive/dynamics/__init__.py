"""overdrive.dynamics: vehicle parameters (``vehicle_params``: their fields, plausible ranges
and validation from plain data; the shipped vehicle files in ``vehicles/``, read by
``overdrive.scenario.vehicles``), the acceleration ellipse and stopping distances
(``ellipse``), control primitives (``control``: PID, limiters, lags), the longitudinal loop
shared by the speed server and the XGV's own loops (``speed_control``) and what counts as a
usable number (``validation``).

Layer 2: pure functions and data, no clock, no I/O. May import ``messages`` only. Must not
import ``safety``, ``servers``, ``vehicle`` or anything above.
"""
