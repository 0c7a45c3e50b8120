"""The backward event-point construction of a stopping pattern, compiled (docs/design.md §5).

The four motions built backwards from the stop, the fixes of motion 4 and the
choice of the entry deceleration at a speed step-down, exactly as the method
in :mod:`planner.stopping.pattern` describes them; the arithmetic of a piece is
in :mod:`planner.stopping.pieces`, the request and the forward breakpoints in
:mod:`planner.stopping.kernel`.

Data layout. The nodes of the construction (the start of every constant-jerk
piece; the last node's piece is the open motion) live in ``st[slot, field, k]``
with the fields ``TAU, Y, V, B, U`` (backward time, distance to run, speed,
deceleration, jerk) and ``REG`` (region, stored as a float), and ``ns[slot]``
nodes. Slot ``W`` is the working construction; the others hold saved ones
(:func:`_copy`): ``BEFORE``/``PAPER`` for the choice at a step-down,
``BEFORE_E``/``PAPER_E`` for re-entering with a chosen deceleration while a
trial finishes the construction. ``ns[FLAGS]`` is set if the store overflows
(an internal error, never seen). Nothing here allocates: the store, the counts
and the other arrays are views of the one work array the caller passes
(:func:`planner.stopping.kernel.kernel`, :func:`planner.stopping.codes.work_size`).

Regions in the backward frame: region ``r`` spans ``y`` in ``[Yb[r], Yb[r+1]]``
with deceleration limit ``A[r]`` and speed cap ``C[r]``; ``capnext[r]`` is where
the cap next rises going backwards; ``entry[r]`` the deceleration chosen on
entry to the step-down of region ``r`` (NaN: not chosen; 0: the paper's rule).
"""
from __future__ import annotations

import math

from planner.stopping.codes import N_SLOTS
from planner.stopping.pieces import (
    AT_CAP, ENERGY, F3, IF, NS, REACH, ST, V, _adv, _illinois, _pmax, _pmin, _region_of, _residual,
    _time_to_speed, _time_to_y, b1, f8, i8, jit, nt,
)

_INF = math.inf
_BAD = 1e9  # the entry choice's objective from here on: the braking does not fit, or no join
_SCAN = 8  # samples of the entry deceleration before Brent's search (_best_entry)
_MAX_STEPS = 10_000  # guard against a construction that fails to make progress (never hit in tests)

# slots of the node store, and the field rows of a slot
W, BEFORE, PAPER, BEFORE_E, PAPER_E = 0, 1, 2, 3, 4
assert N_SLOTS == 5  # codes.N_SLOTS sizes the kernel's work array: one slot per name above
FLAGS = N_SLOTS  # ns[FLAGS] != 0: node store overflow
TAU, Y, V_, B, U, REG = 0, 1, 2, 3, 4, 5

# status codes of _run
DONE, PENDING, NO_PROGRESS = 0, 1, 2


# --------------------------------------------------------------------------------------
# The node store
# --------------------------------------------------------------------------------------


@jit(F3(ST, i8, f8))
def _state(st, i, s):
    return _adv(st[W, Y, i], st[W, V_, i], st[W, B, i], st[W, U, i], s)


@jit(nt.none(ST, NS, f8, f8, f8, f8, f8, i8))
def _push(st, ns, t, y, v, b, u, r):
    n = ns[W]
    if n >= st.shape[2]:
        ns[FLAGS] = 1
        return
    st[W, TAU, n] = t
    st[W, Y, n] = y
    st[W, V_, n] = v
    st[W, B, n] = b
    st[W, U, n] = u
    st[W, REG, n] = r
    ns[W] = n + 1


@jit(nt.none(ST, NS, i8, i8))
def _copy(st, ns, src, dst):
    n = ns[src]
    for f in range(6):
        for k in range(n):
            st[dst, f, k] = st[src, f, k]
    ns[dst] = n




