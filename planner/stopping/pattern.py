"""Minimum-time, jerk-limited stopping patterns with position-dependent limits (DESIGN §5).

The station stop is solved as a one-dimensional optimal-control problem on the
train front, all in SI:

    minimise T  subject to   |j(t)| <= J,   -A(x) <= a(t) <= 0,   0 <= v(t) <= v_lim(x),
                             x(0)=0, v(0)=v_start, a(0)=0,   x(T)=x_stop, v(T)=0, a(T)=0,

with ``A`` and ``v_lim`` step functions of position. DESIGN allows powering to
hold speed (a > 0 only to cancel a gradient); this module keeps ``a <= 0``
throughout, which is the stricter "no re-acceleration" reading, so every pattern
here is also admissible under the looser one.

Method (the event-point method of DESIGN §5)
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

Speed step-downs (the true minimum, DESIGN §5). Where a speed limit steps
down and the pattern cruises at the lower speed before braking on, the paper's
rule reaches the lower speed with ``a = 0`` at the restriction start. That is
not the minimum: the optimum enters the restriction still braking with some
``b_s``, eases off inside it and cruises slightly below the limit
(``C - b_s²/2J``); the time lost inside is paid back by braking later before
it. The construction takes ``b_s`` by a one-dimensional minimisation of the
duration (:meth:`_Builder._best_entry`, Brent's method; each trial finishes the
construction), and with several step-downs runs once more so that each choice
sees the others'. The choice also shortens the braking distance, so approaches
that the paper's rule declares infeasible by less than an easing-off distance
can get a pattern. ``rule="paper"`` keeps the paper's rule for comparison.
``tests/test_stopping_lp.py`` checks the result against an independent
time-discretised MILP: no slower, and within 0.01 s. Not covered: a step-down
met without a cruise (the ease-off would end past the restriction start) is
still entered at exactly the limit speed with the deceleration that gives.

References: DESIGN §5 (event-point constant-jerk stopping pattern method).
"""
from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import numpy as np

from planner.physics.dynamics import track_accel_ms2
from planner.errors import InfeasibleError, InputError

__all__ = [
    "PatternSamples",
    "StopPattern",
    "decel_limit_profile",
    "solve_stop",
]

_INF = math.inf
_MAX_STEPS = 10_000  # guard against a construction that fails to make progress (never hit in tests)


# --------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------


class PatternSamples(NamedTuple):
    """A stopping pattern sampled in time (exact evaluation of the cubic pieces).

    Attributes
    ----------
    t_s, x_m, v_ms, a_ms2, j_ms3 : ndarray
        Time [s], position from the pattern start [m], speed [m/s], acceleration
        [m/s²] (negative when braking) and jerk [m/s³] (of the piece the sample
        lies in; the end point takes the last piece's jerk).
    """

    t_s: np.ndarray
    x_m: np.ndarray
    v_ms: np.ndarray
    a_ms2: np.ndarray
    j_ms3: np.ndarray


