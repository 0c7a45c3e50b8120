"""One-number interpolation and ratio solving of the on-board logic, in Python floats.

The on-board logic (:mod:`planner.tables.onboard`) asks a few numbers per run
and evaluation point: a table row at a fractional ratio, the ratio that meets a
wanted time. On arrays of a few dozen values numpy's calls cost more to set up
than to use, so these walk the values in Python floats, with the same IEEE
operations in the same order as the array expressions they replaced (the tests
check them to the bit against ``np.interp`` and the array form).
"""
from __future__ import annotations

import bisect
import math

import numpy as np

__all__ = ["clip_number", "interp_u", "solve_piecewise"]


def clip_number(x, lo, hi):
    """``np.clip`` of one number, the same value without numpy's call overhead (the on-board logic
    clips a few numbers per run and point; ``np.clip`` was a third of the closed loop's time)."""
    return min(max(x, lo), hi)


_INVERSE_LIST: dict[int, tuple] = {}


def _inverse_list(ratios) -> list[float]:
    """``1 / ratios`` of a grid as Python floats, computed once per grid array (the array is kept, so
    its id stays its own)."""
    hit = _INVERSE_LIST.get(id(ratios))
    if hit is not None and hit[0] is ratios:
        return hit[1]
    if len(_INVERSE_LIST) > 256:
        _INVERSE_LIST.clear()
    u = (1.0 / np.asarray(ratios, float)).tolist()
    _INVERSE_LIST[id(ratios)] = (ratios, u)
    return u


def interp_u(ratios: np.ndarray, values: np.ndarray, r: float) -> float:
    """``values`` (given at the descending grid ``ratios``) at ratio ``r``, linear in ``1/r``.

    ``np.interp`` of one number, written out in Python floats with numpy's own special cases
    and operations (the same bits: tested against it), without its call overhead.
    """
    u = _inverse_list(ratios)
    x = float(1.0 / clip_number(r, ratios[-1], ratios[0]))
    n = len(u)
    if x > u[-1]:
        return float(values[n - 1])
    if x < u[0]:
        return float(values[0])
    if x == u[-1]:
        return float(values[n - 1])
    j = bisect.bisect_right(u, x) - 1  # u[j] <= x < u[j + 1]
    y0 = float(values[j])
    if u[j] == x:
        return y0
    y1 = float(values[j + 1])
    slope = (y1 - y0) / (u[j + 1] - u[j])
    out = slope * (x - u[j]) + y0
    if math.isnan(out):  # as numpy: from the other end, then the flat value
        out = slope * (x - u[j + 1]) + y1
        if math.isnan(out) and y0 == y1:
            out = y0
    return out


def solve_piecewise(ratios: np.ndarray, values_s: np.ndarray, want_s: float, prefer: float) -> float:
    """Ratio where the piecewise-linear-in-``1/r`` function through ``values_s`` equals ``want_s``.

    Unlike :func:`solve_ratio` the function need not be monotone (a sawtooth train's times are
    not, and a learned correction can add noise): every crossing is found exactly, segment by
    segment, and the one nearest the ratio ``prefer`` (the current ratio) in ``u = 1/r`` wins —
    the smallest change of driving that the tables say arrives on time. Without a crossing, the
    grid ratio whose value is nearest ``want_s`` (ties: nearest ``prefer``).

    Parameters
    ----------
    ratios : ndarray
        Grid ratios, descending.
    values_s : ndarray
        Predicted time at each grid ratio [s].
    want_s : float
        Wanted time [s].
    prefer : float
        Current ratio.

    Returns
    -------
    float
        Ratio in [ratios[-1], ratios[0]].

    Examples
    --------
    >>> r = np.array([1.0, 0.5, 0.25])
    >>> round(solve_piecewise(r, np.array([100.0, 200.0, 150.0]), 175.0, 1.0), 4)   # two crossings
    0.5714
    >>> round(solve_piecewise(r, np.array([100.0, 200.0, 150.0]), 175.0, 0.25), 4)
    0.3333
    """
    # one pass over the segments in Python floats: the same IEEE operations, in the same order, as
    # the array expressions this replaced (arrays of a few dozen values cost more to set up than to use)
    u = _inverse_list(ratios)
    f = np.asarray(values_s, float).tolist()
    up = 1.0 / float(clip_number(prefer, ratios[-1], ratios[0]))
    cand: list[float] = []
    flat: list[float] = []
    for i in range(len(f) - 1):
        d0, d1 = f[i] - want_s, f[i + 1] - want_s
        if d0 * d1 <= 0.0 and f[i] != f[i + 1]:
            cand.append(u[i] + d0 / (d0 - d1) * (u[i + 1] - u[i]))
        elif d0 == 0.0 and d1 == 0.0:  # a whole segment on the wanted time: its point nearest prefer
            flat.append(min(max(up, u[i]), u[i + 1]))
    cand += flat
    if cand:
        best_c, best_d = cand[0], abs(cand[0] - up)
        for c in cand[1:]:
            if abs(c - up) < best_d:  # the first of equal distances, as argmin
                best_c, best_d = c, abs(c - up)
        return float(1.0 / best_c)
    err = [abs(x - want_s) for x in f]
    lim = min(err) + 1e-12
    best = [i for i, e in enumerate(err) if e <= lim]
    j = best[0]
    for i in best[1:]:
        if abs(u[i] - up) < abs(u[j] - up):
            j = i
    return float(1.0 / u[j])