@jit(nt.none(ST, NS, f8, i8, f8))
def _cut(st, ns, J, i, s):
    """Keep nodes 0..i with piece i cut at ``s``; the last node then starts the easing-off piece."""
    ns[W] = i + 1
    if s > 0.0:
        y, v, b = _state(st, i, s)
        _push(st, ns, st[W, TAU, i] + s, y, v, b, 0.0, -1)
    st[W, U, ns[W] - 1] = -J


@jit(f8(V, V, f8, f8, f8, i8))
def _motion(A, C, J, v, b, r):
    """Jerk of the motion from state (v, b) in region r: motion 1, 2 or 3."""
    if b >= A[r] * (1.0 - 1e-13):
        return 0.0  # 2: hold the deceleration limit
    if b <= 0.0 and v >= C[r] * (1.0 - 1e-13):
        return 0.0  # 3: hold the speed limit
    return J  # 1: maximum jerk


@jit(IF(ST, i8, f8, f8, f8, i8, f8, i8, f8, f8), inline="always")
def _search(st, kind, p1, p2, J, i_hi, s_hi, i_lo, s_lo, ftol):
    """Latest point (i, s) on the built part, between (i_lo, s_lo) and (i_hi, s_hi), where the
    increasing residual crosses zero; ``> 0`` at (i_hi, s_hi), ``<= 0`` at (i_lo, s_lo).

    Walking back piece by piece is "drop the previous point and backtrack further".
    """
    i = i_hi
    hi = s_hi
    y, v, b = _state(st, i, hi)
    fhi = _residual(kind, p1, p2, J, y, v, b)
    while True:
        lo = s_lo if i == i_lo else 0.0
        y, v, b = _state(st, i, lo)
        flo = _residual(kind, p1, p2, J, y, v, b)
        if flo <= 0.0 or i <= i_lo:
            if flo > 0.0:  # numerical corner: treat the lower limit as the root
                return i, lo
            return i, _illinois(kind, p1, p2, J, st[W, Y, i], st[W, V_, i], st[W, B, i], st[W, U, i],
                                lo, hi, flo, fhi, ftol)
        fhi = flo
        i -= 1
        hi = st[W, TAU, i + 1] - st[W, TAU, i]


# --------------------------------------------------------------------------------------
# The four motions and the fixes
# --------------------------------------------------------------------------------------


@jit(nt.none(ST, NS, f8, V, V, V, i8, i8, f8))
def _fix_decel(st, ns, J, Yb, A, C, r2, i_hi, s_hi):
    """Motion 4 for a deceleration limit that drops to A[r2] at the event point Yb[r2]."""
    A_new = A[r2]
    ye = Yb[r2]
    i, s = _search(st, REACH, A_new, ye, J, i_hi, s_hi, 0, 0.0, 1e-11 * _pmax(1.0, ye))
    y, v, b = _state(st, i, s)
    rr = _pmax(b - A_new, 0.0) / J
    v_e = v + rr * (b - J * rr / 2.0)
    _cut(st, ns, J, i, s)
    n = ns[W] - 1
    _push(st, ns, st[W, TAU, n] + rr, ye, v_e, A_new, _motion(A, C, J, v_e, A_new, r2), r2)


@jit(nt.Tuple((f8, i8, f8))(ST, f8, f8, f8, f8, f8, i8, f8, f8))
def _gap(st, J, Cr, y_cap, b_s, s1, i_v, s_v, ftol):
    """Entering the step-down at ``y_cap`` with ``v = C``, ``b = b_s`` after a full-jerk arc of ``s1``
    (from ``b_m = b_s - J s1``), joined to the part built by easing off (j = -J) from it: where that
    easing-off piece reaches ``b_m`` minus where the arc starts, and the point ``(i, s)`` it leaves
    the built part. ``E = v + b²/2J`` is constant on the easing-off piece, so that point is where the
    built part's ``E`` equals the arc start's."""
    b_m = b_s - J * s1
    v_m = Cr - (b_s * b_s - b_m * b_m) / (2.0 * J)
    y_m = y_cap - s1 * (v_m + s1 * (b_m / 2.0 + J * s1 / 6.0))
    iq, sq = _search(st, ENERGY, v_m + b_m * b_m / (2.0 * J), 0.0, J, i_v, s_v, 0, 0.0, ftol)
    yq, vq, bq = _state(st, iq, sq)
    s2 = _pmax(bq - b_m, 0.0) / J
    return yq + s2 * (vq + s2 * (bq / 2.0 - J * s2 / 6.0)) - y_m, iq, sq


