"""overdrive.cli: the ``overdrive`` command (click): parses flags, calls a runner, prints.

Layer 10 of 10, the top. May import every layer below (``run``, ``observe``, ``scenario``,
``runtime``, ``bus``, ...). Must not import: nothing is above it, and nothing below may import
it. Holds no logic a script would need: everything it does is a call into ``overdrive.run`` or
``overdrive.observe``.
"""
