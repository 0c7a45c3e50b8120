"""Stopping patterns for every station approach of a line, over a sweep of adhesion levels (docs/design.md §5).

The nightly job solves, for every arrival of every interstation, direction and
train type, the minimum-time jerk-limited stopping pattern of
:func:`planner.stopping.pattern.solve_stop` for a sweep of adhesion-limited
decelerations, so the vehicle can pick the pattern for today's rail condition
and the margin report can size the margin from the growth in stopping time.

One *approach* is set up from the line as the vehicle meets it, by
:mod:`planner.stopping.approach` (the one definition the margin report uses too):

* **start**: the TASC beacon before the stop marker (the last ``tasc`` beacon
  read in that direction inside the interstation), where the on-board unit
  learns its exact distance to go; without one, ``approach_m`` before the
  marker when the job or the line sets it, else where the minimum-time run
  must start braking at the pattern's deceleration (the train's lowest
  adhesion level), plus 10 % (:func:`planner.stopping.approach.approach_start`);
* **start speed**: the speed of the minimum-time run there (ratio 1.0, load 0,
  nominal traction, :func:`planner.physics.run_curve.simulate`; the point is an exact
  grid node, read from a snapshot). The pattern takes it with acceleration 0;
* **speed limits**: the on-board maximum ``Track.vmax_interval_ms`` (every
  restriction held until the tail clears, minus the vehicle's speed margin),
  which is piecewise constant on the run-curve grid, as a step function of the
  distance from the approach start;
* **deceleration limits**: ``min(comfort, adhesion, brake) + g s / 1000 / (1 + ρ)``, at most ``brake``
  for the gradient ``s`` [‰] averaged over the whole train in the running
  direction (sign flipped for ``up``), exactly as the run curves take it, each
  linear piece bounded by its least favourable value
  (:func:`planner.stopping.approach.decel_limits`), one profile per adhesion level;
* **jerk**: the vehicle's ``jerk_limit_ms3``.

**Adhesion levels** are the rail's condition, absolute, in km/h/s (job ``[stops]
adhesion_kmh_s``); each train type gets those at or below what it asks of its brake anyway
(min(braking comfort, stopping brake)) and that cap in place of every level above it
(:func:`planner.stopping.approach.train_adhesion_ms2`), so a level is never faster than the
train can brake and the bad day never faster than nominal.

An approach with no admissible pattern at some adhesion level is kept as a row
with ``feasible = False`` and the solver's reason, and produces a warning
(:class:`InfeasibleStopWarning`) naming station, direction, train type and
adhesion: the stopping control must start earlier there, or the limits must
be relaxed.

Outputs are two hive-partitioned Parquet datasets (``stop_summary`` and
``stop_samples``, schemas :data:`STOP_SUMMARY_SCHEMA`,
:data:`STOP_SAMPLES_SCHEMA`) written by :func:`write_stops`.
"""
from __future__ import annotations

import math
import warnings
import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from planner.stopping import approach as _approach
from planner.stopping.approach import DEFAULT_APPROACH_M
from planner.errors import InputError, UnknownNameError
from planner.line.model import DIRECTIONS, Line, sign
from planner.stopping.pattern import StopPattern, solve_stop
from planner.io.parallel import map_tasks
from planner.line.units import KMH_S

__all__ = [
    "ApproachResult",
    "DEFAULT_ADHESION_KMH_S",
    "DEFAULT_APPROACH_M",
    "DEFAULT_SAMPLE_DT_S",
    "InfeasibleStopWarning",
    "adhesion_levels",
    "approach_patterns",
    "approach_tasks",
    "stop_sweep",
]

DEFAULT_SAMPLE_DT_S = 0.1
"""Time step of the sampled patterns in ``stop_samples`` [s]."""
V_START_ROUNDOFF_MS = 1e-6
"""The run's speed may exceed the on-board maximum by round-off only; below this it is clipped [m/s]."""
_MAX_LEVELS = 1000