@jit(b1(ST, NS, f8, V, V, V, V, i8, f8, i8, f8))
def _enter_braking(st, ns, J, Yb, A, C, capnext, i_v, s_v, r, b_s):
    """Replace the part after the step-down so that ``v = C`` exactly at the restriction start, still
    braking with ``b_s`` there: ease off (j = -J backwards) from the part built, down to ``b_m``, then
    full jerk up to ``b_s`` at the restriction start. ``b_m = 0`` with a cruise at ``C - b_s²/(2J)``
    in between when there is room for one; else (no cruise: the step-down met while braking) ``b_m > 0``
    is the root of :func:`_gap`. False when no such join exists or it breaks a limit."""
    Cr = C[r]
    y_cap = capnext[r]
    ftol = 1e-13 * _pmax(1.0, Cr)
    Cp = Cr - b_s * b_s / (2.0 * J)
    s1 = b_s / J  # the arc up to the restriction start
    b_m = 0.0
    v_m = Cp
    iq, sq, yq, vq, bq, y_m = 0, 0.0, 0.0, 0.0, 0.0, 0.0
    cruise = False
    if Cp > 0.0:
        iq, sq = _search(st, ENERGY, Cp, 0.0, J, i_v, s_v, 0, 0.0, ftol)
        yq, vq, bq = _state(st, iq, sq)
        rr = bq / J
        y_m = y_cap - (Cp * s1 + J * s1 ** 3 / 6.0)
        cruise = y_m >= yq + rr * (vq + rr * (bq / 2.0 - J * rr / 6.0))
    if not cruise:
        # no room for a cruise: b_m > 0, the root of the gap in s1 (b_m between 0 and b_s; the
        # built part's E at the point the cap is first exceeded bounds b_m from above)
        y_v, v_v, b_v = _state(st, i_v, s_v)
        hi = s1 if Cp > 0.0 else (b_s - math.sqrt(_pmax(b_s * b_s - 2.0 * J * Cr, 0.0))) / J
        if not Cp > 0.0:
            hi *= 1.0 - 1e-12  # v_m = 0 at the top: stay just inside
        bm_hi = math.sqrt(J * (v_v + b_v * b_v / (2.0 * J) - Cr) + b_s * b_s / 2.0)
        lo = _pmax(b_s - bm_hi, 0.0) / J * (1.0 + 1e-12)
        if not lo < hi:
            return False
        glo, _, _ = _gap(st, J, Cr, y_cap, b_s, lo, i_v, s_v, ftol)
        ghi, iq, sq = _gap(st, J, Cr, y_cap, b_s, hi, i_v, s_v, ftol)
        if not (glo < 0.0 < ghi):
            return False
        side = 0
        for _ in range(100):
            s1 = (lo * ghi - hi * glo) / (ghi - glo)
            if not lo < s1 < hi:
                s1 = 0.5 * (lo + hi)
            g, iq, sq = _gap(st, J, Cr, y_cap, b_s, s1, i_v, s_v, ftol)
            if abs(g) <= 1e-12 * _pmax(1.0, y_cap) or hi - lo <= 4e-16 * hi:
                break
            if g > 0.0:
                hi, ghi = s1, g
                if side == 1:
                    glo *= 0.5
                side = 1
            else:
                lo, glo = s1, g
                if side == -1:
                    ghi *= 0.5
                side = -1
        b_m = b_s - J * s1
        v_m = Cr - (b_s * b_s - b_m * b_m) / (2.0 * J)
        y_m = y_cap - s1 * (v_m + s1 * (b_m / 2.0 + J * s1 / 6.0))
        yq, vq, bq = _state(st, iq, sq)
        if bq < b_m:
            return False
    rr = (bq - b_m) / J  # easing off from the part built, down to b_m
    y_end = _pmin(yq + rr * (vq + rr * (bq / 2.0 - J * rr / 6.0)), y_m)
    # speed: at most v_m while easing off and cruising, at most C on the arc; the caps nearer the
    # stop are lower, so every region the new part runs in is checked (conservatively)
    k = _region_of(Yb, yq)
    while k < A.size and Yb[k] < y_cap:
        if C[k] < (Cr if Yb[k + 1] > y_m else v_m):
            return False
        k += 1
    # easing off (b falls from bq): the deceleration limit at every event point it passes
    k = _region_of(Yb, yq) + 1
    while k < A.size and Yb[k] < y_end:
        if A[k] < bq:
            s_e = _time_to_y(yq, vq, bq, -J, Yb[k], rr)
            if bq - J * s_e > A[k] * (1.0 + 1e-13):
                return False
        k += 1
    # braking on from y_m (b grows from b_m to b_s at y_cap): the limit of every region it runs in
    r_c = _region_of(Yb, y_cap)
    if b_s > A[r_c]:
        return False
    k = _region_of(Yb, y_m)
    while k < r_c:
        y_hi = _pmin(Yb[k + 1], y_cap)
        if b_m + J * _time_to_y(y_m, v_m, b_m, J, y_hi, _INF) > A[k] * (1.0 + 1e-13):
            return False
        k += 1
    _cut(st, ns, J, iq, sq)
    t = st[W, TAU, ns[W] - 1] + rr
    if y_m > y_end:
        _push(st, ns, t, y_end, v_m, 0.0, 0.0, _region_of(Yb, y_end))
        t += (y_m - y_end) / v_m
    _push(st, ns, t, y_m, v_m, b_m, J, _region_of(Yb, y_m))
    _push(st, ns, t + s1, y_cap, Cr, b_s, _motion(A, C, J, Cr, b_s, r_c), r_c)
    return True


