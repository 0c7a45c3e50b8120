"""One stop solved in compiled code: checks, regions, construction, forward breakpoints (docs/design.md §5).

:func:`kernel` is what :func:`planner.stopping.pattern.solve_stop` calls: it
checks the request, builds the regions of the backward frame, runs the
construction (:mod:`planner.stopping.construct`) and writes the forward
breakpoints, or a code saying why there is no pattern; the caller turns the
code into a :class:`~planner.stopping.pattern.StopPattern` or a one-line error.
"""
from __future__ import annotations

import math

import numpy as np

from planner.stopping.construct import DONE, TAU, U, V_, W, Y, B, _construct
from planner.stopping.codes import (  # noqa: F401  (the codes are read through this module too)
    BAD_DECEL, BAD_JERK, BAD_SPEED, BAD_V_START, BAD_X_STOP, EMPTY, FIRST_NOT_ZERO, HEAD, INCONSISTENT, INTERNAL,
    NEEDS_MORE,
    NEGATIVE, NOT_FINITE, NOT_POSITIVE, NOT_SORTED, OK, SOURCES, STANDING, START_ABOVE_LIMIT, ZERO_LIMIT, N_SLOTS,
    out_size, work_size)
from planner.stopping.pieces import STEPS, ST, NS, V, _pmax, _pmin, b1, f8, i8, jit, nt

_INF = math.inf


_PASSES = 3  # coordinate-descent passes over several step-downs' entries after the first (kernel)


@jit(f8(ST, NS, f8, V, f8))
def _score(st, ns, X, C, y_r):
    """The built pattern's duration up to a constant (the start cruise taken out), as the entry choice
    scores it (:func:`planner.stopping.construct._objective`); a braking that does not fit counts first."""
    t = st[W, TAU, ns[W] - 1] - y_r / C[C.size - 1]
    return t if y_r <= X else 1e9 + (y_r - X)


# --------------------------------------------------------------------------------------
# The request: checks, regions, forward breakpoints
# --------------------------------------------------------------------------------------

CHECK_STEPS = nt.UniTuple(i8, 2)(STEPS, i8, i8, i8)
KERNEL = i8(f8, f8, f8, i8, i8, b1, V)
_out_size = jit(i8(i8))(out_size)  # the layout's one definition (planner.stopping.codes), compiled
_work_size = jit(i8(i8))(work_size)


@jit(CHECK_STEPS, public=True, nrt=True)
def check_steps(steps, lo, hi, positive):
    """First fault of the step function ``steps[lo:hi]`` (rows ``x_from, value``): ``(code, row - lo)``,
    ``(0, 0)`` when none. ``positive``: 1 values > 0, 0 values >= 0, -1 any finite value."""
    if hi <= lo:
        return EMPTY, 0
    if steps[lo, 0] != 0.0:
        return FIRST_NOT_ZERO, 0
    for i in range(lo, hi):
        x, val = steps[i, 0], steps[i, 1]
        if not (math.isfinite(x) and math.isfinite(val)):
            return NOT_FINITE, i - lo
        if i > lo and not x > steps[i - 1, 0]:
            return NOT_SORTED, i - lo
        if positive == 1 and not val > 0.0:
            return NOT_POSITIVE, i - lo
        if positive == 0 and val < 0.0:
            return NEGATIVE, i - lo
    return 0, 0


@jit(i8(f8, f8, STEPS, i8, V, V))
def _regions(v0, X, steps, n_dl, tmp, reg):
    """Regions of the backward frame ``y = X - x``: breakpoints of both step functions inside (0, X),
    equal neighbours merged; their number ``k``, with ``reg`` holding ``Yb`` (``k + 1``), ``A`` then
    ``C`` (``k`` each), ``C`` the running minimum of the speed limit. ``steps``: the deceleration
    limits (rows ``:n_dl``) then the speed limits; ``tmp``: room for ``4 n + 3`` temporaries."""
    n = steps.shape[0]
    xs = tmp[:n]
    nx = 0
    for row in range(n):
        x = steps[row, 0]
        if 0.0 < x < X:  # insertion into the sorted distinct positions so far
            k = nx
            while k and xs[k - 1] > x:
                k -= 1
            if k and xs[k - 1] == x:
                continue
            for j in range(nx, k, -1):
                xs[j] = xs[j - 1]
            xs[k] = x
            nx += 1
    nb = nx + 1
    mb = tmp[n:n + nb]
    mA = tmp[n + nb:n + 2 * nb]
    mC = tmp[n + 2 * nb:n + 3 * nb]
    ia, isl = 0, n_dl
    cap = v0
    k = 0
    for j in range(nb):
        x = 0.0 if j == 0 else xs[j - 1]
        while ia + 1 < n_dl and steps[ia + 1, 0] <= x:
            ia += 1
        while isl + 1 < n and steps[isl + 1, 0] <= x:
            isl += 1
        cap = _pmin(cap, steps[isl, 1])
        if k and steps[ia, 1] == mA[k - 1] and cap == mC[k - 1]:
            continue
        mb[k] = x
        mA[k] = steps[ia, 1]
        mC[k] = cap
        k += 1
    reg[0] = 0.0
    for j in range(k):
        if j:
            reg[j] = X - mb[k - j]
        reg[k + 1 + j] = mA[k - 1 - j]
        reg[2 * k + 1 + j] = mC[k - 1 - j]
    reg[k] = _INF
    return k


