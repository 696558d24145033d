"""A classic CAN frame as the kit codecs see it: an identifier and up to 8 bytes. No bus, no clock.

The python-can edge (``overdrive.runtime.can_edge``) turns ``can.Message`` into ``CanFrame`` and
back; every codec below takes and gives only these.
"""

from __future__ import annotations

import msgspec

CAN_STANDARD_ID_MAX = 0x7FF
"""11-bit identifier (ISO 11898-1 base frame format)."""
CAN_EXTENDED_ID_MAX = 0x1FFFFFFF
"""29-bit identifier (extended frame format)."""
CAN_CLASSIC_DATA_MAX_BYTES = 8
"""Classic CAN carries at most 8 data bytes; the kits here use no CAN FD."""


class KitError(ValueError):
    """Anything a kit codec refuses."""


class KitDecodeError(KitError):
    """Bytes that are not a valid frame of the kit: wrong length, bad counter or complement."""


class UnknownFrame(KitDecodeError):
    """An identifier the kit's protocol does not define (counted, never acted on)."""


class KitEncodeError(KitError):
    """A command that cannot be put on the wire as asked: out of range, NaN or infinite."""


class CanFrame(msgspec.Struct, frozen=True, kw_only=True):
    """One classic CAN data frame: ``arbitration_id`` (11 or 29 bits) and ``data`` (0-8 bytes)."""

    arbitration_id: int
    data: bytes
    is_extended: bool = False

    def __post_init__(self) -> None:
        top = CAN_EXTENDED_ID_MAX if self.is_extended else CAN_STANDARD_ID_MAX
        if not 0 <= self.arbitration_id <= top:
            raise KitDecodeError(f"CAN id 0x{self.arbitration_id:X} outside 0..0x{top:X}")
        if len(self.data) > CAN_CLASSIC_DATA_MAX_BYTES:
            raise KitDecodeError(f"CAN id 0x{self.arbitration_id:X}: {len(self.data)} data "
                                 f"bytes, classic CAN carries at most 8")

    def __str__(self) -> str:
        """candump's short form: ``123#DEADBEEF``."""
        width = 8 if self.is_extended else 3
        return f"{self.arbitration_id:0{width}X}#{self.data.hex().upper()}"
