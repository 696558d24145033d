"""Delivery policy by kind of message (issue 20): commands and events versus periodic state.

Commands and events (MOVE/REVERSE/STOP, replies, notices, SPSS, pedal/steer/powertrain commands,
safety devices, simulator world changes) must arrive, once, in order; periodic state (sensors,
statuses) is superseded by its next sample, so a stale one may be dropped under load. The Zenoh
bus publishes each kind with matching quality of service, bounds inboxes accordingly, and the
wall-clock runtime steps a node as soon as a command it subscribes to arrives. Pure data: no
clock, no socket.
"""

from __future__ import annotations

from overdrive.messages import Topic

COMMAND, STATE = "command", "state"
STATE_TOPICS = frozenset({
    Topic.MOVE_STATUS, Topic.DRIVING_STATUS, Topic.SPEED_STATE, Topic.VEHICLE_STATUS,
    Topic.WHEEL_SPEED, Topic.GPS_INS, Topic.IMU, Topic.RADAR, Topic.TRUTH, "launch/clock",
})
"""Periodic state: each sample supersedes the last, so losing a stale one under load is harmless."""


def delivery(topic: str) -> str:
    """``STATE`` for periodic state topics, else ``COMMAND`` (reliable): unknown topics too."""
    return STATE if topic in STATE_TOPICS else COMMAND


def command_topics(topics: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """The command topics among ``topics``: what wakes an event-driven node."""
    return tuple(t for t in topics if t not in STATE_TOPICS)


__all__ = ["COMMAND", "STATE", "STATE_TOPICS", "command_topics", "delivery"]
