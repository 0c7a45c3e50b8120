"""The compiled loops of delay propagation (:mod:`planner.delay.propagate`): one entry point each, one signature.

Built ahead of time at install with the other kernels (``planner kernels build``, :mod:`planner.io.compiled`);
without a build (or with ``PLANNER_JIT=1``) numba compiles them just in time in each process that uses them.
"""
from __future__ import annotations

import numpy as np
from numba import njit

# the signatures of the build; just in time, numba compiles each on its first call
PROPAGATE = "void(i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], f8[:, ::1], f8[:, ::1], f8[::1], i8[::1], f8[::1])"
HISTOGRAM = "void(f8[:, ::1], f8[::1], i8[:, ::1])"


@njit(nogil=True)
def propagate(order, in_ptr, in_act, act_src, slack, prim, z, push, binds, absorbed):  # pragma: no cover - compiled
    n_days = z.shape[1]
    best = np.empty(n_days)
    for e in order:
        for d in range(n_days):
            best[d] = 0.0
        for k in range(in_ptr[e], in_ptr[e + 1]):
            a = in_act[k]
            s = act_src[a]
            sl = slack[a]
            for d in range(n_days):
                v = z[s, d] - sl
                if v > best[d]:
                    best[d] = v
        if push.shape[0] > 0:
            # attribution: the first activity reaching the maximum transmits it; every positive slack absorbs
            for d in range(n_days):
                done = False
                for k in range(in_ptr[e], in_ptr[e + 1]):
                    a = in_act[k]
                    zs = z[act_src[a], d]
                    sl = slack[a]
                    v = zs - sl
                    if not done and v > 0.0 and v == best[d]:
                        push[a] += v
                        binds[a] += 1
                        done = True
                    if sl > 0.0 and zs > 0.0:
                        absorbed[a] += zs if zs < sl else sl
        for d in range(n_days):
            z[e, d] = best[d] + prim[e, d]


@njit(nogil=True)
def histogram(z, edges, hist):  # pragma: no cover - compiled
    """hist[e, k] += days whose delay falls in bin k: (edges[k − 1], edges[k]], bin 0 ≤ edges[0], the last beyond.

    The bin is found arithmetically (10 s bins to edges[60], 60 s bins after: :data:`~planner.delay.montecarlo.EDGES_S`)
    and then checked against the edges themselves, so it is the bin ``searchsorted(edges, z, "left")`` gives."""
    n_ev, n_days = z.shape
    last = edges.shape[0]
    for e in range(n_ev):
        for d in range(n_days):
            v = z[e, d]
            if v <= edges[0]:
                k = 0
            elif v <= 600.0:
                k = int(np.ceil(v / 10.0))
            elif v <= 3600.0:
                k = 60 + int(np.ceil((v - 600.0) / 60.0))
            else:
                k = last
            k = min(max(k, 0), last)
            while k < last and v > edges[k]:
                k += 1
            while k > 0 and v <= edges[k - 1]:
                k -= 1
            hist[e, k] += 1


JIT = {"propagate": (propagate, PROPAGATE), "histogram": (histogram, HISTOGRAM)}
"""The entry points with their one signature each: what ``planner kernels build`` compiles ahead of time."""
