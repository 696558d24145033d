"""Recording a run: trace rows, the event list and peaks, observed from the bus.

The recorder is a bus tap, not a node: it sees every message as published (before channel
faults) and never feeds anything back into the stack. Speed-state, safety-mode and hint events
are derived from state messages; faults, e-stops and rejections come from ``Notice`` messages.
"""

from __future__ import annotations

import csv
import io
import math
from typing import IO, Any

from overdrive.messages import Notice, Topic

TRACE_COLUMNS = (
    "t_s", "x_m", "y_m", "heading_rad", "speed_mps", "accel_mps2", "lat_accel_mps2",
    "curvature_1pm", "throttle_pct", "brake_pct", "steer_pct", "gear", "speed_state",
    "safety_mode", "goal_speed_mps", "authorized_m",
    # beyond the contract
    "odometer_m", "pitch_rad", "throttle_cmd_pct", "brake_cmd_pct", "steer_cmd_pct", "engine",
    "traction_control", "radar_range_m", "hint", "fault",
)


def _fmt(value: float | None) -> str:
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.4f}"


class Recorder:
    def __init__(self, trace_file: IO[str] | None = None, keep_rows: bool = False) -> None:
        self.latest: dict[str, Any] = {}
        self.events: list[dict[str, Any]] = []
        self.rows: list[dict[str, str]] | None = [] if keep_rows else None
        self._writer = csv.writer(trace_file, lineterminator="\n") if trace_file else None
        if self._writer:
            self._writer.writerow(TRACE_COLUMNS)
        self.now_s = 0.0
        self.max_speed_mps = 0.0
        self.max_accel_mps2 = 0.0
        self.max_decel_mps2 = 0.0
        self.max_lat_accel_mps2 = 0.0
        self.contact_at_s: float | None = None
        self.states_seen: set[str] = set()
        self.modes_seen: set[str] = set()
        self._speed_state: str | None = None
        self._hint = "none"
        self._safety_mode: str | None = None
        self.counts: dict[str, int] = {}
        self.moves_accepted = 0            # MOVE / REVERSE replies: accepted, refused
        self.moves_refused = 0
        self.first_refusal = ""
        self._handlers = {Topic.NOTICE: self._notice, Topic.SPEED_STATE: self._speed_state_msg,
                          Topic.VEHICLE_STATUS: self._vehicle_status,
                          Topic.MOVE_REPLY: self._move_reply}
        self._trace_file = trace_file
        self._plain_text: dict[Any, bool] = {}   # value -> the csv module writes it as str(value)

    # ------------------------------------------------------------------ bus tap

    def observe(self, topic: str, msg: Any) -> None:
        self.latest[topic] = msg
        counts = self.counts
        counts[topic] = counts.get(topic, 0) + 1
        handler = self._handlers.get(topic)
        if handler is not None:
            handler(msg)

    def _speed_state_msg(self, msg: Any) -> None:
        if msg.state != self._speed_state:
            if self._speed_state is not None:
                self._event("speed_state", **{"from": self._speed_state, "to": msg.state})
            self._speed_state = msg.state
            self.states_seen.add(msg.state)
        if msg.hint != self._hint:
            if msg.hint != "none":
                self._event("hint", hint=msg.hint)
            self._hint = msg.hint

    def _vehicle_status(self, msg: Any) -> None:
        if msg.safety_mode != self._safety_mode:
            if self._safety_mode is not None:
                self._event("safety_mode", **{"from": self._safety_mode, "to": msg.safety_mode})
            self._safety_mode = msg.safety_mode
            self.modes_seen.add(msg.safety_mode)

    def _move_reply(self, msg: Any) -> None:
        if msg.kind != "stop":
            if msg.accepted:
                self.moves_accepted += 1
            else:
                self.moves_refused += 1
                self.first_refusal = self.first_refusal or f"{msg.code}: {msg.message}"
        if not msg.accepted:
            self._event("rejected", command=msg.kind, reason=msg.code, message=msg.message,
                        command_id=msg.command_id)

    def _notice(self, msg: Notice) -> None:
        fields: dict[str, Any] = {"source": msg.source}
        if msg.kind == "fault":
            fields["code"] = msg.code
            fields["message"] = msg.reason
        else:
            if msg.code:
                fields["code"] = msg.code
            fields["reason"] = msg.reason
        if msg.kind == "rejected" and "command" not in fields:
            fields["command"] = msg.code or msg.source
        self._event(msg.kind, **fields)

    def _event(self, kind: str, **fields: Any) -> None:
        self.events.append({"t_s": round(self.now_s, 4), "kind": kind, **fields})

    # ------------------------------------------------------------------ per tick

    def tick(self, now_s: float) -> None:
        """Write one trace row for time ``now_s`` from the latest messages."""
        self.now_s = now_s
        latest = self.latest
        truth = latest.get(Topic.TRUTH)
        if truth is None:
            return
        speed = abs(truth.speed_mps)
        if speed > self.max_speed_mps:
            self.max_speed_mps = speed
        a = truth.accel_mps2 if truth.speed_mps >= 0 else -truth.accel_mps2
        if a > self.max_accel_mps2:
            self.max_accel_mps2 = a
        if -a > self.max_decel_mps2:
            self.max_decel_mps2 = -a
        lat = abs(truth.lat_accel_mps2)
        if lat > self.max_lat_accel_mps2:
            self.max_lat_accel_mps2 = lat
        if truth.contact and self.contact_at_s is None:
            self.contact_at_s = now_s
            self._event("contact", reason="vehicle footprint touched an obstacle")
        if self._writer is None and self.rows is None:
            return
        if self.rows is None and self._write_fast_row(now_s, truth):
            return
        status = latest.get(Topic.VEHICLE_STATUS)
        speed_state = latest.get(Topic.SPEED_STATE)
        driving = latest.get(Topic.DRIVING_STATUS)
        pedals = latest.get(Topic.PEDALS)
        steer = latest.get(Topic.STEER)
        radar = latest.get(Topic.RADAR)
        row = (
            f"{now_s:.2f}", _fmt(truth.x_m), _fmt(truth.y_m), _fmt(truth.heading_rad),
            _fmt(truth.speed_mps), _fmt(truth.accel_mps2), _fmt(truth.lat_accel_mps2),
            _fmt(truth.curvature_1pm),
            _fmt(status.throttle_pct) if status else "", _fmt(status.brake_pct) if status else "",
            _fmt(status.steer_pct) if status else "", status.gear if status else "",
            speed_state.state if speed_state else "", status.safety_mode if status else "",
            _fmt(driving.goal_speed_mps) if driving else "",
            _fmt(driving.authorized_m) if driving else "",
            _fmt(truth.odometer_m), _fmt(truth.pitch_rad),
            _fmt(pedals.throttle_pct) if pedals else "", _fmt(pedals.brake_pct) if pedals else "",
            _fmt(steer.steer_pct) if steer else "", status.engine if status else "",
            "1" if status and status.traction_control else "0",
            _fmt(radar.range_m) if radar and radar.target else "",
            speed_state.hint if speed_state else "", str(speed_state.fault) if speed_state else "",
        )
        if self._writer is not None:
            self._writer.writerow(row)
        if self.rows is not None:
            self.rows.append(dict(zip(TRACE_COLUMNS, row, strict=True)))

    def _write_fast_row(self, now_s: float, truth: Any) -> bool:
        """Write the row ``tick`` would write, with one ``%`` format; False when it cannot.

        Formatting the row field by field and through ``csv.writer`` cost more than the rest of
        the recorder together. This path applies when every message of the row is there, the
        always-written numbers are finite and the text fields need no csv quoting; it writes
        the same bytes (``"%.4f" % x == f"{x:.4f}"``; the optional numbers go through ``_fmt``).
        """
        latest = self.latest
        status = latest.get(Topic.VEHICLE_STATUS)
        speed_state = latest.get(Topic.SPEED_STATE)
        driving = latest.get(Topic.DRIVING_STATUS)
        pedals = latest.get(Topic.PEDALS)
        steer = latest.get(Topic.STEER)
        if status is None or speed_state is None or driving is None or pedals is None \
                or steer is None:
            return False
        numbers = (truth.x_m, truth.y_m, truth.heading_rad, truth.speed_mps, truth.accel_mps2,
                   truth.lat_accel_mps2, truth.curvature_1pm, status.throttle_pct,
                   status.brake_pct, status.steer_pct, truth.odometer_m, truth.pitch_rad,
                   pedals.throttle_pct, pedals.brake_pct, steer.steer_pct)
        texts = (status.gear, speed_state.state, status.safety_mode, status.engine,
                 speed_state.hint, speed_state.fault)
        plain = self._plain_text
        try:
            for text in texts:
                if not plain.get(text, False) and not self._check_plain(text):
                    return False
            if not math.isfinite(sum(numbers)):   # NaN or inf somewhere: let _fmt decide
                return False
        except TypeError:   # not a number, or an unhashable text: the csv path handles it
            return False
        radar = latest.get(Topic.RADAR)
        self._trace_file.write(_ROW_FORMAT % (
            now_s, *numbers[:10], status.gear, speed_state.state, status.safety_mode,
            _fmt(driving.goal_speed_mps), _fmt(driving.authorized_m), *numbers[10:],
            status.engine, "1" if status.traction_control else "0",
            _fmt(radar.range_m) if radar and radar.target else "", speed_state.hint,
            speed_state.fault))
        return True

    def _check_plain(self, value: Any) -> bool:
        """True (and remembered) when ``csv.writer`` writes ``value`` as ``%s`` would."""
        out = io.StringIO()
        csv.writer(out, lineterminator="\n").writerow((value, ""))
        plain = out.getvalue() == f"{value},\n" and isinstance(value, (str, int))
        if plain:
            self._plain_text[value] = True
        return plain


_ROW_FORMAT = ("%.2f," + "%.4f," * 10 + "%s," * 5 + "%.4f," * 5 + "%s," * 4 + "%s\n")
"""One trace row (``TRACE_COLUMNS``) for ``Recorder._write_fast_row``."""
