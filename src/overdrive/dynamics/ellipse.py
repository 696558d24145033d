"""The acceleration ellipse (seed 003): what the tyres can do, and what follows from it.

Pure functions, no state except ``TractionMonitor`` (time passed in). Reference: docs/dynamics.md.

Model, in vehicle coordinates (x forward along the direction of travel, y to the right):

- The tyres can supply a specific force ``(f_x, f_y)`` inside the ellipse
  ``(f_x / A)^2 + (f_y / B)^2 <= 1``. On level ground ``B = skid-pad lateral g * g`` and
  ``A`` = the deceleration implied by the 60-0 mph stopping distance, both derated
  (25 % by default: seed 003 "derate these numbers by 25% or so") and scaled by
  ``mu / mu_ref``: the world friction relative to the dry pavement the preset figures were
  measured on (``mu_ref = 0.9``), never above the published figures.
- Tilt: the friction limit scales with the normal load, so on a slope both semi-axes are
  multiplied by ``cos(grade) * cos(roll)``; and gravity is added to what the tyres supply:
  along the travel direction ``-g sin(grade)`` (``grade`` > 0 uphill: braking helped,
  acceleration hindered), sideways ``+g sin(roll)`` towards the lower (right, ``roll`` > 0) side.
- A turn of curvature ``k`` (+ right) at speed ``v`` needs ``v^2 k`` towards the right; the
  tyres supply the rest, the lateral demand ``f_y = v^2 k - g sin(roll)``. What is left for
  the longitudinal direction is ``A sqrt(1 - (f_y / B)^2)``.
- Traction-control activity shrinks the ellipse for a while (``TractionMonitor``).
- Rollover (seed 003): the lateral semi-axis is ``min(B, R)``, ``R = g * SSF * (1 - derate)``
  with the static stability factor ``SSF = track / (2 h_cg)``: a rigid vehicle on level ground
  lifts its inner wheels at ``g * SSF`` whatever the friction. ``R`` scales with the normal
  load like ``B`` (on a side slope tipping compares the lateral force with ``g cos(roll)``) and
  is not shrunk by friction or traction control. Using the ellipse's shape below ``R`` is
  conservative: the longitudinal share left in a curve is planned as if the grip were ``R``.

Signs: ``grade_rad`` is the slope of the direction of travel (pitch for forward driving,
-pitch in reverse); ``roll_rad`` is right side down positive; curvature + right, as the
steering geometry defines it (the turn's centre on the right) in both directions of travel.
"""

from __future__ import annotations

import math

import msgspec

from overdrive.dynamics.vehicle_params import G_MPS2, VehicleParams

_TINY_SPAN = 1e-6   # |s1 - s0| below which a curve is integrated as a straight line (error ~1e-12)
_SERIES_X = 1e-4    # |x| below which atan(x)/x and atanh(x)/x use their two-term series


class EnvelopeConfig(msgspec.Struct, frozen=True, forbid_unknown_fields=True, kw_only=True):
    """How the preset's published figures become the ellipse used for planning."""

    derate: float = 0.25              # seed 003: "We probably derate these numbers by 25% or so."
    reference_friction: float = 0.9   # dry asphalt mu, where skid-pad and 60-0 figures are measured
    max_friction_scale: float = 1.0   # never plan beyond the published figures
    traction_shrink: float = 0.5      # semi-axes x this while traction control was active recently
    traction_hold_s: float = 5.0      # ... for this long after the last activity (estimate)
    rollover_derate: float = 0.25     # seed 003's derate, on g * SSF too: the static factor
                                      # ignores suspension roll and tyre deflection (the CG moves
                                      # outward) and a transient's overshoot, which tip a vehicle
                                      # below it (the 2004 Escape 4x4 tipped up in NHTSA's
                                      # fishhook test: autos.ca, 10 Aug 2004)


DEFAULT_ENVELOPE = EnvelopeConfig()


class Ellipse(msgspec.Struct, frozen=True):
    """Tyre specific-force semi-axes on level ground, m/s^2 (derated, friction-scaled)."""

    lon_mps2: float
    lat_mps2: float


