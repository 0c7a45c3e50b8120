"""Constant-jerk pieces of a stopping pattern: closed forms and roots, compiled (docs/design.md §5).

The scalar arithmetic under :mod:`planner.stopping.construct`: the state after
a time on a piece, the time to reach a speed or a position, the residuals whose
roots place the switching points of motion 4, and the root finder. All in the
backward frame of the construction (``y`` distance still to run, ``v`` speed,
``b`` deceleration, ``u`` jerk: ``dy/dtau = v``, ``dv/dtau = b``, ``db/dtau = u``).

Compiled with numba, each function with its one signature when this module is
first imported (:func:`planner.stopping.pattern.solve_stop` imports it on its
first call): a solve is a few hundred float operations spread over tens of
small functions, and as Python it cost 0.1-0.3 ms, nearly all interpreter
overhead. ``cache=False``: numba's on-disk cache is a pickled index plus
machine code read back from ``__pycache__`` and run, which the project's rule
(nothing read back from disk may execute code) forbids, so every process
compiles once (figures in ``benchmarks/bench_stopping.py``).
"""
from __future__ import annotations

import math

from numba import njit
from numba import types as nt

_INF = math.inf


def jit(sig, public=False, nrt=False, inline="never"):
    """Compile now with the one signature ``sig``: internal calls convert their arguments to it
    and never respecialise (a constant argument would otherwise compile one copy per value).

    ``nrt``: numba's reference-counted memory, needed only to allocate (nothing here does: the
    caller passes one work array); without it a call does not count references to each of its
    array arguments, atomically, on entry and exit (that was 15 % of a solve). ``inline="always"``:
    compiled into every caller (the root search, the objective of the entry choice: called in
    every trial with dozens of words of arguments). Neither changes an operation on a float."""
    return njit(sig, cache=False, error_model="numpy", nogil=True, no_cpython_wrapper=not public,
                no_cfunc_wrapper=True, _nrt=nrt, inline=inline)


f8, i8, b1 = nt.float64, nt.int64, nt.boolean
V = nt.float64[::1]  # a float vector
ST = nt.float64[:, :, ::1]  # the node store of the construction
NS = nt.int64[::1]  # node counts of the node store
STEPS = nt.float64[:, ::1]  # step functions, rows (x_from, value)
F3 = nt.UniTuple(f8, 3)
IF = nt.Tuple((i8, f8))

# residual kinds of the motion-4 searches
ENERGY, AT_CAP, REACH = 0, 1, 2


# --------------------------------------------------------------------------------------
# Scalar helpers
# --------------------------------------------------------------------------------------


@jit(f8(f8, f8))
def _pmax(a, b):
    """Python's ``max(a, b)`` for floats (keeps ``a`` unless ``b > a``)."""
    return b if b > a else a


@jit(f8(f8, f8))
def _pmin(a, b):
    """Python's ``min(a, b)`` for floats (keeps ``a`` unless ``b < a``)."""
    return b if b < a else a


@jit(F3(f8, f8, f8, f8, f8))
def _adv(y, v, b, u, s):
    """Backward state after time ``s`` on a piece of jerk ``u`` (db/dtau = u)."""
    return (
        y + s * (v + s * (b / 2.0 + u * s / 6.0)),
        v + s * (b + u * s / 2.0),
        b + u * s,
    )


@jit(f8(f8, f8, f8, f8))
def _time_to_speed(v, b, u, C):
    """Time until ``v + b s + u s²/2`` reaches ``C`` on a piece with ``u >= 0`` (inf if never)."""
    dv = C - v
    if dv <= 0.0:
        return 0.0
    if u > 0.0:
        return 2.0 * dv / (b + math.sqrt(b * b + 2.0 * u * dv))
    if b > 0.0:
        return dv / b
    return _INF


