"""The move server's forward-radar corridor and its reverse limits (seed 004's VORAD failsafe).

The VORAD sees a narrow cone (12 deg) and reports the nearest target in it; the vehicle needs
a corridor as wide as itself. So the radar alone forgets a target that is inside the
vehicle's width but off the centre line as soon as it leaves the cone (issue 16). This module:

- **remembers** every target a trusted reading reports, in a dead-reckoned local frame (issue
  30: the pose at the reading is the conservative progress, integrated along the integrated
  gyro yaw rate, never the GPS/INS pose, whose position and heading can step when an RTK fix
  drops to float), until the vehicle has passed it, or a later trusted reading sees through
  its place (the point lies well inside the cone, nearer than what the radar now reports).
  "Passed" needs the pose AND the conservative progress since the last sighting (more than the
  target's distance then). The frame drifts only as odometry and gyro do (over the ~6 m a
  target 0.6 m off the centre line is remembered outside the cone: a 1 % odometry error is
  0.06 m; a 0.01 rad/s gyro bias at 2 m/s turns it 0.03 rad, 0.18 m); an over-reading odometer
  moves the vehicle towards its targets (it stops short);
- judges the **corridor** along the predicted path: the arc of the commanded and of the
  measured (steering) curvature, as wide as the vehicle plus ``corridor_margin_m`` on each
  side (plus what the front corner swings out in a curve), and gives the path distance from
  the front bumper to the nearest remembered target in it (``nearest_m``), which the move
  server's emergency stop uses instead of the raw range;
- watches the radar's **health**: no reading for ``timeout_s`` is fault 1151 (silent); readings
  that repeat (the same alive counter ``seq``, or the same target range while the vehicle
  travelled ``frozen_travel_m``) are fault 1152 (frozen). While untrusted, the forward
  authorization is capped by the last verified clear range minus the travel since
  (``forward_cap_m``), so the vehicle stops before the end of what was seen clear;
- **reversing has no radar**: a REVERSE is clamped (``clamp_reverse``) to
  ``reverse_max_speed_mps`` and to the ground verified clear behind: the track the vehicle's
  rear bumper swept while driving forward (its own footprint covered it), followed back along
  the REVERSE's arc, plus ``reverse_blind_m`` of unverified ground, once per reverse (a
  stream of REVERSE commands shares it).

Limits (docs/move-server.md, "Radar corridor and reverse limits"): the cone does not see the
path of a tight curve (for curvature above ~tan(6 deg) / (2 x front overhang from the axle),
~0.014 1/m on both presets, no point of the arc's centre line ever enters the cone): there the
failsafe protects only what it saw before the curve; targets nearer than ~11 m at the
corridor's edge are outside the cone from a standstill (the start-up blind wedge); a frozen
radar without an alive counter and without a target cannot be told from a clear road.
"""

from __future__ import annotations

import enum
import itertools
import math
from collections import deque
from collections.abc import Iterable

import msgspec

from overdrive.dynamics.vehicle_params import VehicleParams
from overdrive.messages import GpsIns, MoveCommand, Notice, Radar

SOURCE = "move"
STRAIGHT_1PM = 1e-6   # below this curvature the arc is treated as a straight line


class RadarFault(enum.IntEnum):
    """Numbered faults of the radar corridor (issue 16 range 1151-1159)."""

    SILENT = 1151   # no radar reading for longer than ``timeout_s``
    FROZEN = 1152   # the same reading repeated (alive counter, or target range while moving)


class RadarConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """Tuning of the corridor; every default says where it comes from."""

    fitted: bool = True                 # False: the vehicle has no radar (an XGV over JAUS: the
                                        # planner owns the clearance ahead, hazard H22)
    corridor_margin_m: float = 0.3      # each side: GPS/INS 0.02 m + path tracking at turn-in
                                        # (steering lag), ~15 % of the vehicles' half width
    timeout_s: float = 0.2              # same as the GPS/INS timeout: 3 VORAD cycles (~15 Hz)
    frozen_travel_m: float = 0.5        # a static target's range must change by this much:
                                        # 5x a VORAD's ~0.1 m range resolution
    see_through_m: float = 1.0          # a remembered point is gone when the radar reports this
                                        # much beyond it: 10x the range resolution + GPS noise
    see_through_angle_rad: float = 0.02  # ...and the point lies this far inside the cone
                                        # (heading noise and a target's angular extent)
    merge_m: float = 0.3                # a new reading this close to a remembered one is the same
                                        # target (10x the GPS/INS position noise)
    merge_readings: int = 20            # running mean over up to this many readings (0.2 s):
                                        # GPS/INS noise / 4.5, still follows a slow target
    max_targets: int = 32               # memory bound (nearest kept): ~a cone full of clutter
    hold_gap_m: float = 1.0             # untrusted radar: stop this much more short of the end
                                        # of the verified range than the e-stop margin
    reverse_max_speed_mps: float = 2.5  # issue 31 item 9 (was 1.5, walking pace): a STOP from it
                                        # stops both presets within reverse_blind_m (0.47-0.68 m
                                        # on 0 / +-5 %); no rear sensor: any surprise at low speed
    reverse_blind_m: float = 1.0        # policy: unverified ground a REVERSE may back into (less
                                        # than a rear parking aid's ~1.5 m zone would have seen)
    trail_spacing_m: float = 0.25       # rear-bumper track resolution
    trail_length_m: float = 60.0        # how much of the own track is kept (240 points)
    trail_tolerance_m: float = 0.15     # the reverse path may deviate this much from the track
                                        # (segments between its points): GPS noise 0.02 m x 3,
                                        # path tracking at 1.5 m/s


