"""Condition waits for wall-clock tests, sized for a loaded 2-core host."""

from __future__ import annotations

import time
from collections.abc import Callable

LOADED_TIMEOUT_S = 30.0
"""Conditions come true in milliseconds on an idle host; a 2-core host with both cores busy can
starve Zenoh's threads for seconds, so waits end on the condition with this generous bound."""
POLL_S = 0.005     # how often a condition is re-checked (not a delay the test depends on)


def wait_for(predicate: Callable[[], bool], timeout_s: float = LOADED_TIMEOUT_S) -> bool:
    """True as soon as ``predicate()`` is; False if it is still false after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(POLL_S)
    return predicate()
