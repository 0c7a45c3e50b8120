"""The on-board ratio choice: pick the target-speed ratio from the running-time tables (docs/design.md §3).

This is the logic the vehicle runs. It sees **only the tables** (table (a),
table (b) and the evaluation points, as read from the Parquet datasets by
:func:`load_tables`) and, while running, the designated or remaining running
time. It never calls the simulator.

Modes
-----
``nearest`` — the published rule. At departure pick the grid ratio whose
table-(a) time is nearest the designated running time; at each evaluation
point X, in the row of the current ratio in X's table (b), pick the grid ratio
whose remaining time is nearest the remaining time (scheduled arrival − now).
Ties go to the higher ratio (arriving early is cheaper than late).

``interpolate`` — a continuous version of the same rule. Running time is
monotone in the ratio, and close to affine in its reciprocal ``u = 1/r`` (the
cruise part of a run takes distance / (r · v_max)). So the table is treated as
samples of a function T(u) and the ratio is the fractional one whose
interpolated time *equals* the wanted time:

* at departure: solve T_a(u) = designated for u by piecewise-linear
  interpolation of table (a) in u, r = 1/u;
* at evaluation point X with the current (fractional) ratio r_b: the row of
  table (b) for r_b is interpolated linearly in u between the rows of the two
  neighbouring grid ratios (the state at X, reached at r_b, lies between the
  states reached at its neighbours), then T_b(u_after) = remaining is solved
  the same way.

The result is clamped to [lowest grid ratio, 1]. Any ratio between grid values
is valid for the simulator and the vehicle (the target speed is just
``r × maximum speed``). The residual error is then the interpolation error at
the last evaluation points instead of the grid step, and because every point
re-solves with fresh remaining time the errors do not add up.

``adaptive`` — ``interpolate`` that also learns how far the real train is
from the table train. Tables (a)/(b) are built for one train (load 0, nominal
traction); a heavier or weaker train is slower at every ratio, and a rule that
trusts the tables keeps choosing slightly too low a ratio and arrives late.
Table (c) holds, for every evaluation point X and ratio r, the remaining time
at constant r for the table train T(X, r) and for a reference train (full
load, traction × 0.9: the degraded train the margin report plans for)
T_ref(X, r); their difference Δ(X, r) is the table's estimate of how much
a slower train loses from X on. The vehicle models its own remaining time as

    T(X, r_b, r_a; θ) = T_b(X, r_b, r_a) + θ · Δ(X, r_a)        (θ = 0: table train, 1: reference)

and learns θ from what it has already run: on each leg between evaluation
points, observed leg time − table leg time = θ · (reference − table leg time),
summed over the legs so far (least squares through the origin):
θ = Σ(observed − table) / Σ(reference − table). At X it then solves
T(X, r_b, r_a; θ) = remaining for r_a. The leg times come from the vehicle's
clock between beacons, which it has anyway; nothing but the tables and the
clock is used. θ is clipped to ``AdaptiveRule.THETA_RANGE`` (never below 0:
the table train is the fastest).

Three details make it robust for sawtooth vehicles, whose running time is not a
smooth (not even a monotone) function of the ratio:

* Δ(X, ·) is used as table (c) gives it, only clipped at 0 (a heavier, weaker
  train is never faster). Table (c) compares two constant-ratio runs from
  departure, so Δ also holds the difference of the two trains' coasting-band
  phases at X, which can flip sign from one ratio to the next. It was once
  smoothed across the grid (median of each ratio and its two neighbours)
  because such a spike, multiplied by θ, sent an on-time train to the lowest
  ratio 325 m before the stop; that was the last point, where sawtooth
  vehicles now use table (d), and the crossing nearest the current ratio (next
  item) keeps spikes at far ratios out of the choice. The median also removed
  real single-ratio features: E6 NKN→YMT, the reference train at ratio 0.95 is
  0.6–1.1 s slower than at both neighbours from every point up to 700 m
  before the stop; smoothed away, the perturbed train trusted 0.94 and arrived
  1.2 s late at ratio 1.0 (study: 5 % steps, points every 200–1000 m).
* T(X, r_b, ·; θ) is piecewise linear in 1/r between grid ratios and need not
  be monotone, so every crossing with the remaining time is found exactly
  (:func:`solve_piecewise`) and the one nearest the current ratio wins: the
  smallest change of driving that the tables say arrives on time.
* At the **last** evaluation point of a sawtooth vehicle, where nothing later
  can correct the choice, the row of table (b) is replaced by table (d)
  (:class:`ApproachTable`, built for sawtooth vehicles only): the
  remaining time from the train's *own* state there — its measured speed,
  interpolated on a 2 km/h grid, and whether it is in its coasting band
  (:func:`out_of_band`: the vehicle's cruise-control state, not the phase of
  its last step; a train that arrives braking onto a restriction below its
  band powers up to a raised target, and taking it for a coasting one cost
  1.1 s 200 m before the stop) — at every ratio
  of a 1 % grid, for the table and the reference train, so
  T = T_d(v, band, r_a) + θ · (T_d,ref − T_d). A sawtooth train's place in
  its coasting band is part of that state, which a row indexed by the ratio
  run before cannot know (it cost up to 1.5 s on the sample line). Here the
  reference difference is not clipped: from the same state a heavier train
  really does coast further.

A **sawtooth vehicle aims early**: every decision after departure and before
the last point aims ``AdaptiveRule.AIM_EARLY_S`` (0.5 s) early; the last point
aims on time. The reason is an asymmetry near the stop: the last point (a home
signal some 300 m out, or an odometer point closer still) can nearly always
*lose* time (a lower ratio, an earlier brake) but seldom *gain* any (no room is
left to accelerate), so an error of the tables at the last point with authority
is final when it makes the train late and corrected when it makes it early.
For a sawtooth vehicle such errors reach a second or more, because the remaining
time from a point is not even continuous in the ratio chosen there. E6 KWB→HGO,
2.5 % steps, beacons only, designated 209 s: at D-SIG-009, 1,213 m before the
stop, the train's remaining time is 80.97 s at every ratio from 0.667 to 0.685
(it coasts all the way to its braking point) and 78.79 s at 0.6855 (its band's
lower edge now lies above the speed it coasts down to, so it powers again). The
tables, whose row indexes the state by the ratio run before, said 79.2 s at
0.6841; the wanted time fell in the gap, and aiming on time the train arrived
1.27 s late (the home signal 325 m out could not gain it back); aiming early,
the worst run of that setting is 0.36 s late, and the worst of the whole
evaluation-interval study (16 settings, both scenarios) 0.91 s. A state-indexed
table at every point would be the thorough fix, at several times the tables'
CPU. A constant-speed vehicle's rows describe its state exactly (r_b × maximum
speed, or a braking curve), its errors are the small, two-sided ones of
interpolation, and aiming early only left it early where the last point could
not shed the 0.5 s, so it aims on time throughout. The vehicle tells which kind
it is by the tables it holds: table (d) exists for sawtooth vehicles only.

A new mode is a :class:`RatioChooser` factory registered in :data:`CHOOSERS`
(``register_mode``); modes that do not use the tables (e.g. time-keeping) are
dispatched by :mod:`planner.tables.closed_loop` instead.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from planner.errors import InputError
from planner.tables.piecewise import interp_u, row_at_ratio, solve_piecewise
from planner.physics.run_curve import (  # the run state's phase code (a constant; no simulation here)
    PHASE_POWER,
)

SAME_POINT_M = 1e-3
"""A decision within this distance [m] of an evaluation point is that point (grid round-off)."""


@dataclass(frozen=True, eq=False)
class ApproachTable:
    """Table (d): remaining time from the last evaluation point, indexed by the train's own state.

    Tables (b) and (c) index the state at a point by the ratio the train ran before it. At the
    last point nothing later can correct the choice, and a sawtooth train's state there (where
    in its coasting band it is) is not a function of that ratio. Table (d) instead holds, for
    a grid of speeds at the point and both band states (out of the coasting band: powers when
    below its target; in it: coasts to the band's lower edge first), the remaining time at
    each ratio of a fine grid, for the table train and the reference train; the vehicle
    interpolates at its measured speed in its actual band state.

    Attributes
    ----------
    speeds_ms : ndarray, shape (n_v,)
        Start speeds, ascending [m/s].
    powering : tuple of bool, length n_p
        Band state of each slice: True = out of the coasting band (the train powers whenever it
        is below its target; a start in phase power), False = in its coasting band (it coasts
        down to the band's lower edge first; a start in any other phase). Look it up with
        :func:`out_of_band`.
    ratios : ndarray, shape (n_ra,)
        Ratios after the point, descending.
    time_s, ref_time_s : ndarray, shape (n_p, n_v, n_ra)
        Remaining time to arrival of the table train and of the reference train [s].
    vmax_ms : float
        On-board maximum speed just after the point [m/s]: ratio r's target there is
        ``r × vmax_ms``.
    coast_band_ms : float
        The vehicle's coasting band [m/s].

    Notes
    -----
    Each column is smooth in speed except at its kinks: the target (above it the train brakes
    at once) and, not powering, the coasting band's lower edge ``max(target − band,
    run_curve.SAWTOOTH_MIN_FRACTION × target)`` (below it the train powers at once). :meth:`rows`
    interpolates linearly across them, which is off by up to ~0.8 s within one speed step of
    a kink. Taking both nodes on the train's side of the kink instead was tried and measured
    worse in closed loop on the sample line (extrapolating a steep column), so it is not done.
    """

    speeds_ms: np.ndarray
    powering: tuple[bool, ...]
    ratios: np.ndarray
    time_s: np.ndarray
    ref_time_s: np.ndarray
    vmax_ms: float = float("inf")
    coast_band_ms: float = 0.0

    def rows(self, speed_ms, powering) -> tuple[np.ndarray, np.ndarray]:
        """Table and reference remaining time per ratio at a speed and band state, linear in speed [s].

        ``speed_ms`` is one speed (rows of shape (n_ra,)) or one per run (shape (n, n_ra));
        ``powering`` is one band state for all or one per run. Speeds outside the grid are
        clamped to its ends; a band state the table does not hold (e.g. coasting for a
        constant-speed vehicle, whose phase does not change its future) uses the one it does.
        """
        if np.ndim(speed_ms) == 0:
            t, ref = self.rows(np.array([speed_ms], float), powering)
            return t[0], ref[0]
        v = np.asarray(speed_ms, float)
        on = np.broadcast_to(np.asarray(powering, bool), v.shape)
        slot = {b: self.powering.index(b) if b in self.powering else 0 for b in (True, False)}
        p = np.where(on, slot[True], slot[False])
        s = self.speeds_ms
        if len(s) == 1:
            return self.time_s[p, 0], self.ref_time_s[p, 0]
        v = np.minimum(np.maximum(v, s[0]), s[-1])
        j = np.clip(np.searchsorted(s, v, side="right") - 1, 0, len(s) - 2)
        f = ((v - s[j]) / (s[j + 1] - s[j]))[:, None]
        t = (1.0 - f) * self.time_s[p, j] + f * self.time_s[p, j + 1]
        ref = (1.0 - f) * self.ref_time_s[p, j] + f * self.ref_time_s[p, j + 1]
        return t, ref


@dataclass(frozen=True, eq=False)
class RunningTimeTables:
    """The tables of one interstation, direction and train type, as the vehicle holds them.

    Attributes
    ----------
    origin, destination : str
        Station ids.
    ratios : ndarray, shape (n_r,)
        Grid ratios, descending (1.0 first).
    time_a_s : ndarray, shape (n_r,)
        Table (a): running time departure → arrival at constant ratio [s].
    eval_point_ids : tuple of str, length n_x
        Evaluation points in running order (``dep`` first).
    eval_distance_m : ndarray, shape (n_x,)
        Running distance of each point from the departure stop marker [m].
    eval_position_m : ndarray, shape (n_x,)
        Chainage of each point [m].
    remaining_s : ndarray, shape (n_x, n_r, n_r)
        Table (b): ``remaining_s[x, i, j]`` is the running time from point x
        to arrival after running at ``ratios[i]`` up to x and ``ratios[j]``
        from x on [s].
    ref_remaining_s : ndarray, shape (n_x, n_r), optional
        Table (c): remaining time from point x at constant ``ratios[i]`` for
        the reference (full-load, traction × 0.9) train [s]; needed by the ``adaptive`` mode.
    speed_ms : ndarray, shape (n_x, n_r), optional
        Table (c): speed of the table train at point x at constant ``ratios[i]`` [m/s].
    approach : ApproachTable, optional
        Table (d) at the last evaluation point; used by the ``adaptive`` mode there.
    flags : tuple of planner.tables.flags.LegFlag
        Physical verdicts on the leg found while building the tables (e.g. the reference train
        stalls, so there is no table (c)).
    """

    origin: str
    destination: str
    ratios: np.ndarray
    time_a_s: np.ndarray
    eval_point_ids: tuple[str, ...]
    eval_distance_m: np.ndarray
    eval_position_m: np.ndarray
    remaining_s: np.ndarray
    ref_remaining_s: np.ndarray | None = None
    speed_ms: np.ndarray | None = None
    approach: ApproachTable | None = None
    flags: tuple = ()

    @property
    def min_time_s(self) -> float:
        """Minimum running time: table (a) at the highest ratio [s]."""
        return float(self.time_a_s[0])

    @property
    def max_time_s(self) -> float:
        """Longest running time the table can stretch to (lowest ratio) [s]."""
        return float(self.time_a_s[-1])


class RatioChooser(Protocol):
    """A ratio-choice rule, vectorised over n runs that share one interstation's tables."""

    def depart(self, tables: RunningTimeTables, designated_s: np.ndarray) -> np.ndarray:
        """Ratio per run at departure, from the designated running time [s]."""

    def at_point(
        self, tables: RunningTimeTables, k: int, ratio: np.ndarray, remaining_s: np.ndarray,
        speed_ms: np.ndarray | None = None, powering: np.ndarray | None = None,
    ) -> np.ndarray:
        """New ratio per run at evaluation point ``k`` from the current ratio, remaining time [s]
        and, for modes that use them, the measured speed [m/s] and whether the train is
        out of its coasting band (:func:`out_of_band`) as it passes the point."""


def _nearest_index(values: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Index of the value nearest each target; the first (highest ratio) wins ties."""
    return np.argmin(np.abs(values[None, :] - np.asarray(target, float)[:, None]), axis=1)


def grid_index(ratios: np.ndarray, ratio: np.ndarray) -> np.ndarray:
    """Index of the grid ratio nearest each of ``ratio``."""
    return _nearest_index(ratios, ratio)


class NearestRule:
    """The published nearest-time rule (docs/design.md §3); chooses grid ratios only."""

    name = "nearest"

    def depart(self, tables: RunningTimeTables, designated_s: np.ndarray) -> np.ndarray:
        return tables.ratios[_nearest_index(tables.time_a_s, designated_s)]

    def at_point(self, tables, k, ratio, remaining_s, speed_ms=None, powering=None):
        rows = tables.remaining_s[k, grid_index(tables.ratios, ratio)]  # (n, n_r)
        j = np.argmin(np.abs(rows - np.asarray(remaining_s, float)[:, None]), axis=1)
        return tables.ratios[j]


def solve_ratio(ratios: np.ndarray, times_s: np.ndarray, want_s: float) -> float:
    """Fractional ratio whose time, interpolated linearly in ``u = 1/r``, equals ``want_s``.

    Parameters
    ----------
    ratios : ndarray
        Grid ratios, descending.
    times_s : ndarray
        Running time at each grid ratio [s]; expected to grow as the ratio
        falls. Where it does not (a higher ratio that is no faster, e.g. a
        target that the train never reaches anyway), the running maximum is
        used, which picks the highest ratio among equally fast ones.
    want_s : float
        Wanted time [s].

    Returns
    -------
    float
        Ratio in [ratios[-1], ratios[0]]; the end ratio when ``want_s`` lies
        outside the table's range.

    Examples
    --------
    >>> round(solve_ratio(np.array([1.0, 0.5]), np.array([100.0, 200.0]), 150.0), 4)
    0.6667
    """
    u = 1.0 / ratios
    t = np.maximum.accumulate(times_s)
    if want_s <= t[0]:
        return float(ratios[0])
    if want_s >= t[-1]:
        return float(ratios[-1])
    # first node with t >= want: the segment (j-1, j) brackets it, t[j] > t[j-1]
    j = int(np.searchsorted(t, want_s, side="left"))
    f = (want_s - t[j - 1]) / (t[j] - t[j - 1])
    return float(1.0 / (u[j - 1] + f * (u[j] - u[j - 1])))


def row_at(tables: RunningTimeTables, k: int, ratio) -> np.ndarray:
    """Table (b) rows at point ``k`` for a fractional ratio before per run, linear in ``1/r``,
    shape (n, n_r) [s]."""
    return row_at_ratio(tables.ratios, tables.remaining_s[k], ratio)


class InterpolateRule:
    """Fractional ratios from tables interpolated in ``1/r`` (module doc)."""

    name = "interpolate"

    def depart(self, tables, designated_s):
        d = np.atleast_1d(np.asarray(designated_s, float))
        return np.array([solve_ratio(tables.ratios, tables.time_a_s, x) for x in d])

    def at_point(self, tables, k, ratio, remaining_s, speed_ms=None, powering=None):
        ratio = np.atleast_1d(np.asarray(ratio, float))
        rem = np.broadcast_to(np.asarray(remaining_s, float), ratio.shape)
        rows = row_at(tables, k, ratio)
        return np.array([solve_ratio(tables.ratios, row, x) for row, x in zip(rows, rem)])


class AdaptiveRule:
    """``interpolate`` plus a learned performance offset (module doc, mode ``adaptive``).

    Stateful per batch of runs: create one per closed-loop batch (:func:`chooser` does).
    """

    name = "adaptive"
    NEEDS_TABLE_C = True
    """Runs only where the leg has table (c) (no reference-train stall)."""
    THETA_RANGE = (0.0, 4.0)
    """Bounds of the learned performance parameter (0 = table train, 1 = reference train). The
    table train is the empty train at nominal traction, so a real train is never systematically
    faster: a negative estimate is noise (sawtooth cycles, legs of a few metres) and is not
    acted on. Above 4 the train is broken, not slow; extrapolating further would amplify noise."""
    AIM_EARLY_S = 0.5
    """How early a sawtooth vehicle's decisions after departure and before the last evaluation
    point aim [s]: the last point can lose time but seldom gain it, so a late error of the tables
    before it is final and an early one is corrected there (module doc). The learner still
    compares what the train did with what the tables said for the ratio chosen, so aiming early
    does not bias it."""

    def __init__(self):
        self._s: dict | None = None
        self._dcache: dict = {}

    def _delta_row(self, tables: RunningTimeTables, k: int) -> np.ndarray:
        """Reference − table remaining time from point k at constant ratio, per grid ratio [s].

        Table (c) compares two constant-ratio runs from departure, so besides the reference
        train's own loss after X it holds the difference of the two trains' states at X (for a
        sawtooth train, the phase of the coasting band). It is clipped at 0, because a heavier,
        weaker train is never faster than the table train from the same state, and otherwise
        used as it is: a median across neighbouring ratios also removes real one-ratio features
        (module doc).
        """
        key = (id(tables), k)
        if key not in self._dcache:
            ref = tables.ref_remaining_s
            if ref is None:
                raise InputError("mode adaptive needs table (c) (table_c dataset); rebuild the tables with "
                                 "`planner tables`")
            d = ref[k] - np.diagonal(tables.remaining_s[k])
            self._dcache[key] = (tables, np.maximum(d, 0.0))  # keep tables alive: id stays unique
        return self._dcache[key][1]

    def _delta(self, tables: RunningTimeTables, k: int, r: np.ndarray) -> np.ndarray:
        """Reference − table remaining time from point k at ratio r (per run), clipped at 0 [s]."""
        return interp_u(tables.ratios, self._delta_row(tables, k), r)

    def depart(self, tables, designated_s):
        d = np.atleast_1d(np.asarray(designated_s, float))
        r0 = np.array([solve_ratio(tables.ratios, tables.time_a_s, x) for x in d])
        self._s = {
            "k": np.zeros(d.size, int),
            "rem": d.copy(),  # actual remaining time at the last point
            "pred": interp_u(tables.ratios, tables.time_a_s, r0),
            "delta": self._delta(tables, 0, r0),
            "num": np.zeros(d.size),
            "den": np.zeros(d.size),
        }
        return r0

    def at_point(self, tables, k, ratio, remaining_s, speed_ms=None, powering=None):
        ratio = np.atleast_1d(np.asarray(ratio, float))
        rem = np.broadcast_to(np.asarray(remaining_s, float), ratio.shape)
        st = self._s
        if st is None:
            raise RuntimeError("AdaptiveRule.at_point before depart")
        dk = self._delta_row(tables, k)
        last = k == len(tables.eval_distance_m) - 1
        ap = tables.approach if last and speed_ms is not None else None
        # aim early before the last point where the tables cannot see the train's state (sawtooth
        # vehicles: the ones with table (d)); a constant-speed vehicle's rows describe it exactly
        early = self.AIM_EARLY_S if tables.approach is not None and not last else 0.0
        row = row_at(tables, k, ratio)
        # the leg just run, at the ratio run before: observed vs. table time, and the reference's extra
        st["num"] += (st["rem"] - rem) - (st["pred"] - interp_u(tables.ratios, row, ratio))
        st["den"] += st["delta"] - self._delta(tables, k, ratio)
        with np.errstate(divide="ignore", invalid="ignore"):
            theta = np.where(st["den"] > 1e-3, st["num"] / st["den"], 0.0)
        theta = np.minimum(np.maximum(theta, self.THETA_RANGE[0]), self.THETA_RANGE[1])[:, None]
        if ap is not None:
            # the last point: predict from the train's own state (table (d), fine ratio grid)
            on = True if powering is None else powering
            t_d, ref_d = ap.rows(np.broadcast_to(np.asarray(speed_ms, float), ratio.shape), on)
            ra = solve_piecewise(ap.ratios, t_d + theta * (ref_d - t_d), rem, ratio)
        else:
            # predicted remaining time per grid ratio after X; piecewise linear in 1/r between them
            ra = solve_piecewise(tables.ratios, row + theta * dk, rem - early, ratio)
        st["rem"] = np.array(rem, float)
        st["pred"] = interp_u(tables.ratios, row, ra)
        st["delta"] = self._delta(tables, k, ra)
        return ra


CHOOSERS: dict[str, Callable[[], RatioChooser]] = {
    "nearest": NearestRule, "interpolate": InterpolateRule, "adaptive": AdaptiveRule,
}
"""Table-based on-board modes by name: a factory giving a fresh chooser per batch of runs."""


def register_mode(name: str, factory: Callable[[], RatioChooser]) -> None:
    """Add a table-based on-board mode (selectable by ``--mode name``)."""
    CHOOSERS[name] = factory


def chooser(mode: str) -> RatioChooser:
    """A fresh chooser for ``mode``; InputError naming the known modes otherwise."""
    try:
        return CHOOSERS[mode]()
    except KeyError:
        raise InputError(f"--mode {mode!r} is not a table mode; known: {', '.join(CHOOSERS)}") from None


def out_of_band(state) -> np.ndarray:
    """Per run: True when the vehicle is *not* in a sawtooth coasting band, i.e. it powers
    whenever it is below its target — table (d)'s ``powering`` slice.

    That is the vehicle's cruise-control state (:attr:`planner.physics.run_curve.RunState.coasting`),
    not the phase of the last step: a sawtooth train that arrives *braking* may be in its band
    (riding a falling ceiling it met from a coast) or out of it (braked onto a restriction
    below its band: given a higher target it powers up to it). Table (d) starts its runs
    from the two band states, so the look-up must use the same one. Without the state
    (a start state, an older caller), the phase decides: powering = out of the band.
    """
    coasting = getattr(state, "coasting", None)
    if coasting is None:
        return np.asarray(state.phase) == PHASE_POWER
    return ~np.asarray(coasting, bool)


def make_controller(
    tables: RunningTimeTables, mode: str | RatioChooser, arrival_s: np.ndarray
) -> tuple[Callable, list[float], list[list[float]]]:
    """A simulator controller that runs the on-board choice at each evaluation point after departure.

    The vehicle evaluates at a point when its odometer passes it (beacon points and odometer
    points alike); the simulator's odometer is exact, so that is the point's running distance.

    Parameters
    ----------
    tables : RunningTimeTables
    mode : str or RatioChooser
        A key of :data:`CHOOSERS`, or the chooser that also made the departure choice
        (stateful modes need the same instance).
    arrival_s : ndarray, shape (n,)
        Scheduled arrival per run, in the run's clock (departure at t = 0) [s].

    Returns
    -------
    controller : callable ``(s_m, state) -> ratio``
        For ``planner.physics.run_curve.simulate(controller=..., decision_m=...)``.
    decision_m : list of float
        Running distances of the evaluation points after departure [m].
    chosen : list of list of float
        Filled while running: the ratios returned at each decision, per point.
    """
    ch = chooser(mode) if isinstance(mode, str) else mode
    ks = [k for k, s in enumerate(tables.eval_distance_m) if s > 0]
    pts = np.asarray(tables.eval_distance_m, float)
    chosen: list[np.ndarray] = []
    arrival = np.asarray(arrival_s, float)

    def controller(s_m, state):
        k = int(np.argmin(np.abs(pts - float(s_m))))
        if k not in ks or abs(pts[k] - float(s_m)) > SAME_POINT_M:
            return state.ratio  # a decision we did not ask for: keep the ratio
        new = ch.at_point(tables, k, state.ratio, arrival - state.t_s, state.v_ms, out_of_band(state))
        chosen.append(np.asarray(new, float))
        return new

    return controller, [float(pts[k]) for k in ks], chosen


# --- reading the tables back (the vehicle's side) -------------------------------