@jit(b1(ST, NS, f8, V, V, V, V, V, b1, i8, f8, i8))
def _fix_speed(st, ns, J, Yb, A, C, capnext, entry, optimize, i_v, s_v, r):
    """Motion 4 for the speed cap C[r], first exceeded at (i_v, s_v).

    Returns True when the entry deceleration of this step-down is still to be chosen
    (``optimize``): the paper's fix is then built and slot BEFORE holds the state before it.
    """
    Cr = C[r]
    iq, sq = _search(st, ENERGY, Cr, 0.0, J, i_v, s_v, 0, 0.0, 1e-13 * _pmax(1.0, Cr))
    yq, vq, bq = _state(st, iq, sq)
    rr = bq / J
    y_end = yq + rr * (vq + rr * (bq / 2.0 - J * rr / 6.0))
    y_cap = capnext[r]
    touch = y_end > y_cap
    if touch:
        # meet v = C exactly at the event point where the cap rises (a free there)
        iq, sq = _search(st, AT_CAP, Cr, y_cap, J, i_v, s_v, iq, sq, 1e-11 * _pmax(1.0, y_cap))
        yq, vq, bq = _state(st, iq, sq)
        dv = Cr - vq
        disc = _pmax(bq * bq - 2.0 * J * dv, 0.0)
        rr = 2.0 * dv / (bq + math.sqrt(disc)) if dv > 0.0 else 0.0
        y_end = y_cap
    # the easing-off piece may cross points where the deceleration limit falls below it
    r_q = _region_of(Yb, yq)
    r_end = _region_of(Yb, y_end) if not touch else _region_of(Yb, y_cap)
    for r2 in range(r_q + 1, min(r_end, A.size - 1) + 1):
        ye = Yb[r2]
        if ye > y_end:
            break
        if A[r2] >= bq:
            continue
        s_e = _time_to_y(yq, vq, bq, -J, ye, rr)
        if bq - J * s_e > A[r2] * (1.0 + 1e-13):
            _fix_decel(st, ns, J, Yb, A, C, r2, iq, sq)
            return False
    b_end = bq - J * rr if touch else 0.0
    step_down = optimize and y_cap < _INF and Cr < C[A.size - 1]
    has_entry = entry[r] > 0.0
    if step_down:
        _copy(st, ns, W, BEFORE)
    elif has_entry:
        _copy(st, ns, W, BEFORE_E)
    _cut(st, ns, J, iq, sq)
    r_next = _region_of(Yb, y_end)
    b_end = _pmax(b_end, 0.0)
    n = ns[W] - 1
    _push(st, ns, st[W, TAU, n] + rr, y_end, Cr, b_end, _motion(A, C, J, Cr, b_end, r_next), r_next)
    if step_down:
        return True
    if has_entry and y_cap < _INF:
        _copy(st, ns, W, PAPER_E)
        _copy(st, ns, BEFORE_E, W)
        if not _enter_braking(st, ns, J, Yb, A, C, capnext, i_v, s_v, r, entry[r]):
            _copy(st, ns, PAPER_E, W)
    return False


