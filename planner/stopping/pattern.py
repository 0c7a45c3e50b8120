"""Minimum-time, jerk-limited stopping patterns with position-dependent limits (docs/design.md §5).

The station stop is solved as a one-dimensional optimal-control problem on the
train front, all in SI:

    minimise T  subject to   |j(t)| <= J,   -A(x) <= a(t) <= 0,   0 <= v(t) <= v_lim(x),
                             x(0)=0, v(0)=v_start, a(0)=0,   x(T)=x_stop, v(T)=0, a(T)=0,

with ``A`` and ``v_lim`` step functions of position. Powering to hold speed (a > 0 only to cancel a
gradient) would be allowed; this module keeps ``a <= 0`` throughout, the stricter "no
re-acceleration" reading, so every pattern here is also admissible under the looser one.

Method (the event-point method of docs/design.md §5)
-------------------------------------------
The trajectory is piecewise constant jerk, each piece a cubic in time::

    a = a0 + j t,   v = v0 + a0 t + j t²/2,   x = x0 + v0 t + a0 t²/2 + j t³/6.

It is built *backwards* from the stop. In backward time ``tau = T - t`` with
``y = x_stop - x`` (distance still to run), ``b = -a`` (deceleration) the
dynamics are ``dy/dtau = v``, ``dv/dtau = b``, ``db/dtau = j`` — the forward
jerk ``j`` keeps its value, and speed *grows* going backwards. Two facts make
the construction simple and exact:

* Because ``a <= 0`` the speed never rises, so the speed limits only matter
  through the running minimum ``v_cap(x) = min(v_start, min_{x'<=x} v_lim(x'))``
  and a speed step-down is a *point* constraint at its start. The start
  condition (``v_start`` with ``a = 0``) is the last, unbounded cap.
* ``E = v + b²/(2J)`` — the speed reached by easing the brake off at full jerk
  now — never decreases along a backward trajectory (``dE/dtau = b (1 + j/J) >= 0``)
  and is constant on a ``j = -J`` piece. Every "back up and add the opposite
  jerk" question therefore has a unique answer found by walking back over the
  pieces already built.

The four motions, from the stop (v = 0, a = 0) backwards, between event points
(positions where a limit changes):

1. below both limits: maximum jerk (deceleration grows, ``j = +J``) until the
   deceleration limit or the next event point;
2. deceleration at its limit: constant deceleration to the next event point;
3. speed at its limit with ``a = 0``: constant speed to the next event point;
4. a limit would be violated: back up to the point ``q`` on the part already
   built, then ``j = -J`` from ``q`` to ``r`` so that the violated limit is met
   exactly:

   - speed cap ``C``: ``r`` is where ``b = 0`` and ``v = C`` (``q`` solves
     ``E(q) = C``, a quadratic), followed by motion 3 — unless that ``r`` lies
     beyond the event point where the cap changes; then ``v = C`` exactly at
     that event point with ``a`` free (``q`` from a cubic/square-root equation);
   - deceleration limit dropping to ``A'`` at event point ``e``: ``b = A'``
     exactly at ``e`` (``q`` from a cubic), then motion 2.

   If ``q`` is not on the last piece, earlier points are dropped ("backtrack
   further"); the monotone residuals guarantee one real root. A replacement
   piece lies pointwise below (in speed and deceleration at every position)
   the part it replaces, so limits already checked stay met.

The construction ends when the speed reaches ``v_start`` with ``a = 0``
(motion 3 on the last cap); that point is where braking starts. If it lies
beyond the pattern start, no pattern exists and the needed distance is reported.

Why it is minimum-time: the time is ``∫ dx / v``. Going backwards every motion
makes speed and deceleration grow as fast as the limits allow, and each fix
meets the violated limit with equality at the latest possible point (any other
point on the part already built gives a trajectory that is lower in speed and
deceleration at every position). On the position-independent problem (one
cap, one deceleration) this is the classic cruise / max-jerk / max-deceleration
/ max-jerk profile, the time-optimal one (it matches Ruckig to ~1e-6 s in the
tests). Where the deceleration limit falls, meeting it with equality at the
event point is best for the parts on both sides; an independent time-discretised
MILP agrees within its discretisation error on such cases.

Speed step-downs (the true minimum, docs/design.md §5). Speed falls, so a step-down
to ``C`` is the point constraint ``v <= C`` at its start. The paper's rule meets
it with ``a = 0``; the optimum enters still braking with some ``b_s`` (a free
variable), eases off inside to ``b_m`` and brakes on: ``b_m = 0`` with a cruise
at ``C - b_s²/2J`` where there is room, else ``b_m > 0`` (met while braking).
The construction takes ``b_s`` by a one-dimensional minimisation of the
duration (:func:`planner.stopping.construct._best_entry`, a scan, Brent's, each
trial finishing the construction; an optimum on the edge of the entries whose
braking fits is found to round-off by bisection), and with several step-downs
chooses each again, seeing the others', while that makes it faster. ``rule="paper"`` keeps the
paper's rule for comparison. ``tests/test_stopping_lp.py`` checks the result
against an independent time-discretised MILP (no slower; its bound comes down
onto it as the grid is refined).

Code. This module is the public face (input checks, the deceleration rule, :func:`solve_stop`; the
result, :class:`StopPattern`, is :mod:`planner.stopping.result`); the construction runs compiled with numba: :mod:`planner.stopping.kernel`
(request, regions, forward breakpoints), :mod:`planner.stopping.construct` (motions, fixes, entry
choice), :mod:`planner.stopping.pieces` (closed forms and roots of a piece). They are built at install
(``planner kernels build``, :mod:`planner.io.compiled`); without a build they compile on the first
solve of a process, some seconds (``benchmarks/bench_stopping.py``); a solve then costs microseconds.

References: docs/design.md §5 (event-point constant-jerk stopping pattern method).
"""
from __future__ import annotations

