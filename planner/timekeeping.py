"""Time-keeping driver support: the cruise speed that arrives on time (DESIGN §4).

A continuous on-board support method, an alternative to the ratio tables of
§3: from the remaining time t_d and remaining distance x_d, and the stopping
deceleration β, compute the constant cruise speed v_m that reaches the stop
marker exactly at the scheduled arrival, and re-compute it as the train runs
and whenever the traffic-control centre moves the scheduled arrival.

Layout follows the computation:

1. pure target-speed functions (no I/O, floats or arrays, SI):
   :func:`cruise_speed` (the closed form of §4), :func:`braking_pattern_speed`,
   :func:`cruise_speed_limited` (the same with a position-dependent on-board
   maximum, solved exactly on a distance grid);
2. the closed-loop run (:func:`drive`): a single train driven by that target
   with the real train dynamics of :mod:`planner.dynamics` under the on-board
   maximum of :mod:`planner.speed_profile`, stopping on a constant-β pattern
   onto the marker, with scheduled-arrival changes en route;
3. the high-level API :func:`timekeeping_run` (line database in, a result
   with a run curve DataFrame out).
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .errors import InfeasibleError, InputError

__all__ = [
    "CruiseTarget",
    "cruise_speed",
    "braking_pattern_speed",
    "cruise_speed_limited",
    "profile_time",
]


# --------------------------------------------------------------------------
# 1. Pure target-speed functions
# --------------------------------------------------------------------------
class CruiseTarget(NamedTuple):
    """The answer of a target-speed computation.

    Attributes
    ----------
    speed_ms : float or ndarray
        Cruise speed to run at [m/s]. When the arrival cannot be met
        (``shortfall_s > 0``) it is the fastest admissible speed instead: run
        there and arrive ``shortfall_s`` late.
    shortfall_s : float or ndarray
        How late the train arrives even at ``speed_ms`` [s]; 0 when on time is
        possible. Never silently dropped: callers must report it.
    decel_ms2 : float
        Where the cruise speed lies below the current speed: the deceleration
        [m/s²] the answer assumes for getting down to it (see
        :func:`cruise_speed_limited`); NaN otherwise.
    """

    speed_ms: np.ndarray | float
    shortfall_s: np.ndarray | float
    decel_ms2: float = math.nan

    @property
    def feasible(self):
        """True where the scheduled arrival can be kept (no shortfall)."""
        return np.asarray(self.shortfall_s) <= 0.0


def braking_pattern_speed(x_d, beta):
    """Speed of the constant-deceleration stopping pattern onto the marker.

    ``v_t = sqrt(2 β x_d)``: the highest speed at remaining distance ``x_d``
    from which braking at ``β`` still stops at the marker (DESIGN §4).

    Parameters
    ----------
    x_d : float or array_like
        Remaining distance to the stop marker [m]; negative counts as 0.
    beta : float or array_like
        Stopping deceleration [m/s²], > 0.

    Returns
    -------
    float or ndarray
        Pattern speed [m/s].

    Examples
    --------
    >>> float(braking_pattern_speed(200.0, 1.0))
    20.0
    """
    x = np.maximum(np.asarray(x_d, dtype=float), 0.0)
    return np.sqrt(2.0 * np.asarray(beta, dtype=float) * x)


def cruise_speed(t_d, x_d, beta) -> CruiseTarget:
    """Cruise speed that arrives exactly on time, then stops at constant ``β``.

    Running at v_m and braking at β onto the marker covers the cruise part
    x_d − v_m²/(2β) in (x_d − v_m²/(2β))/v_m and the braking part in v_m/β, so
    arriving after exactly t_d means (DESIGN §4)

        x_d − v_m²/(2β) = v_m (t_d − v_m/β)
        ⇔  v_m²/(2β) − t_d v_m + x_d = 0
        ⇔  v_m = β (t_d − sqrt(t_d² − 2 x_d/β)).

    The smaller root is the physical one (the larger gives v_m/β > t_d: more
    braking time than time left). It is evaluated in the cancellation-free
    form v_m = 2 x_d / (t_d + sqrt(t_d² − 2 x_d/β)) (multiply by the
    conjugate), which stays accurate when t_d² ≫ 2 x_d/β.

    No solution when t_d² < 2 x_d/β: the running time x_d/v + v/(2β) is
    smallest, sqrt(2 x_d/β), at the braking-pattern speed v = sqrt(2 β x_d)
    (run on the pattern from here); with less time than that the train can
    only run there and arrive ``shortfall_s = sqrt(2 x_d/β) − t_d`` late.

    Parameters
    ----------
    t_d : float or array_like
        Remaining time until the scheduled arrival [s].
    x_d : float or array_like
        Remaining distance to the stop marker [m], ≥ 0.
    beta : float or array_like
        Stopping deceleration [m/s²], > 0.

    Returns
    -------
    CruiseTarget
        ``speed_ms`` v_m [m/s] (the pattern speed where infeasible) and
        ``shortfall_s`` [s] (0 where feasible). Arrays broadcast.

    Notes
    -----
    Acceleration and speed limits are ignored here (the train is assumed to
    be at v_m already); :func:`cruise_speed_limited` adds the on-board
    maximum, and the closed loop re-computes v_m as the train runs.

    Examples
    --------
    t_d = 100 s, x_d = 2000 m, β = 1 m/s²: v_m = 100 − sqrt(6000) ≈ 22.54 m/s.

    >>> round(float(cruise_speed(100.0, 2000.0, 1.0).speed_ms), 4)
    22.5403
    """
    t = np.asarray(t_d, dtype=float)
    x = np.maximum(np.asarray(x_d, dtype=float), 0.0)
    b = np.asarray(beta, dtype=float)
    t_min = np.sqrt(2.0 * x / b)  # fastest possible: on the braking pattern
    disc = t * t - 2.0 * x / b
    ok = (disc >= 0.0) & (t > 0.0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        v_ok = np.where(x > 0.0, 2.0 * x / np.where(ok, t + root, 1.0), 0.0)
    speed = np.where(ok, v_ok, braking_pattern_speed(x, b))
    # At x_d = 0 with t_d <= 0 the train is already there: no shortfall.
    short = np.where(ok, 0.0, np.maximum(t_min - t, 0.0))
    if speed.ndim == 0:
        return CruiseTarget(float(speed), float(short))
    return CruiseTarget(speed, short)


def _interval_times(v, a2, b2, ds):
    """Time [s] to cross each interval at min(v, u(s)), u² linear from a2 to b2.

    On an interval of length ds where the squared limit speed u² runs
    linearly from ``a2`` to ``b2`` (exact for constant-deceleration braking
    curves and constant limits), the speed is min(v, u). Where u stays above
    v the time is ds/v; where it stays below, constant acceleration gives
    2 ds/(u_a + u_b); where it crosses v² the interval is split at the
    crossing.
    """
    v2 = v * v
    ua, ub = np.sqrt(a2), np.sqrt(b2)
    lo2, hi2 = np.minimum(a2, b2), np.maximum(a2, b2)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_cap = ds / v
        t_lim = 2.0 * ds / (ua + ub)
        # fraction of the interval where u² < v² (the limited part)
        frac = np.where(hi2 > lo2, (v2 - lo2) / (hi2 - lo2), 0.0)
        ulo = np.minimum(ua, ub)
        t_cross = frac * ds * 2.0 / (ulo + v) + (1.0 - frac) * ds / v
    return np.where(lo2 >= v2, t_cap, np.where(hi2 <= v2, t_lim, t_cross))


def profile_time(s_m, u_ms, v_ms=np.inf) -> float:
    """Running time [s] along a speed profile capped at a constant speed.

    Parameters
    ----------
    s_m : array_like
        Increasing distance grid [m].
    u_ms : array_like
        Limit speed at each node [m/s]; between nodes u² is taken linear in
        distance (exact for constant-deceleration curves and constant limits).
    v_ms : float
        Constant cap [m/s]; ``inf`` for the limit profile itself.

    Returns
    -------
    float
        ∫ ds / min(v, u(s)) over the grid [s]; ``inf`` if the profile stands
        still anywhere except at the final node.
    """
    s = np.asarray(s_m, dtype=float)
    u = np.asarray(u_ms, dtype=float)
    if len(s) < 2:
        return 0.0
    ds = np.diff(s)
    u2 = u * u
    if np.isinf(v_ms):
        a, b = u[:-1], u[1:]
        with np.errstate(divide="ignore"):
            return float(np.sum(2.0 * ds / (a + b)))
    return float(np.sum(_interval_times(float(v_ms), u2[:-1], u2[1:], ds)))


def _min_with_line(s, lim2, line2):
    """Grid and min(lim², line²) where both are linear in s on every interval.

    The minimum of two linear functions has at most one kink per interval,
    where they cross; inserting that crossing as a node keeps the result
    linear between nodes (exact on coarse grids too).
    """
    d = lim2 - line2
    cross = (d[:-1] * d[1:]) < 0.0
    if np.any(cross):
        i = np.nonzero(cross)[0]
        f = d[i] / (d[i] - d[i + 1])
        s_new = s[i] + f * (s[i + 1] - s[i])
        lim_new = lim2[i] + f * (lim2[i + 1] - lim2[i])
        line_new = line2[i] + f * (line2[i + 1] - line2[i])
        order = np.argsort(np.concatenate([s, s_new]), kind="stable")
        s = np.concatenate([s, s_new])[order]
        lim2 = np.concatenate([lim2, lim_new])[order]
        line2 = np.concatenate([line2, line_new])[order]
    return s, np.minimum(lim2, line2)


def cruise_speed_limited(t_d, s_m, vmax_ms, beta, *, v0_ms: float | None = None,
                         accel_ms2: float | None = None, decel_ms2: float | None = None,
                         xtol_ms: float = 1e-9) -> CruiseTarget:
    """Constant cruise speed that arrives on time under a position-dependent maximum.

    The train runs at u(s) = min(v, vmax(s), sqrt(2 β (L − s))) from the
    first grid node to the stop marker at L = ``s_m[-1]``: the cruise speed
    v where allowed, the on-board maximum where it is lower, and the
    constant-β stopping pattern at the end. The running time

        T(v) = ∫ ds / u(s)

    is continuous and strictly decreasing in v (until v reaches the highest
    limit), so the v with T(v) = t_d is unique; it is found by Brent's method
    on an exact evaluation of T (between nodes the squared limit speed is
    linear in distance, so every interval's time is closed form; where two
    such lines cross inside an interval the crossing becomes a node). With no
    limit below the cruise speed this is exactly :func:`cruise_speed`, whose
    derivation (x_d − v_m²/(2β) = v_m (t_d − v_m/β)) is the special case of
    one cruise and one braking piece.

    Optionally the way from the current speed v0 to v is modelled too, so the
    answer does not assume an instant change of speed: up to v at constant
    ``accel_ms2`` (u² ≤ v0² + 2 a (s − s0)), down to v at constant
    ``decel_ms2`` (u² ≥ v0² − 2 d (s − s0), still under the maximum). Both
    keep T(v) continuous and decreasing.

    If even the limit profile itself (v → ∞) takes longer than t_d, there is
    no solution: the answer is that profile (``speed_ms`` = its highest speed,
    so min(speed_ms, limit) is the limit) and the shortfall T(∞) − t_d.

    Parameters
    ----------
    t_d : float
        Remaining time until the scheduled arrival [s].
    s_m : array_like
        Increasing distance grid from the train's position to the stop marker
        [m] (running distance; the last node is the marker).
    vmax_ms : array_like
        Admissible speed at each node [m/s]: the on-board maximum, possibly
        already lowered to braking curves towards restrictions ahead; u² is
        taken linear between nodes. Must be > 0 except at the first node
        (standing at departure) and the last.
    beta : float
        Stopping deceleration [m/s²], > 0.
    v0_ms : float, optional
        Current speed [m/s] (needed by ``accel_ms2`` / ``decel_ms2``).
    accel_ms2 : float, optional
        Acceleration [m/s²] (> 0) the train will use to get up from v0 to
        the cruise speed. Omit for an instant change (the plain model of
        DESIGN §4).
    decel_ms2 : float or sequence of float, optional
        Deceleration(s) [m/s²] (> 0) for getting down from v0, tried in
        order (e.g. a gentle trim, then the service brake): the first with
        which running down and holding can still take t_d is used and
        returned in ``decel_ms2``; if none can, an instant change.
    xtol_ms : float
        Absolute tolerance on v [m/s].

    Returns
    -------
    CruiseTarget
        Scalar ``speed_ms`` [m/s], ``shortfall_s`` [s] and ``decel_ms2``
        [m/s²] (NaN unless a deceleration from v0 was modelled).

    Examples
    --------
    High limits reproduce the closed form of :func:`cruise_speed`:

    >>> s = np.linspace(0.0, 2000.0, 2001)
    >>> round(cruise_speed_limited(100.0, s, np.full_like(s, 50.0), 1.0).speed_ms, 4)
    22.5403
    """
    from scipy.optimize import brentq

    s = np.asarray(s_m, dtype=float)
    vmax = np.asarray(vmax_ms, dtype=float)
    if s.ndim != 1 or s.shape != vmax.shape:
        raise ValueError("s_m and vmax_ms must be 1-D arrays of the same length")
    t_d = float(t_d)
    if len(s) < 2 or s[-1] - s[0] <= 0.0:
        return CruiseTarget(0.0, max(-t_d, 0.0) if len(s) >= 1 else 0.0)
    if np.any(np.diff(s) <= 0.0):
        raise ValueError("s_m must be strictly increasing")
    beta = float(beta)
    # the ceiling: maximum and stopping pattern, u² piecewise linear
    sc, c2 = _min_with_line(s, vmax * vmax, 2.0 * beta * (s[-1] - s))
    c2[-1] = 0.0  # standing at the marker
    if np.any((c2[:-1] <= 0.0) & (c2[1:] <= 0.0)):
        raise ValueError("vmax_ms must not stand still over an interval (> 0 inside the grid)")
    v0 = None if v0_ms is None else float(v0_ms)
    # the fast side (v ≥ v0): also under the acceleration envelope
    sf, f2 = sc, c2
    if v0 is not None and accel_ms2 is not None and accel_ms2 > 0.0:
        sf, f2 = _min_with_line(sc, c2, v0 * v0 + 2.0 * float(accel_ms2) * (sc - sc[0]))
    dsf, fa2, fb2 = np.diff(sf), f2[:-1], f2[1:]

    def t_fast(v):
        return float(np.sum(_interval_times(v, fa2, fb2, dsf)))

    u_top = np.sqrt(f2)
    v_top = float(np.max(u_top))
    t_limit = profile_time(sf, u_top)
    if t_d <= t_limit:
        return CruiseTarget(v_top, t_limit - t_d)
    decels = () if decel_ms2 is None else tuple(np.atleast_1d(np.asarray(decel_ms2, dtype=float)))
    slow = v0 is not None and v0 > 0.0 and len(decels) > 0
    dsc = np.diff(sc)
    for d in (decels if slow and t_fast(v0) < t_d else ()):
        # slower than now: run down from v0 at d to v (reached at s_x), then hold v,
        # never above the ceiling. T = ∫ under min(C, run-down line) up to s_x (the
        # same for every v: prefix sums) + ∫ under min(C, v) after s_x.
        sd, md = _min_with_line(sc, c2, v0 * v0 - 2.0 * d * (sc - sc[0]))
        ud = np.sqrt(np.maximum(md, 0.0))
        dsd = np.diff(sd)
        with np.errstate(divide="ignore", invalid="ignore"):
            pieces = np.where(dsd > 0.0, 2.0 * dsd / (ud[:-1] + ud[1:]), 0.0)
        cum_d = np.concatenate([[0.0], np.cumsum(pieces)])

        def t_slow(v, d=d, sd=sd, md=md, ud=ud, cum_d=cum_d):
            sx = sc[0] + (v0 * v0 - v * v) / (2.0 * d)
            if sx >= sc[-1]:
                return float(cum_d[-1])  # still running down at the marker
            i = min(int(np.searchsorted(sd, sx, side="right")) - 1, len(sd) - 2)
            wx = md[i] + (md[i + 1] - md[i]) * (sx - sd[i]) / (sd[i + 1] - sd[i])
            first = cum_d[i] + 2.0 * (sx - sd[i]) / (ud[i] + math.sqrt(max(wx, 0.0)))
            j = min(int(np.searchsorted(sc, sx, side="right")) - 1, len(sc) - 2)
            cx = c2[j] + (c2[j + 1] - c2[j]) * (sx - sc[j]) / (sc[j + 1] - sc[j])
            part = _interval_times(v, np.array([cx]), c2[j + 1:j + 2], np.array([sc[j + 1] - sx]))
            rest = _interval_times(v, c2[j + 1:-1], c2[j + 2:], dsc[j + 1:])
            return float(first + part.sum() + rest.sum())

        lo = 0.5 * v0
        while t_slow(lo) < t_d and lo > 1e-3 * v0:
            lo *= 0.5
        if t_slow(v0) >= t_d:  # round-off at the boundary between the two sides
            return CruiseTarget(v0, 0.0, float(d))
        if t_slow(lo) >= t_d:
            v = brentq(lambda x: t_slow(x) - t_d, lo, v0, xtol=xtol_ms,
                       rtol=4 * np.finfo(float).eps, maxiter=200)
            return CruiseTarget(float(v), 0.0, float(d))
        # so much time that running down at d loses too little: try the next
        # (stronger) deceleration, at last an instant change
    # T(v) ≥ (L − s0)/v on this side, so v = (L − s0)/t_d is slow enough
    v_lo = (s[-1] - s[0]) / t_d
    v = brentq(lambda x: t_fast(x) - t_d, v_lo, v_top, xtol=xtol_ms, rtol=4 * np.finfo(float).eps,
               maxiter=200)
    return CruiseTarget(float(v), 0.0)


# --------------------------------------------------------------------------
# 2. The closed-loop run: one train driven by the time-keeping target
# --------------------------------------------------------------------------
ADVICE_POWER, ADVICE_HOLD, ADVICE_COAST, ADVICE_BRAKE = 0, 1, 2, 3
ADVICE_NAMES = ("power", "hold", "coast", "brake")
"""Driver-support indication per sample (int8 codes index this tuple)."""

RECOMPUTE_S = 1.0
"""Re-compute the target at least this often [s] ..."""
RECOMPUTE_M = 10.0
"""... and at least every this many metres [m] (whichever comes first)."""
COAST_BAND_MS = 2.0 / 3.6
"""Above the target by more than this [m/s] the advice is to coast (or trim-brake)."""
TRIM_DECEL_MS2 = 0.2
"""Deceleration [m/s²] used to shed speed above the target where coasting alone
would slow the train less (level track with little resistance, falling gradient):
a light brake, so a later scheduled arrival is still kept. Comfortable, well
below the service brake."""
HOLD_BAND_MS = 0.5 / 3.6
"""Below the target by less than this [m/s] the advice stays ``hold`` (the
constant-speed control makes it up), so the display does not flicker."""
COAST_MIN_DECEL_MS2 = 0.05
"""Coasting counts as a way to shed speed only where it slows the train by at
least this much [m/s²]; weaker coasting would need kilometres."""
ACCEL_FLOOR_MS2 = 0.02
"""Below this full-notch acceleration [m/s²] the acceleration envelope is left
out of the target computation (the train holds its speed rather than gains)."""
_W_TOL = 1e-9
"""Tolerance on v² [m²/s²] when comparing with a target or ceiling node value."""


def _compress(s: np.ndarray, w: np.ndarray, tol: float = 1e-7):
    """Keep only the nodes where the slope of a piecewise-linear w(s) changes.

    Lossless for the ceiling (linear in v² between grid nodes): the target
    computation then runs on tens of nodes instead of thousands.
    """
    if len(s) <= 2:
        return s.copy(), w.copy()
    slope = np.diff(w) / np.diff(s)
    keep = np.ones(len(s), dtype=bool)
    keep[1:-1] = np.abs(np.diff(slope)) > tol * np.maximum(1.0, np.abs(slope[1:]))
    return s[keep], w[keep]


GUIDE_TOL_MS2 = 0.01
"""Tolerance [m²/s²] on v² when the flat-out speed profile is thinned to the
nodes that matter (≈ 3e-4 m/s at 20 m/s: far below a 0.01 s effect on time)."""


def _compress_tol(s: np.ndarray, w: np.ndarray, tol: float):
    """Thin a sampled w(s) to a polyline within ``tol`` (Ramer–Douglas–Peucker).

    Exactly linear stretches (holding, constant-deceleration braking) keep
    only their ends; curved ones (powering) keep as many nodes as the
    tolerance needs.
    """
    n = len(s)
    if n <= 2:
        return s.copy(), w.copy()
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            continue
        x = s[i + 1:j]
        chord = w[i] + (w[j] - w[i]) * (x - s[i]) / (s[j] - s[i])
        dev = np.abs(w[i + 1:j] - chord)
        m = int(np.argmax(dev))
        if dev[m] > tol:
            keep[i + 1 + m] = True
            stack.append((i, i + 1 + m))
            stack.append((i + 1 + m, j))
    return s[keep], w[keep]


class _Vehicle:
    """Scalar force model of one train on one track: :mod:`planner.dynamics`, one speed at a time.

    The closed loop advances a single train, so numpy's per-call overhead on
    0-d arrays would dominate; this adapter evaluates the same formulas
    (dynamics' mass, track-acceleration and resistance functions, and its
    linear traction-curve interpolation and acceleration cap, re-stated for
    Python floats). ``tests/test_timekeeping_drive.py`` checks it against
    :func:`planner.dynamics.acceleration_ms2` on random speeds.
    """

    def __init__(self, track, train, load: float, traction_factor: float):
        from . import dynamics

        self.dyn = dynamics
        m = dynamics.mass_kg(train.empty_mass_kg, train.full_load_mass_kg, load)
        self.inv_me = 1.0 / float(dynamics.effective_mass_kg(m, train.rotating_mass_factor))
        self.ag = np.asarray(
            dynamics.track_accel_ms2(track.gradient, track.curve_specific, train.rotating_mass_factor),
            dtype=float,
        ).tolist()
        self.train = train
        self.tf = float(traction_factor)
        self._vs = [float(x) for x in train.traction_speed_ms]
        self._fs = [float(x) * self.tf for x in train.traction_effort_N]
        self._r = (float(train.davis_a_N), float(train.davis_b_N_per_ms), float(train.davis_c_N_per_ms2))
        self._amax = float(train.max_accel_ms2)

    def effort(self, v: float) -> float:
        """Full-notch tractive effort [N]: linear interpolation, end values held (as np.interp)."""
        vs, fs = self._vs, self._fs
        if v <= vs[0]:
            return fs[0]
        if v >= vs[-1]:
            return fs[-1]
        i = bisect.bisect_right(vs, v)
        return fs[i - 1] + (fs[i] - fs[i - 1]) * (v - vs[i - 1]) / (vs[i] - vs[i - 1])

    def resistance(self, v: float) -> float:
        """Davis running resistance [N]."""
        a, b, c = self._r
        return a + v * (b + c * v)

    def full(self, v: float, k: int) -> float:
        """Full-notch acceleration at speed v, grid node k [m/s²] (dynamics.acceleration_ms2)."""
        coast = self.ag[k] - self.resistance(v) * self.inv_me
        full = coast + self.effort(v) * self.inv_me
        return min(full, max(self._amax, coast))

    def coast(self, v: float, k: int) -> float:
        """Coasting acceleration at speed v, grid node k [m/s²] (resistance and track only)."""
        return self.ag[k] - self.resistance(v) * self.inv_me


def _piece(w0: float, slope: float, g0: float, g1: float, ds: float, from_below: bool):
    """One step: a piece of constant dw/ds ``slope`` until it meets the guide line, then the guide.

    The guide (target or ceiling, squared) runs linearly from g0 to g1 over the
    step. Returns (w1, dt) with each piece's time exact for constant
    acceleration, Δt = 2 Δs / (v_a + v_b) (the same scheme as
    :mod:`planner.run_curve`).
    """
    wend = w0 + slope * ds
    gap0, gap1 = w0 - g0, wend - g1
    cross = gap1 > 0.0 if from_below else gap1 < 0.0
    if cross:
        den = gap0 - gap1
        x = ds * min(max(gap0 / den, 0.0), 1.0) if den != 0.0 else 0.0
        wc = max(w0 + slope * x, 0.0)
        w1 = max(g1, 0.0)
    else:
        x, wc, w1 = ds, max(wend, 0.0), max(wend, 0.0)
    v0, vc, v1 = math.sqrt(w0), math.sqrt(wc), math.sqrt(w1)
    dt = 0.0
    if x > 0.0:
        dt += 2.0 * x / (v0 + vc) if v0 + vc > 0.0 else math.inf
    if ds - x > 0.0:
        dt += 2.0 * (ds - x) / (vc + v1) if vc + v1 > 0.0 else math.inf
    return w1, dt


@dataclass(frozen=True)
class ChangeRecord:
    """A scheduled-arrival change as the run applied it.

    Attributes
    ----------
    at_s : float
        Time after departure the change was sent [s].
    applied_s : float
        Time it took effect (the first grid node at or after ``at_s``) [s].
    arrival_s : float
        New scheduled arrival [s after departure].
    earliest_s : float
        Earliest possible arrival from the state at ``applied_s`` (full
        performance to the ceiling, then the stop) [s after departure].
    shortfall_s : float
        max(0, earliest − scheduled) [s]: how late the train must be.
    """

    at_s: float
    applied_s: float
    arrival_s: float
    earliest_s: float
    shortfall_s: float


@dataclass(frozen=True)
class DriveResult:
    """Outcome of :func:`drive` (arrays on the track's grid, SI).

    Attributes
    ----------
    s_m, t_s, v_ms, target_ms : ndarray
        Running distance [m], time after departure [s], speed [m/s] and the
        target the driver is shown [m/s] at every grid node.
    advice : ndarray of int8
        Index into :data:`ADVICE_NAMES` for the step arriving at each node
        (the first node repeats the first step's).
    time_s : float
        Arrival at the stop (speed zero) [s after departure].
    scheduled_s : float
        Scheduled arrival in force at the end [s after departure].
    stop_m : float
        Running distance where the train came to a stand [m].
    length_m : float
        Distance to the stop marker [m].
    shortfall_s : float
        Predicted lateness when the last scheduled arrival could not be met
        (see :class:`ChangeRecord`); 0 when it could.
    changes : tuple of ChangeRecord
        The departure schedule first (``at_s`` = 0), then every change.
    recomputes : int
        How many times the target was re-computed.
    """

    s_m: np.ndarray
    t_s: np.ndarray
    v_ms: np.ndarray
    target_ms: np.ndarray
    advice: np.ndarray
    time_s: float
    scheduled_s: float
    stop_m: float
    length_m: float
    shortfall_s: float
    changes: tuple
    recomputes: int

    @property
    def arrival_error_s(self) -> float:
        """Actual − scheduled arrival [s] (positive: late)."""
        return self.time_s - self.scheduled_s

    @property
    def stop_error_m(self) -> float:
        """Stop position − stop marker [m] (positive: overrun)."""
        return self.stop_m - self.length_m

    @property
    def feasible(self) -> bool:
        """True if the final scheduled arrival could be kept."""
        return self.shortfall_s <= 0.0


class _Driver:
    """The time-keeping driver on one track: shared set-up for the run and its look-aheads."""

    def __init__(self, track, train, load, traction_factor, recompute_s, recompute_m):
        from . import speed_profile

        self.track, self.train = track, train
        self.veh = _Vehicle(track, train, load, traction_factor)
        self.s = np.asarray(track.s_m, dtype=float)
        self.beta = float(train.stop_brake_ms2)
        # ceiling: on-board maximum lowered by service-brake curves to every drop
        # ahead and by the stopping-brake curve onto the marker (v², linear per step)
        self.c2 = np.asarray(speed_profile.ceiling_sq(
            self.s, np.asarray(track.vmax_ms, dtype=float), train.service_brake_ms2,
            track.length_m, train.stop_brake_ms2), dtype=float)
        self.stop2 = np.asarray(speed_profile.stop_curve_sq(self.s, track.length_m, train.stop_brake_ms2))
        self.gs, self.gw = _compress(self.s, self.c2)  # limit profile (see _plan)
        self.brake_max = max(train.service_brake_ms2, train.stop_brake_ms2)
        self.recompute_s, self.recompute_m = float(recompute_s), float(recompute_m)

    # -- the target ------------------------------------------------------------
    def target(self, k: int, t: float, v: float, arrival_s: float) -> CruiseTarget:
        """Limit-aware cruise speed from node k at time t and speed v."""
        s0 = self.s[k]
        j = int(np.searchsorted(self.gs, s0, side="right"))
        s_sub = np.concatenate([[s0], self.gs[j:]])
        w_sub = np.concatenate([[max(np.interp(s0, self.gs, self.gw), v * v)], self.gw[j:]])
        a0 = self.veh.full(v, k)
        # how the driver gets down to a lower target, gentlest first: coasting (where
        # it slows the train noticeably), a light trim brake, the service brake
        dc = -self.veh.coast(v, k)
        d_trim = max(TRIM_DECEL_MS2, dc)
        decels = ((dc,) if dc >= COAST_MIN_DECEL_MS2 else ()) + (d_trim, max(d_trim, self.train.service_brake_ms2))
        return cruise_speed_limited(
            arrival_s - t, s_sub, np.sqrt(np.maximum(w_sub, 0.0)), self.beta,
            v0_ms=v, accel_ms2=a0 if a0 > ACCEL_FLOOR_MS2 else None, decel_ms2=decels), dc

    # -- the integrator --------------------------------------------------------
    def run(self, k0: int, t0: float, v0: float, *, schedule=None, record=True):
        """Drive from node k0 (time t0, speed v0) to the stop.

        ``schedule`` None runs flat out (target = ceiling: the earliest
        arrival). Otherwise it is ``(arrival_s, changes)`` with changes sorted
        by time; the target is re-computed every ``recompute_s`` /
        ``recompute_m`` and at once when a change takes effect.
        """
        s, c2, stop2, veh = self.s, self.c2, self.stop2, self.veh
        m = len(s)
        b_serv = self.train.service_brake_ms2
        w, t = v0 * v0, t0
        vm2 = math.inf
        pending = list(schedule[1]) if schedule is not None else []
        records: list[ChangeRecord] = []
        shortfall = 0.0
        arrival = schedule[0] if schedule is not None else math.nan
        flat_out = schedule is None
        next_t, next_s = -math.inf, -math.inf
        committed = False
        recomputes = 0
        decel, coast_plan = TRIM_DECEL_MS2, False
        if record:
            out_t = np.empty(m - k0)
            out_v = np.empty(m - k0)
            out_tg = np.empty(m - k0)
            out_a = np.zeros(m - k0, dtype=np.int8)
            out_t[0], out_v[0] = t0, v0
        if schedule is not None:
            rec = self._plan(k0, t0, v0, 0.0, arrival)
            records.append(rec)
            shortfall = rec.shortfall_s
            flat_out = shortfall > 0.0
        for k in range(k0, m - 1):
            v = math.sqrt(w)
            # scheduled-arrival changes take effect at the first node at or after their time
            changed = False
            while pending and t >= pending[0][0] - 1e-12:
                at, arrival = pending.pop(0)
                if committed:
                    # already braking onto the marker: the stop cannot be re-planned
                    records.append(ChangeRecord(at, t, arrival, math.nan, math.nan))
                    continue
                rec = self._plan(k, t, v, at, arrival)
                records.append(rec)
                shortfall = rec.shortfall_s
                flat_out = shortfall > 0.0
                changed = True
            if not committed and w >= stop2[k] - 1e-9 and k > k0:
                committed = True  # on the stopping pattern: keep braking onto the marker
            if not flat_out and not committed and (changed or t >= next_t or s[k] >= next_s):
                tg, dc = self.target(k, t, v, arrival)
                recomputes += 1
                vm2 = tg.speed_ms ** 2 if tg.feasible else math.inf
                # getting down to a lower target: as planned (trim/coast, or the
                # service brake when that is needed to lose enough time)
                decel = tg.decel_ms2 if math.isfinite(tg.decel_ms2) else self.train.service_brake_ms2
                coast_plan = tg.decel_ms2 == dc
                next_t, next_s = t + self.recompute_s, s[k] + self.recompute_m
            if flat_out:
                vm2 = math.inf
            ds = s[k + 1] - s[k]
            c0, c1 = c2[k], c2[k + 1]
            g0, g1 = min(vm2, c0), min(vm2, c1)
            if w > c0 * (1.0 + 1e-12) + _W_TOL:
                # above the ceiling (never on a planned run, kept for safety): service brake
                w1, dt = _piece(w, -2.0 * b_serv, c0, c1, ds, from_below=False)
                adv = ADVICE_BRAKE
            elif w < g0 - _W_TOL:
                # below the target: full notch (Heun in v²) until it is reached
                a0 = veh.full(v, k)
                vp = math.sqrt(max(w + 2.0 * a0 * ds, 0.0))
                a1 = veh.full(vp, k + 1)
                w1, dt = _piece(w, a0 + a1, g0, g1, ds, from_below=True)
                # a small shortfall after a re-computation is made up within "hold"
                adv = ADVICE_POWER if v < math.sqrt(g0) - HOLD_BAND_MS else ADVICE_HOLD
            elif v > math.sqrt(g0) + COAST_BAND_MS:
                # well above the target (a later arrival): coast, or trim-brake if coasting is too weak
                a0 = veh.coast(v, k)
                vp = math.sqrt(max(w + 2.0 * a0 * ds, 0.0))
                a1 = veh.coast(vp, k + 1)
                slope = a0 + a1
                if coast_plan or slope <= -2.0 * decel:
                    adv = ADVICE_COAST
                else:
                    slope, adv = -2.0 * decel, ADVICE_BRAKE
                w1, dt = _piece(w, slope, g0, g1, ds, from_below=False)
            else:
                # at the target: constant-speed control follows it (the target line is
                # linear in v² over the step), within what power and brake can do
                need = (g1 - w) / ds
                a0 = veh.full(v, k)
                vp = math.sqrt(max(w + 2.0 * a0 * ds, 0.0))
                up = a0 + veh.full(vp, k + 1)
                # a braking curve of the ceiling is followed at whatever it asks (≤ the
                # brakes); a lowered cruise target only at the gentle trim rate
                follow_ceiling = c1 <= vm2
                lo = -2.0 * (self.brake_max if follow_ceiling else decel)
                if need > up:
                    w1, dt = _piece(w, up, g0, g1, ds, from_below=True)
                    adv = ADVICE_POWER if math.sqrt(g1) - math.sqrt(w1) > HOLD_BAND_MS else ADVICE_HOLD
                else:
                    slope = max(need, lo)
                    w1 = max(w + slope * ds, 0.0)
                    v1 = math.sqrt(w1)
                    dt = 2.0 * ds / (v + v1) if v + v1 > 0 else math.inf
                    if follow_ceiling and slope < -_W_TOL:
                        adv = ADVICE_BRAKE  # on a braking curve (restriction ahead, or the stop)
                    else:
                        adv = ADVICE_HOLD
            # the ceiling always holds (the last node is the marker: standing)
            w1 = min(w1, c1)
            if k + 1 == m - 1:
                w1 = 0.0
            if not math.isfinite(dt) or (w1 <= 0.0 and k + 1 < m - 1):
                raise InfeasibleError(
                    f"train type {self.train.train_type} stalls {self.track.origin}->"
                    f"{self.track.destination} at running distance {s[k + 1]:.1f} m: "
                    "tractive effort cannot overcome resistance and gradient")
            w, t = w1, t + dt
            if record:
                j = k + 1 - k0
                out_t[j], out_v[j], out_a[j] = t, math.sqrt(w), adv
                out_tg[j - 1] = math.sqrt(min(vm2, c0))
        if not record:
            return t, records, shortfall, recomputes, None
        out_tg[-1] = 0.0
        if len(out_a) > 1:
            out_a[0] = out_a[1]
        return t, records, shortfall, recomputes, (out_t, out_v, out_tg, out_a)

    def _plan(self, k: int, t: float, v: float, at: float, arrival: float) -> ChangeRecord:
        """Earliest possible arrival from the current state, and so the shortfall.

        The flat-out run's speed profile is also the highest speed the train
        can reach anywhere ahead (full power, braking only for the ceiling), so
        it replaces the ceiling as the limit profile of the target
        computation: power-limited stretches (long rises, acceleration out of
        a restriction) are then part of the prediction.
        """
        earliest, _, _, _, rec = self.run(k, t, v, schedule=None, record=True)
        self.gs, self.gw = _compress_tol(self.s[k:], np.square(rec[1]), GUIDE_TOL_MS2)
        return ChangeRecord(at, t, arrival, earliest, max(0.0, earliest - arrival))


def _check_schedule(arrival_s: float, changes) -> list[tuple[float, float]]:
    """Validate the scheduled arrival and the changes; return changes sorted by time."""
    if not (isinstance(arrival_s, (int, float, np.floating)) and math.isfinite(arrival_s) and arrival_s > 0):
        raise InputError(f"scheduled arrival must be a positive number of seconds after departure, "
                         f"got {arrival_s!r} (--arrival)")
    out = []
    for i, ch in enumerate(changes):
        try:
            at, new = (float(x) for x in ch)
        except (TypeError, ValueError):
            raise InputError(f"change {i} must be (seconds after departure, new arrival), got {ch!r} "
                             "(--change T:ARRIVAL)") from None
        if not (math.isfinite(at) and math.isfinite(new) and at >= 0.0 and new > 0.0):
            raise InputError(f"change {i} ({at:g}:{new:g}) needs a time ≥ 0 and a new arrival > 0 "
                             "seconds after departure (--change T:ARRIVAL)")
        out.append((at, new))
    return sorted(out, key=lambda c: c[0])


def drive(track, train, arrival_s: float, *, changes=(), load: float = 0.0,
          traction_factor: float = 1.0, recompute_s: float = RECOMPUTE_S,
          recompute_m: float = RECOMPUTE_M) -> DriveResult:
    """Closed-loop run of one train driven by the time-keeping target (DESIGN §4).

    The on-board logic, at departure, every ``recompute_s`` seconds or
    ``recompute_m`` metres (whichever first) and at once when a change of the
    scheduled arrival takes effect, computes the cruise speed v_m with
    :func:`cruise_speed_limited` from the remaining time and the remaining
    distance under the ceiling (on-board maximum lowered by the service-brake
    curves to every drop ahead and by the stopping-brake curve at β =
    ``train.stop_brake_ms2``), including the constant-acceleration envelope
    from the current speed. The train follows the target min(v_m, ceiling):

    * below it: full notch (``power``) until it is reached;
    * at it: constant-speed control (``hold``), trimming down at most
      :data:`TRIM_DECEL_MS2` when v_m is lowered, following braking curves
      of the ceiling at the deceleration they ask (``brake``);
    * above it by more than :data:`COAST_BAND_MS` (a later arrival): coast if
      that slows the train by at least the trim deceleration, else a light
      trim brake (``coast`` / ``brake``);
    * above the ceiling: service brake (``brake``);
    * once on the stopping pattern (v² ≥ 2β(L − s)) the stop is committed:
      it brakes at β onto the marker, and later changes are recorded but
      cannot re-plan the stop.

    Whenever the schedule is set (departure and each change) an earliest-
    arrival look-ahead runs the same train flat out (target = ceiling) from
    the current state. If even that is later than the scheduled arrival the
    run reports the shortfall and drives flat out — it is never silently
    missed.

    Integration is the scheme of :mod:`planner.run_curve` on the track's grid
    (Heun's method in v² against distance, pieces split where they meet the
    target or ceiling, Δt = 2Δs/(v₀ + v₁) per constant-acceleration piece),
    with the forces of :mod:`planner.dynamics`. A change takes effect at the
    first grid node at or after its time (≤ one step, ≈ 0.05 s at speed).

    Parameters
    ----------
    track : planner.run_curve.Track
    train : planner.model.TrainType
        Must be ``track``'s train type.
    arrival_s : float
        Scheduled arrival [s after departure].
    changes : sequence of (at_s, arrival_s)
        At ``at_s`` seconds after departure the scheduled arrival becomes
        ``arrival_s`` seconds after departure.
    load, traction_factor : float
        Load factor and tractive-effort multiplier of the real train.
    recompute_s, recompute_m : float
        Re-computation period [s] and spacing [m].

    Returns
    -------
    DriveResult
    """
    if train.train_type != track.train_type:
        raise InputError(f"track is for train type {track.train_type!r}, not {train.train_type!r}")
    if not (load >= 0.0 and traction_factor > 0.0):
        raise InputError(f"load must be ≥ 0 and traction factor > 0, got {load} and {traction_factor}")
    ch = _check_schedule(arrival_s, changes)
    drv = _Driver(track, train, float(load), float(traction_factor), recompute_s, recompute_m)
    t_end, records, shortfall, recomputes, rec = drv.run(0, 0.0, 0.0, schedule=(float(arrival_s), ch))
    out_t, out_v, out_tg, out_a = rec
    s = drv.s
    # the stop: the first node after departure where the train stands (the marker, unless it stalled)
    standing = np.flatnonzero(out_v[1:] <= 0.0)
    stop_m = float(s[1 + standing[0]]) if len(standing) else float(s[-1])
    # changes that came while braking onto the marker could not re-plan the stop:
    # the earliest arrival was the committed one
    records = [r if math.isfinite(r.earliest_s) else
               ChangeRecord(r.at_s, r.applied_s, r.arrival_s, t_end, max(0.0, t_end - r.arrival_s))
               for r in records]
    shortfall = records[-1].shortfall_s
    return DriveResult(
        s_m=s.copy(), t_s=out_t, v_ms=out_v, target_ms=out_tg, advice=out_a, time_s=float(t_end),
        scheduled_s=float(records[-1].arrival_s), stop_m=stop_m, length_m=float(track.length_m),
        shortfall_s=float(shortfall), changes=tuple(records), recomputes=recomputes)


# --------------------------------------------------------------------------
# 3. High-level API
# --------------------------------------------------------------------------
@dataclass(frozen=True)
class TimekeepingResult:
    """Result of :func:`timekeeping_run` (a ``RunResult``-like object).

    Attributes
    ----------
    time_s : float
        Actual arrival [s after departure].
    scheduled_s : float
        Scheduled arrival in force at the end [s after departure].
    arrival_error_s : float
        ``time_s − scheduled_s`` [s] (positive: late).
    stop_error_m : float
        Stop position − stop marker [m] (positive: overrun).
    shortfall_s : float
        > 0 when the scheduled arrival could not be met at all: the predicted
        lateness (earliest possible arrival − scheduled). The run then drives
        flat out and ``arrival_error_s`` ≈ ``shortfall_s``.
    curve : pandas.DataFrame
        One row per grid node: ``position_m`` (chainage), ``distance_m``
        (from the departure marker), ``time_s``, ``speed_kmh``,
        ``target_kmh`` (the speed the driver is shown), ``advice``
        (``power``/``hold``/``coast``/``brake``).
    changes : pandas.DataFrame
        The schedule at departure and every change: ``at_s``, ``applied_s``,
        ``arrival_s``, ``earliest_s``, ``shortfall_s``.
    drive : DriveResult
        The arrays behind it.
    """

    time_s: float
    scheduled_s: float
    arrival_error_s: float
    stop_error_m: float
    shortfall_s: float
    curve: object
    changes: object
    drive: DriveResult

    @property
    def feasible(self) -> bool:
        """True if the final scheduled arrival could be kept."""
        return self.shortfall_s <= 0.0


def _as_line(line_or_path):
    from .model import Line

    if isinstance(line_or_path, Line):
        return line_or_path
    from . import load_line

    return load_line(line_or_path)


def timekeeping_run(line_or_path, train_type: str, origin: str, destination: str, *,
                    arrival_s: float, changes=(), load: float = 0.0,
                    traction_factor: float = 1.0, settings=None,
                    recompute_s: float = RECOMPUTE_S, recompute_m: float = RECOMPUTE_M) -> TimekeepingResult:
    """One interstation driven in time-keeping mode (DESIGN §4); see :func:`drive`.

    Parameters
    ----------
    line_or_path : Line or str or Path
        A loaded line or a line database folder.
    train_type, origin, destination : str
        Train type and the two stations (direction follows from them).
    arrival_s : float
        Scheduled arrival [s after departure].
    changes : sequence of (at_s, arrival_s)
        Scheduled-arrival changes: at ``at_s`` seconds after departure the
        arrival becomes ``arrival_s`` seconds after departure.
    load, traction_factor : float
        Conditions of the real train (load factor, traction multiplier).
    settings : planner.run_curve.SimSettings, optional
        Grid step (default 1 m).

    Returns
    -------
    TimekeepingResult

    Examples
    --------
    >>> from planner import testing
    >>> line = testing.line(length_m=1000.0, limits=[(400.0, 600.0, 60.0)])
    >>> r = timekeeping_run(line, "T", "S0", "S1", arrival_s=80.0, changes=[(40.0, 90.0)])
    >>> abs(r.arrival_error_s) < 0.2 and abs(r.stop_error_m) < 0.2
    True
    """
    import pandas as pd

    from .run_curve import SimSettings, make_track
    from .units import kmh

    line = _as_line(line_or_path)
    train = line.train_type(train_type)
    track = make_track(line, train_type, origin, destination,
                       settings=settings if settings is not None else SimSettings())
    d = drive(track, train, arrival_s, changes=changes, load=load, traction_factor=traction_factor,
              recompute_s=recompute_s, recompute_m=recompute_m)
    curve = pd.DataFrame({
        "position_m": np.asarray(track.position_m(d.s_m), dtype=float),
        "distance_m": d.s_m,
        "time_s": d.t_s,
        "speed_kmh": kmh(d.v_ms),
        "target_kmh": kmh(d.target_ms),
        "advice": pd.Categorical.from_codes(d.advice.astype(int), categories=list(ADVICE_NAMES)),
    })
    ch = pd.DataFrame([r.__dict__ for r in d.changes],
                      columns=["at_s", "applied_s", "arrival_s", "earliest_s", "shortfall_s"])
    return TimekeepingResult(
        time_s=d.time_s, scheduled_s=d.scheduled_s, arrival_error_s=d.arrival_error_s,
        stop_error_m=d.stop_error_m, shortfall_s=d.shortfall_s, curve=curve, changes=ch, drive=d)


def closed_loop_runner(track, train, tables, designated_s, sc, mode="timekeeping"):
    """Runner for :func:`planner.closed_loop.register_runner` (``planner simulate --mode timekeeping``).

    Drives every designated running time of the sweep in time-keeping mode
    (no tables needed: the target comes from the remaining time and distance)
    under the scenario's load and traction.

    Returns
    -------
    actual_s : ndarray (n,)
        Simulated running times [s].
    ratios : ndarray (n, n_x)
        NaN: this mode chooses no ratios (shape as the table modes' for the datasets).
    """
    designated = np.asarray(designated_s, dtype=float).reshape(-1)
    actual = np.array([drive(track, train, float(t), load=sc.load, traction_factor=sc.traction_factor).time_s
                       for t in designated])
    n_x = len(getattr(tables, "eval_point_ids", ()))
    return actual, np.full((len(designated), n_x), np.nan)
