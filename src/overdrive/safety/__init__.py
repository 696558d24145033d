"""overdrive.safety: what stands between the stack and the actuators, and the judge of every run.

Modules
-------
- ``gate``: the command gate. Pure limiters ``(new, last, limits) -> applied`` re-check every
  actuator command (range, NaN, throttle with brake, steering rate) after the servers and
  before the vehicle, independent of the code that produced the command.
- ``watchdog``: the silence-timeout rule (seed 001's 200 ms SPSS budget), shared by the speed
  server and the vehicle's own pedal-command timeout.
- ``monitor``: the independent safety judge on every simulated run. It judges only from ground
  truth (the path integrated from x/y), from the commands as their sources issued them, and
  from what was delivered to each node after channel faults; never from the stack's own view.

Rules of the judge (``monitor``; docs/reliability.md, hazard log in docs/safety-case.md)
---------------------------------------------------------------------------------------
1. ``authorization``: no travel past the end of a MOVE / REVERSE / advance, fixed where the
   vehicle truly was when the command was issued (STOP: stop now); a command shorter than the
   shortest physical stop is noted and judged against that stop; the largest overrun is reported.
2. ``direction``: no travel of more than 0.10 m against the commanded direction, nor before the
   first command.
3. ``speed``: no more than 0.3 m/s above the lowest live limit for longer than 0.5 s.
4. ``unintended_motion``: no motion after a pause, manual override or e-stop disable ends until
   a command issued after it.
5. ``watchdog``: an emergency stop within 200 ms + one period of the last SPSS delivered.
6. ``finite``: no NaN or infinity in ground truth or in any command.
7. ``throttle_while_braking``, 8. ``control``, 9. ``acceleration_ellipse``,
10. ``estop_precedence``, 11. ``contact``.

Import the modules themselves (``overdrive.safety.monitor``): the vehicle simulator imports the
gate, and the monitor knows the simulator's world topic, so this package imports nothing eagerly.
"""

RULES = ("authorization", "direction", "speed", "unintended_motion", "watchdog", "finite",
         "throttle_while_braking", "control", "acceleration_ellipse", "estop_precedence", "contact")
"""The judge's rules, in the order of the docstring above."""

__all__ = ["RULES"]