class Longitudinal(msgspec.Struct, frozen=True):
    """Longitudinal acceleration still available, both >= what gravity alone gives."""

    accel_mps2: float   # speeding up (may be negative: cannot even hold speed uphill)
    decel_mps2: float   # slowing down (may be negative: cannot hold speed downhill)


def ellipse_for(params: VehicleParams, friction: float,
                config: EnvelopeConfig = DEFAULT_ENVELOPE, shrink: float = 1.0) -> Ellipse:
    """The ellipse of ``params`` on ground of ``friction``, times ``shrink`` (traction control).

    ``A = max_decel * (1 - derate) * s``, ``B = skidpad_lat_g * g * (1 - derate) * s`` with
    ``s = min(friction / reference_friction, max_friction_scale) * shrink``.
    """
    scale = min(max(friction, 0.0) / config.reference_friction, config.max_friction_scale)
    scale *= (1.0 - config.derate) * max(shrink, 0.0)
    return Ellipse(lon_mps2=params.max_decel_mps2 * scale,
                   lat_mps2=min(params.skidpad_lat_g * G_MPS2 * scale,
                                rollover_lat_mps2(params, config)))


def rollover_lat_mps2(params: VehicleParams, config: EnvelopeConfig = DEFAULT_ENVELOPE) -> float:
    """The rollover limit on the lateral specific force, level ground: ``g * SSF * (1 - derate)``
    (``SSF = track / (2 h_cg)``); the ellipse's lateral semi-axis never exceeds it."""
    return G_MPS2 * params.static_stability_factor * (1.0 - config.rollover_derate)


def load_axes_mps2(e: Ellipse, grade_rad: float = 0.0, roll_rad: float = 0.0) -> tuple[float, float]:
    """Semi-axes ``(A', B')`` on a slope: the friction limit follows the normal load."""
    n = math.cos(grade_rad) * math.cos(roll_rad)
    return e.lon_mps2 * n, e.lat_mps2 * n


def lateral_demand_mps2(speed_mps: float, curvature_1pm: float, roll_rad: float = 0.0) -> float:
    """Lateral specific force the tyres must supply (+ right): ``v^2 k - g sin(roll)``."""
    return speed_mps * speed_mps * curvature_1pm - G_MPS2 * math.sin(roll_rad)


def longitudinal_limits(e: Ellipse, speed_mps: float, curvature_1pm: float,
                        grade_rad: float = 0.0, roll_rad: float = 0.0) -> Longitudinal:
    """Acceleration and deceleration left at ``speed_mps`` in a turn of ``curvature_1pm``.

    Tyre share ``a_t = A' sqrt(1 - (f_y / B')^2)`` (0 outside the ellipse), then
    ``accel = a_t - g sin(grade)``, ``decel = a_t + g sin(grade)``; ``A', B'`` are the
    load-scaled semi-axes.
    """
    a, b = load_axes_mps2(e, grade_rad, roll_rad)
    demand = lateral_demand_mps2(speed_mps, curvature_1pm, roll_rad)
    tyre = tyre_longitudinal_mps2(a, b, demand)
    g_along = G_MPS2 * math.sin(grade_rad)
    return Longitudinal(accel_mps2=tyre - g_along, decel_mps2=tyre + g_along)


def tyre_longitudinal_mps2(lon_axis_mps2: float, lat_axis_mps2: float,
                           lat_demand_mps2: float) -> float:
    """``A sqrt(1 - (f_y / B)^2)``: the longitudinal part of the ellipse at lateral ``f_y``."""
    if lat_axis_mps2 <= 0.0:
        return 0.0
    r = lat_demand_mps2 / lat_axis_mps2
    return lon_axis_mps2 * math.sqrt(max(0.0, 1.0 - r * r))


def lateral_available_mps2(e: Ellipse, lon_demand_mps2: float, grade_rad: float = 0.0,
                           roll_rad: float = 0.0) -> float:
    """``B' sqrt(1 - (f_x / A')^2)``: lateral tyre force left while supplying ``f_x``."""
    a, b = load_axes_mps2(e, grade_rad, roll_rad)
    if a <= 0.0:
        return 0.0
    r = lon_demand_mps2 / a
    return b * math.sqrt(max(0.0, 1.0 - r * r))


