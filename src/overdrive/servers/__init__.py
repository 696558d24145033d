"""overdrive.servers: the control stack's servers, each a plain object stepped with the time
passed in (``step(now_s, inbox) -> outbox``): the move server (seed 004: ``move`` and its
planner, feasibility, conditions, radar failsafe, adaptation), the driving module (seed 003:
``driving``, gear hints, direction hold) and the speed server (seed 001: ``speed``, its
transition table, hints).

Layer 4 (beside ``vehicle``, which it does not import). May import ``safety``, ``dynamics``,
``messages``. Must not import ``vehicle``, ``bus``, ``runtime`` or anything above; never a
clock or a socket.
"""