import math
import threading
from dataclasses import fields
from typing import Sequence

import numpy as np

from planner.io import compiled
from planner.physics.dynamics import track_accel_ms2
from planner.errors import InputError
from planner.stopping import codes
from planner.stopping.result import PatternSamples, StopPattern, set_raw

__all__ = [
    "PatternSamples",
    "StopPattern",
    "decel_limit_profile",
    "solve_stop",
]


# --------------------------------------------------------------------------------------
# Input checking
# --------------------------------------------------------------------------------------


def _check_number(name: str, value, *, positive: bool = False) -> float:
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(f):
        raise InputError(f"{name} must be finite, got {value!r}")
    if positive and not f > 0.0:
        raise InputError(f"{name} must be > 0, got {f!r}")
    if not positive and f < 0.0:
        raise InputError(f"{name} must be >= 0, got {f!r}")
    return f


def _rows(name: str, steps, what: str) -> np.ndarray:
    """A step function given as ``[(x_from_m, value), ...]`` as an ``(n, 2)`` float array (unchecked)."""
    try:
        return np.array([(p[0], p[1]) for p in steps], dtype=np.float64).reshape(-1, 2)
    except (TypeError, ValueError, IndexError, KeyError):
        raise InputError(f"{name} must be a sequence of (x_from_m, {what}) pairs") from None


_POSITIVE = {True: 1, False: 0, None: -1}


def _step_fault(name: str, rows: np.ndarray, code: int, i: int, *, what: str, noun: str = "step") -> str:
    """The one-line message for fault ``code`` of :func:`planner.stopping.kernel.check_steps` at row ``i``."""
    k = codes
    if code == k.EMPTY:
        return f"{name} is empty; give at least one (0.0, {what}) pair"
    x, val = rows[i].tolist()
    if code == k.FIRST_NOT_ZERO:
        return f"{name}[0] starts at x_from={x!r} m; the first {noun} must start at 0.0"
    if code == k.NOT_FINITE:
        return f"{name}[{i}] = ({x!r}, {val!r}) is not finite"
    if code == k.NOT_SORTED:
        prev = float(rows[i - 1, 0])
        return (f"{name}[{i}] x_from={x!r} m is not after {name}[{i - 1}] x_from={prev!r} m; "
                f"sort the {noun}s by strictly increasing x_from")
    sign = ">" if code == k.NOT_POSITIVE else ">="
    return f"{name}[{i}] at x_from={x!r} m: {what} must be {sign} 0, got {val!r}"


