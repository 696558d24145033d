"""Link faults for datagrams (``overdrive link-proxy``): loss, delay, jitter and cuts, decided
per datagram. Pure and clock-free: the caller passes each datagram's arrival time (seconds
since the link's origin) and gets back when to deliver it, or ``None`` (lost).

One ``LinkFaults`` per direction; each draws from its own generator seeded from the spec's
seed and the direction, so a run with the same seed and the same arrival order makes the same
decisions (``tests/xgv/test_link_proxy.py``). Per datagram, in this order: inside a cut
(``at_s <= t < at_s + for_s``) it is lost; before ``start_s`` it passes untouched (the link
comes up clean, then degrades); else lost with probability ``loss``; else delivered at
``t + delay_s + U(0, jitter_s)``. Jitter larger than the gap between datagrams
reorders them, as a real network does. ``way`` puts every fault on one direction only (a
link delayed or cut one way: an asymmetric route, a half-duplex radio); the other passes.
"""

from __future__ import annotations

import math
import random
from typing import Final

import msgspec

MAX_DELAY_S: Final = 60.0          # a delay or jitter beyond this is a cut, not a delay
MAX_CUT_S: Final = 86_400.0        # one day: the longest run anyone tests
DIRECTIONS: Final = ("to-vehicle", "from-vehicle")
WAYS: Final = ("both", *DIRECTIONS)   # which way the faults act (``LinkFaultSpec.way``)


class LinkFaultSpec(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """What to do to every datagram, both ways or one (validated on construction)."""

    loss: float = 0.0                                  # probability each datagram is lost
    delay_s: float = 0.0                               # added to every datagram kept
    jitter_s: float = 0.0                              # plus uniform in [0, jitter_s]
    cuts: tuple[tuple[float, float], ...] = ()         # (at_s, for_s): nothing passes
    start_s: float = 0.0                               # loss, delay, jitter from here on
    seed: int = 0
    way: str = "both"                                  # or one direction: the other passes

    def __post_init__(self) -> None:
        if self.way not in WAYS:
            raise ValueError(f"way: one of {WAYS}, got {self.way!r}")
        if not 0.0 <= self.loss <= 1.0:   # also refuses NaN
            raise ValueError(f"loss: a fraction in [0, 1], got {self.loss!r}")
        for name in ("delay_s", "jitter_s"):
            value = getattr(self, name)
            if not 0.0 <= value <= MAX_DELAY_S:
                raise ValueError(f"{name}: in [0, {MAX_DELAY_S}] s, got {value!r}")
        if not 0.0 <= self.start_s <= MAX_CUT_S:
            raise ValueError(f"start_s: in [0, {MAX_CUT_S}] s, got {self.start_s!r}")
        for at_s, for_s in self.cuts:
            if not (0.0 <= at_s <= MAX_CUT_S and 0.0 < for_s <= MAX_CUT_S):
                raise ValueError(f"cut: AT_S in [0, {MAX_CUT_S}] and FOR_S in (0, "
                                 f"{MAX_CUT_S}] s, got {at_s!r}:{for_s!r}")
        if not 0 <= self.seed < 2**63:
            raise ValueError(f"seed: in [0, 2^63), got {self.seed!r}")


class LinkFaults:
    """The decisions for one direction of a link (see the module docstring)."""

    def __init__(self, spec: LinkFaultSpec, direction: str) -> None:
        if direction not in DIRECTIONS:
            raise ValueError(f"direction: one of {DIRECTIONS}, got {direction!r}")
        self.spec = spec
        self.direction = direction
        self.rng = random.Random(f"{spec.seed}/{direction}")   # str seeds are deterministic
        self.counts = {"forwarded": 0, "lost": 0, "cut": 0}

    def in_cut(self, t_s: float) -> bool:
        return any(at_s <= t_s < at_s + for_s for at_s, for_s in self.spec.cuts)

    def decide(self, t_s: float) -> float | None:
        """When a datagram arriving at ``t_s`` is delivered, or ``None``: lost."""
        if not math.isfinite(t_s):
            raise ValueError(f"arrival time: finite, got {t_s!r}")
        spec = self.spec
        if spec.way not in ("both", self.direction):   # a fault one way: this way is clean
            self.counts["forwarded"] += 1
            return t_s
        if self.in_cut(t_s):
            self.counts["cut"] += 1
            return None
        if t_s < spec.start_s:
            self.counts["forwarded"] += 1
            return t_s
        if spec.loss > 0.0 and self.rng.random() < spec.loss:
            self.counts["lost"] += 1
            return None
        self.counts["forwarded"] += 1
        jitter = self.rng.uniform(0.0, spec.jitter_s) if spec.jitter_s > 0.0 else 0.0
        return t_s + spec.delay_s + jitter


def parse_cut(text: str) -> tuple[float, float]:
    """``AT_S:FOR_S`` (seconds) as given on the command line; ValueError saying why."""
    at, sep, length = text.partition(":")
    try:
        if not sep:
            raise ValueError
        at_s, for_s = float(at), float(length)
    except ValueError:
        raise ValueError(f"--cut: expected AT_S:FOR_S in seconds, got {text!r}") from None
    if not (math.isfinite(at_s) and math.isfinite(for_s)):
        raise ValueError(f"--cut: finite numbers, got {text!r}")
    return at_s, for_s


__all__ = ["DIRECTIONS", "WAYS", "LinkFaultSpec", "LinkFaults", "parse_cut"]