def lateral_speed_limit_mps(e: Ellipse, curvature_1pm: float, grade_rad: float = 0.0,
                            roll_rad: float = 0.0) -> float:
    """Highest speed at which the turn fits in the ellipse while holding speed on the grade.

    Holding speed takes ``f_x = g sin(grade)``, leaving ``B_h = B' sqrt(1 - (g sin(grade)/A')^2)``;
    then ``v = sqrt((B_h + g sin(roll) sign(k)) / |k|)`` (``inf`` for ``k = 0`` unless the
    roll alone exceeds ``B_h``; 0 when nothing fits).
    """
    b_hold = lateral_available_mps2(e, G_MPS2 * math.sin(grade_rad), grade_rad, roll_rad)
    c = G_MPS2 * math.sin(roll_rad)
    if curvature_1pm == 0.0:
        return math.inf if abs(c) <= b_hold else 0.0
    if abs(c) > b_hold:
        return 0.0
    room = b_hold + (c if curvature_1pm > 0.0 else -c)
    return math.sqrt(max(room, 0.0) / abs(curvature_1pm))


# --------------------------------------------------------------------------- stopping

def _ratio_series(x: float, hyperbolic: bool) -> float:
    """``atanh(x)/x`` (hyperbolic) or ``atan(x)/x``, stable near 0."""
    if abs(x) < _SERIES_X:
        return 1.0 + x * x / 3.0 if hyperbolic else 1.0 - x * x / 3.0
    if hyperbolic and abs(x) >= 1.0:
        return math.inf   # the integrand's pole (braking runs out), reached by rounding
    return (math.atanh(x) if hyperbolic else math.atan(x)) / x


def _h(t: float, a: float, g_along: float) -> float:
    """``H(t) = integral_0^t cos(u) / (A cos(u) + G) du`` (closed form; requires the integrand > 0).

    ``H = (t - G J(t)) / A`` with ``J = integral dt / (A cos t + G)
    = 2 tan(t/2) / (A + G) * f(x)``, ``x = sqrt(|A - G| / (A + G)) tan(t/2)``,
    ``f = atanh(x)/x`` for ``G < A``, ``atan(x)/x`` for ``G > A``, 1 for ``G = A``.
    """
    if g_along == 0.0:
        return t / a
    tan_half = math.tan(0.5 * t)
    r = math.sqrt(abs(a - g_along) / (a + g_along))
    j = 2.0 * tan_half / (a + g_along) * _ratio_series(r * tan_half, g_along < a)
    return (t - g_along * j) / a


def _lateral_bound(a: float, g_along: float) -> float:
    """Largest ``|f_y / B'|`` at which braking still works: 1, or ``sqrt(1 - (G/A)^2)`` downhill."""
    if g_along >= 0.0:
        return 1.0
    r = -g_along / a
    return math.sqrt(1.0 - r * r) if r < 1.0 else 0.0