@jit(f8(f8, f8, f8, f8, f8, f8))
def _time_to_y(y, v, b, u, Y, s_up):
    """Time until the position ``y(s)`` reaches ``Y`` (>= y); ``s_up`` an upper bound when u < 0.

    y(s) is increasing and convex on every piece (v >= 0, b >= 0 throughout), so
    Newton from an upper bound converges monotonically to the root of the cubic.
    """
    D = Y - y
    if D <= 0.0:
        return 0.0
    if D == _INF:
        return _INF
    if u == 0.0:
        if b > 0.0:
            return 2.0 * D / (v + math.sqrt(v * v + 2.0 * b * D))
        return D / v if v > 0.0 else _INF
    if u > 0.0:
        # each term of v s + b s²/2 + u s³/6 alone reaching D bounds s from above
        s = (6.0 * D / u) ** (1.0 / 3.0)
        if v > 0.0:
            s = _pmin(s, D / v)
        if b > 0.0:
            s = _pmin(s, math.sqrt(2.0 * D / b))
    else:
        s = s_up
    for _ in range(60):
        f = s * (v + s * (b / 2.0 + u * s / 6.0)) - D
        df = v + s * (b + u * s / 2.0)
        if df <= 0.0:
            break
        step = f / df
        s -= step
        if abs(step) <= 1e-15 * s + 1e-300:
            break
    return _pmax(s, 0.0)


@jit(f8(i8, f8, f8, f8, f8, f8, f8))
def _residual(kind, p1, p2, J, y, v, b):
    """The increasing residual of a motion-4 search at the state (y, v, b).

    ENERGY (cap ``p1``): speed reached by easing off now, minus the cap.
    AT_CAP (cap ``p1`` at ``p2``): where easing off from here reaches the cap, minus ``p2``
    (negated: increasing). REACH (limit ``p1`` at ``p2``): where easing off meets
    ``b = p1``, minus the event point ``p2``.
    """
    if kind == ENERGY:
        return v + b * b / (2.0 * J) - p1
    if kind == AT_CAP:
        dv = p1 - v
        if dv <= 0.0:
            return p2 - y
        disc = b * b - 2.0 * J * dv
        if disc < 0.0:
            disc = 0.0
        rr = 2.0 * dv / (b + math.sqrt(disc))
        return p2 - (y + rr * (v + rr * (b / 2.0 - J * rr / 6.0)))
    if b <= p1:
        return y - p2
    rr = (b - p1) / J
    return y + rr * (v + rr * (b / 2.0 - J * rr / 6.0)) - p2


@jit(f8(i8, f8, f8, f8, f8, f8, f8, f8, f8, f8, f8, f8, f8), inline="always")
def _illinois(kind, p1, p2, J, y0, v0, b0, u0, lo, hi, flo, fhi, ftol):
    """Root in ``s`` of the residual along one piece, increasing, ``flo <= 0 < fhi`` (Illinois)."""
    side = 0
    s = lo
    for _ in range(200):
        if fhi - flo <= 0.0:
            return lo
        s = (lo * fhi - hi * flo) / (fhi - flo)
        if not lo <= s <= hi:
            s = 0.5 * (lo + hi)
        y, v, b = _adv(y0, v0, b0, u0, s)
        fs = _residual(kind, p1, p2, J, y, v, b)
        if abs(fs) <= ftol or hi - lo <= 4e-16 * _pmax(1.0, abs(hi)):
            return s
        if fs > 0.0:
            hi, fhi = s, fs
            if side == 1:
                flo *= 0.5
            side = 1
        else:
            lo, flo = s, fs
            if side == -1:
                fhi *= 0.5
            side = -1
    return s


@jit(i8(V, f8))
def _region_of(Yb, y):
    """Region an open motion starting at ``y`` runs in (a boundary belongs to the far side)."""
    lo, hi = 0, Yb.size
    while lo < hi:  # bisect_right
        mid = (lo + hi) // 2
        if y < Yb[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo - 1
