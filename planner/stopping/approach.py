"""A station approach as the stopping control meets it: where it starts, and its limits (docs/design.md §5).

One definition, used by the stopping-pattern sweep (:mod:`planner.stopping.sweep`), the
margin report (:mod:`planner.report.margins`) and so by the on-board bundles (which
carry the sweep's ``stop_summary``):

* **where the approach starts** (:func:`approach_start`): the last ``tasc``
  beacon read in the running direction strictly inside the run, where the
  on-board unit learns its exact distance to go; without one, ``approach_m``
  before the stop marker when the job or the line sets it (:func:`fixed_approach_m`),
  else from the physics (:func:`physics_start_m`): where the minimum-time run, at
  the speed it has there, must start braking at the pattern's deceleration
  (jerk-limited, at the train's lowest adhesion level, gradient included),
  plus :data:`APPROACH_MARGIN` of that braking distance. A fixed start at or
  before the departure marker is returned as such (``s_m <= 0``) and the
  callers say that no pattern fits;
* **speed limits** (:func:`speed_limits`): the on-board maximum of the
  run-curve track (every restriction held until the tail clears, minus the
  vehicle's speed margin), a step function of the distance from the start;
* **deceleration limits** (:func:`decel_limits`): ``min(braking comfort,
  adhesion, the train's stopping brake)`` plus what gravity adds, and never
  more than the stopping brake in all (the run curves' stop: a pattern is never
  faster), from the gradient averaged over the whole train exactly as the run
  curves take it (:func:`planner.physics.dynamics.running_gradient`,
  :func:`planner.physics.dynamics.track_accel_ms2`: ``g ḡ / (1 + ρ)``).
  Averaged over the length, ḡ is piecewise linear in the front's position
  (kinks where the front or the tail passes a gradient change). The solver
  takes step functions, so each linear piece is bounded from the safe side by
  its least favourable value (the smaller end value): the pattern never asks
  the brake for more than ``min(comfort, adhesion, stopping brake)``. Curve and
  running resistance, which only help the brake, are left out (safe side too;
  running resistance also depends on speed and load).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.errors import InputError
from planner.physics import dynamics
from planner.line.model import Line, sign

__all__ = [
    "DEFAULT_APPROACH_M",
    "APPROACH_MARGIN",
    "AUTO",
    "ApproachStart",
    "approach_start",
    "brake_cap_ms2",
    "brake_demand_ms2",
    "decel_limits",
    "fixed_approach_m",
    "gradient_steps",
    "physics_start_m",
    "speed_limits",
    "train_adhesion_ms2",
]

AUTO = "auto"
"""``approach_m`` value: the approach start comes from the physics (:func:`physics_start_m`)."""
DEFAULT_APPROACH_M = AUTO
"""Approach where a run has no TASC beacon and neither the job nor the line sets ``approach_m``."""
APPROACH_MARGIN = 0.10
"""Physics start: this share of the braking distance is added before it (as the sample line places its TASC
beacons: brake build-up, then 10 %), for the odometer's error and a faster run than the minimum-time one."""
SLICE_M = 25.0
"""Longest step of the safe-side gradient bound where the train-averaged gradient changes [m]."""


@dataclass(frozen=True)
class ApproachStart:
    """Where the stopping pattern of an arrival starts.

    Attributes
    ----------
    s_m : float
        Running distance from the departure stop marker [m] (``<= 0`` when the
        fixed approach is not shorter than the run).
    source : str
        ``"tasc"`` (at a TASC beacon), ``"approach"`` (``approach_m`` set by the job or
        line) or ``"physics"`` (:func:`physics_start_m`).
    beacon_id : str
        The TASC beacon, or ``""``.
    """

    s_m: float
    source: str
    beacon_id: str


def fixed_approach_m(line: Line, approach_m: float | str | None = AUTO) -> float | None:
    """The fixed approach length [m] in force: the job's number, else the line's ``approach_m``, else None (physics).

    Raises
    ------
    InputError
        ``approach_m`` is neither ``"auto"`` nor a positive number of metres.
    """
    if approach_m is None or approach_m == AUTO:
        return line.approach_m
    if isinstance(approach_m, bool) or not isinstance(approach_m, (int, float)) or not (
            math.isfinite(approach_m) and approach_m > 0.0):
        raise InputError(f"approach_m must be \"auto\" or a positive number of metres, got {approach_m!r}")
    return float(approach_m)


