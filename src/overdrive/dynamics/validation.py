"""Input validation shared by every node: what counts as a usable number."""

from __future__ import annotations

import math
import sys
from typing import Any

FLOAT_MAX_INT = int(sys.float_info.max)
"""The largest integer a float holds: a larger one is no finite number here."""


def finite(*values: Any) -> bool:
    """Every value is a finite real number (bools are not numbers here).

    A plain loop, checked for floats first: it runs on every incoming message.
    """
    for v in values:
        if type(v) is not float:
            if not isinstance(v, (int, float)) or isinstance(v, bool):
                return False
            if isinstance(v, int) and not -FLOAT_MAX_INT <= v <= FLOAT_MAX_INT:
                return False      # beyond any float: math.isfinite would raise OverflowError
        if not math.isfinite(v):
            return False
    return True


def valid_sigma(value: Any) -> bool:
    """A reported 1-sigma that is absent (None) or a finite number >= 0 (``GpsIns``)."""
    return value is None or (finite(value) and value >= 0.0)