class InfeasibleStopWarning(UserWarning):
    """A station approach has no admissible stopping pattern at one adhesion level."""


# --------------------------------------------------------------------------------------
# The adhesion sweep
# --------------------------------------------------------------------------------------


def adhesion_levels(spec: str | Sequence[float]) -> tuple[float, ...]:
    """Adhesion levels [km/h/s] from ``'START:STOP:STEP'`` (inclusive), ``'a,b,c'`` or numbers.

    Parameters
    ----------
    spec : str or sequence of float
        ``"2.5:3.5:0.1"`` gives 2.5, 2.6, …, 3.5 (the stop is included when the
        steps land on it within 1e-9 of a step); ``"2.5,3.0"`` a list; or the
        levels themselves.

    Returns
    -------
    tuple of float
        Sorted, distinct, positive levels [km/h/s], rounded to 9 decimals (so
        2.6 is 2.6, not 2.6000000000000005).

    Raises
    ------
    InputError
        Naming the ``--adhesion`` flag and the accepted forms.

    Examples
    --------
    >>> adhesion_levels("2.5:3.0:0.1")
    (2.5, 2.6, 2.7, 2.8, 2.9, 3.0)
    """
    how = "give --adhesion as START:STOP:STEP in km/h/s (e.g. 2.5:3.5:0.1) or a list like 2.5,3.0,3.5"
    if isinstance(spec, str):
        text = spec.strip()
        try:
            if ":" in text:
                parts = [float(p) for p in text.split(":")]
                if len(parts) != 3:
                    raise ValueError
                start, stop, step = parts
                if not (step > 0.0 and math.isfinite(start) and math.isfinite(stop) and stop >= start):
                    raise InputError(f"--adhesion {spec!r}: need STOP >= START and STEP > 0; {how}")
                n = int(math.floor((stop - start) / step + 1e-9)) + 1
                if n > _MAX_LEVELS:
                    raise InputError(f"--adhesion {spec!r} gives {n} levels (at most {_MAX_LEVELS}); "
                                     "use a larger STEP")
                values = [start + k * step for k in range(n)]
            else:
                values = [float(p) for p in text.split(",") if p.strip()]
        except ValueError:
            raise InputError(f"--adhesion {spec!r} is not understood; {how}") from None
    else:
        try:
            values = [float(v) for v in spec]
        except (TypeError, ValueError):
            raise InputError(f"adhesion levels {spec!r} are not numbers; {how}") from None
    if not values:
        raise InputError(f"--adhesion {spec!r} gives no levels; {how}")
    for v in values:
        if not (math.isfinite(v) and v > 0.0):
            raise InputError(f"--adhesion level {v!r} km/h/s must be a positive number; {how}")
    return tuple(sorted({round(v, 9) for v in values}))


DEFAULT_ADHESION_KMH_S = adhesion_levels("2.5:3.5:0.1")
"""Default sweep: 2.5 … 3.5 km/h/s in 0.1 km/h/s steps (issue 5)."""