@jit(nt.none(ST, NS, f8, f8, f8, V), nrt=True)
def _forward(st, ns, v0, X, y_r, out):
    """The backward nodes as forward breakpoints into ``out`` (merging equal-jerk neighbours)."""
    m = ns[W] - 1  # closed backward pieces 0..m-1; node m is the cruise at v_start
    P = m + 2  # room for every piece plus the cruise
    ts = out[HEAD: HEAD + P]
    xs = out[HEAD + P: HEAD + 2 * P]
    vv = out[HEAD + 2 * P: HEAD + 3 * P]
    aa = out[HEAD + 3 * P: HEAD + 4 * P]
    jj = out[HEAD + 4 * P: HEAD + 5 * P]
    t_cruise = (X - y_r) / v0
    T = t_cruise + st[W, TAU, m]
    ts[0], xs[0], vv[0], aa[0] = 0.0, 0.0, v0, 0.0
    n = 0  # pieces so far
    if t_cruise > 1e-12 * _pmax(1.0, T):  # a round-off sliver of cruise is not a piece
        jj[0] = 0.0
        n = 1
        ts[1], xs[1], vv[1], aa[1] = t_cruise, X - y_r, v0, 0.0
    for k in range(m - 1, -1, -1):
        dur = st[W, TAU, k + 1] - st[W, TAU, k]
        if dur <= 1e-14 * _pmax(1.0, T):
            continue
        j = st[W, U, k]
        if not (n and jj[n - 1] == j):  # else the same cubic continues: merge
            jj[n] = j
            n += 1
        ts[n], xs[n], vv[n], aa[n] = T - st[W, TAU, k], X - st[W, Y, k], st[W, V_, k], -st[W, B, k]
    # the end point is exact by construction
    ts[n], xs[n], vv[n], aa[n] = T, X, 0.0, 0.0
    # compact: t, x, v, a (n + 1 each) then j (n) from out[HEAD]
    for f in range(1, 5):
        for k in range(n + 1):
            out[HEAD + f * (n + 1) + k] = out[HEAD + f * P + k]
    out[2], out[3], out[4], out[5] = T, X - y_r, y_r, n


@jit(f8(V, f8, f8, f8))
def _discontinuity(out, v0, X, J):
    """Where the forward pattern's pieces fail to join (x [m]), else -1: each piece integrated from its start
    (constant jerk) must end in the next breakpoint's acceleration, speed and position, to round-off. A
    construction that loses a node's continuity (seen: a speed step-down 4 m before a 50 m stop, where the
    braking acceleration jumped from -0.49 to 0 m/s² and the position ran back 0.25 m) is caught here."""
    n = int(out[5])
    ts = out[HEAD: HEAD + n + 1]
    xs = out[HEAD + (n + 1): HEAD + 2 * (n + 1)]
    vv = out[HEAD + 2 * (n + 1): HEAD + 3 * (n + 1)]
    aa = out[HEAD + 3 * (n + 1): HEAD + 4 * (n + 1)]
    jj = out[HEAD + 4 * (n + 1): HEAD + 4 * (n + 1) + n]
    tol_x = 1e-6 * _pmax(1.0, X)
    tol_v = 1e-6 * _pmax(1.0, v0)
    tol_a = 1e-6 * _pmax(1.0, J)
    for i in range(n):
        dt = ts[i + 1] - ts[i]
        j = jj[i]
        a1 = aa[i] + j * dt
        v1 = vv[i] + aa[i] * dt + 0.5 * j * dt * dt
        x1 = xs[i] + vv[i] * dt + 0.5 * aa[i] * dt * dt + j * dt * dt * dt / 6.0
        if abs(a1 - aa[i + 1]) > tol_a * _pmax(1.0, dt) or abs(v1 - vv[i + 1]) > tol_v * _pmax(1.0, dt) or \
                abs(x1 - xs[i + 1]) > tol_x * _pmax(1.0, dt):
            return xs[i]
    return -1.0


