"""overdrive.observe: what a run leaves behind and who judges it: the trace recorder, run.mcap
(writer and reader), CAN logs (``can_log``: candump / ASC export, replay through a kit's
decoder), the live Foxglove view, plots, run files and provenance, and the run judge
(``judge``: the independent safety monitor of whole runs, from ground truth).

The judge lives here, not in ``safety``: it watches runs from outside, over the bus taps, and
nothing in the stack may consult it. ``safety`` holds what the servers and the vehicle own.
``observe`` sits one layer above ``scenario`` (the issue put them side by side): a plot reads the
scenario recorded with a run and the run files escape names as scenario errors do, so observe
reads scenario, never the other way.

Layer 8. May import ``scenario``, ``runtime``, ``bus``, ``vehicle``, ``servers`` (for the types
it records), ``safety``, ``dynamics``, ``messages``, ``kits`` (``can_log`` decodes CAN logs).
Must not import ``run`` or ``cli``.
"""