def approach_start(line: Line, origin: str, destination: str, approach_m: float | str | None = AUTO, *,
                   train_type: str | None = None, adhesion_ms2: float | None = None,
                   settings=None) -> ApproachStart:
    """Start of the stopping approach of the run ``origin`` → ``destination`` (module doc).

    The one definition of the start, for the stopping sweep, the margin report and so the bundles.
    ``train_type``, ``adhesion_ms2`` (the lowest level of the train's sweep; default its braking
    cap) and ``settings`` (the run curves' grid) are what the physics start needs.

    Examples
    --------
    >>> from planner.line import testing
    >>> approach_start(testing.line(length_m=3000.0, stations=[0.0, 900.0, 2900.0]), "S0", "S1", 550.0)
    ApproachStart(s_m=350.0, source='approach', beacon_id='')
    """
    ext = line.run_between(origin, destination)
    best = None
    for b in line.beacons_on(ext):  # running order: the last one inside wins
        if b.kind == "tasc" and 0.0 < ext.sign * (b.position_m - ext.start_m) < ext.length_m:
            best = b
    if best is not None:
        return ApproachStart(float(ext.sign * (best.position_m - ext.start_m)), "tasc", best.beacon_id)
    fixed = fixed_approach_m(line, approach_m)
    if fixed is not None:
        return ApproachStart(float(ext.length_m - fixed), "approach", "")
    if train_type is None:
        raise InputError("the approach start from the physics needs the train type; give train_type or approach_m")
    return ApproachStart(physics_start_m(line, train_type, origin, destination, adhesion_ms2, settings),
                         "physics", "")


def physics_start_m(line: Line, train_type: str, origin: str, destination: str, adhesion_ms2: float | None = None,
                    settings=None) -> float:
    """Running distance [m] where the approach starts without a TASC beacon or a set ``approach_m``.

    The minimum-time run (ratio 1.0, load 0, traction 1.0: the speed the train can have at each
    point; :func:`planner.physics.run_curve.simulate`) meets, going back from the stop marker, the
    first point ``s*`` from which a jerk-limited stop at the pattern's deceleration fits:
    ``L − s* >= v²/(2b) + v b/(2J)``, ``v`` the run's speed at ``s*``, ``b`` the least deceleration
    limit of the stretch from ``s*`` to the marker at ``adhesion_ms2`` (:func:`decel_limits`, gradient
    included). The start is :data:`APPROACH_MARGIN` of ``L − s*`` before ``s*``, and never before
    half-way from the departure to ``s*`` (a short run that brakes as soon as it has started),
    nor inside a braking of the run for a lower speed limit before ``s*``: there the run brakes
    on its braking curve, which a jerk-limited pattern starting in it cannot follow (a 160 km/h
    limit 2 km before the stop put the start 200 m into the run's braking from 288 km/h: "needs
    2221.1 m to stop from 167.8 km/h, only 2197.8 m available", for a brake that makes the stop).
    The start is then where that braking ends, the run at the lower limit.
    """
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings, make_track

    train = line.train_type(train_type)
    ext = line.run_between(origin, destination)
    length = float(ext.length_m)
    if not length > 0.0:
        return 0.0
    a = brake_cap_ms2(train) if adhesion_ms2 is None else min(float(adhesion_ms2), brake_cap_ms2(train))
    track = make_track(line, train_type, origin, destination, settings=settings or SimSettings())
    s = np.asarray(track.s_m, float)
    run = simulate(track, train, 1.0, load=0.0, traction_factor=1.0, record=True)
    v = np.asarray(run.v_ms[0], float)
    grads = gradient_steps(line, train.length_m, ext.direction, ext.start_m, length)
    try:
        dl = decel_limits(line, train, ext.direction, ext.start_m, length, a, grads)
    except InputError:  # a fall leaves no deceleration somewhere: no pattern fits; the sweep says why
        return 0.5 * float(s[1]) if s.size > 1 else 0.0
    xs = np.array([x for x, _ in dl])
    b = np.array([d for _, d in dl])[np.searchsorted(xs, s, side="right") - 1]
    b = np.minimum.accumulate(b[::-1])[::-1]  # the least limit from each node to the marker
    need = v * v / (2.0 * b) + v * b / (2.0 * train.jerk_limit_ms3)
    fits = np.flatnonzero((length - s[:-1]) >= need[:-1])  # the marker itself (v = 0) does not count
    s_star = float(s[fits[-1]]) if fits.size else 0.0
    start = max(s_star - APPROACH_MARGIN * (length - s_star), 0.5 * s_star)
    return _out_of_braking(s, np.asarray(run.phase[0]), start, s_star)


