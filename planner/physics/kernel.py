"""The compiled inner loop of the one integrator (:mod:`planner.physics.run_curve`).

:class:`planner.physics.run_curve._Integrator` keeps everything that happens at
a grid node where something can change (snapshots, ratio changes, the
on-board controller, the ceiling's segment table ``E``); :func:`advance` does
every grid step between two such nodes for the whole batch, compiled with
numba. The arithmetic is the module doc's method, written per run and in the
same order of operations as the former numpy step, so results are the same to
the bit (the bit-identity battery in ``benchmarks/bench_kernel.py`` checks it).
Runs are stepped several at a time in lanes (:func:`_sweep`), which changes
the order in which the processor meets the runs' operations, never a run's own. Two small entry
points serve :mod:`planner.physics.reuse` (runs that meet stepped once): :func:`groups` finds runs
whose key words are equal, :func:`follow` adds a stepped run's recorded increments to the
sums of the runs that follow it.

Two batch-wide switches of the numpy step are kept as they were, because they
pick between two roundings of the same formula: whether any run may be above
its ceiling (after a lowered target; then the crossing fraction is clipped and
the traction work is summed piece by piece), and the stall check every 64
steps (its window names the stretch in the error message).

Layout of the arrays (row constants in :mod:`~planner.physics.kernel_abi`): ``trk`` (7, m) per node of the
track, ``seg`` (m,) the ceiling segment of each node, ``par`` (9, n) per run
and constant between events, ``st`` (``S_ROWS``, n) the runs' state (``S_*``) and the sweep's
scratch (``X_*``), ``lane`` (2, n)
int8 phase code and sawtooth coasting flag, ``e`` (segments, n) the
ceiling's service-brake value at each segment end, ``flags`` int64 (5,);
``rec`` (5, n, nodes) and ``rec_p`` (n, nodes) the recorded curves; ``inc`` (2, leaders, nodes) each step's
time and traction work increments of the runs others follow (``slot``, :func:`advance`).

Built ahead of time at install (:mod:`planner.io.compiled`: ``planner
kernels build``, which ``make install`` runs), so a process loads machine code
instead of compiling: :func:`planner.physics.kernel_abi.load` picks, and this
module (and numba) is imported only without a build for these exact sources.
It then compiles lazily on first use, in memory only (no ``cache=True``:
numba's cache index is a pickle read back from disk, which the project does
not trust): about 5 s of CPU once per process (``benchmarks/bench_kernel.py``
prints it). Every argument type is fixed (:data:`SIGNATURES`).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from numba import types as nt

from planner.physics.kernel_abi import (  # noqa: F401  (the rows are read through this module too)
    F_K_OK, F_MAYBE_OVER, F_STALL_FROM, F_STALL_RUN, F_STALL_TO, L_COAST, L_PHASE, P_CAP2, P_CAPV, P_R2,
    P_RAM, P_RATIO, P_RBM, P_RCM, P_SHED, P_TFI, PHASE_BRAKE, PHASE_COAST, PHASE_HOLD, PHASE_POWER, PHASE_STOP,
    I_DT, I_DWORK, R_A, R_CAP, R_RATIO, R_T, R_V, S_BAD, S_C0, S_T, S_V, S_W, S_WLAST, S_WORK, SAWTOOTH_MIN_FRACTION,
    SOURCES,
    T_AG, T_AHEAD, T_S, T_STEEP, T_STOP2, T_VINT, T_VN2, LANES, X_A0, X_C1, X_CO, X_CROSS, X_CS0, X_CS1, X_FRAC, X_J,
    X_LB, X_OVER, X_SLOPE, X_VP, X_W1, X_WEND,
)

_JIT = dict(nogil=True, error_model="numpy")


@njit(**_JIT)
def _mn(a, b):
    """``np.minimum`` on two floats (NaN propagates)."""
    return a if (a <= b or a != a) else b


@njit(**_JIT)
def _mx(a, b):
    """``np.maximum`` on two floats (NaN propagates)."""
    return a if (a >= b or a != a) else b


@njit(**_JIT)
def _bracket(x, tab):
    """The piece of the table x falls in, by binary search: ``xp[j] ≤ x < xp[j+1]`` for x inside it."""
    lo, hi = 0, tab.shape[1] - 1
    while hi - lo > 1:  # xp[lo] ≤ x < xp[hi] for x inside the table
        mid = (lo + hi) >> 1
        if tab[0, mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo


@njit(**_JIT)
def _interp(x, tab, j):
    """``np.interp(x, xp, fp)`` for one x, with numpy's formula, end values and NaN fall-backs; and
    the piece it used, the guess ``j`` for the next call.

    ``tab`` rows: ``xp``, ``fp`` and the slopes ``(fp[j+1] − fp[j]) / (xp[j+1] − xp[j])``, which
    numpy also computes once for a call on as many x as table points. The piece is hunted from
    ``j`` (a run's speed changes little from call to call): for x inside the table and xp not
    decreasing (the line's validation: strictly increasing) the one ``j`` with ``xp[j] ≤ x <
    xp[j+1]`` is what :func:`_bracket` finds, ties included; outside the table or NaN no piece is used.
    """
    n = tab.shape[1]
    if x != x:
        return x, j
    if x < tab[0, 0]:
        return tab[1, 0], j
    if x >= tab[0, n - 1]:
        return tab[1, n - 1], j
    while x < tab[0, j]:  # stops at j = 0 at the latest: xp[0] ≤ x (or NaN)
        j -= 1
    while x >= tab[0, j + 1]:  # stops at j = n − 2 at the latest: x < xp[n−1] (or NaN)
        j += 1
    return _lin(x, tab[0, j], tab[0, j + 1], tab[1, j], tab[1, j + 1], tab[2, j],
                tab[0, 0], tab[0, n - 1], tab[1, 0], tab[1, n - 1]), j


@njit(**_JIT)
def _lin(x, x0, x1, f0, f1, slope, x_first, x_last, f_first, f_last):
    """numpy's interpolation between (x0, f0) and (x1, f1), its end values and NaN fall-backs."""
    if x != x:
        return x
    if x < x_first:
        return f_first
    if x >= x_last:
        return f_last
    if x0 == x:
        return f0
    r = slope * (x - x0) + f0
    if r != r:
        r = slope * (x - x1) + f1
        if r != r and f0 == f1:
            r = f0
    return r


@njit(**_JIT)
def _accel(vv, ag, steep, amax, ram, rbm, rcm, tfi, effort):
    """Full-notch acceleration at speed vv with tractive effort ``effort`` (capped at a_max, not below
    coasting on a steep fall) and the coasting acceleration ``a_track − R/M_e``."""
    coast = ag - (ram + vv * (rbm + rcm * vv))
    cap = _mx(amax, coast) if steep != 0.0 else amax
    return _mn(coast + effort * tfi, cap), coast


@njit(inline="always", **_JIT)
def _guided(w, c0, c1, st1, a0, a1, shed, ds, use_over):
    """Free running capped by the ceiling, or braking at ``shed`` onto it from above (a lowered target).

    Returns the slope dw/ds before the crossing, the end without the ceiling, whether and where
    (fraction of the step) it crosses, the end value and whether the run was above its ceiling.
    """
    if not use_over:
        slope = a0 + a1
        wend = w + slope * ds
        cross = wend > c1
        w1 = _mn(wend, c1)
        gap0 = w - c0
        frac = gap0 / (gap0 - (wend - c1)) if cross else 1.0
        return slope, wend, cross, frac, w1, False
    over = w > c0 * (1.0 + 1e-12) + 1e-9
    slope = -2.0 * shed if over else a0 + a1
    wend = w + slope * ds
    cross = (wend < c1) if over else (wend > c1)
    # braked down onto a ceiling that rises inside the step (a restriction's tail clears): from
    # the crossing the train runs free, capped by the ceiling
    fc = _mn(_mx((w - c0) / ((w - c0 - (wend - c1)) if cross else 1.0), 0.0), 1.0)
    free = w + slope * fc * ds + (a0 + a1) * (1.0 - fc) * ds
    w1 = _mn((_mn(c1, free) if over else c1) if cross else wend, st1)
    gap0 = w - c0
    frac = _mn(_mx(gap0 / (gap0 - (wend - c1)), 0.0), 1.0) if cross else 1.0
    return slope, wend, cross, frac, w1, over


@njit(**_JIT)
def _phase(coasting_step, over, cross, c0, c1, w1, st1, band_x, sawtooth):
    """Phase code of the step (what the run did arriving at the node)."""
    ph = PHASE_COAST if (sawtooth and coasting_step) else PHASE_POWER
    if over:
        ph = PHASE_BRAKE
    if cross:
        if c1 < c0 * (1 - 1e-12):
            ph = PHASE_BRAKE
        elif c1 > c0 * (1 + 1e-12):
            ph = PHASE_POWER
        else:
            ph = PHASE_HOLD
        if sawtooth and w1 < c1 * (1 - 1e-12):
            ph = PHASE_COAST
    if band_x:
        ph = PHASE_POWER
    if w1 >= st1:
        ph = PHASE_STOP
    return ph


@njit(**_JIT)
def _ceiling2(k, i, trk, seg, e, r2, cap2, st2):
    """Run ``i``'s ceiling² at node k: its target ratio² × the line maximum², its cruise cap², its
    service-brake curve and the stopping curve² ``st2`` (the one copy: the step, :func:`_over_until` and
    :func:`set_targets`)."""
    return _mn(_mn(_mn(r2 * trk[T_VN2, k], cap2), e[seg[k], i] + trk[T_AHEAD, k]), st2)


@njit(**_JIT)
def _start2(k, i, trk, seg, e, r2, cap2, st2, c):
    """Run ``i``'s ceiling² at the start of the step from node k, given its ceiling² ``c`` at the node
    (:func:`_ceiling2`, with the same ``st2``): ``c``, except where a limit rises at node k (a restriction's tail
    clears there): the node's value is the lower neighbour's, the one the step arriving at k ends on, and the step
    leaving it starts from the interval's (the node S_C0 holds)."""
    vi2 = trk[T_VINT, k] * trk[T_VINT, k]
    if vi2 <= trk[T_VN2, k]:
        return c
    return _mn(_mn(_mn(r2 * vi2, cap2), e[seg[k], i] + trk[T_AHEAD, k]), st2)


@njit(**_JIT)
def _band_edge(k, trk, ratio, capv, band):
    """A sawtooth run's coasting-band lower edge on the step from node k [m/s]."""
    tgt = _mn(ratio * trk[T_VINT, k], capv)
    return _mx(tgt - band, SAWTOOTH_MIN_FRACTION * tgt)


@njit(**_JIT)
def _power_back(w, v, wend, lb, c1, ds, ag, amax, p, tab, j):
    """A sawtooth run's step that coasts below its band's lower edge ``lb``: it coasts to the edge, powers the
    rest of the step, and when it meets its target ``c1`` (speed²) on the way (a crawl: a few km/h gained within a
    step) it coasts from there on. ``p``: the run's column of ``par``. Returns w₁, v₁, Δt, Δwork, the traction
    piece's index and whether it arrives coasting."""
    lb2 = lb * lb
    xb = ds * _mn(_mx((w - lb2) / (w - wend), 0.0), 1.0)
    sub = ds - xb
    ef, j = _interp(lb, tab, j)
    aa, cbl = _accel(lb, ag, 1.0, amax, p[P_RAM], p[P_RBM], p[P_RCM], p[P_TFI], ef)
    vq = math.sqrt(_mx(lb2 + 2.0 * aa * sub, 0.0))
    ef, j = _interp(vq, tab, j)
    ab, cq = _accel(vq, ag, 1.0, amax, p[P_RAM], p[P_RBM], p[P_RCM], p[P_TFI], ef)
    wp = lb2 + (aa + ab) * sub
    if wp > c1 and c1 > lb2:  # meets its target after xh of the powered part, coasts the rest
        xh = sub * (c1 - lb2) / (wp - lb2)
        vh = math.sqrt(c1)
        w1 = _mn(c1 + 2.0 * cq * (sub - xh), c1)
        v1 = math.sqrt(w1)
        dt = 2.0 * (xb / (v + lb) + xh / (lb + vh) + (sub - xh) / (vh + v1))
        return w1, v1, dt, _mx(0.5 * (c1 - lb2) - xh * 0.5 * (cbl + cq), 0.0), j, True
    w1 = _mn(wp, c1)
    v1 = math.sqrt(w1)
    dt = 2.0 * (xb / (v + lb) + sub / (lb + v1))
    return w1, v1, dt, _mx(0.5 * (w1 - lb2) - sub * 0.5 * (cbl + cq), 0.0), j, False


@njit(**_JIT)
def _sweep(k_from, k_to, k0, use_over, trk, seg, par, st, lane, e, cst, tab, rec, rec_p, record, inc, slot):
    """Every run on its own from node k_from to k_to, with the batch-wide ``use_over`` switch fixed.
    Returns whether any run ended still above its ceiling (having been above it and not met it on
    the last step) and the first step after which a run's time is not finite (k_to if none).

    Lanes: the runs go up to :data:`~planner.physics.kernel_abi.LANES` at a time, and each step is done in
    three stages, each a loop over the lanes (the predictor; the corrector and the ceiling; the
    split, time and work). A run's step is one chain of dependent square roots and divisions, but
    the lanes' chains are independent, so within a stage the processor overlaps them; values pass
    from stage to stage through the scratch rows ``X_*`` of ``st``. Each run's operations are its
    own and in the same order as alone, so the same bits; and each stage is written once (the
    compile cost of one step, not of one copy per lane).
    """
    n = st.shape[1]
    amax, band, sawtooth = cst[0], cst[1], cst[2] != 0.0
    still_over, increments = False, slot.shape[0] != 0
    groups = (n + LANES - 1) // LANES
    width = (n + groups - 1) // groups if groups else 1  # groups of even widths: 9 runs go 5 + 4, not 8 + 1
    for a in range(0, n, width):
        b = min(a + width, n)
        for i in range(a, b):  # the tractive-effort piece of each run's speed, then hunted step by step
            st[X_J, i] = _bracket(st[S_V, i], tab)
        for k in range(k_from, k_to):
            ds = trk[T_S, k + 1] - trk[T_S, k]
            st1 = trk[T_STOP2, k + 1]
            for i in range(a, b):  # the ceiling ahead, the coasting band and Heun's predictor ṽ₁
                w, v = st[S_W, i], st[S_V, i]
                c1 = _ceiling2(k + 1, i, trk, seg, e, par[P_R2, i], par[P_CAP2, i], st1)
                lb = _band_edge(k, trk, par[P_RATIO, i], par[P_CAPV, i], band) if sawtooth else 0.0
                # a coasting run powers again at the band's edge
                co = lane[L_COAST, i] != 0 and (not sawtooth or w > lb * lb)
                ef, j = _interp(v, tab, np.int64(st[X_J, i]))
                a0, cs0 = _accel(v, trk[T_AG, k], trk[T_STEEP, k], amax, par[P_RAM, i], par[P_RBM, i],
                                 par[P_RCM, i], par[P_TFI, i], ef)
                if co:
                    a0 = cs0
                st[X_VP, i] = math.sqrt(_mx(w + (2.0 * ds) * a0, 0.0))
                st[X_C1, i], st[X_LB, i], st[X_CO, i], st[X_J, i], st[X_A0, i], st[X_CS0, i] = (
                    c1, lb, 1.0 if co else 0.0, j, a0, cs0)
            for i in range(a, b):  # the corrector, and free running capped by the ceiling or braking onto it
                vp, co = st[X_VP, i], st[X_CO, i] != 0.0
                ef, j = _interp(vp, tab, np.int64(st[X_J, i]))
                a1, cs1 = _accel(vp, trk[T_AG, k + 1], trk[T_STEEP, k + 1], amax, par[P_RAM, i], par[P_RBM, i],
                                 par[P_RCM, i], par[P_TFI, i], ef)
                if co:
                    a1 = cs1
                slope, wend, cross, frac, w1, over = _guided(st[S_W, i], st[S_C0, i], st[X_C1, i], st1, st[X_A0, i],
                                                             a1, par[P_SHED, i], ds, use_over)
                st[X_J, i], st[X_CS1, i], st[X_SLOPE, i], st[X_WEND, i], st[X_FRAC, i], st[X_W1, i] = (
                    j, cs1, slope, wend, frac, w1)
                st[X_CROSS, i], st[X_OVER, i] = 1.0 if cross else 0.0, 1.0 if over else 0.0
            for i in range(a, b):  # split at the crossing: time Δt = 2Δs/(v₀ + v₁) and traction work / M_e
                w, v, c0, t = st[S_W, i], st[S_V, i], st[S_C0, i], st[S_T, i]
                c1, lb, co, j = st[X_C1, i], st[X_LB, i], st[X_CO, i] != 0.0, np.int64(st[X_J, i])
                cs0, cs1, slope, wend, frac, w1 = (st[X_CS0, i], st[X_CS1, i], st[X_SLOPE, i], st[X_WEND, i],
                                                   st[X_FRAC, i], st[X_W1, i])
                cross, over = st[X_CROSS, i] != 0.0, st[X_OVER, i] != 0.0
                coasting_step = co
                xc = frac * ds
                wc = w + slope * xc
                vc = math.sqrt(wc)
                # no crossing and no run above its ceiling: the step ends where it would free, w1 = wc
                v1 = vc if not (cross or use_over) else math.sqrt(w1)
                rest = ds - xc
                dt = 2.0 * (xc / (v + vc) + rest / (vc + v1))
                cb = 0.5 * (cs0 + cs1)
                if not use_over:
                    dwork = xc * (0.5 * slope - cb) + _mx(0.5 * (w1 - wc) - rest * cb, 0.0)
                else:
                    dwork = _mx(0.5 * (wc - w) - xc * cb, 0.0) + _mx(0.5 * (w1 - wc) - rest * cb, 0.0)
                band_x = False
                if sawtooth:
                    hit = cross and c1 <= c0 * (1 + 1e-12)
                    if hit:  # meets a level or falling ceiling: coasts from there, still capped by it
                        wco = _mn(wc + 2.0 * cs1 * rest, c1)
                        vco = math.sqrt(wco)
                        dt = 2.0 * (xc / (v + vc) + rest / (vc + vco))
                        dwork = _mx(0.5 * (wc - w) - xc * cb, 0.0) + _mx(0.5 * (wco - wc) - rest * cb, 0.0)
                        w1, v1 = wco, vco
                    band_x = co and not cross and wend < lb * lb
                    if band_x:  # below the band's lower edge: coast to it, power the rest of the step
                        w1, v1, dt, dwork, j, co = _power_back(w, v, wend, lb, c1, ds, trk[T_AG, k + 1], amax,
                                                               par[:, i], tab, j)
                        band_x = not co  # met its target within the step: arrives coasting
                    co = co or hit
                ph = _phase(coasting_step, over, cross, c0, c1, w1, st1, band_x, sawtooth)
                if record:
                    jr = k + 1 - k0
                    rec[R_T, i, jr], rec[R_V, i, jr], rec[R_A, i, jr] = t + dt, v1, (w1 - w) / (2.0 * ds)
                    rec[R_RATIO, i, jr], rec[R_CAP, i, jr] = par[P_RATIO, i], par[P_CAPV, i]
                    rec_p[i, jr] = ph
                if increments and slot[i] >= 0:  # a run others follow: the step's own increments (reuse)
                    inc[I_DT, slot[i], k + 1 - k0], inc[I_DWORK, slot[i], k + 1 - k0] = dt, dwork
                if k + 2 == trk.shape[1]:
                    st[S_WLAST, i] = w  # entering the last step, onto the marker
                t = t + dt
                st[S_W, i], st[S_V, i], st[S_C0, i], st[S_T, i], st[X_J, i] = w1, v1, c1, t, j
                st[S_WORK, i] += dwork
                if not math.isfinite(t) and k < st[S_BAD, i]:
                    st[S_BAD, i] = k
                lane[L_PHASE, i], lane[L_COAST, i] = ph, 1 if co else 0
                if k + 1 == k_to:
                    still_over = still_over or (over and not cross)
            if trk[T_VINT, k + 1] * trk[T_VINT, k + 1] > trk[T_VN2, k + 1]:  # a limit rises at k + 1: the next step
                # starts from the interval's ceiling, not the node's
                for i in range(a, b):
                    st[S_C0, i] = _start2(k + 1, i, trk, seg, e, par[P_R2, i], par[P_CAP2, i], st1, st[S_C0, i])
    first_bad = k_to
    for i in range(n):
        bad_at = st[S_BAD, i]
        if bad_at < k_to:  # a time once not finite stays so: stalled from bad_at, or before this sweep
            first_bad = min(first_bad, max(int(bad_at), k_from))
    return still_over, first_bad


@njit(**_JIT)
def set_targets(k, trk, seg, bounds, par, st, e):
    """From the ratios and cruise caps in ``par``: ratio² into ``par``, the ceiling's segment table
    ``e`` (the service-brake ceiling at each segment's end node, ``bounds``), and the ceiling² at
    node k into ``st``. ``c²_k = min(r² V_k², cap², E_seg(k) + 2 b (s_end − s_k), stopping curve²)``."""
    nb = bounds.shape[0]
    for i in range(par.shape[1]):
        r2 = par[P_RATIO, i] * par[P_RATIO, i]
        cap2 = par[P_CAP2, i]
        par[P_R2, i] = r2
        e[nb - 1, i] = np.inf
        e[nb - 2, i] = _mn(r2 * trk[T_VN2, bounds[nb - 1]], cap2)
        for j in range(nb - 3, -1, -1):
            kb = bounds[j + 1]
            e[j, i] = _mn(_mn(r2 * trk[T_VN2, kb], cap2), e[j + 1, i] + trk[T_AHEAD, kb])
        st[S_C0, i] = _start2(k, i, trk, seg, e, r2, cap2, trk[T_STOP2, k],
                              _ceiling2(k, i, trk, seg, e, r2, cap2, trk[T_STOP2, k]))


@njit(**_JIT)
def _any_over(st):
    for i in range(st.shape[1]):
        if st[S_W, i] > st[S_C0, i] * (1.0 + 1e-12) + 1e-9:
            return True
    return False


@njit(**_JIT)
def _over_until(k_from, k_to, trk, seg, par, st, lane, e, cst):
    """The first node from ``k_from`` (at most ``k_to``) where no run is above its ceiling.

    Each run above its ceiling brakes at its shed rate (the over-mode step of :func:`_guided`, the
    same expressions) until the step that meets the ceiling or drops below the coasting band; a run
    not above it never rises above it again (every step ends at or below the ceiling). So each run
    is followed alone, only while it is above, and the batch-wide switch ends at the latest of
    them: the node the node-by-node test of :func:`advance` would reach, without its passes over
    the whole batch at every node.
    """
    band, sawtooth = cst[1], cst[2] != 0.0
    k_end = k_from
    for i in range(st.shape[1]):
        w, c0 = st[S_W, i], st[S_C0, i]
        r2, cap2, ratio, capv, shed = par[P_R2, i], par[P_CAP2, i], par[P_RATIO, i], par[P_CAPV, i], par[P_SHED, i]
        co = lane[L_COAST, i] != 0
        k = k_from
        while k < k_to and w > c0 * (1.0 + 1e-12) + 1e-9:
            ds = trk[T_S, k + 1] - trk[T_S, k]
            st1 = trk[T_STOP2, k + 1]
            c1 = _ceiling2(k + 1, i, trk, seg, e, r2, cap2, st1)
            lb = _band_edge(k, trk, ratio, capv, band) if sawtooth else 0.0
            co = co and (not sawtooth or w > lb * lb)
            wend = w + (-2.0 * shed) * ds
            k += 1
            if wend < c1 or (sawtooth and co and wend < lb * lb):
                break  # meets the ceiling, or below the band: at or below the ceiling from node k
            w, c0 = _mn(wend, st1), _start2(k, i, trk, seg, e, r2, cap2, st1, c1)
        if k > k_end:
            k_end = k
    return k_end


@njit(**_JIT)
def advance(k_from, k_to, k0, trk, seg, par, st, lane, e, cst, tab, flags, rec, rec_p, record, inc, slot):
    """Advance every run from node ``k_from`` to node ``k_to`` (no event strictly between).

    While some run may be above its ceiling (after a lowered target) every run steps in the
    batch-wide above-ceiling mode, as the numpy step did, up to the first node where no run is
    above it (:func:`_over_until`); from there every run goes on to k_to on its own. Stops early
    (``flags[F_STALL_TO] ≥ 0``) at the first stall check (every 64 steps and at the end, as the
    numpy step) that finds a run whose time is no longer finite.

    ``inc`` (2, leaders, nodes) and ``slot`` (n,) are for :mod:`planner.physics.reuse`: a run with
    ``slot[i] ≥ 0`` (one that others follow) gets each step's time and traction work increments in
    ``inc[I_DT, slot[i]]``, ``inc[I_DWORK, slot[i]]``, column ``k + 1 − k0`` for the step arriving at
    node k + 1; an empty ``slot``: none are kept.
    """
    m = trk.shape[1]
    k = k_from
    while k < k_to:
        over_mode = flags[F_MAYBE_OVER] != 0 and _any_over(st)
        k_end = _over_until(k, k_to, trk, seg, par, st, lane, e, cst) if over_mode else k_to
        still_over, first_bad = _sweep(k, k_end, k0, over_mode, trk, seg, par, st, lane, e, cst, tab,
                                       rec, rec_p, record, inc, slot)
        flags[F_MAYBE_OVER] = 1 if over_mode and still_over else 0
        for kc in range(k, k_end):  # the stall checks of the steps just made
            if (kc & 63) == 0 or kc + 2 >= m - 1:
                if kc >= first_bad:
                    flags[F_STALL_FROM], flags[F_STALL_TO] = flags[F_K_OK], kc + 1
                    for i in range(st.shape[1]):  # the first run stalled by then
                        if st[S_BAD, i] <= kc:
                            flags[F_STALL_RUN] = i
                            break
                    return
                flags[F_K_OK] = kc + 1
        k = k_end


@njit(**_JIT)
def follow(inc, lead, t, work):
    """Each follower adds its leader's increments (``inc`` rows ``I_DT``, ``I_DWORK``, columns 1 on; its
    leader's slot ``lead``: :func:`advance`) to its own time and traction work, one step at a time in step
    order: the additions stepping it would make (:mod:`planner.physics.reuse`)."""
    steps = inc.shape[2]
    for f in range(lead.shape[0]):
        i = lead[f]
        tf, wf = t[f], work[f]
        for j in range(1, steps):
            tf = tf + inc[I_DT, i, j]
            wf = wf + inc[I_DWORK, i, j]
        t[f], work[f] = tf, wf


@njit(**_JIT)
def groups(keys, mix, table, rep):
    """For each run (column of ``keys``, (c, n) uint64), the lowest run whose column has the same
    bits into ``rep``, else itself (:mod:`planner.physics.reuse`). An open-addressing hash table
    (``table``: a power of two ≥ 2n slots, −1 = empty) finds candidates; a run is given one only
    if every word is equal, so a hash collision (``mix``: the hash's multiplier) can only miss a
    pair, never join two different runs."""
    c, n = keys.shape
    mask = table.shape[0] - 1
    for i in range(n):
        h = keys[0, i]
        for r in range(1, c):
            h = (h * mix) ^ keys[r, i]
        h ^= h >> np.uint64(29)
        slot = np.int64(h & np.uint64(mask))
        rep[i] = i
        while table[slot] >= 0:
            j = table[slot]
            same = True
            for r in range(c):
                if keys[r, i] != keys[r, j]:
                    same = False
                    break
            if same:
                rep[i] = j
                break
            slot = (slot + 1) & mask
        if rep[i] == i:
            table[slot] = i


_F1, _F2, _F3 = nt.float64[::1], nt.float64[:, ::1], nt.float64[:, :, ::1]
_I1, _B2 = nt.int64[::1], nt.int8[:, ::1]
SIGNATURES = {
    "advance": nt.void(nt.int64, nt.int64, nt.int64, _F2, _I1, _F2, _F2, _B2, _F2, _F1, _F2, _I1, _F3, _B2,
                       nt.boolean, _F3, _I1),
    "set_targets": nt.void(nt.int64, _F2, _I1, _I1, _F2, _F2, _F2),
    "follow": nt.void(_F3, _I1, _F1, _F1),
    "groups": nt.void(nt.uint64[:, ::1], nt.uint64, _I1, _I1),
}
"""The one signature of each entry point (the arrays C-contiguous, as
:func:`planner.physics.kernel_abi.check_layout` requires)."""
JIT = {name: (globals()[name], sig) for name, sig in SIGNATURES.items()}
"""The just-in-time entry points with their signatures: what ``planner kernels build`` compiles."""
