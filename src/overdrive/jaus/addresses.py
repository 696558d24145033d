"""JAUS IDs and the ByWire XGV's well-known addresses.

A JAUS ID names one component instance as ``subsystem.node.component.instance``
(reference §1: each part one byte, 0 invalid, 255 broadcast). The XGV addresses and the
client defaults come from reference §7.
"""

from __future__ import annotations

from enum import IntEnum
from typing import Final

import msgspec

BROADCAST: Final = 255
"""Reference §1: an ID part of 255 addresses every subsystem/node/component/instance."""

INVALID: Final = 0
"""Reference §1: an ID part of 0 is invalid."""


class JausId(msgspec.Struct, frozen=True, order=True):
    """A component address, written ``subsystem.node.component.instance``."""

    subsystem: int
    node: int
    component: int
    instance: int = 1

    def __post_init__(self) -> None:
        for part in (self.subsystem, self.node, self.component, self.instance):
            if type(part) is not int or not 0 <= part <= 255:
                raise ValueError(f"JAUS ID parts must be integers 0..255, got {self!r}")

    @classmethod
    def parse(cls, text: str) -> JausId:
        """Parse ``"1.1.33.1"``; raises ``ValueError`` on anything else."""
        parts = text.strip().split(".")
        if len(parts) != 4 or not all(p.isdigit() for p in parts):
            raise ValueError(
                f"expected a JAUS ID 'subsystem.node.component.instance', got {text!r}"
            )
        return cls(*(int(p) for p in parts))

    def __str__(self) -> str:
        return f"{self.subsystem}.{self.node}.{self.component}.{self.instance}"

    @property
    def is_valid(self) -> bool:
        """False when any part is 0 (reference §1)."""
        return INVALID not in (self.subsystem, self.node, self.component, self.instance)

    @property
    def is_broadcast(self) -> bool:
        """True when any part is 255, i.e. the ID addresses a group."""
        return BROADCAST in (self.subsystem, self.node, self.component, self.instance)

    def matches(self, other: JausId) -> bool:
        """True when a message sent to ``self`` reaches ``other`` (255 matches any part)."""
        return all(
            BROADCAST in (a, b) or a == b
            for a, b in (
                (self.subsystem, other.subsystem),
                (self.node, other.node),
                (self.component, other.component),
                (self.instance, other.instance),
            )
        )


class XgvComponent(IntEnum):
    """Component ids on the ByWire XGV controller (reference §7)."""

    NODE_MANAGER = 1
    MOTION_PROFILE_DRIVER = 10
    SIGNALS_DRIVER = 11
    ERROR_MANAGER = 12
    PRIMITIVE_DRIVER = 33


XGV_SUBSYSTEM: Final = 1  # reference §7: "subsystem 1, node 1 by default"
XGV_NODE: Final = 1
XGV_INSTANCE: Final = 1  # reference §7: "instance 1"
CLIENT_COMPONENT: Final = 4  # reference §7: "clients commonly use component id 4"
DEFAULT_AUTHORITY: Final = 6  # reference §7: "... and authority 6"


def xgv_id(
    component: int,
    *,
    subsystem: int = XGV_SUBSYSTEM,
    node: int = XGV_NODE,
    instance: int = XGV_INSTANCE,
) -> JausId:
    """The ID of an XGV component, e.g. ``xgv_id(XgvComponent.PRIMITIVE_DRIVER)`` -> 1.1.33.1."""
    return JausId(subsystem, node, int(component), instance)


XGV_NODE_MANAGER: Final = xgv_id(XgvComponent.NODE_MANAGER)
XGV_MOTION_PROFILE_DRIVER: Final = xgv_id(XgvComponent.MOTION_PROFILE_DRIVER)
XGV_SIGNALS_DRIVER: Final = xgv_id(XgvComponent.SIGNALS_DRIVER)
XGV_ERROR_MANAGER: Final = xgv_id(XgvComponent.ERROR_MANAGER)
XGV_PRIMITIVE_DRIVER: Final = xgv_id(XgvComponent.PRIMITIVE_DRIVER)

DEFAULT_CLIENT_ID: Final = JausId(XGV_SUBSYSTEM, 2, CLIENT_COMPONENT, 1)
"""Default source of client messages: subsystem 1, node 2 (the XGV is node 1), component 4,
as in the Set Motion Profile reference vector (reference §8)."""