# --------------------------------------------------------------------------------------
# One approach
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ApproachResult:
    """Stopping patterns of one station approach (interstation, direction, train type) per adhesion level.

    Positions ``x`` in the step functions are metres from the approach start in
    the running direction (the frame of :func:`planner.stopping.pattern.solve_stop`);
    ``*_m`` positions called chainage are line chainages.

    Attributes
    ----------
    line_id, train_type, direction, origin, station_id : str
        The approach: arrival at ``station_id`` from ``origin``.
    stop_m : float
        Chainage of the stop marker [m].
    approach_start_m : float
        Chainage of the approach start [m].
    approach_length_m : float
        Distance from the approach start to the stop marker [m] (``x_stop``).
    tasc_beacon_id : str
        The TASC beacon the approach starts at, or ``""`` (``approach_m``, or the physics start).
    v_start_ms : float
        Speed of the minimum-time run at the approach start [m/s] (NaN if none).
    run_phase : str
        Phase of that run there (``power``, ``hold``, ``coast``, ``brake``, ``stop``):
        ``brake`` (for a restriction) or ``stop`` (on the stopping-brake curve) means the
        run was already braking there; the pattern still starts with a = 0.
    jerk_max_ms3, comfort_ms2 : float
        Vehicle jerk limit [m/s³] and ride-comfort limit on braking [m/s²] (``brake_comfort_kmh_s``).
    speed_limits : tuple of (x_from_m, speed_ms)
        On-board maximum over the approach.
    gradients_permil : tuple of (x_from_m, gradient_permil)
        Gradient averaged over the train, positive rising in the running
        direction, each linear piece at its least favourable value
        (:func:`planner.stopping.approach.gradient_steps`).
    adhesion_ms2 : tuple of float
        The train's adhesion levels (adhesion-limited braking decelerations) [m/s²], ascending: the
        job's levels, those above the train's braking cap replaced by the cap once.
    decel_limits : tuple
        Per level, the deceleration limit step function ``((x_from_m, decel_ms2), ...)``,
        or ``()`` when the gradient leaves no deceleration.
    patterns : tuple of StopPattern
        Per level, the pattern (``feasible`` False with the reason when there is none).
    warnings : tuple of str
        One message per infeasible level, naming station, direction, train type, adhesion.
    """

    line_id: str
    train_type: str
    direction: str
    origin: str
    station_id: str
    stop_m: float
    approach_start_m: float
    approach_length_m: float
    tasc_beacon_id: str
    v_start_ms: float
    run_phase: str
    jerk_max_ms3: float
    comfort_ms2: float
    speed_limits: tuple[tuple[float, float], ...]
    gradients_permil: tuple[tuple[float, float], ...]
    adhesion_ms2: tuple[float, ...]
    decel_limits: tuple[tuple[tuple[float, float], ...], ...]
    patterns: tuple[StopPattern, ...]
    warnings: tuple[str, ...]

    @property
    def n_feasible(self) -> int:
        """Number of adhesion levels with a pattern."""
        return sum(p.feasible for p in self.patterns)

    @property
    def best_duration_s(self) -> float:
        """Shortest feasible pattern duration over the sweep [s] (NaN if none)."""
        d = [p.duration_s for p in self.patterns if p.feasible]
        return min(d) if d else math.nan

    @property
    def time_lost_s(self) -> tuple[float, ...]:
        """Per level, duration minus the best duration of the sweep [s] (NaN when infeasible)."""
        best = self.best_duration_s
        return tuple(p.duration_s - best if p.feasible else math.nan for p in self.patterns)

    def chainage_m(self, x_m):
        """Chainage [m] of a distance ``x_m`` from the approach start."""
        return self.approach_start_m + sign(self.direction) * np.asarray(x_m, dtype=float)


def no_stop_leg(r: "ApproachResult"):
    """The leg of an approach with no stopping pattern at some adhesion level of its sweep, flagged
    :data:`~planner.tables.flags.NO_STOP` (a :class:`~planner.tables.flags.FlaggedLeg`), or None when every level
    stops the train: a train that cannot stop at the station at some level is a verdict on its leg, counted and
    noted with the stalls, not only a count of infeasible patterns."""
    from planner.line.units import KMH_S
    from planner.tables.flags import NO_STOP, FlaggedLeg, LegFlag

    bad = [a / KMH_S for a, p in zip(r.adhesion_ms2, r.patterns) if not p.feasible]
    if not bad:
        return None
    first = next(p for p in r.patterns if not p.feasible)
    levels = f"{bad[0]:g}" if len(bad) == 1 else f"{bad[0]:g}…{bad[-1]:g}"
    why = (f"no stopping pattern at {r.station_id} for adhesion {levels} km/h/s ({len(bad)} of {len(r.patterns)} "
           f"levels): {first.reason}")
    return FlaggedLeg(r.train_type, r.direction, r.origin, r.station_id,
                      (LegFlag(NO_STOP, "stops", float(r.stop_m), why),))