class Braking:
    """Braking in one ellipse, curve and slope: ``braking_distance_m``, ``stopping_distance_m``,
    ``braking_speed_cap_mps`` and ``max_safe_speed_mps`` for those, at any speed or distance.

    The speed-independent terms (load-scaled axes, gravity, the lateral bound, ``H(t0)``, the
    speed cap) are computed once: ``max_safe_speed_mps``' Newton iteration evaluates only what
    depends on the speed, and a node whose ellipse, curve and slope stay the same from one
    period to the next can keep the object. Each term is the same expression as in a direct
    computation, so results are bit-for-bit the functions' (which use this class).
    """

    __slots__ = ("_cap", "_h0", "a", "b", "bound", "c", "curvature_1pm", "feasible", "g_along",
                 "s0")

    def __init__(self, e: Ellipse, curvature_1pm: float = 0.0, grade_rad: float = 0.0,
                 roll_rad: float = 0.0) -> None:
        self.curvature_1pm = curvature_1pm
        a, b = load_axes_mps2(e, grade_rad, roll_rad)
        g_along = G_MPS2 * math.sin(grade_rad)
        self.a, self.b, self.g_along = a, b, g_along
        self.feasible = not (a <= 0.0 or b <= 0.0 or a + g_along <= 0.0)
        self.c = G_MPS2 * math.sin(roll_rad)
        if self.feasible:
            self.s0 = -self.c / b
            self.bound = _lateral_bound(a, g_along)
        self._h0: float | None = None
        self._cap: float | None = None

    def distance_m(self, speed_mps: float) -> float:
        """``braking_distance_m``."""
        v = abs(speed_mps)
        if v == 0.0:
            return 0.0
        if not self.feasible:
            return math.inf
        a, b, g_along, k = self.a, self.b, self.g_along, self.curvature_1pm
        s0 = self.s0
        s1 = (v * v * k - self.c) / b
        bound = self.bound
        worst = max(abs(s0), abs(s1))
        if worst > bound or (g_along < 0.0 and (
                worst >= bound or a * math.sqrt(1.0 - worst * worst) + g_along <= 0.0)):
            return math.inf
        if abs(s1 - s0) < _TINY_SPAN:
            s_mid = 0.5 * (s0 + s1)
            decel = a * math.sqrt(1.0 - s_mid * s_mid) + g_along
            return v * v / (2.0 * decel)
        if self._h0 is None:
            self._h0 = _h(math.asin(s0), a, g_along)
        t1 = math.asin(min(1.0, max(-1.0, s1)))
        return b / (2.0 * k) * (_h(t1, a, g_along) - self._h0)

    def stopping_distance_m(self, speed_mps: float, reaction_s: float = 0.0) -> float:
        """``stopping_distance_m``."""
        return abs(speed_mps) * reaction_s + self.distance_m(speed_mps)

    def speed_cap_mps(self) -> float:
        """``braking_speed_cap_mps``."""
        if self._cap is None:
            self._cap = self._speed_cap_mps()
        return self._cap

    def _speed_cap_mps(self) -> float:
        if not self.feasible:
            return 0.0
        b, c, bound = self.b, self.c, self.bound
        if abs(c) / b > bound:
            return 0.0
        if self.curvature_1pm == 0.0:
            return math.inf
        room = bound * b + (c if self.curvature_1pm > 0.0 else -c)
        return math.sqrt(max(room, 0.0) / abs(self.curvature_1pm))

    def max_safe_speed_mps(self, distance_m: float, reaction_s: float = 0.0) -> float:
        """``max_safe_speed_mps``."""
        if not distance_m > 0.0:
            return 0.0
        a, b, g_along, c = self.a, self.b, self.g_along, self.c
        curvature_1pm = self.curvature_1pm
        cap = self.speed_cap_mps()
        if cap <= 0.0:
            return 0.0
        t_r = max(reaction_s, 0.0)
        if curvature_1pm == 0.0:
            decel = tyre_longitudinal_mps2(a, b, -c) + g_along
            if decel <= 0.0:
                return 0.0
            if math.isinf(distance_m):
                return math.inf
            return -decel * t_r + math.sqrt((decel * t_r) ** 2 + 2.0 * decel * distance_m)
        if math.isinf(distance_m):
            return cap

        braking_distance = self.distance_m

        def excess(v: float) -> float:
            return v * t_r + braking_distance(v) - distance_m

        at_cap = excess(cap)
        if at_cap <= 0.0:
            return cap
        best = a + g_along   # no curve, no roll: the largest deceleration anywhere
        hi = min(cap, -best * t_r + math.sqrt((best * t_r) ** 2 + 2.0 * best * distance_m))
        lo = 0.0
        v = hi
        tol_m = 1e-12 * distance_m + 1e-15
        for _ in range(200):
            f = excess(v)
            if abs(f) <= tol_m:
                return v
            if f > 0.0:
                hi = v
            else:
                lo = v
            s = (v * v * curvature_1pm - c) / b
            decel = a * math.sqrt(max(0.0, 1.0 - s * s)) + g_along
            nxt = v - f / (t_r + v / decel) if decel > 0.0 and math.isfinite(f) else -1.0
            v = nxt if lo < nxt < hi else 0.5 * (lo + hi)
            if hi - lo <= 1e-15 * max(hi, 1.0):
                break
        return lo