class Pose(msgspec.Struct, frozen=True):
    x_m: float
    y_m: float
    heading_rad: float


def to_vehicle(pose: Pose, x_m: float, y_m: float) -> tuple[float, float]:
    """(along, left) of a world point from the rear axle, along the heading."""
    c, s = math.cos(pose.heading_rad), math.sin(pose.heading_rad)
    dx, dy = x_m - pose.x_m, y_m - pose.y_m
    return dx * c + dy * s, -dx * s + dy * c


def path_offset(along_m: float, left_m: float, curvature_1pm: float, front_m: float,
                half_width_m: float) -> tuple[float, float, float]:
    """(path distance, offset, outer half width) of a point on the arc of ``curvature_1pm``.

    The path distance is how far the rear axle travels until the front bumper reaches the
    point (negative: passed); the offset is the point's distance from the path's centre line
    (signed outward of the curve; left on a straight); the outer half width is what the body
    covers on the outside (the front corner swings out in a curve)."""
    k = curvature_1pm
    if abs(k) < STRAIGHT_1PM:
        return along_m - front_m, left_m, half_width_m
    radius = 1.0 / abs(k)
    u = (1.0 + k * left_m) * radius          # component along the centre -> axle direction
    rho = math.hypot(along_m, u)
    theta = math.atan2(along_m, u)           # angle still to turn until the point is abeam
    lead = math.asin(min(1.0, front_m / rho)) if rho > 0.0 else 0.5 * math.pi
    outer = math.hypot(radius + half_width_m, front_m) - radius
    return radius * (theta - lead), rho - radius, outer


def in_corridor(offset_m: float, outer_m: float, half_width_m: float, margin_m: float,
                curvature_1pm: float) -> bool:
    if abs(curvature_1pm) < STRAIGHT_1PM:
        return abs(offset_m) <= half_width_m + margin_m
    return -(half_width_m + margin_m) <= offset_m <= outer_m + margin_m


