"""Input validation shared by every node: what counts as a usable number."""

from __future__ import annotations

import math
from typing import Any


def finite(*values: Any) -> bool:
    """Every value is a finite real number (bools are not numbers here).

    A plain loop, checked for floats first: it runs on every incoming message.
    """
    for v in values:
        if type(v) is not float and (not isinstance(v, (int, float)) or isinstance(v, bool)):
            return False
        if not math.isfinite(v):
            return False
    return True
