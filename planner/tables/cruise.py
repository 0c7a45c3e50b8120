"""The cruise speed that arrives on time (docs/design.md §4): pure target-speed functions.

From the remaining time t_d and distance x_d and the stopping deceleration β:
:func:`cruise_speed` (the closed form of §4), :func:`braking_pattern_speed`,
:func:`cruise_speed_limited` (the same under a position-dependent on-board
maximum, solved exactly on a distance grid, optionally with the way from the
current speed) and :func:`profile_time`. Floats and arrays in SI; no I/O. The
time-keeping controller (:mod:`planner.tables.timekeeping`) calls them.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

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
    from which braking at ``β`` still stops at the marker (docs/design.md §4).

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
    arriving after exactly t_d means (docs/design.md §4)

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


def _run_down_time(sc, c2, v0: float, d: float):
    """T(v) for running down from v0 at ``d`` to v (reached at s_x), then holding v, never above the
    ceiling ``c2`` (u² on the nodes ``sc``): ∫ under min(C, run-down line) up to s_x (the same for
    every v: prefix sums) + ∫ under min(C, v) after s_x."""
    dsc = np.diff(sc)
    sd, md = _min_with_line(sc, c2, v0 * v0 - 2.0 * d * (sc - sc[0]))
    ud = np.sqrt(np.maximum(md, 0.0))
    dsd = np.diff(sd)
    with np.errstate(divide="ignore", invalid="ignore"):
        pieces = np.where(dsd > 0.0, 2.0 * dsd / (ud[:-1] + ud[1:]), 0.0)
    cum_d = np.concatenate([[0.0], np.cumsum(pieces)])

    def t_slow(v):
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

    return t_slow


def _slower_target(t_d: float, sc, c2, v0: float, decels, xtol_ms: float) -> CruiseTarget | None:
    """The cruise speed below v0 reached by running down at the first of ``decels`` that can still
    take ``t_d``; None when none can (so much time that running down loses too little: the caller
    then changes speed instantly)."""
    from scipy.optimize import brentq

    for d in decels:
        t_slow = _run_down_time(sc, c2, v0, float(d))
        lo = 0.5 * v0
        while t_slow(lo) < t_d and lo > 1e-3 * v0:
            lo *= 0.5
        if t_slow(v0) >= t_d:  # round-off at the boundary between the two sides
            return CruiseTarget(v0, 0.0, float(d))
        if t_slow(lo) >= t_d:
            v = brentq(lambda x: t_slow(x) - t_d, lo, v0, xtol=xtol_ms,
                       rtol=4 * np.finfo(float).eps, maxiter=200)
            return CruiseTarget(float(v), 0.0, float(d))
    return None


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
        docs/design.md §4).
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
    if v0 is not None and v0 > 0.0 and decels and t_fast(v0) < t_d:
        slower = _slower_target(t_d, sc, c2, v0, decels, xtol_ms)
        if slower is not None:
            return slower
    # T(v) ≥ (L − s0)/v on this side, so v = (L − s0)/t_d is slow enough
    v_lo = (s[-1] - s[0]) / t_d
    v = brentq(lambda x: t_fast(x) - t_d, v_lo, v_top, xtol=xtol_ms, rtol=4 * np.finfo(float).eps,
               maxiter=200)
    return CruiseTarget(float(v), 0.0)