@dataclass(frozen=True)
class StopPattern:
    """A minimum-time jerk-limited stopping pattern, or why there is none.

    Attributes
    ----------
    feasible : bool
        True when a pattern meeting every limit exists.
    reason : str
        ``""`` when feasible; otherwise one line saying why (distance needed, ...).
    v_start_ms, x_stop_m, jerk_max_ms3 : float
        The request: start speed [m/s], stop position [m], jerk limit [m/s³].
    duration_s : float
        Pattern duration [s] (NaN when infeasible).
    brake_start_m : float
        Position where deceleration first begins, from the pattern start [m]
        (NaN when infeasible).
    braking_distance_m : float
        Distance from the brake start to the stop that the limits need [m]; also
        set when infeasible (it is then larger than ``x_stop_m``), NaN when
        unknown (start speed above the first limit).
    t_s, x_m, v_ms, a_ms2 : tuple of float
        Breakpoints: state at the start of every piece, plus the end state
        (length ``n_pieces + 1``).
    j_ms3 : tuple of float
        Jerk of every piece [m/s³] (length ``n_pieces``).
    """

    feasible: bool
    reason: str
    v_start_ms: float
    x_stop_m: float
    jerk_max_ms3: float
    duration_s: float = math.nan
    brake_start_m: float = math.nan
    braking_distance_m: float = math.nan
    t_s: tuple[float, ...] = ()
    x_m: tuple[float, ...] = ()
    v_ms: tuple[float, ...] = ()
    a_ms2: tuple[float, ...] = ()
    j_ms3: tuple[float, ...] = ()

    @property
    def n_pieces(self) -> int:
        """Number of constant-jerk pieces."""
        return len(self.j_ms3)

    def sample(self, dt_s: float) -> PatternSamples:
        """Sample the pattern every ``dt_s`` seconds, always including the end point.

        Parameters
        ----------
        dt_s : float
            Sampling interval [s], > 0.

        Returns
        -------
        PatternSamples
            Exact values of the cubic pieces at ``t = 0, dt, 2 dt, ..., T``.

        Raises
        ------
        InfeasibleError
            When the pattern is infeasible (there is nothing to sample).
        InputError
            When ``dt_s`` is not a positive number.
        """
        if not self.feasible:
            raise InfeasibleError(f"no stopping pattern to sample: {self.reason}")
        if not (dt_s > 0.0) or not math.isfinite(dt_s):
            raise InputError(f"sample: dt_s must be a positive number of seconds, got {dt_s!r}")
        T = self.duration_s
        t = np.arange(0.0, T, dt_s) if T > 0.0 else np.zeros(0)
        if t.size and T - t[-1] < 1e-9 * max(1.0, T):
            t = t[:-1]
        t = np.append(t, T)
        starts = np.asarray(self.t_s[:-1])
        if starts.size == 0:  # zero-length pattern (already standing at the stop)
            z = np.zeros_like(t)
            return PatternSamples(t, z + self.x_m[-1], z, z, z)
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, starts.size - 1)
        tau = t - starts[idx]
        x0 = np.asarray(self.x_m[:-1])[idx]
        v0 = np.asarray(self.v_ms[:-1])[idx]
        a0 = np.asarray(self.a_ms2[:-1])[idx]
        j = np.asarray(self.j_ms3)[idx]
        a = a0 + j * tau
        v = v0 + tau * (a0 + j * tau / 2.0)
        x = x0 + tau * (v0 + tau * (a0 / 2.0 + j * tau / 6.0))
        return PatternSamples(t, x, v, a, j)


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


def _check_steps(name: str, steps, *, what: str, positive: bool | None,
                 noun: str = "step") -> list[tuple[float, float]]:
    """Validate a step function given as ``[(x_from_m, value), ...]`` sorted, first at 0.

    ``positive``: True = values > 0, False = values >= 0, None = any finite value.
    """
    try:
        pairs = [(float(p[0]), float(p[1])) for p in steps]
    except (TypeError, ValueError, IndexError):
        raise InputError(f"{name} must be a sequence of (x_from_m, {what}) pairs") from None
    if not pairs:
        raise InputError(f"{name} is empty; give at least one (0.0, {what}) pair")
    if pairs[0][0] != 0.0:
        raise InputError(f"{name}[0] starts at x_from={pairs[0][0]!r} m; the first {noun} must start at 0.0")
    for i, (x, val) in enumerate(pairs):
        if not (math.isfinite(x) and math.isfinite(val)):
            raise InputError(f"{name}[{i}] = ({x!r}, {val!r}) is not finite")
        if i and not x > pairs[i - 1][0]:
            raise InputError(
                f"{name}[{i}] x_from={x!r} m is not after {name}[{i - 1}] x_from={pairs[i - 1][0]!r} m; "
                f"sort the {noun}s by strictly increasing x_from"
            )
        if positive and not val > 0.0:
            raise InputError(f"{name}[{i}] at x_from={x!r} m: {what} must be > 0, got {val!r}")
        if positive is False and val < 0.0:
            raise InputError(f"{name}[{i}] at x_from={x!r} m: {what} must be >= 0, got {val!r}")
    return pairs


# --------------------------------------------------------------------------------------
# Domain rule: deceleration limit along an approach
# --------------------------------------------------------------------------------------