class BrakingCache:
    """``Braking`` objects for one ellipse, by curve and slope: a node whose ellipse, curve and
    slope stay the same from one period to the next builds each once. A new ellipse (by
    identity) starts afresh; at most ``size`` are kept. Keys that compare equal share an entry
    (+0.0 and -0.0 give the same distances)."""

    __slots__ = ("_by_key", "_ellipse", "size")

    def __init__(self, size: int = 8) -> None:
        self.size = size
        self._ellipse: Ellipse | None = None
        self._by_key: dict[tuple[float, float, float], Braking] = {}

    def get(self, ellipse: Ellipse, curvature_1pm: float, grade_rad: float,
            roll_rad: float) -> Braking:
        if ellipse is not self._ellipse:
            self._ellipse = ellipse
            self._by_key.clear()
        key = (curvature_1pm, grade_rad, roll_rad)
        braking = self._by_key.get(key)
        if braking is None:
            if len(self._by_key) >= self.size:
                self._by_key.clear()
            braking = self._by_key[key] = Braking(ellipse, curvature_1pm, grade_rad, roll_rad)
        return braking


def braking_distance_m(e: Ellipse, speed_mps: float, curvature_1pm: float = 0.0,
                       grade_rad: float = 0.0, roll_rad: float = 0.0) -> float:
    """Distance to stop from ``speed_mps`` using the whole ellipse, the curve held throughout.

    ``d = integral_0^v w dw / b(w)`` with ``b(w) = A' sqrt(1 - s(w)^2) + G``,
    ``s = (w^2 k - c) / B'``, ``G = g sin(grade)``, ``c = g sin(roll)``. Straight (``k = 0``):
    ``d = v^2 / (2 b)``. In a curve, substituting ``s = sin t``:
    ``d = B' / (2 k) * (H(t1) - H(t0))`` (see ``_h``). Infinite when braking runs out on the
    way (downhill ``b <= 0``) or the curve does not fit in the ellipse at ``v``.
    """
    if speed_mps == 0.0:
        return 0.0
    return Braking(e, curvature_1pm, grade_rad, roll_rad).distance_m(speed_mps)


def stopping_distance_m(e: Ellipse, speed_mps: float, curvature_1pm: float = 0.0,
                        grade_rad: float = 0.0, roll_rad: float = 0.0,
                        reaction_s: float = 0.0) -> float:
    """``|v| * reaction_s + braking_distance_m``: travel during the reaction, then braking."""
    return abs(speed_mps) * reaction_s + braking_distance_m(e, speed_mps, curvature_1pm,
                                                            grade_rad, roll_rad)


def braking_speed_cap_mps(e: Ellipse, curvature_1pm: float, grade_rad: float = 0.0,
                          roll_rad: float = 0.0) -> float:
    """Speed above which ``braking_distance_m`` is infinite (curve leaves the braking ellipse)."""
    return Braking(e, curvature_1pm, grade_rad, roll_rad).speed_cap_mps()


def max_safe_speed_mps(e: Ellipse, distance_m: float, curvature_1pm: float = 0.0,
                       grade_rad: float = 0.0, roll_rad: float = 0.0,
                       reaction_s: float = 0.0) -> float:
    """Inverse of ``stopping_distance_m``: the highest speed that stops within ``distance_m``.

    Straight: ``v = -b t_r + sqrt((b t_r)^2 + 2 b D)``. In a curve: safeguarded Newton on
    ``v t_r + d(v) = D`` (``d'(v) = v / b(v)``) to 1e-12 relative, capped at
    ``braking_speed_cap_mps``. 0 for ``D <= 0``, NaN, or when braking is impossible.
    """
    if not distance_m > 0.0:
        return 0.0
    return Braking(e, curvature_1pm, grade_rad, roll_rad).max_safe_speed_mps(distance_m,
                                                                             reaction_s)


# --------------------------------------------------------------------------- traction control

class TractionMonitor:
    """Shrinks the ellipse for ``traction_hold_s`` after any traction-control activity."""

    def __init__(self, config: EnvelopeConfig = DEFAULT_ENVELOPE) -> None:
        self.config = config
        self.last_active_s = -math.inf

    def update(self, now_s: float, active: bool) -> None:
        if active:
            self.last_active_s = now_s

    def active(self, now_s: float) -> bool:
        return now_s - self.last_active_s < self.config.traction_hold_s

    def shrink(self, now_s: float) -> float:
        """Factor for ``ellipse_for``: ``traction_shrink`` while active, else 1."""
        return self.config.traction_shrink if self.active(now_s) else 1.0