def _warning(train_type: str, direction: str, origin: str, station_id: str, adhesion_kmh_s: float,
             reason: str) -> str:
    return (f"no stopping pattern at {station_id} ({direction}, train type {train_type}, from {origin}) "
            f"at adhesion {adhesion_kmh_s:g} km/h/s: {reason}")


def approach_patterns(
    line: Line,
    train_type: str,
    origin: str,
    destination: str,
    adhesions_ms2: Sequence[float],
    approach_m: float | str = DEFAULT_APPROACH_M,
    *,
    settings=None,
) -> ApproachResult:
    """Stopping patterns of the arrival at ``destination`` from ``origin``, one per adhesion level.

    Pure: no I/O, no warnings issued (they are returned); the unit of work of
    the nightly job.

    Parameters
    ----------
    line : Line
    train_type, origin, destination : str
        Consecutive stations; the direction follows from them.
    adhesions_ms2 : sequence of float
        Adhesion-limited braking decelerations [m/s²], > 0, the rail's condition: the result has the
        train's levels (:func:`planner.stopping.approach.train_adhesion_ms2`: every level above the
        train's braking cap becomes the cap, once), ascending.
    approach_m : float or "auto"
        Approach length where the interstation has no TASC beacon [m], > 0; ``"auto"``: the line's
        ``approach_m``, else from the physics (:func:`planner.stopping.approach.physics_start_m`).
    settings : planner.physics.track.SimSettings, optional
        Grid of the minimum-time run (default 1 m).

    Returns
    -------
    ApproachResult

    Raises
    ------
    UnknownNameError
        Unknown train type or station.
    InputError
        Bad ``approach_m`` or adhesion levels.

    Notes
    -----
    ``A(x) = min(min(comfort, adhesion, brake) + g s(x) / 1000 / (1 + ρ), brake)`` with
    ``s`` the gradient averaged over the train, bounded per piece from the safe
    side (:mod:`planner.stopping.approach`); ``v_lim(x)`` the on-board maximum (restriction
    held to the tail, minus the speed margin); the start speed is the
    minimum-time run's (ratio 1.0, load 0, traction 1.0) at the approach start.
    """
    _approach.fixed_approach_m(line, approach_m)  # a bad value is an InputError before any work
    levels_ms2 = sorted(float(a) for a in adhesions_ms2)
    if not levels_ms2 or not all(math.isfinite(a) and a > 0.0 for a in levels_ms2):
        raise InputError(f"adhesion levels must be positive decelerations [m/s²], got {list(adhesions_ms2)!r}")
    train = line.train_type(train_type)
    levels_ms2 = list(_approach.train_adhesion_ms2(train, levels_ms2))  # none above what the train asks anyway
    start = _approach.approach_start(line, origin, destination, approach_m, train_type=train_type,
                                     adhesion_ms2=levels_ms2[0], settings=settings)
    result = _patterns_from(line, train_type, origin, destination, levels_ms2, start, settings)
    if start.source == "tasc" and result.n_feasible < len(result.patterns):
        # a beacon placed for other trains may lie too close for this one: where no stop fits from it, the
        # approach starts where the physics says, as without a beacon (the margin report moves it alike)
        s_phys = _approach.physics_start_m(line, train_type, origin, destination, levels_ms2[0], settings)
        need = max((p.braking_distance_m for p in result.patterns if not p.feasible
                    and math.isfinite(p.braking_distance_m)), default=0.0)  # what the solver found it needs
        length = start.s_m + result.approach_length_m
        s_phys = min(s_phys, length - (1.0 + _approach.APPROACH_MARGIN) * need)
        if 0.0 < s_phys < start.s_m:
            moved = _patterns_from(line, train_type, origin, destination, levels_ms2,
                                   _approach.ApproachStart(s_phys, "physics", ""), settings)
            if moved.n_feasible > result.n_feasible:
                note = (f"{train_type} {moved.direction} {origin}->{destination}: TASC "
                        f"beacon {start.beacon_id} lies {result.approach_length_m:.0f} m before the marker, too close "
                        f"for this train: its approach starts {moved.approach_length_m:.0f} m before (where it must start "
                        "braking, plus the margin)")
                return dataclasses.replace(moved, warnings=moved.warnings + (note,))
    return result