def _check_steps(name: str, steps, *, what: str, positive: bool | None,
                 noun: str = "step") -> list[tuple[float, float]]:
    """Validate a step function given as ``[(x_from_m, value), ...]`` sorted, first at 0.

    ``positive``: True = values > 0, False = values >= 0, None = any finite value.
    The checks are :func:`planner.stopping.kernel.check_steps`, the ones :func:`solve_stop` runs.
    """
    rows = _rows(name, steps, what)
    code, i = (_k or _compiled()).check_steps(rows, 0, rows.shape[0], _POSITIVE[positive])
    if code:
        raise InputError(_step_fault(name, rows, code, i, what=what, noun=noun))
    return [tuple(r) for r in rows.tolist()]


# --------------------------------------------------------------------------------------
# Domain rule: deceleration limit along an approach
# --------------------------------------------------------------------------------------


def decel_limit_profile(
    comfort_ms2: float,
    adhesion_ms2: float,
    gradient_segments: Sequence[tuple[float, float]] = ((0.0, 0.0),),
    rotating_mass_factor: float = 0.0,
    brake_ms2: float = math.inf,
) -> list[tuple[float, float]]:
    """Largest deceleration available along a station approach, as a step function.

    ``A(x) = min(min(comfort, adhesion, brake) + g s(x) / 1000 / (1 + ρ), brake)`` [m/s²], ``s`` the
    gradient in ‰ *in the running direction*. Comfort, adhesion and the train's own stopping brake
    bound the braking effort (what passengers feel, what the wheel–rail contact transmits, what the
    brake gives); a rising gradient adds gravity's share to the deceleration achieved (the run curves'
    :func:`planner.physics.dynamics.track_accel_ms2`: M g s on the inertial mass M (1 + ρ)), a falling
    one takes it away. The stopping brake also caps the deceleration achieved, as the run curves stop
    at it whatever the gradient: a pattern never stops harder than the run curves (a bad day is never
    faster than nominal). On a line ``s`` is averaged over the train, bounded per piece from the safe
    side: :func:`planner.stopping.approach.decel_limits` builds it.

    Parameters
    ----------
    comfort_ms2 : float
        Comfort limit on the braking deceleration [m/s²], > 0.
    adhesion_ms2 : float
        Adhesion-limited braking deceleration [m/s²], > 0.
    gradient_segments : sequence of (x_from_m, gradient_permil)
        Gradient from ``x_from_m`` on (positions from the pattern start, sorted,
        the first at 0), in ‰, positive when rising in the running direction.
    rotating_mass_factor : float
        The train's rotating-mass allowance ρ (>= 0; 0 gives g/1000 per ‰).
    brake_ms2 : float
        The train's own stopping brake [m/s²] (``TrainType.stop_brake_ms2``), > 0; inf: no cap.

    Returns
    -------
    list of (x_from_m, decel_ms2)
        Step function for :func:`solve_stop`'s ``decel_limits``; equal
        neighbours are merged.

    Raises
    ------
    InputError
        On bad numbers, unsorted segments, or a falling gradient so steep that
        no deceleration is left (the message names the position).

    Examples
    --------
    >>> decel_limit_profile(1.0, 0.8, [(0.0, 0.0), (100.0, -10.0), (250.0, 5.0)])
    [(0.0, 0.8), (100.0, 0.7019335), (250.0, 0.84903325)]
    """
    comfort = _check_number("comfort_ms2", comfort_ms2, positive=True)
    adhesion = _check_number("adhesion_ms2", adhesion_ms2, positive=True)
    rho = _check_number("rotating_mass_factor", rotating_mass_factor)
    brake = math.inf if brake_ms2 == math.inf else _check_number("brake_ms2", brake_ms2, positive=True)
    base = min(comfort, adhesion, brake)
    try:
        segs = list(gradient_segments)
    except TypeError:
        raise InputError("gradient_segments must be a sequence of (x_from_m, gradient_permil) pairs") from None
    segs = (_check_steps("gradient_segments", segs, what="gradient_permil", positive=None, noun="segment")
            if segs else [(0.0, 0.0)])
    out: list[tuple[float, float]] = []
    for i, (x, s) in enumerate(segs):
        value = round(min(base - float(track_accel_ms2(s / 1000.0, 0.0, rho)), brake), 12)  # round: stable merging
        if not value > 0.0:
            raise InputError(
                f"gradient_segments[{i}]: at x_from={x!r} m the falling gradient {s!r} ‰ leaves "
                f"{value:.4f} m/s² of deceleration (min(comfort, adhesion, brake) = {base!r} m/s²); "
                "no stop is possible there — check the gradient sign or the adhesion level"
            )
        if out and out[-1][1] == value:
            continue
        out.append((x, value))
    return out


