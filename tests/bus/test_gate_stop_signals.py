"""The tool gate stops on a second SIGTERM arriving inside its first handler.

The launcher sends the gate SIGTERM twice (to every process group, then to the gate alone). A
handler that takes a lock (``threading.Event.set``) deadlocks when the second signal is handled
while the first holds it: the gate then hangs until SIGKILL and writes no report, and the run's
``access["tool_denied"]`` comes out empty. Here the second signal is delivered, in turn, at every
line the first handler executes (a trace function re-enters it), in a child process so that a
deadlock fails the test instead of hanging it.
"""

from __future__ import annotations

import subprocess
import sys

from tests.bus.test_launch import ROOT
from tests.bus.waits import LOADED_TIMEOUT_S

REENTER = """
import signal, sys
from overdrive.bus.tool_gate import stop_on_signals
stopping = stop_on_signals()
handler = signal.getsignal(signal.SIGTERM)
nested = []
reentered = []

def line_tracer(frame, event, arg):
    if event == "line" and not nested:      # a second SIGTERM here, inside the first handler
        nested.append(1)
        handler(signal.SIGTERM, None)
        nested.pop()
        reentered.append(frame.f_code.co_name)
    return line_tracer

sys.settrace(lambda frame, event, arg: line_tracer)
handler(signal.SIGTERM, None)
sys.settrace(None)
print(len(stopping), len(reentered))
"""


def test_a_second_sigterm_inside_the_first_handler_still_stops_the_gate() -> None:
    try:
        done = subprocess.run([sys.executable, "-c", REENTER], cwd=ROOT, capture_output=True,
                              text=True, timeout=LOADED_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise AssertionError("the stop handler deadlocked when re-entered") from None
    assert done.returncode == 0, done.stderr
    signals, reentries = map(int, done.stdout.split())
    assert reentries >= 1, "the second signal was never delivered inside the first handler"
    assert signals == 1 + reentries, "every SIGTERM is recorded"