def decel_limit_profile(
    comfort_ms2: float,
    adhesion_ms2: float,
    gradient_segments: Sequence[tuple[float, float]] = ((0.0, 0.0),),
    rotating_mass_factor: float = 0.0,
) -> list[tuple[float, float]]:
    """Largest deceleration available along a station approach, as a step function.

    ``A(x) = min(comfort, adhesion) + g s(x) / 1000 / (1 + ρ)``  [m/s²], with
    ``s`` the gradient in ‰ *in the running direction* (DESIGN §5): comfort
    and adhesion both bound the braking effort (what passengers feel, what the
    wheel–rail contact transmits); a rising gradient adds its share of gravity
    to the deceleration achieved, a falling one (``s < 0``) takes it away. The
    gravity part is the run curves' (:func:`planner.physics.dynamics.track_accel_ms2`:
    the weight M g s acts on the inertial mass M (1 + ρ)). For a line, ``s``
    is the gradient averaged over the train, bounded per piece from the safe
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
    base = min(comfort, adhesion)
    try:
        segs = list(gradient_segments)
    except TypeError:
        raise InputError("gradient_segments must be a sequence of (x_from_m, gradient_permil) pairs") from None
    segs = (_check_steps("gradient_segments", segs, what="gradient_permil", positive=None, noun="segment")
            if segs else [(0.0, 0.0)])
    out: list[tuple[float, float]] = []
    for i, (x, s) in enumerate(segs):
        value = round(base - float(track_accel_ms2(s / 1000.0, 0.0, rho)), 12)  # round: stable merging/printing
        if not value > 0.0:
            raise InputError(
                f"gradient_segments[{i}]: at x_from={x!r} m the falling gradient {s!r} ‰ leaves "
                f"{value:.4f} m/s² of deceleration (min(comfort, adhesion) = {base!r} m/s²); "
                "no stop is possible there — check the gradient sign or the adhesion level"
            )
        if out and out[-1][1] == value:
            continue
        out.append((x, value))
    return out


# --------------------------------------------------------------------------------------
# Backward construction (pure floats; numpy per-call overhead would dominate here)
# --------------------------------------------------------------------------------------


def _adv(y: float, v: float, b: float, u: float, s: float) -> tuple[float, float, float]:
    """Backward state after time ``s`` on a piece of jerk ``u`` (db/dtau = u)."""
    return (
        y + s * (v + s * (b / 2.0 + u * s / 6.0)),
        v + s * (b + u * s / 2.0),
        b + u * s,
    )


def _time_to_speed(v: float, b: float, u: float, C: float) -> float:
    """Time until ``v + b s + u s²/2`` reaches ``C`` on a piece with ``u >= 0`` (inf if never)."""
    dv = C - v
    if dv <= 0.0:
        return 0.0
    if u > 0.0:
        return 2.0 * dv / (b + math.sqrt(b * b + 2.0 * u * dv))
    if b > 0.0:
        return dv / b
    return _INF


def _time_to_y(y: float, v: float, b: float, u: float, Y: float, s_up: float = _INF) -> float:
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
            s = min(s, D / v)
        if b > 0.0:
            s = min(s, math.sqrt(2.0 * D / b))
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
    return max(s, 0.0)


def _illinois(f, lo: float, hi: float, flo: float, fhi: float, ftol: float) -> float:
    """Root of an increasing ``f`` on ``[lo, hi]`` with ``flo <= 0 < fhi`` (Illinois false position)."""
    side = 0
    s = lo
    for _ in range(200):
        if fhi - flo <= 0.0:
            return lo
        s = (lo * fhi - hi * flo) / (fhi - flo)
        if not lo <= s <= hi:
            s = 0.5 * (lo + hi)
        fs = f(s)
        if abs(fs) <= ftol or hi - lo <= 4e-16 * max(1.0, abs(hi)):
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


def _brent_min(f, a: float, b: float, xtol: float, maxiter: int = 60) -> tuple[float, float]:
    """Minimum of ``f`` on ``[a, b]`` (Brent: golden section with parabolic steps); ``(x, f(x))``."""
    g = 0.5 * (3.0 - math.sqrt(5.0))
    x = w = v = a + g * (b - a)
    fx = fw = fv = f(x)
    d = e = 0.0
    for _ in range(maxiter):
        m = 0.5 * (a + b)
        tol = xtol + 1e-10 * abs(x)
        if abs(x - m) <= 2.0 * tol - 0.5 * (b - a):
            break
        para = False
        if abs(e) > tol and fx < _INF and fw < _INF and fv < _INF:
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
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
        fu = f(u)
        if fu <= fx:
            if u >= x:
                a = x
            else:
                b = x
            v, fv, w, fw, x, fx = w, fw, x, fx, u, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, fv, w, fw = w, fw, u, fu
            elif fu <= fv or v == x or v == w:
                v, fv = u, fu
    return x, fx


class _Builder:
    """The backward event-point construction over one approach (all floats, backward frame)."""

    __slots__ = ("J", "Yb", "A", "C", "capnext", "tau", "y", "v", "b", "u", "reg", "X", "optimize", "entry")

    def __init__(self, J: float, Yb: list[float], A: list[float], C: list[float], X: float = _INF,
                 optimize: bool = False, entry: dict | None = None):
        self.J = J
        self.X = X  # approach length: the objective of the entry choice at a speed step-down
        self.optimize = optimize  # True: choose the entry at speed step-downs; False: take self.entry
        self.entry = dict(entry or {})  # region of a step-down -> deceleration on entry (0: the paper's rule)
        self.Yb = Yb  # region r spans y in [Yb[r], Yb[r+1]]; Yb[0] = 0, Yb[-1] = inf
        self.A = A
        self.C = C
        n = len(A)
        cn = [_INF] * n  # y where the speed cap next rises (backwards), per region
        nxt = _INF
        for r in range(n - 1, -1, -1):
            cn[r] = nxt
            if r and C[r - 1] != C[r]:
                nxt = Yb[r]
        self.capnext = cn
        # nodes: start of each piece; the last node's piece is the open (current) motion
        self.tau = [0.0]
        self.y = [0.0]
        self.v = [0.0]
        self.b = [0.0]
        self.u = [J]
        self.reg = [0]

    # -- helpers ----------------------------------------------------------------------

    def _state(self, i: int, s: float) -> tuple[float, float, float]:
        return _adv(self.y[i], self.v[i], self.b[i], self.u[i], s)

    def _region_of(self, y: float) -> int:
        """Region an open motion starting at ``y`` runs in (a boundary belongs to the far side)."""
        return bisect_right(self.Yb, y) - 1

    def _cut(self, i: int, s: float) -> None:
        """Keep nodes 0..i with piece i cut at ``s``; the last node then starts the easing-off piece."""
        del self.tau[i + 1 :], self.y[i + 1 :], self.v[i + 1 :], self.b[i + 1 :], self.u[i + 1 :], self.reg[i + 1 :]
        if s > 0.0:
            y, v, b = self._state(i, s)
            self._push(self.tau[i] + s, y, v, b, 0.0, -1)
        self.u[-1] = -self.J

    def _push(self, t, y, v, b, u, r):
        self.tau.append(t)
        self.y.append(y)
        self.v.append(v)
        self.b.append(b)
        self.u.append(u)
        self.reg.append(r)

    def _motion(self, v: float, b: float, r: int) -> float:
        """Jerk of the motion from state (v, b) in region r: motion 1, 2 or 3."""
        if b >= self.A[r] * (1.0 - 1e-13):
            return 0.0  # 2: hold the deceleration limit
        if b <= 0.0 and v >= self.C[r] * (1.0 - 1e-13):
            return 0.0  # 3: hold the speed limit
        return self.J  # 1: maximum jerk

    def _search(self, f, i_hi: int, s_hi: float, i_lo: int = 0, s_lo: float = 0.0, ftol: float = 1e-12):
        """Latest point (i, s) on the built part, between (i_lo, s_lo) and (i_hi, s_hi), where the
        increasing residual ``f(y, v, b)`` crosses zero; ``f > 0`` at (i_hi, s_hi), ``f <= 0`` at (i_lo, s_lo).

        Walking back piece by piece is "drop the previous point and backtrack further".
        """
        i = i_hi
        hi = s_hi
        fhi = f(*self._state(i, hi))
        while True:
            lo = s_lo if i == i_lo else 0.0
            flo = f(*self._state(i, lo))
            if flo <= 0.0 or i <= i_lo:
                if flo > 0.0:  # numerical corner: treat the lower limit as the root
                    return i, lo
                y0, v0, b0, u0 = self.y[i], self.v[i], self.b[i], self.u[i]

                def g(s, y0=y0, v0=v0, b0=b0, u0=u0):
                    return f(*_adv(y0, v0, b0, u0, s))

                return i, _illinois(g, lo, hi, flo, fhi, ftol)
            fhi = flo
            i -= 1
            hi = self.tau[i + 1] - self.tau[i]

    # -- the four motions and the fixes -----------------------------------------------

    def run(self) -> float:
        """Build backwards until cruising at the last cap; return that position (braking distance)."""
        A, C, Yb = self.A, self.C, self.Yb
        last = len(A) - 1
        for _ in range(_MAX_STEPS):
            i = len(self.tau) - 1
            y0, v0, b0, u, r = self.y[i], self.v[i], self.b[i], self.u[i], self.reg[i]
            y_hi = Yb[r + 1]
            if u == 0.0 and b0 <= 0.0:  # motion 3: cruise at the cap
                if r == last or C[r] >= C[last]:
                    # cruising at the start speed (the last, highest cap): every region further back
                    # has the same cap and a = 0 meets any deceleration limit, so braking starts here
                    return y0
                s = (y_hi - y0) / v0
                r2 = r + 1
                self._push(self.tau[i] + s, y_hi, v0, 0.0, self._motion(v0, 0.0, r2), r2)
                continue
            s_lim = (A[r] - b0) / u if u > 0.0 else _INF
            s_v = _time_to_speed(v0, b0, u, C[r])
            s_ev = _time_to_y(y0, v0, b0, u, y_hi)
            if s_v < s_ev and s_v <= s_lim:
                self._fix_speed(i, s_v, r)
            elif s_lim < s_ev:
                y1, v1, _ = _adv(y0, v0, b0, u, s_lim)
                self._push(self.tau[i] + s_lim, y1, v1, A[r], 0.0, r)
            else:
                y1, v1, b1 = _adv(y0, v0, b0, u, s_ev)
                y1 = y_hi
                r2 = r + 1
                if b1 > A[r2] * (1.0 + 1e-13):
                    self._fix_decel(r2, i, s_ev)
                else:
                    b1 = min(b1, A[r2])
                    self._push(self.tau[i] + s_ev, y1, v1, b1, self._motion(v1, b1, r2), r2)
        raise RuntimeError("stopping pattern construction made no progress (internal error)")

    def _fix_decel(self, r2: int, i_hi: int, s_hi: float) -> None:
        """Motion 4 for a deceleration limit that drops to A[r2] at the event point Yb[r2]."""
        J = self.J
        A_new = self.A[r2]
        ye = self.Yb[r2]

        def reach(y, v, b):  # where easing off from here meets b = A_new, minus the event point
            if b <= A_new:
                return y - ye
            rr = (b - A_new) / J
            return y + rr * (v + rr * (b / 2.0 - J * rr / 6.0)) - ye

        i, s = self._search(reach, i_hi, s_hi, ftol=1e-11 * max(1.0, ye))
        y, v, b = self._state(i, s)
        rr = max(b - A_new, 0.0) / J
        v_e = v + rr * (b - J * rr / 2.0)
        self._cut(i, s)
        self._push(self.tau[-1] + rr, ye, v_e, A_new, self._motion(v_e, A_new, r2), r2)

    def _fix_speed(self, i_v: int, s_v: float, r: int) -> None:
        """Motion 4 for the speed cap C[r], first exceeded at (i_v, s_v)."""
        J, C = self.J, self.C[r]

        def energy(y, v, b):  # E - C: speed reached by easing off now, minus the cap
            return v + b * b / (2.0 * J) - C

        iq, sq = self._search(energy, i_v, s_v, ftol=1e-13 * max(1.0, C))
        yq, vq, bq = self._state(iq, sq)
        rr = bq / J
        y_end = yq + rr * (vq + rr * (bq / 2.0 - J * rr / 6.0))
        y_cap = self.capnext[r]
        touch = y_end > y_cap
        if touch:
            # meet v = C exactly at the event point where the cap rises (a free there)
            def at_cap(y, v, b):
                dv = C - v
                if dv <= 0.0:
                    return y_cap - y
                disc = b * b - 2.0 * J * dv
                if disc < 0.0:
                    disc = 0.0
                rr = 2.0 * dv / (b + math.sqrt(disc))
                return y_cap - (y + rr * (v + rr * (b / 2.0 - J * rr / 6.0)))

            iq, sq = self._search(at_cap, i_v, s_v, iq, sq, ftol=1e-11 * max(1.0, y_cap))
            yq, vq, bq = self._state(iq, sq)
            dv = C - vq
            disc = max(bq * bq - 2.0 * J * dv, 0.0)
            rr = 2.0 * dv / (bq + math.sqrt(disc)) if dv > 0.0 else 0.0
            y_end = y_cap
        # the easing-off piece may cross points where the deceleration limit falls below it
        r_q = self._region_of(yq)
        r_end = self._region_of(y_end) if not touch else self._region_of(y_cap)
        for r2 in range(r_q + 1, min(r_end, len(self.A) - 1) + 1):
            ye = self.Yb[r2]
            if ye > y_end:
                break
            if self.A[r2] >= bq:
                continue
            s_e = _time_to_y(yq, vq, bq, -J, ye, rr)
            if bq - J * s_e > self.A[r2] * (1.0 + 1e-13):
                self._fix_decel(r2, iq, sq)
                return
        b_end = bq - J * rr if touch else 0.0
        v_end = C
        step_down = not touch and self.optimize and y_cap < _INF and C < self.C[-1]
        if step_down or (not touch and self.entry.get(r, 0.0) > 0.0):
            before = before_entry = self._save()
        self._cut(iq, sq)
        r_next = self._region_of(y_end)
        b_end = max(b_end, 0.0)
        self._push(self.tau[-1] + rr, y_end, v_end, b_end, self._motion(v_end, b_end, r_next), r_next)
        if step_down:
            self._best_entry(before, i_v, s_v, r)
        elif not touch and self.entry.get(r, 0.0) > 0.0 and y_cap < _INF:
            paper = self._save()
            self._load(before_entry)
            if not self._enter_braking(i_v, s_v, r, self.entry[r]):
                self._load(paper)

    # -- the true minimum at a speed step-down ----------------------------------------

    def _save(self):
        return (self.tau[:], self.y[:], self.v[:], self.b[:], self.u[:], self.reg[:])

    def _load(self, st) -> None:
        self.tau, self.y, self.v, self.b, self.u, self.reg = (x[:] for x in st)

    def _objective(self) -> float:
        """Finish the construction with the entries chosen so far; the pattern duration minus X/v0.

        ``tau_end - y_r / v0``: the duration up to a constant when the braking fits
        (``y_r <= X``); past that, the needed distance counts first.
        """
        opt = self.optimize
        self.optimize = False
        try:
            y_r = self.run()
        except RuntimeError:
            return _INF
        finally:
            self.optimize = opt
        v0 = self.C[-1]
        t = self.tau[-1] - y_r / v0
        return t if y_r <= self.X else 1e9 + (y_r - self.X)

    def _enter_braking(self, i_v: int, s_v: float, r: int, b_s: float) -> bool:
        """Replace the part after the step-down: ease off to the lower cruise ``C - b_s²/(2J)``, cruise,
        then brake on with full jerk so that ``v = C`` exactly at the restriction start, still braking
        with ``b_s`` there. False when that needs more room than there is or breaks a limit."""
        J, C, A, Yb = self.J, self.C[r], self.A, self.Yb
        y_cap = self.capnext[r]
        Cp = C - b_s * b_s / (2.0 * J)
        if not Cp > 0.0:
            return False

        def energy(y, v, b):
            return v + b * b / (2.0 * J) - Cp

        iq, sq = self._search(energy, i_v, s_v, ftol=1e-13 * max(1.0, C))
        yq, vq, bq = self._state(iq, sq)
        rr = bq / J
        y_end = yq + rr * (vq + rr * (bq / 2.0 - J * rr / 6.0))
        s_r = b_s / J
        y0 = y_cap - (Cp * s_r + J * s_r ** 3 / 6.0)
        if y0 < y_end:
            return False
        # speed: at most Cp while easing off and cruising, at most C on the arc; the caps nearer the
        # stop are lower, so every region the new part runs in is checked (conservatively)
        k = self._region_of(yq)
        while k < len(A) and Yb[k] < y_cap:
            if self.C[k] < (C if Yb[k + 1] > y0 else Cp):
                return False
            k += 1
        # easing off (b falls from bq): the deceleration limit at every event point it passes
        k = self._region_of(yq) + 1
        while k < len(A) and Yb[k] < y_end:
            if A[k] < bq:
                s_e = _time_to_y(yq, vq, bq, -J, Yb[k], rr)
                if bq - J * s_e > A[k] * (1.0 + 1e-13):
                    return False
            k += 1
        # braking on from y0 (b grows to b_s at y_cap): the limit of every region it runs in
        r_c = self._region_of(y_cap)
        if b_s > A[r_c]:
            return False
        k = self._region_of(y0)
        while k < r_c:
            y_hi = min(Yb[k + 1], y_cap)
            if J * _time_to_y(y0, Cp, 0.0, J, y_hi) > A[k] * (1.0 + 1e-13):
                return False
            k += 1
        self._cut(iq, sq)
        t = self.tau[-1] + rr
        if y0 > y_end:
            self._push(t, y_end, Cp, 0.0, 0.0, self._region_of(y_end))
            t += (y0 - y_end) / Cp
        self._push(t, y0, Cp, 0.0, J, self._region_of(y0))
        self._push(t + s_r, y_cap, C, b_s, self._motion(C, b_s, r_c), r_c)
        return True

    def _best_entry(self, before, i_v: int, s_v: float, r: int) -> None:
        """Choose the deceleration ``b_s`` at the restriction start that minimises the duration.

        The paper's rule is ``b_s = 0`` (the state on entry to this call). The
        optimum enters still braking: one-dimensional minimisation of the
        duration over ``b_s`` (Brent's method, to 0.5 % of its range, a few 1e-3 m/s²;
        the duration is flat at the optimum, so its error is some 1e-4 s), each trial finishing
        the construction with the entries already chosen (``self.entry``, else
        the paper's rule) at the step-downs further back; :func:`solve_stop`
        repeats the whole construction once when there are several step-downs,
        so each choice sees the others' (coordinate descent).
        """
        paper = self._save()
        f0 = self._objective()

        def f(b_s: float) -> float:
            self._load(before)
            if not self._enter_braking(i_v, s_v, r, b_s):
                return _INF
            return self._objective()

        hi = min(self.A[self._region_of(self.capnext[r])], math.sqrt(2.0 * self.J * self.C[r]) * 0.999)
        best, fb = _brent_min(f, 0.0, hi, xtol=5e-3 * hi, maxiter=12)
        self._load(before)
        if fb < f0 and self._enter_braking(i_v, s_v, r, best):
            self.entry[r] = best
            return
        self.entry[r] = 0.0
        self._load(paper)


# --------------------------------------------------------------------------------------
# Public solver
# --------------------------------------------------------------------------------------


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
    The event-point method of DESIGN §5, built backwards from the stop (see the
    module docstring for the construction and why it is minimum-time). Exact:
    every switching point solves its cubic (or lower) equation to machine
    precision; there is no time grid. Acceleration stays ``<= 0`` throughout.

    Examples
    --------
    >>> p = solve_stop(20.0, 400.0, jerk_max=0.8, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 25.0)])
    >>> round(p.duration_s, 3), round(p.brake_start_m, 2)
    (30.625, 187.5)
    """
    if rule not in ("min-time", "paper"):
        raise InputError(f"rule must be 'min-time' or 'paper', got {rule!r}")
    v0 = _check_number("v_start", v_start)
    X = _check_number("x_stop", x_stop)
    J = _check_number("jerk_max", jerk_max, positive=True)
    dl = _check_steps("decel_limits", decel_limits, what="decel_ms2", positive=True)
    sl = _check_steps("speed_limits", speed_limits, what="speed_ms", positive=False)
    base = dict(v_start_ms=v0, x_stop_m=X, jerk_max_ms3=J)

    if v0 > sl[0][1]:
        return StopPattern(
            False,
            f"start speed {v0:.2f} m/s is above the speed limit {sl[0][1]:.2f} m/s at the pattern start",
            **base,
        )
    # the running minimum of the speed limit over [0, x) for x < x_stop (a <= 0: speed never rises)
    cap = v0
    for x, val in sl:
        if x >= X:
            break
        if val < cap:
            cap = val
        if cap <= 0.0 and v0 > 0.0:
            return StopPattern(
                False, f"speed limit 0 m/s from x={x:.1f} m, before the stop at {X:.1f} m", **base
            )
    if v0 == 0.0:
        if X == 0.0:
            return StopPattern(True, "", **base, duration_s=0.0, brake_start_m=0.0, braking_distance_m=0.0,
                               t_s=(0.0,), x_m=(0.0,), v_ms=(0.0,), a_ms2=(0.0,), j_ms3=())
        return StopPattern(False, f"standing at the start and no re-acceleration allowed, cannot reach x_stop={X:.1f} m",
                           **base)

    # regions in the backward frame y = X - x: breakpoints of both step functions inside (0, X)
    xs = sorted({x for x, _ in dl if 0.0 < x < X} | {x for x, _ in sl if 0.0 < x < X})
    bounds = [0.0] + xs  # forward region starts
    A_f: list[float] = []
    C_f: list[float] = []
    ia = isl = 0
    cap = v0
    for x in bounds:
        while ia + 1 < len(dl) and dl[ia + 1][0] <= x:
            ia += 1
        while isl + 1 < len(sl) and sl[isl + 1][0] <= x:
            isl += 1
        cap = min(cap, sl[isl][1])
        A_f.append(dl[ia][1])
        C_f.append(cap)
    # merge equal neighbours, then reverse into the backward frame
    mb, mA, mC = [bounds[0]], [A_f[0]], [C_f[0]]
    for x, a_, c_ in zip(bounds[1:], A_f[1:], C_f[1:]):
        if a_ == mA[-1] and c_ == mC[-1]:
            continue
        mb.append(x)
        mA.append(a_)
        mC.append(c_)
    n = len(mb)
    Yb = [0.0] + [X - mb[k] for k in range(n - 1, 0, -1)] + [_INF]
    A = mA[::-1]
    C = mC[::-1]

    builder = _Builder(J, Yb, A, C, X, optimize=(rule == "min-time"))
    y_r = builder.run()
    if len(builder.entry) > 1 and 0.0 in builder.entry.values():
        # several step-downs and one kept the paper's rule, maybe because the others were still at it:
        # choose each again, knowing the others' choice
        builder = _Builder(J, Yb, A, C, X, optimize=True, entry=builder.entry)
        y_r = builder.run()
    if y_r > X * (1.0 + 1e-12) + 1e-9:
        return StopPattern(
            False,
            f"needs {y_r:.1f} m to stop from {v0:.2f} m/s under these limits, only {X:.1f} m available",
            **base,
            braking_distance_m=y_r,
        )
    y_r = min(y_r, X)
    return _forward(builder, v0, X, J, y_r, base)


def _forward(builder: _Builder, v0: float, X: float, J: float, y_r: float, base: dict) -> StopPattern:
    """Turn the backward node list into forward breakpoints (merging equal-jerk neighbours)."""
    tau, ys, vs, bs, us = builder.tau, builder.y, builder.v, builder.b, builder.u
    m = len(tau) - 1  # closed backward pieces 0..m-1; node m is the cruise at v_start
    t_cruise = (X - y_r) / v0
    T = t_cruise + tau[m]
    ts: list[float] = [0.0]
    xs: list[float] = [0.0]
    vv: list[float] = [v0]
    aa: list[float] = [0.0]
    jj: list[float] = []
    if t_cruise > 1e-12 * max(1.0, T):  # a round-off sliver of cruise is not a piece
        jj.append(0.0)
        ts.append(t_cruise)
        xs.append(X - y_r)
        vv.append(v0)
        aa.append(0.0)
    for k in range(m - 1, -1, -1):
        dur = tau[k + 1] - tau[k]
        if dur <= 1e-14 * max(1.0, T):
            continue
        j = us[k]
        if jj and jj[-1] == j:  # same cubic continues: merge
            ts[-1] = T - tau[k]
            xs[-1] = X - ys[k]
            vv[-1] = vs[k]
            aa[-1] = -bs[k]
            continue
        jj.append(j)
        ts.append(T - tau[k])
        xs.append(X - ys[k])
        vv.append(vs[k])
        aa.append(-bs[k])
    # the end point is exact by construction
    ts[-1], xs[-1], vv[-1], aa[-1] = T, X, 0.0, 0.0
    return StopPattern(
        True,
        "",
        **base,
        duration_s=T,
        brake_start_m=X - y_r,
        braking_distance_m=y_r,
        t_s=tuple(ts),
        x_m=tuple(xs),
        v_ms=tuple(vv),
        a_ms2=tuple(aa),
        j_ms3=tuple(jj),
    )
