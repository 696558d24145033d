"""overdrive.safety: what stands between the stack and the actuators, owned by the servers
and the vehicle.

- ``gate``: the command gate. Pure limiters ``(new, last, limits) -> applied`` re-check every
  actuator command (range, NaN, throttle with brake, steering rate) after the servers and
  before the vehicle, independent of the code that produced the command.
- ``watchdog``: the silence-timeout rule (seed 001's 200 ms SPSS budget), shared by the speed
  server and the vehicle's own pedal-command timeout.
- ``plausibility``: sensor plausibility (frozen, jumping, disagreeing readings).
- ``actuators``: actuator monitoring (a brake or throttle that does not do what it is told).

The judge of whole runs is not here: it watches from outside (``overdrive.observe.judge``).

Layer 3. May import ``dynamics`` and ``messages``. Must not import ``servers``, ``vehicle`` or
anything above.
"""