def segment_distance_m(x_m: float, y_m: float, a: tuple[float, float],
                       b: tuple[float, float]) -> float:
    """Distance from a point to the segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n2 = dx * dx + dy * dy
    t = 0.0 if n2 == 0.0 else min(1.0, max(0.0, ((x_m - a[0]) * dx + (y_m - a[1]) * dy) / n2))
    return math.hypot(x_m - a[0] - t * dx, y_m - a[1] - t * dy)


class RadarCorridor:
    """Memory, corridor, health and reverse limits; see the module docstring."""

    def __init__(self, params: VehicleParams, config: RadarConfig | None = None) -> None:
        self.params = params
        self.config = cfg = config or RadarConfig()
        self.fitted = cfg.fitted   # no radar: no health faults
        self.front_m = params.length_m - params.rear_overhang_m   # rear axle -> front bumper
        self.half_width_m = 0.5 * params.width_m
        # remembered world points: x, y, readings merged, and the progress at which the front
        # bumper reaches it as of its last sighting (forgotten only once the progress is past)
        self.targets: list[tuple[float, float, int, float]] = []
        self.trail: deque[tuple[float, float]] = deque(
            maxlen=max(2, int(cfg.trail_length_m / cfg.trail_spacing_m)))
        self.forward_odometer_m = 0.0      # travel counted while driving forward
        self.trail_odometer_m: float | None = None   # forward_odometer_m at the last trail point
        self.last_odometer_m: float | None = None
        # where the current reverse began (pose, odometer): a stream of REVERSE commands shares
        # one allowance instead of being granted the blind metre again and again
        self.reverse_anchor: GpsIns | None = None
        self.forward_since_anchor_m = 0.0
        self.pending: Radar | None = None    # a reading received this period
        self.last: Radar | None = None       # the last reading received (fresh or not)
        self.fresh_s: float | None = None    # when the last fresh reading came
        self.received_s: float | None = None
        self.same_since_odometer_m: float | None = None   # a target reading unchanged since
        self.clear_end_m: float | None = None  # progress up to which the path was seen clear
        self.fault: RadarFault | None = None
        self.nearest_m = math.inf
        self.closing_mps = 0.0   # closing speed of this period's reading, if in the corridor
        # the dead-reckoned pose (issue 30): progress along the integrated gyro yaw rate
        self.pose = Pose(0.0, 0.0, 0.0)
        self.pose_progress_m: float | None = None
        self.pose_s: float | None = None

    # ------------------------------------------------------------------ inputs

    def receive(self, now_s: float, msg: Radar) -> None:
        self.received_s = now_s
        self.pending = msg

    def record_trail(self, gps: GpsIns, direction: int) -> None:
        """Keep the rear bumper's track while driving forward (it swept that ground); forward
        travel of ``reverse_blind_m`` ends the current reverse (its anchor)."""
        odo = gps.odometer_m
        last, self.last_odometer_m = self.last_odometer_m, odo
        advanced_m = max(odo - last, 0.0) if last is not None else 0.0
        if direction <= 0:
            if advanced_m > 0.0:
                self.trail_odometer_m = None   # reversed: the next forward travel starts a point
            return
        # only forward travel counts: the odometer also counts reversing, and GPS speed noise
        # at a standstill reads as "forward" (a point where the vehicle stands after a reverse
        # would cut the track the next REVERSE of the stream backs along)
        self.forward_odometer_m += advanced_m
        if self.reverse_anchor is not None:
            self.forward_since_anchor_m += advanced_m
            if self.forward_since_anchor_m >= self.config.reverse_blind_m:
                self.reverse_anchor = None
        if self.trail and (advanced_m == 0.0 if self.trail_odometer_m is None else
                           self.forward_odometer_m - self.trail_odometer_m
                           < self.config.trail_spacing_m):
            return
        self.trail_odometer_m = self.forward_odometer_m
        rear = self.params.rear_overhang_m
        h = gps.heading_rad
        self.trail.append((gps.x_m - rear * math.cos(h), gps.y_m - rear * math.sin(h)))

    # ------------------------------------------------------------------ per period

    def dead_reckon(self, now_s: float, progress_m: float, yaw_rate_rps: float) -> Pose:
        """Advance the local frame's pose by the progress since the last call, along the
        heading integrated from the gyro's yaw rate (midpoint); the first call anchors it."""
        last, last_s = self.pose_progress_m, self.pose_s
        self.pose_progress_m, self.pose_s = progress_m, now_s
        if last is None or last_s is None:
            return self.pose
        pose = self.pose
        dh = yaw_rate_rps * max(now_s - last_s, 0.0)
        ds = progress_m - last
        mid = pose.heading_rad + 0.5 * dh
        self.pose = Pose(pose.x_m + ds * math.cos(mid), pose.y_m + ds * math.sin(mid),
                         math.remainder(pose.heading_rad + dh, math.tau))
        return self.pose

    def update(self, now_s: float, gps: GpsIns | None, curvatures_1pm: Iterable[float],
               forward: bool, *, progress_m: float | None = None,
               yaw_rate_rps: float = 0.0) -> list[Notice]:
        """One period: health, memory and the nearest corridor target; the fault notices.

        ``progress_m``: the conservative signed forward progress (the move server's
        ``progress_m("forward")``; default the GPS/INS odometer); ``yaw_rate_rps``: the gyro's
        (counter-clockwise). The memory lives in the dead-reckoned frame these two integrate
        to: the GPS/INS pose is not used."""
        cfg = self.config
        msg, self.pending = self.pending, None
        notices: list[Notice] = []
        odo = progress_m if progress_m is not None else (gps.odometer_m if gps is not None else 0.0)
        fresh = msg is not None and not (
            self.last is not None and msg.seq is not None and msg.seq == self.last.seq)
        frozen_content = False
        if fresh and msg is not None:
            last = self.last
            if msg.target and last is not None and last.target and \
                    (msg.range_m, msg.bearing_rad) == (last.range_m, last.bearing_rad):
                if self.same_since_odometer_m is None:
                    self.same_since_odometer_m = odo
                frozen_content = odo - self.same_since_odometer_m > cfg.frozen_travel_m
            else:
                self.same_since_odometer_m = None
            self.fresh_s = now_s
        if msg is not None:
            self.last = msg
        fault: RadarFault | None = None
        if frozen_content:
            fault = RadarFault.FROZEN
        elif self.fitted and (self.fresh_s is None or now_s - self.fresh_s > cfg.timeout_s):
            repeating = self.received_s is not None and now_s - self.received_s <= cfg.timeout_s
            fault = RadarFault.FROZEN if repeating else RadarFault.SILENT
        if fault is not None and fault != self.fault:
            notices.append(self._fault_notice(now_s, fault))
        self.fault = fault
        pose = self.dead_reckon(now_s, odo, yaw_rate_rps)
        ks = tuple(curvatures_1pm)
        self.nearest_m = math.inf
        self.closing_mps = 0.0
        if fault is None and fresh and msg is not None:
            if not (msg.target and self.same_since_odometer_m is not None):
                # a changed reading (or a clear road): the path is seen clear up to its range
                self.clear_end_m = odo + msg.range_m
            if msg.target:   # the reading itself, in the vehicle frame: needs no pose
                b = msg.bearing_rad or 0.0
                self.nearest_m = self._corridor_distance(
                    self.front_m + msg.range_m * math.cos(b), msg.range_m * math.sin(b), ks)
                if math.isfinite(self.nearest_m):
                    self.closing_mps = msg.closing_speed_mps
            self._observe(pose, msg, odo)
        self.nearest_m = min(self.nearest_m, self._nearest(pose, ks, odo))
        return notices

    def _fault_notice(self, now_s: float, fault: RadarFault) -> Notice:
        if fault == RadarFault.SILENT:
            what = f"radar silent for more than {self.config.timeout_s:.2f} s"
        else:
            what = "radar frozen: the same reading repeated"
        end = ("nothing seen clear yet: no forward motion" if self.clear_end_m is None
               else "the vehicle stops before the end of the range last seen clear")
        return Notice(kind="fault", source=SOURCE, code=str(int(fault)), reason=f"{what}; {end}")

    def _observe(self, pose: Pose, msg: Radar, progress_m: float) -> None:
        """Clear what the reading sees through; remember its target."""
        cfg, p = self.config, self.params
        c, s = math.cos(pose.heading_rad), math.sin(pose.heading_rad)
        bx, by = pose.x_m + self.front_m * c, pose.y_m + self.front_m * s
        keep = []
        cone = p.radar_half_angle_rad - cfg.see_through_angle_rad
        for target in self.targets:
            tx, ty, _, pass_m = target
            dx, dy = tx - bx, ty - by
            along, left = dx * c + dy * s, -dx * s + dy * c
            rng = math.hypot(dx, dy)
            if along > 0.0 and abs(math.atan2(left, along)) <= cone \
                    and rng < msg.range_m - cfg.see_through_m:
                continue                       # the radar looks through where it was
            if along < -p.length_m and progress_m > pass_m:
                continue                       # behind the vehicle: passed
            keep.append(target)
        if msg.target:
            b = pose.heading_rad + (msg.bearing_rad or 0.0)
            x, y = bx + msg.range_m * math.cos(b), by + msg.range_m * math.sin(b)
            pass_m = progress_m + msg.range_m * math.cos(msg.bearing_rad or 0.0)
            near = [t for t in keep if math.hypot(t[0] - x, t[1] - y) <= cfg.merge_m]
            if near:   # the same target again: a running mean averages the pose noise out
                old = min(near, key=lambda t: math.hypot(t[0] - x, t[1] - y))
                keep.remove(old)
                tx, ty, n, _ = old
                w = 1.0 / (n + 1)
                x, y, n = tx + w * (x - tx), ty + w * (y - ty), min(n + 1, cfg.merge_readings)
            else:
                n = 1
            keep.append((x, y, n, pass_m))
        if len(keep) > cfg.max_targets:
            keep.sort(key=lambda t: math.hypot(t[0] - bx, t[1] - by))
            keep = keep[:cfg.max_targets]
        self.targets = keep

    def _corridor_distance(self, along_m: float, left_m: float,
                           curvatures_1pm: tuple[float, ...]) -> float:
        """Path distance to a vehicle-frame point in the corridor of any arc (inf if in none)."""
        best = math.inf
        hw, margin, front = self.half_width_m, self.config.corridor_margin_m, self.front_m
        for k in curvatures_1pm:
            dist, offset, outer = path_offset(along_m, left_m, k, front, hw)
            if dist >= 0.0 and in_corridor(offset, outer, hw, margin, k):
                best = min(best, dist)
        return best

    def _nearest(self, pose: Pose, curvatures_1pm: tuple[float, ...], progress_m: float) -> float:
        """Path distance from the front bumper to the nearest remembered target in the corridor
        of any of ``curvatures_1pm``; targets behind the front bumper are forgotten (passed)
        once the progress since their last sighting is past them too."""
        best = math.inf
        keep = []
        for target in self.targets:
            tx, ty, _, pass_m = target
            along, left = to_vehicle(pose, tx, ty)
            if along < self.front_m:
                if progress_m > pass_m:
                    continue
                keep.append(target)
                continue
            keep.append(target)
            best = min(best, self._corridor_distance(along, left, curvatures_1pm))
        self.targets = keep
        return best

    # ------------------------------------------------------------------ outputs

    @property
    def trusted(self) -> bool:
        return self.fault is None

    def forward_cap_m(self, progress_m: float, estop_margin_m: float) -> float:
        """Largest forward authorization: unlimited while the radar is trusted; else what is
        left of the range last seen clear, short of it by the e-stop margin and ``hold_gap_m``."""
        if self.fault is None:
            return math.inf
        if self.clear_end_m is None:
            return 0.0
        left = self.clear_end_m - progress_m - estop_margin_m - self.config.hold_gap_m
        return max(left, 0.0)

    def rear_clear_m(self, gps: GpsIns | None, curvature_1pm: float,
                     up_to_m: float = math.inf) -> float:
        """How far the rear axle may back along the arc of ``curvature_1pm`` with the rear
        bumper on the track the vehicle swept forward (within ``trail_tolerance_m``); the search
        stops at ``up_to_m``."""
        cfg = self.config
        if gps is None or not self.trail:
            return 0.0
        rear = self.params.rear_overhang_m
        step = cfg.trail_spacing_m
        x, y, h = gps.x_m, gps.y_m, gps.heading_rad
        trail = (*self.trail, (x - rear * math.cos(h), y - rear * math.sin(h)))   # and where it is
        segments = [(a, b) for a, b in itertools.pairwise(trail)
                    if math.dist(a, b) <= 2.0 * step + cfg.trail_tolerance_m] or [(trail[0], trail[0])]
        tol = cfg.trail_tolerance_m
        k = curvature_1pm
        travelled = 0.0
        limit = min(cfg.trail_length_m, up_to_m)
        while travelled <= limit:
            bx, by = x - rear * math.cos(h), y - rear * math.sin(h)
            if not any(segment_distance_m(bx, by, a, b) <= tol for a, b in segments):
                return max(travelled - step, 0.0)
            # one step backwards along the arc (heading rate -v k, v < 0)
            dh = k * step
            hm = h + 0.5 * dh
            x -= step * math.cos(hm)
            y -= step * math.sin(hm)
            h += dh
            travelled += step
        return limit

    def clamp_reverse(self, cmd: MoveCommand, gps: GpsIns | None) -> tuple[MoveCommand, str]:
        """A REVERSE limited to the reverse speed and to the rear ground verified clear plus the
        blind allowance; the reply's note says what was clamped ("" if nothing)."""
        cfg = self.config
        if cmd.kind != "reverse":
            return cmd, ""
        notes = []
        speed = cmd.maxspeed_mps
        if speed > cfg.reverse_max_speed_mps:
            speed = cfg.reverse_max_speed_mps
            notes.append(f"maxspeed clamped to {speed:.2f} m/s (no rear sensor)")
        anchor = self.reverse_anchor if self.reverse_anchor is not None else gps
        if gps is not None and self.reverse_anchor is None:
            self.reverse_anchor, self.forward_since_anchor_m = gps, 0.0
        used = 0.0 if gps is None or anchor is None else max(gps.odometer_m - anchor.odometer_m, 0.0)
        verified = self.rear_clear_m(anchor, cmd.curvature_1pm, cmd.distance_m + used)
        allowed = max(verified + cfg.reverse_blind_m - used, 0.0)
        distance = cmd.distance_m
        if distance > allowed:
            distance = allowed
            notes.append(f"distance clamped to {allowed:.2f} m: the own forward track verified "
                         f"{verified:.2f} m clear behind where this reverse began, plus "
                         f"{cfg.reverse_blind_m:.2f} m blind, {used:.2f} m already used "
                         "(no rear sensor)")
        if not notes:
            return cmd, ""
        return msgspec.structs.replace(cmd, maxspeed_mps=speed, distance_m=distance), \
            "REVERSE " + "; ".join(notes)


__all__ = ["Pose", "RadarConfig", "RadarCorridor", "RadarFault", "in_corridor", "path_offset",
           "to_vehicle"]