# --------------------------------------------------------------------------------------
# The true minimum at a speed step-down
# --------------------------------------------------------------------------------------


@jit(IF(ST, NS, f8, f8, V, V, V, V, V, b1, V))
def _run(st, ns, J, X, Yb, A, C, capnext, entry, optimize, pend):
    """Build backwards until cruising at the last cap.

    Returns ``(status, y)``: ``DONE`` with the braking distance ``y``; ``PENDING``
    when (``optimize``) a speed step-down was met and its entry deceleration is to
    be chosen (``pend`` = i_v, s_v, r; the paper's fix is built, slot BEFORE holds
    the construction before it); ``NO_PROGRESS`` on an internal failure.
    """
    last = A.size - 1
    for _ in range(_MAX_STEPS):
        if ns[FLAGS]:
            break
        i = ns[W] - 1
        y0, v0, b0, u = st[W, Y, i], st[W, V_, i], st[W, B, i], st[W, U, i]
        r = int(st[W, REG, i])
        y_hi = Yb[r + 1]
        if u == 0.0 and b0 <= 0.0:  # motion 3: cruise at the cap
            if r == last or C[r] >= C[last]:
                # cruising at the start speed (the last, highest cap): every region further back
                # has the same cap and a = 0 meets any deceleration limit, so braking starts here
                return DONE, y0
            s = (y_hi - y0) / v0
            r2 = r + 1
            _push(st, ns, st[W, TAU, i] + s, y_hi, v0, 0.0, _motion(A, C, J, v0, 0.0, r2), r2)
            continue
        s_lim = (A[r] - b0) / u if u > 0.0 else _INF
        s_v = _time_to_speed(v0, b0, u, C[r])
        s_ev = _time_to_y(y0, v0, b0, u, y_hi, _INF)
        if s_v < s_ev and s_v <= s_lim:
            if _fix_speed(st, ns, J, Yb, A, C, capnext, entry, optimize, i, s_v, r):
                pend[0] = i
                pend[1] = s_v
                pend[2] = r
                return PENDING, 0.0
        elif s_lim < s_ev:
            y1, v1, _ = _adv(y0, v0, b0, u, s_lim)
            _push(st, ns, st[W, TAU, i] + s_lim, y1, v1, A[r], 0.0, r)
        else:
            y1, v1, b1 = _adv(y0, v0, b0, u, s_ev)
            y1 = y_hi
            r2 = r + 1
            if b1 > A[r2] * (1.0 + 1e-13):
                _fix_decel(st, ns, J, Yb, A, C, r2, i, s_ev)
            else:
                b1 = _pmin(b1, A[r2])
                _push(st, ns, st[W, TAU, i] + s_ev, y1, v1, b1, _motion(A, C, J, v1, b1, r2), r2)
    return NO_PROGRESS, _INF