# --------------------------------------------------------------------------------------
# Public solver (the construction itself is compiled: planner.stopping.kernel)
# --------------------------------------------------------------------------------------

_new = object.__new__
_UNSOLVED = {f.name: f.default for f in fields(StopPattern)} | {"feasible": False}  # every field, in order
_local = threading.local()
_k = None  # the solver: its build (planner.io.compiled) or planner.stopping.kernel, chosen on the first solve


def _compiled():
    """The solver's entry points: the module built at install for these sources, else the just-in-time kernel."""
    global _k
    built = compiled.load("stopping", codes.SOURCES)
    if built is None:
        from planner.stopping import kernel as built
    _k = built
    return built


def solve_stop(
    v_start: float,
    x_stop: float,
    *,
    jerk_max: float,
    decel_limits: Sequence[tuple[float, float]],
    speed_limits: Sequence[tuple[float, float]],
    rule: str = "min-time",
) -> StopPattern:
    """Minimum-time jerk-limited stopping pattern under position-dependent limits.

    Parameters
    ----------
    v_start : float
        Speed at the pattern start [m/s] (acceleration 0 there), >= 0.
    x_stop : float
        Stop marker position from the pattern start [m], >= 0.
    jerk_max : float
        Jerk limit ``J`` [m/s³], > 0: ``|j| <= J``.
    decel_limits : sequence of (x_from_m, decel_ms2)
        Largest deceleration magnitude available from ``x_from_m`` on [m/s²],
        > 0; sorted by strictly increasing ``x_from_m``, the first at 0. See
        :func:`decel_limit_profile` for the comfort/adhesion/gradient rule.
    speed_limits : sequence of (x_from_m, speed_ms)
        Speed limit of the train front from ``x_from_m`` on [m/s], >= 0; same
        ordering rules.
    rule : {"min-time", "paper"}
        At a speed step-down followed by a cruise: ``"min-time"`` (default) the
        true minimum, entering the restriction still easing off the brake;
        ``"paper"`` the paper's rule, the lower speed reached with a = 0 at the
        restriction start (slower, kept for comparison).

    Returns
    -------
    StopPattern
        ``feasible=True`` with the breakpoints of the piecewise-constant-jerk
        pattern, or ``feasible=False`` with the reason. An infeasible request
        never yields a pattern that breaks a limit.

    Raises
    ------
    InputError
        On negative or non-finite numbers, empty or unsorted step functions, a
        step function whose first step is not at 0, or a non-positive
        deceleration limit.

    Notes
    -----
    The event-point method of docs/design.md §5, built backwards from the stop (see the
    module docstring for the construction and why it is minimum-time). Exact:
    every switching point solves its cubic (or lower) equation to machine
    precision; there is no time grid. Acceleration stays ``<= 0`` throughout.

    Examples
    --------
    >>> p = solve_stop(20.0, 400.0, jerk_max=0.8, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 25.0)])
    >>> round(p.duration_s, 3), round(p.brake_start_m, 2)
    (30.625, 187.5)
    """
    if rule == "min-time":
        optimize = True
    elif rule == "paper":
        optimize = False
    else:
        raise InputError(f"rule must be 'min-time' or 'paper', got {rule!r}")
    k = _k or _compiled()
    try:  # the common case: lists of (x, value) tuples, written straight into this thread's array
        if type(decel_limits) is not list or type(speed_limits) is not list:
            raise TypeError
        v0, X, J = float(v_start), float(x_stop), float(jerk_max)
        n_dl = len(decel_limits)
        n = n_dl + len(speed_limits)
        work, room, mem = _local.work  # AttributeError in a thread's first solve (_work makes it)
        if n > room:
            raise ValueError
        i = 0
        for row in decel_limits:
            if type(row) is not tuple:
                raise TypeError
            mem[i], mem[i + 1] = row  # exactly a pair, each as float(...) gives it, else refused
            i += 2
        for row in speed_limits:
            if type(row) is not tuple:
                raise TypeError
            mem[i], mem[i + 1] = row
            i += 2
    except (TypeError, ValueError, AttributeError):  # anything else: checked (the first fault raised)
        v0, X, J, steps, n_dl = _request(v_start, x_stop, jerk_max, decel_limits, speed_limits)
        n = steps.shape[0]
        work, _, mem = _work(n)
        work[:2 * n] = steps.ravel()
    p = k.kernel(v0, X, J, n_dl, n, optimize, work)
    if p < 0:
        return _not_solved(-p, work, n, v0, X, J, n_dl)
    # the pattern holds a copy of the kernel's output, each field read from it when first read (the
    # constructor would spend ~1.5 µs on frozen setattr; this module ~1 µs on floats and tuples no one
    # may read): out[2:HEAD] (T, brake start, braking distance, ...), then t, x, v, a (p + 1 each), j (p)
    r = _new(StopPattern)
    o = 2 * n + 2  # out[2] (out is work[2 n:])
    set_raw(r, (True, "", v0, X, J, mem[o:o + _TAIL + 5 * p].tobytes()))  # planner.stopping.result.RAW
    return r