def _patterns_from(line: Line, train_type: str, origin: str, destination: str, levels_ms2: list[float],
                   start, settings) -> ApproachResult:
    """The patterns of :func:`approach_patterns` from the approach start ``start`` (an ApproachStart)."""
    from planner.physics.run_curve import PHASE_NAMES, simulate
    from planner.physics.track import SimSettings, make_track

    train = line.train_type(train_type)
    levels_kmh_s = tuple(round(a / KMH_S, 9) for a in levels_ms2)
    ext = line.run_between(origin, destination)
    direction, sg, x0, stop, length = ext.direction, ext.sign, ext.start_m, ext.end_m, ext.length_m
    s_a = start.s_m
    X = length - s_a
    J = train.jerk_limit_ms3
    comfort = train.brake_comfort_ms2
    common = dict(line_id=line.line_id, train_type=train_type, direction=direction, origin=origin,
                  station_id=destination, stop_m=float(stop), approach_start_m=float(x0 + sg * s_a),
                  approach_length_m=float(X), tasc_beacon_id=start.beacon_id,
                  jerk_max_ms3=J, comfort_ms2=comfort, adhesion_ms2=tuple(float(a) for a in levels_ms2))

    def all_infeasible(reason: str, v0: float, phase: str, sl=(), grads=()) -> ApproachResult:
        pats = tuple(StopPattern(False, reason, v_start_ms=v0, x_stop_m=max(X, 0.0), jerk_max_ms3=J)
                     for _ in levels_ms2)
        msgs = tuple(_warning(train_type, direction, origin, destination, a, reason) for a in levels_kmh_s)
        return ApproachResult(**common, v_start_ms=v0, run_phase=phase, speed_limits=tuple(sl),
                              gradients_permil=tuple(grads), decel_limits=tuple(() for _ in levels_ms2),
                              patterns=pats, warnings=msgs)

    if not s_a > 0.0:
        return all_infeasible(
            f"the approach of {X:.0f} m is not shorter than the interstation ({length:.1f} m); "
            "lower approach_m or add a TASC beacon", math.nan, "")

    track = make_track(line, train_type, origin, destination, settings=settings or SimSettings(),
                       nodes_m=[s_a])
    res = simulate(track, train, 1.0, load=0.0, traction_factor=1.0, snapshots_m=[s_a])
    snap = res.snapshots[s_a]
    v0 = float(snap.v_ms[0])
    phase = PHASE_NAMES[int(snap.phase[0])]
    sl = _approach.speed_limits(track, s_a)
    if sl[0][1] < v0 <= sl[0][1] + V_START_ROUNDOFF_MS:
        v0 = sl[0][1]  # the run holds the maximum; its last bit of round-off is not a violation
    grads = _approach.gradient_steps(line, train.length_m, direction, common["approach_start_m"], X)

    decels: list[tuple[tuple[float, float], ...]] = []
    pats: list[StopPattern] = []
    msgs: list[str] = []
    for a_ms2, a_kmh_s in zip(levels_ms2, levels_kmh_s):
        try:
            dl = _approach.decel_limits(line, train, direction, common["approach_start_m"], X, a_ms2, grads)
        except InputError as e:  # a fall so steep that nothing is left: no pattern at this level
            decels.append(())
            p = StopPattern(False, str(e), v_start_ms=v0, x_stop_m=X, jerk_max_ms3=J)
        else:
            decels.append(tuple(dl))
            p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
        pats.append(p)
        if not p.feasible:
            msgs.append(_warning(train_type, direction, origin, destination, a_kmh_s, p.reason))
    return ApproachResult(**common, v_start_ms=v0, run_phase=phase, speed_limits=tuple(sl),
                          gradients_permil=tuple(grads), decel_limits=tuple(decels), patterns=tuple(pats),
                          warnings=tuple(msgs))