@jit(f8(ST, NS, f8, f8, V, V, V, V, V, V, i8, f8, i8, b1, f8), inline="always")
def _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, enter, b_s):
    """Finish the construction with the entries chosen so far; the pattern duration minus X/v0.

    With ``enter`` the working construction is first the one before the step-down of
    region ``r`` (slot BEFORE) entered with deceleration ``b_s`` (inf when that fails);
    else it is taken as it is. ``tau_end - y_r / v0``: the duration up to a
    constant when the braking fits (``y_r <= X``); past that, the needed distance counts first.
    One function for both (not two): every compiled function costs compile time.
    """
    if enter:
        _copy(st, ns, BEFORE, W)
        if not _enter_braking(st, ns, J, Yb, A, C, capnext, i_v, s_v, r, b_s):
            return _INF
    status, y_r = _run(st, ns, J, X, Yb, A, C, capnext, entry, False, pend)
    if status != DONE or ns[FLAGS]:
        return _INF
    t = st[W, TAU, ns[W] - 1] - y_r / C[A.size - 1]
    return t if y_r <= X else _BAD + (y_r - X)


@jit(nt.none(ST, NS, f8, f8, V, V, V, V, V, V, i8, f8, i8))
def _best_entry(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r):
    """Choose the deceleration ``b_s`` at the restriction start that minimises the duration.

    The working construction on entry (slot PAPER; slot BEFORE the one before the
    fix) has the paper's rule ``b_s = 0``, or, where easing off to ``a = 0`` would
    end past the restriction start, ``v = C`` met there easing off. The optimum
    enters still braking with ``b_s`` up to the deceleration limits on both sides
    of the restriction start (:func:`_enter_braking` joins it, with or without a
    cruise): one-dimensional minimisation of the duration over ``b_s`` (a scan of
    ``_SCAN`` entries, then Brent's method, golden section with parabolic steps, on
    the bracket around the best, to 1e-7 of the range: the duration is flat at an
    inner optimum, so its error is round-off (at 0.1 % of the range it was up to
    2e-5 s, enough for a lower deceleration limit that does not bind to give a
    different, faster pattern); an
    optimum on the edge of the entries that work, where it is not flat, is
    found by bisection to round-off), each trial
    finishing the construction with the entries already chosen at the step-downs
    further back (else the paper's rule); :func:`planner.stopping.kernel.kernel` repeats the whole
    construction when there are several step-downs, so each choice sees the
    others' (coordinate descent, while a pass makes the pattern faster).
    """
    _copy(st, ns, W, PAPER)
    f0 = _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, False, 0.0)
    r_c = _region_of(Yb, capnext[r])
    hi = _pmin(A[r_c], A[r_c - 1])
    xtol = 1e-7 * hi
    g = 0.5 * (3.0 - math.sqrt(5.0))
    # a coarse scan first: the duration can dip narrowly near b_s = 0 with a second, shallower
    # valley or a region where the join fails further up; Brent's search then runs on the bracket
    # around the best sample (its ends' objective known: an edge of the entries that work is seen)
    x, fx, k_x, f_prev, fa, fb = 0.0, _INF, 0, 0.0, 0.0, 0.0
    for k in range(1, _SCAN + 1):
        f_k = _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, True, hi * k / _SCAN)
        if f_k < fx:
            x, fx, k_x, fa, fb = hi * k / _SCAN, f_k, k, f_prev, 0.0
        elif k == k_x + 1:
            fb = f_k
        f_prev = f_k
    a, b = hi * (k_x - 1) / _SCAN, _pmin(hi * (k_x + 1) / _SCAN, hi)
    if k_x == 0:  # nothing works: Brent's search as before, from the golden point of the whole range
        a, b, fa, fb = 0.0, hi, 0.0, 0.0
        x = a + g * (b - a)
        fx = _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, True, x)
    if k_x == 1:
        fa = 0.0  # b_s = 0 is the paper's rule, f0, not a failed join
    w = v = x
    fw = fv = fx
    d = e = 0.0
    for _ in range(80):
        m = 0.5 * (a + b)
        tol = xtol + 1e-10 * abs(x)
        if abs(x - m) <= 2.0 * tol - 0.5 * (b - a):
            break
        para = False
        if abs(e) > tol and fx < _BAD and fw < _BAD and fv < _BAD:
            rp = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * rp
            q = 2.0 * (q - rp)
            if q > 0.0:
                p = -p
            q = abs(q)
            if abs(p) < abs(0.5 * q * e) and a * q < p + q * x - 0.0 and p < q * (b - x):
                e, d = d, p / q
                u = x + d
                if u - a < 2.0 * tol or b - u < 2.0 * tol:
                    d = tol if m >= x else -tol
                para = True
        if not para:
            e = (a - x) if x >= m else (b - x)
            d = g * e
        u = x + (d if abs(d) >= tol else (tol if d > 0.0 else -tol))
        fu = _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, True, u)
        if fu <= fx:
            if u >= x:
                a, fa = x, fx
            else:
                b, fb = x, fx
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a, fa = u, fu
            else:
                b, fb = u, fu
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    # the minimum on the edge of the entries that work (the braking fits, the join exists): there the
    # duration is not flat, so the edge is found to round-off by bisection, not to Brent's tolerance
    if fx < _BAD:
        for side in range(2):
            lo, hi = (x, a) if side == 0 else (x, b)  # lo works, hi does not
            if not (side == 0 and fa >= _BAD or side == 1 and fb >= _BAD):
                continue
            f_lo = fx
            for _ in range(64):
                if abs(hi - lo) <= 1e-14 * _pmax(1.0, abs(x)):
                    break
                mid = 0.5 * (lo + hi)
                fm = _objective(st, ns, J, X, Yb, A, C, capnext, entry, pend, i_v, s_v, r, True, mid)
                if fm < _BAD:
                    lo, f_lo = mid, fm
                else:
                    hi = mid
            if f_lo < fx:
                x, fx = lo, f_lo
    _copy(st, ns, BEFORE, W)
    if fx < f0 and _enter_braking(st, ns, J, Yb, A, C, capnext, i_v, s_v, r, x):
        entry[r] = x
        return
    entry[r] = 0.0
    _copy(st, ns, PAPER, W)


@jit(IF(ST, NS, f8, f8, V, V, V, V, V, V, b1))
def _construct(st, ns, J, X, Yb, A, C, entry, capnext, pend, optimize):
    """The whole backward construction from the stop; ``(status, braking distance)``."""
    n = A.size
    nxt = _INF
    for r in range(n - 1, -1, -1):
        capnext[r] = nxt
        if r and C[r - 1] != C[r]:
            nxt = Yb[r]
    for k in range(ns.size):
        ns[k] = 0
    _push(st, ns, 0.0, 0.0, 0.0, 0.0, J, 0)
    while True:
        status, y_r = _run(st, ns, J, X, Yb, A, C, capnext, entry, optimize, pend)
        if status != PENDING:
            return (NO_PROGRESS if ns[FLAGS] else status), y_r
        _best_entry(st, ns, J, X, Yb, A, C, capnext, entry, pend, int(pend[0]), pend[1], int(pend[2]))
