"""Delivery policy by kind of message (issue 20): commands and events versus periodic state.

Commands and events (MOVE/REVERSE/STOP, replies, notices, SPSS, pedal/steer/powertrain commands,
safety devices, simulator world changes) must arrive, once, in order; periodic state (sensors,
statuses) is superseded by its next sample, so a stale one may be dropped under load. The Zenoh
bus publishes each kind with matching quality of service, bounds inboxes accordingly, and the
wall-clock runtime steps a node as soon as a command of the chain it serves arrives. Pure data: no
clock, no socket.
"""

from __future__ import annotations

from overdrive.messages import Topic
from overdrive.servers.clock_offset import CLOCK_REPORT_TOPIC

COMMAND, STATE = "command", "state"
STATE_TOPICS = frozenset({
    Topic.MOVE_STATUS, Topic.DRIVING_STATUS, Topic.SPEED_STATE, Topic.VEHICLE_STATUS,
    Topic.WHEEL_SPEED, Topic.GPS_INS, Topic.IMU, Topic.RADAR, Topic.TRUTH, "launch/clock",
    CLOCK_REPORT_TOPIC, Topic.TICK,
})
"""Periodic state: each sample supersedes the last, so losing a stale one under load is harmless."""


def delivery(topic: str) -> str:
    """``STATE`` for periodic state topics, else ``COMMAND`` (reliable): unknown topics too."""
    return STATE if topic in STATE_TOPICS else COMMAND


CHAIN_TOPICS = frozenset({
    Topic.MOVE_COMMAND, Topic.STEERING, Topic.MAX_SPEED, Topic.ADVANCE, Topic.DRIVE_MODE,
    Topic.SET_SPEED,
})
"""Commands flowing down planner -> move -> driving -> speed: each wakes its receiver at once.
Not ``vehicle/*`` (the plant integrates at a fixed rate, and the move server only observes
``vehicle/steer``: a trigger there would loop move -> driving -> move) and not ``events``."""


def trigger_topics(topics: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The chain commands among a node's subscriptions: what wakes an event-driven node."""
    return tuple(t for t in topics if t in CHAIN_TOPICS)


__all__ = ["CHAIN_TOPICS", "COMMAND", "STATE", "STATE_TOPICS", "delivery", "trigger_topics"]