# --------------------------------------------------------------------------------------
# The whole line
# --------------------------------------------------------------------------------------


def approach_tasks(line: Line, train_types: Sequence[str] | None = None,
                   directions: Sequence[str] | None = None) -> list[tuple[str, str, str, str]]:
    """The fixed task order: ``(train_type, direction, origin, destination)`` for every arrival.

    Raises
    ------
    UnknownNameError
        For an unknown train type or direction (the message lists the known ones).
    """
    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    for t in types:
        line.train_type(t)
    dirs = list(directions) if directions else list(DIRECTIONS)
    for d in dirs:
        if d not in DIRECTIONS:
            raise UnknownNameError(f"unknown direction {d!r}; use down or up")
    return [(t, d, a.station_id, b.station_id) for t in types for d in DIRECTIONS if d in dirs
            for a, b in line.interstations(d)]


def _approach_task(line: Line, train_type: str, origin: str, destination: str, adhesions_ms2, approach_m,
                   settings) -> ApproachResult:
    """joblib worker: one approach (module-level, picklable inputs)."""
    return approach_patterns(line, train_type, origin, destination, adhesions_ms2, approach_m, settings=settings)


def stop_sweep(
    line: Line,
    *,
    train_types: Sequence[str] | None = None,
    adhesion_kmh_s: str | Sequence[float] = DEFAULT_ADHESION_KMH_S,
    approach_m: float | str = DEFAULT_APPROACH_M,
    directions: Sequence[str] | None = None,
    n_jobs: int = -1,
    settings=None,
    progress: Callable[[int, int], None] | None = None,
) -> list[ApproachResult]:
    """Stopping patterns for every station approach of a line over an adhesion sweep, in parallel.

    Parameters
    ----------
    line : Line
    train_types : sequence of str, optional
        Default every train type of the line.
    adhesion_kmh_s : str or sequence of float
        Adhesion levels [km/h/s], or a spec for :func:`adhesion_levels`
        (default 2.5 … 3.5 in 0.1 steps).
    approach_m : float or "auto"
        Approach length where there is no TASC beacon [m], or ``"auto"`` (:func:`approach_patterns`).
    directions : sequence of str, optional
        Default both.
    n_jobs : int
        joblib processes; -1 = all cores, 1 = in this process.
    settings : planner.physics.track.SimSettings, optional
    progress : callable ``(done, total)``, optional
        Called after each finished approach.

    Returns
    -------
    list of ApproachResult
        In :func:`approach_tasks` order, independent of ``n_jobs``.

    Warns
    -----
    InfeasibleStopWarning
        Once per approach and adhesion level without a pattern, naming station,
        direction, train type and adhesion (also in ``ApproachResult.warnings``).
    """
    levels = adhesion_levels(adhesion_kmh_s)
    levels_ms2 = [a * KMH_S for a in levels]
    tasks = approach_tasks(line, train_types, directions)
    out: list[ApproachResult] = map_tasks(
        _approach_task, [(line, t, o, d, levels_ms2, approach_m, settings) for t, _, o, d in tasks], n_jobs, progress)
    for r in out:
        for msg in r.warnings:  # issued here: warnings raised in worker processes are lost
            warnings.warn(msg, InfeasibleStopWarning, stacklevel=2)
    return out