def _out_of_braking(s: np.ndarray, phase: np.ndarray, start: float, s_star: float) -> float:
    """``start``, or where the run's braking it lies in ends, when that is no later than ``s_star``; ``phase``
    the run's phase code at each node of ``s`` (the step arriving there)."""
    from planner.physics.kernel_abi import PHASE_BRAKE

    k = int(np.searchsorted(s, start))  # the node at or after the start
    if k + 1 >= s.size or not (phase[k] == PHASE_BRAKE or phase[k + 1] == PHASE_BRAKE):
        return start
    j = k + 1
    while j < s.size and phase[j] == PHASE_BRAKE:
        j += 1
    end = float(s[j - 1])  # the last node the braking arrives at: the run is at the lower limit from there
    return end if end <= s_star else start


def speed_limits(track, s_start_m: float) -> list[tuple[float, float]]:
    """On-board maximum [m/s] from the track node at ``s_start_m`` on, as steps ``(x_from_m, speed_ms)``.

    ``track`` is a :func:`planner.physics.track.make_track` track with a node at
    ``s_start_m``; ``vmax_interval_ms`` is constant on each grid interval.
    """
    k0 = track.node_index(s_start_m)
    s = np.asarray(track.s_m[k0:], float) - float(track.s_m[k0])
    v = np.asarray(track.vmax_interval_ms[k0:], float)
    change = np.flatnonzero(v[1:] != v[:-1]) + 1
    idx = np.concatenate([[0], change])
    return [(float(s[i]), float(v[i])) for i in idx]