def _work(n_steps: int) -> tuple[np.ndarray, int, memoryview]:
    """This thread's array for the kernel to work in (the kernel runs without the GIL), large enough for
    ``n_steps`` rows: ``(array, rows it has room for, a memoryview of it)``."""
    w = getattr(_local, "work", None)
    if w is None or n_steps > w[1]:
        room = max(n_steps, 2 * w[1] if w else 16)
        buf = np.zeros(codes.work_size(room))
        w = _local.work = (buf, room, memoryview(buf))
    return w


_TAIL = codes.HEAD - 2 + 4  # out[2:HEAD] and the breakpoints' 4 beyond 5 per piece


def _request(v_start, x_stop, jerk_max, decel_limits, speed_limits):
    """The checked request when the fast conversion failed: the first fault raised, in argument order."""
    v0 = _check_number("v_start", v_start)
    X = _check_number("x_stop", x_stop)
    J = _check_number("jerk_max", jerk_max, positive=True)
    dl = _check_steps("decel_limits", decel_limits, what="decel_ms2", positive=True)
    sl = _check_steps("speed_limits", speed_limits, what="speed_ms", positive=False)
    return v0, X, J, np.array(dl + sl, dtype=np.float64).reshape(-1, 2), len(dl)


NEEDED_SLACK_M = 1e-5
"""Absolute part of the round-off allowance on an infeasible stop's needed distance [m]."""
NEEDED_SLACK_REL = 1e-8
"""Relative part of that allowance (per metre of the distance)."""


