"""Interpolation and ratio solving of the on-board logic, vectorised over the runs of a batch.

The on-board logic (:mod:`planner.tables.onboard`) asks a few numbers per run and evaluation point:
a table row at a fractional ratio, a row's value at a ratio, the ratio that meets a wanted time.
Each function here answers them for every run of a batch at once: one row of values per run (or
one row shared by all), one ratio per run. The arithmetic is elementwise and in the order of the
one-run rule it states (the tests check it to the bit against ``np.interp`` and against that rule
run by run), so a run's answer does not depend on the batch it is in.
"""
from __future__ import annotations

import numpy as np

__all__ = ["interp_u", "row_at_ratio", "solve_piecewise"]


def _clip_ratio(ratios: np.ndarray, r) -> np.ndarray:
    """``r`` clipped to the descending grid's range, as an array of shape (n,)."""
    return np.minimum(np.maximum(np.atleast_1d(np.asarray(r, float)), ratios[-1]), ratios[0])


def interp_u(ratios: np.ndarray, values: np.ndarray, r) -> np.ndarray:
    """``values`` (given at the descending grid ``ratios``) at ratio ``r``, linear in ``1/r``.

    Parameters
    ----------
    ratios : ndarray, shape (n_r,)
        Grid ratios, descending.
    values : ndarray, shape (n_r,) or (n, n_r)
        One row shared by every run, or one row per run.
    r : float or ndarray, shape (n,)
        Ratio per run; clipped to the grid's range.

    Returns
    -------
    ndarray, shape (n,)
        Per run, what ``np.interp(1 / r, 1 / ratios, row)`` gives, with its special cases (an
        infinite value, e.g. a stalled entry) and its operations.
    """
    ratios = np.asarray(ratios, float)
    u = 1.0 / ratios
    x = 1.0 / _clip_ratio(ratios, r)
    v = np.broadcast_to(np.asarray(values, float), x.shape + u.shape)
    n_r = u.size
    j = np.clip(np.searchsorted(u, x, side="right") - 1, 0, max(n_r - 2, 0))
    j1 = np.minimum(j + 1, n_r - 1)
    runs = np.arange(x.size)
    y0, y1 = v[runs, j], v[runs, j1]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        slope = (y1 - y0) / (u[j1] - u[j])
        out = slope * (x - u[j]) + y0
        nan = np.isnan(out)
        if nan.any():  # as numpy: from the other end, then the flat value
            other = slope * (x - u[j1]) + y1
            other = np.where(np.isnan(other) & (y0 == y1), y0, other)
            out = np.where(nan, other, out)
    out = np.where(u[j] == x, y0, out)
    out = np.where(x >= u[-1], v[:, -1], out)
    return np.where(x < u[0], v[:, 0], out)


def row_at_ratio(ratios: np.ndarray, table: np.ndarray, r) -> np.ndarray:
    """Rows of ``table`` (one per grid ratio) at a fractional ratio per run, linear in ``1/r``.

    Parameters
    ----------
    ratios : ndarray, shape (n_r,)
        Grid ratios, descending.
    table : ndarray, shape (n_r, m)
        Row ``i`` belongs to ``ratios[i]``.
    r : float or ndarray, shape (n,)
        Ratio per run; clipped to the grid's range.

    Returns
    -------
    ndarray, shape (n, m)
        A grid ratio's own row where ``r`` is one (or the lowest); else ``(1 − f) row_i + f row_i+1``
        with ``f`` the fraction of the way from ``1/ratios[i]`` to ``1/ratios[i + 1]``.
    """
    ratios = np.asarray(ratios, float)
    rb = _clip_ratio(ratios, r)
    n_r = ratios.size
    # ratios descend: i is the last grid ratio >= rb
    i = np.clip(np.searchsorted(-ratios, -rb, side="right") - 1, 0, n_r - 1)
    i1 = np.minimum(i + 1, n_r - 1)
    exact = (i == n_r - 1) | (ratios[i] == rb)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (1.0 / rb - 1.0 / ratios[i]) / (1.0 / ratios[i1] - 1.0 / ratios[i])
        mixed = (1.0 - f)[:, None] * table[i] + f[:, None] * table[i1]
    return np.where(exact[:, None], table[i], mixed)


def solve_piecewise(ratios: np.ndarray, values_s: np.ndarray, want_s, prefer) -> np.ndarray:
    """Per run, the ratio where the piecewise-linear-in-``1/r`` function through its row equals ``want_s``.

    Unlike :func:`planner.tables.onboard.solve_ratio` the function need not be monotone (a sawtooth
    train's times are not, and a learned correction can add noise): every crossing is found exactly,
    segment by segment, and the one nearest the ratio ``prefer`` (the current ratio) in ``u = 1/r``
    wins — the smallest change of driving that the tables say arrives on time. A whole segment on
    the wanted time offers its point nearest ``prefer``, after the crossings. Of equal distances the
    first candidate wins. Without a candidate, the grid ratio whose value is nearest ``want_s``
    (within 1e-12 s; ties: nearest ``prefer``, then the first).

    Parameters
    ----------
    ratios : ndarray, shape (n_r,)
        Grid ratios, descending.
    values_s : ndarray, shape (n, n_r)
        Predicted time at each grid ratio, per run [s].
    want_s : float or ndarray, shape (n,)
        Wanted time per run [s].
    prefer : float or ndarray, shape (n,)
        Current ratio per run.

    Returns
    -------
    ndarray, shape (n,)
        Ratio per run, in [ratios[-1], ratios[0]].

    Examples
    --------
    >>> r = np.array([1.0, 0.5, 0.25])
    >>> f = np.array([[100.0, 200.0, 150.0], [100.0, 200.0, 150.0]])
    >>> np.round(solve_piecewise(r, f, 175.0, [1.0, 0.25]), 4)   # two crossings: the nearer one
    array([0.5714, 0.3333])
    """
    ratios = np.asarray(ratios, float)
    u = 1.0 / ratios
    up = 1.0 / _clip_ratio(ratios, prefer)
    f = np.asarray(values_s, float).reshape(up.size, u.size)
    want = np.broadcast_to(np.asarray(want_s, float), up.shape)[:, None]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        d0, d1 = f[:, :-1] - want, f[:, 1:] - want
        cross = (d0 * d1 <= 0.0) & (f[:, :-1] != f[:, 1:])
        crossing = u[:-1] + d0 / (d0 - d1) * (u[1:] - u[:-1])
    flat = ~cross & (d0 == 0.0) & (d1 == 0.0)
    on_flat = np.minimum(np.maximum(up[:, None], u[:-1]), u[1:])
    cand = np.concatenate([crossing, on_flat], axis=1)
    valid = np.concatenate([cross, flat], axis=1)
    dist = np.abs(cand - up[:, None])
    runs = np.arange(up.size)
    first = np.argmax(valid, axis=1)
    nearest = np.argmin(np.where(valid & ~np.isnan(dist), dist, np.inf), axis=1)
    # a scan keeps its first candidate unless a later one is strictly nearer (never one at NaN)
    keep_first = np.isnan(dist[runs, first]) | ~np.isfinite(dist[runs, nearest]) | ~valid[runs, nearest]
    best = np.where(keep_first, first, nearest)
    by_crossing = 1.0 / cand[runs, best]
    err = np.abs(f - want)
    close = err <= err.min(axis=1, keepdims=True) + 1e-12
    j = np.argmin(np.where(close, np.abs(u[None, :] - up[:, None]), np.inf), axis=1)
    return np.where(valid.any(axis=1), by_crossing, 1.0 / u[j])