def _mean_gradient_knots(line: Line, train_length_m: float, direction: str, start_chainage_m: float,
                         length_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Front positions from the start where ḡ kinks (with 0 and ``length_m``) and ḡ there [rise/m]."""
    sg = sign(direction)
    g = line.gradients
    edges = np.concatenate([np.asarray(g.start_m, float), np.asarray(g.end_m, float)])
    # the front at x has chainage c0 + sg x and the tail c0 + sg (x - L): kinks where either is on an edge
    xf = sg * (edges - start_chainage_m)
    xs = np.concatenate([[0.0, length_m], xf, xf + train_length_m])
    xs = np.unique(xs[(xs >= 0.0) & (xs <= length_m)])
    gbar = dynamics.running_gradient(g, start_chainage_m + sg * xs, train_length_m, sg)
    return xs, np.asarray(gbar, float)


def gradient_steps(line: Line, train_length_m: float, direction: str, start_chainage_m: float,
                   length_m: float, slice_m: float = SLICE_M) -> list[tuple[float, float]]:
    """Safe-side step bound of the train-averaged gradient over an approach, in ‰ (running direction).

    Each linear piece of ḡ (between kinks) takes its smaller end value, the
    least favourable for braking. Equal neighbours are merged.

    Parameters
    ----------
    line : Line
    train_length_m : float
        Train length [m].
    direction : str
    start_chainage_m : float
        Chainage of the front at the approach start [m].
    length_m : float
        Approach length (to the stop marker) [m].

    Returns
    -------
    list of (x_from_m, gradient_permil)
        From the approach start, the first at 0.
    """
    xs, gbar = _mean_gradient_knots(line, train_length_m, direction, start_chainage_m, length_m)
    if xs.size >= 2 and slice_m < math.inf:
        # cut the sloping pieces into slices of at most slice_m (ḡ is linear there: interpolate exactly)
        cuts = [xs[:1]]
        for x0, x1, g0, g1 in zip(xs[:-1], xs[1:], gbar[:-1], gbar[1:]):
            n = int(math.ceil((x1 - x0) / slice_m)) if g0 != g1 else 1
            cuts.append(x0 + (x1 - x0) * np.arange(1, n + 1) / n)
        fine = np.concatenate(cuts)
        gbar = np.interp(fine, xs, gbar)
        xs = fine
    out: list[tuple[float, float]] = []
    if xs.size < 2:
        return [(0.0, round(float(gbar[0]) * 1000.0, 9) + 0.0)] if xs.size else [(0.0, 0.0)]
    lo = np.minimum(gbar[:-1], gbar[1:]) * 1000.0
    for x, permil in zip(xs[:-1], lo):
        permil = round(float(permil), 9) + 0.0  # round: ‰ -> rise/m -> ‰ loses the last bit; +0.0: no -0.0
        if out and out[-1][1] == permil:
            continue
        out.append((float(x), permil))
    return out


def decel_limits(line: Line, train, direction: str, start_chainage_m: float, length_m: float,
                 adhesion_ms2: float, gradients_permil=None) -> list[tuple[float, float]]:
    """Deceleration limit along an approach [m/s²], a step function from its start (module doc).

    ``min(min(comfort, adhesion, brake) + g ḡ / (1 + ρ), brake)`` (the train's braking comfort
    and stopping brake) with ḡ bounded per piece from the safe side (:func:`gradient_steps`,
    passed in as ``gradients_permil`` when already computed). Raises
    :class:`planner.errors.InputError` when a fall leaves no deceleration (as
    :func:`planner.stopping.pattern.decel_limit_profile`).
    """
    from planner.stopping.pattern import decel_limit_profile

    if gradients_permil is None:
        gradients_permil = gradient_steps(line, train.length_m, direction, start_chainage_m, length_m)
    return decel_limit_profile(train.brake_comfort_ms2, adhesion_ms2, gradients_permil,
                               rotating_mass_factor=train.rotating_mass_factor, brake_ms2=train.stop_brake_ms2)


def brake_cap_ms2(train) -> float:
    """The most a stop of ``train`` asks of its brake on the level [m/s²]: min(braking comfort, stopping brake)."""
    return min(float(train.brake_comfort_ms2), float(train.stop_brake_ms2))


def train_adhesion_ms2(train, levels_ms2) -> tuple[float, ...]:
    """The adhesion levels [m/s²] that are levels for ``train``, ascending.

    The job's levels are the rail's condition, in absolute terms. A level above what the train
    asks of its brake anyway (:func:`brake_cap_ms2`) would give the same pattern as the cap: it is
    not a level of its own for this train, so every such level becomes the cap, once. A freight
    braking at 0.81 km/h/s has the one level 0.81 km/h/s under a 2.5 … 3.5 km/h/s sweep: rail
    adhesion that low does not limit it, and its bad day stops no faster than its nominal day.

    Examples
    --------
    >>> from planner.line import testing
    >>> tt = testing.train_type(stop_brake_kmh_s=3.0, brake_comfort_kmh_s=3.5)
    >>> [round(a * 3.6, 9) for a in train_adhesion_ms2(tt, [x / 3.6 for x in (2.5, 2.8, 3.1, 3.4)])]
    [2.5, 2.8, 3.0]
    """
    cap = brake_cap_ms2(train)
    return tuple(sorted({min(float(a), cap) for a in levels_ms2}))


def brake_demand_ms2(line: Line, train, direction: str, start_chainage_m: float, x_m, a_ms2):
    """What the brake must give at the front positions ``x_m`` for the accelerations ``a_ms2`` [m/s²].

    The run-curve force model without the resistances that only help:
    ``-a + a_track(ḡ)``, with ḡ averaged over the train at each sample
    (:func:`planner.physics.dynamics.running_gradient`, :func:`planner.physics.dynamics.track_accel_ms2`).
    """
    sg = sign(direction)
    front = start_chainage_m + sg * np.asarray(x_m, float)
    gbar = dynamics.running_gradient(line.gradients, front, train.length_m, sg)
    return -np.asarray(a_ms2, float) + dynamics.track_accel_ms2(gbar, 0.0, train.rotating_mass_factor)