def needed_bound(y_r: float) -> float:
    """The braking distance an infeasible stop reports: an upper bound on what it needs [m].

    The construction's needed distance ``y_r`` is exact up to the round-off of its switching points'
    cubics, which is not monotone at the boundary: on 40,000 random approaches an approach given
    ``y_r + 1 µm`` (the limits shifted with it) was still infeasible in 9, each by less than 2 µm
    (the start speed equal to the first limit, a braking curve that meets it at the very start). So
    what is reported is ``y_r`` plus 10 µm and 1e-8 of it: any approach at least that long is feasible,
    and the verdict is consistent with it (infeasible means ``x_stop_m`` below the bound)."""
    return y_r + NEEDED_SLACK_M + NEEDED_SLACK_REL * y_r


def _infeasible(reason: str, v0: float, X: float, J: float, braking_distance_m: float = math.nan) -> StopPattern:
    """``StopPattern(False, reason, ...)`` as the constructor makes it (the fields in their order, the
    dataclass's own defaults), minus its frozen per-field setattr: a third of the random approaches of
    ``benchmarks/bench_stopping.py`` end here."""
    r = _new(StopPattern)
    r.__dict__.update(_UNSOLVED, reason=reason, v_start_ms=v0, x_stop_m=X, jerk_max_ms3=J,
                      braking_distance_m=braking_distance_m)
    return r


def _not_solved(code: int, work: np.ndarray, n: int, v0: float, X: float, J: float, n_dl: int) -> StopPattern:
    """The kernel's verdict other than a pattern (``work``: its array, ``n`` step rows): an infeasible
    StopPattern, or the InputError raised."""
    k = codes
    out = 2 * n  # where the kernel's result starts in work
    if code == k.NEEDS_MORE:  # the common verdict first
        y_r = needed_bound(float(work[out + 4]))
        return _infeasible(f"needs {y_r:.1f} m to stop from {v0 * 3.6:.1f} km/h under these limits, only "
                           f"{X:.1f} m available", v0, X, J, y_r)
    if code == k.INCONSISTENT:  # a defect of the construction, caught: no pattern rather than a wrong one
        return _infeasible(f"no valid stopping pattern from {v0 * 3.6:.1f} km/h over {X:.1f} m: the construction's "
                           f"pieces do not join at x={float(work[out + 1]):.1f} m (a defect of the solver, caught; "
                           "report the approach)", v0, X, J)
    if code == k.START_ABOVE_LIMIT:
        return _infeasible(f"start speed {v0 * 3.6:.1f} km/h is above the speed limit "
                           f"{float(work[2 * n_dl + 1]) * 3.6:.1f} km/h at the pattern start", v0, X, J)
    if code == k.ZERO_LIMIT:
        return _infeasible(f"speed limit 0 km/h from x={float(work[out + 1]):.1f} m, before the stop at {X:.1f} m",
                           v0, X, J)
    if code == k.STANDING:
        return _infeasible(f"standing at the start and no re-acceleration allowed, cannot reach "
                           f"x_stop={X:.1f} m", v0, X, J)
    if code == k.BAD_V_START:
        _check_number("v_start", v0)
    if code == k.BAD_X_STOP:
        _check_number("x_stop", X)
    if code == k.BAD_JERK:
        _check_number("jerk_max", J, positive=True)
    steps = work[:2 * n].reshape(n, 2)
    if k.BAD_DECEL < code < k.BAD_SPEED:
        raise InputError(_step_fault("decel_limits", steps[:n_dl], code - k.BAD_DECEL, int(work[out + 1]),
                                     what="decel_ms2"))
    if code > k.BAD_SPEED:
        raise InputError(_step_fault("speed_limits", steps[n_dl:], code - k.BAD_SPEED, int(work[out + 1]),
                                     what="speed_ms"))
    raise RuntimeError("stopping pattern construction made no progress (internal error)")