@jit(KERNEL, public=True, nrt=True)
def kernel(v0, X, J, n_dl, n, optimize, work):
    """Solve one stop: ``work[:2 n]`` holds the ``n`` step rows (x_from, value), the decel limits
    (first ``n_dl`` rows) then the speed limits; ``work`` is at least ``work_size(n)`` long
    (:mod:`planner.stopping.codes`) and the kernel allocates nothing.

    Returns the number of pieces ``p`` of the pattern, or minus a code (an infeasibility or a bad
    input). From ``work[2 n]`` on (``out`` below) it writes ``out[0]`` the code (OK or that code),
    ``out[1]`` an index or position for the message, and for OK: ``out[2:5]`` the duration, brake
    start and braking distance, ``out[5]`` ``p`` and from ``out[HEAD]`` the breakpoints t, x, v, a
    (``p + 1`` each) then the jerks (``p``); for NEEDS_MORE the braking distance needed in ``out[4]``.
    """
    if n < 0 or not 0 <= n_dl <= n or work.size < _work_size(n):
        return -INTERNAL  # the caller's error: nothing written
    steps = work[:2 * n].reshape((n, 2))
    o = 2 * n + _out_size(n)
    out = work[2 * n:o]
    out[1] = 0.0
    if not (math.isfinite(v0) and v0 >= 0.0):
        out[0] = BAD_V_START
        return -int(out[0])
    if not (math.isfinite(X) and X >= 0.0):
        out[0] = BAD_X_STOP
        return -int(out[0])
    if not (math.isfinite(J) and J > 0.0):
        out[0] = BAD_JERK
        return -int(out[0])
    code, i = check_steps(steps, 0, n_dl, 1)
    if code:
        out[0], out[1] = BAD_DECEL + code, i
        return -int(out[0])
    code, i = check_steps(steps, n_dl, n, 0)
    if code:
        out[0], out[1] = BAD_SPEED + code, i
        return -int(out[0])
    if v0 > steps[n_dl, 1]:
        out[0] = START_ABOVE_LIMIT
        return -int(out[0])
    # the running minimum of the speed limit over [0, x) for x < x_stop (a <= 0: speed never rises)
    cap = v0
    for i in range(n_dl, n):
        if steps[i, 0] >= X:
            break
        if steps[i, 1] < cap:
            cap = steps[i, 1]
        if cap <= 0.0 and v0 > 0.0:
            out[0], out[1] = ZERO_LIMIT, steps[i, 0]
            return -int(out[0])
    if v0 == 0.0:
        if X == 0.0:
            out[0], out[2], out[3], out[4], out[5] = OK, 0.0, 0.0, 0.0, 0.0
            for k in range(4):
                out[HEAD + k] = 0.0
            return 0
        out[0] = STANDING
        return -int(out[0])
    # the scratch, in the order of codes.work_size
    tmp = work[o:o + 4 * n + 3]
    o += 4 * n + 3
    reg = work[o:o + 3 * n + 5]
    o += 3 * n + 5
    k = _regions(v0, X, steps, n_dl, tmp, reg)
    Yb, A, C = reg[:k + 1], reg[k + 1:2 * k + 1], reg[2 * k + 1:3 * k + 1]
    entry = work[o:o + k]
    entry[:] = math.nan  # no entry chosen at that region's step-down
    o += n + 1
    capnext = work[o:o + k]  # y where the speed cap next rises (backwards), per region
    o += n + 1
    pend = work[o:o + 3]
    o += 3
    ns = work[o:o + N_SLOTS + 1].view(np.int64)
    o += N_SLOTS + 1
    cap_nodes = 8 * k + 64
    st = work[o:o + N_SLOTS * 6 * cap_nodes].reshape((N_SLOTS, 6, cap_nodes))
    status, y_r = _construct(st, ns, J, X, Yb, A, C, entry, capnext, pend, optimize)
    if status == DONE and optimize:
        chosen = 0
        for e in entry:
            if not math.isnan(e):
                chosen += 1
        if chosen > 1:
            # several step-downs, each entry chosen while those nearer the start were still at the
            # paper's rule: choose each again, knowing the others' choice (coordinate descent), as
            # long as a pass makes the pattern faster; a pass that does not is undone (the best
            # entries rebuilt, the step-downs at them). The temporaries of _regions keep the best.
            best = tmp[:k]
            best[:] = entry
            f_best = _score(st, ns, X, C, y_r)
            better = False
            for _ in range(_PASSES):
                status, y_r = _construct(st, ns, J, X, Yb, A, C, entry, capnext, pend, True)
                f = _score(st, ns, X, C, y_r) if status == DONE else _INF
                better = f < f_best
                if not better:
                    break
                f_best = f
                best[:] = entry
            if not better:
                entry[:] = best
                status, y_r = _construct(st, ns, J, X, Yb, A, C, entry, capnext, pend, False)
    if status != DONE:
        out[0] = INTERNAL
        return -int(out[0])
    if y_r > X * (1.0 + 1e-12) + 1e-9:
        out[0], out[4] = NEEDS_MORE, y_r
        return -int(out[0])
    out[0] = OK
    _forward(st, ns, v0, X, _pmin(y_r, X), out)
    bad = _discontinuity(out, v0, X, J)
    if bad >= 0.0:  # never a pattern whose pieces do not join: the stop is infeasible, loudly (out[1]: where)
        out[0], out[1] = INCONSISTENT, bad
        return -int(out[0])
    return int(out[5])



JIT = {"kernel": (kernel, KERNEL), "check_steps": (check_steps, CHECK_STEPS)}
"""The entry points with their one signature each: what ``planner kernels build`` compiles ahead of time."""
