"""overdrive.kits: CAN drive-by-wire kits as sans-IO codecs: ``frames`` (a classic CAN frame and
the codecs' errors) and ``pacmod3`` (AutonomouStuff / Hexagon PACMod 3, from its DBC with
cantools). Bytes to typed commands and reports and back; the python-can edge that puts frames on
a bus is ``overdrive.runtime.can_edge``.

Layer 1, the bottom, beside ``messages`` and ``jaus``. May import nothing of overdrive but its own
modules (and cantools). Must not import anything above, nor open a bus or read a clock.
"""
