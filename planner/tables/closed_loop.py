"""Closed-loop proof of the tables: the on-board logic driving the simulated train (docs/design.md §3).

For every interstation, direction and train type, and for designated running
times from the minimum (table (a) at ratio 1.0, rounded up to the second) to
the minimum + 60 s in 1 s steps, one batch of runs is simulated in which the
on-board logic (:mod:`planner.tables.onboard`, reading only the tables) picks the
ratio at departure and at every evaluation point, through the simulator's
``controller``/``decision_m`` hook. The arrival error is actual − designated
running time.

Scenarios
---------
``nominal``: the train the tables assume (load 0, traction × 1.0).
``perturbed``: the tables stay the nominal ones, the train runs at load 1.0
and traction × 0.9 (heavier and weaker: every ratio is slower than the table).

Infeasible designated times
---------------------------
A designated time below the *scenario's* minimum running time (ratio 1.0 from
departure to arrival under the scenario's conditions, simulated) cannot be
met by any choice of ratios: the method's fastest run is ratio 1.0
throughout. Those runs are flagged ``feasible = False`` and reported apart:
their lateness is physics, not controller error. The error statistics of the
summary cover feasible runs only; for the infeasible ones the summary reports
how many there were and ``infeasible_excess_max_s``, the worst arrival after
the scenario's minimum (the controller's share of their lateness: it should
be ≈ 0, i.e. the logic did run at 1.0). Designated times above the slowest
table time (lowest ratio) would be infeasible the other way; they do not occur
in the default sweep of +60 s but are flagged the same way.

Stalls
------
A plant that stalls (a heavy train on a climb under the perturbed scenario's
load and traction) is a physical verdict on the leg, not a failed run: its
runs have NaN times and are neither feasible nor counted in the error
statistics, and the result carries a :class:`~planner.tables.flags.LegFlag`
(scenario, chainage) that the summary's ``n_stalled`` and ``flag_*`` columns
show (:func:`drive_runs`). A mode that needs table (c) (``adaptive``) does not
run on a leg without it (its reference train stalls): every run NaN, the
tables' flag carried on.

Mode dispatch
-------------
A mode name maps to a *runner* in :data:`MODE_RUNNERS`. Every table mode of
:data:`planner.tables.onboard.CHOOSERS` is run by :func:`table_runner`; the
time-keeping mode (docs/design.md §4, :mod:`planner.tables.timekeeping`) drives the same
integrator with its own controller; other modes register a runner with
:func:`register_runner`.

Every mode's stop error is where the plant actually came to a stand, from the
integrator (:attr:`planner.physics.run_curve.BatchResult.stop_m`), minus the marker.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from planner.errors import InputError, StallError
from planner.line.model import Line
from planner.tables.flags import REFERENCE, STALL, LegFlag
from planner.tables.onboard import CHOOSERS, RunningTimeTables, chooser, make_controller
from planner.tables.timekeeping import closed_loop_runner as _timekeeping_runner

DEFAULT_EXTRA_S = 60.0
"""Sweep designated times up to the minimum + this [s] (docs/design.md §3)."""
DEFAULT_STEP_S = 1.0
"""Step of the designated-time sweep [s]."""
FEASIBLE_TOL_S = 1e-6
"""A designated time this close below the scenario minimum still counts as feasible (round-off)."""


@dataclass(frozen=True)
class Scenario:
    """Conditions of the real run (the tables always assume load 0, traction 1.0)."""

    name: str
    load: float
    traction_factor: float


SCENARIOS: dict[str, Scenario] = {
    "nominal": Scenario("nominal", 0.0, 1.0),
    "perturbed": Scenario("perturbed", 1.0, 0.9),
}


def get_scenario(name: "str | Scenario") -> Scenario:
    """The :class:`Scenario` called ``name`` (or ``name`` itself when it is one); InputError otherwise."""
    if isinstance(name, Scenario):
        return name
    try:
        return SCENARIOS[name]
    except KeyError:
        raise InputError(f"--scenario {name!r} is unknown; use one of {', '.join(SCENARIOS)}") from None


@dataclass(frozen=True, eq=False)
class ClosedLoopResult:
    """Closed-loop runs of one interstation, direction, train type, scenario and mode.

    Attributes
    ----------
    designated_s, actual_s : ndarray, shape (n,)
        Designated and simulated running time [s].
    stop_error_m : ndarray, shape (n,)
        Where the plant came to a stand − the stop marker [m] (positive: overrun).
    ratios : ndarray, shape (n, n_x)
        Ratio in force after the decision at each evaluation point (departure first).
    eval_point_ids : tuple of str, length n_x
    min_time_s : float
        Scenario minimum: ratio 1.0 throughout under the scenario's conditions [s].
    max_time_s : float
        Scenario time at the lowest grid ratio [s] (+inf for the time-keeping mode: no ratio grid).
    flags : tuple of planner.tables.flags.LegFlag
        Physical verdicts (module doc, "Stalls"): the plant stalls under the scenario (its stalled
        runs have NaN times), or the mode cannot run on the leg (no table (c): every run NaN).
    """

    line_id: str
    direction: str
    train_type: str
    origin: str
    destination: str
    scenario: str
    mode: str
    designated_s: np.ndarray
    actual_s: np.ndarray
    ratios: np.ndarray
    eval_point_ids: tuple[str, ...]
    min_time_s: float
    max_time_s: float
    stop_error_m: np.ndarray | None = None
    flags: tuple = ()

    @property
    def stalled(self) -> np.ndarray:
        """Runs that did not arrive: the plant stalled, or the mode could not run (NaN time)."""
        return ~np.isfinite(self.actual_s)

    @property
    def error_s(self) -> np.ndarray:
        """Arrival error, actual − designated [s]; positive = late."""
        return self.actual_s - self.designated_s

    @property
    def feasible(self) -> np.ndarray:
        """Designated time within [scenario minimum, scenario slowest] (module doc), and the run arrived
        (not :attr:`stalled`)."""
        d = self.designated_s
        return (d >= self.min_time_s - FEASIBLE_TOL_S) & (d <= self.max_time_s + FEASIBLE_TOL_S) & ~self.stalled


def designated_times(tables: RunningTimeTables, extra_s: float = DEFAULT_EXTRA_S,
                     step_s: float = DEFAULT_STEP_S) -> np.ndarray:
    """Designated running times: ceil(minimum) … ceil(minimum) + extra in ``step_s`` steps [s]."""
    t0 = math.ceil(tables.min_time_s - 1e-9)
    n = int(math.floor(extra_s / step_s + 1e-9))
    return t0 + step_s * np.arange(n + 1)


Runner = Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]]


def drive_tables(track, train, tables: RunningTimeTables, designated_s: np.ndarray,
                 scenarios: Sequence[Scenario], modes: Sequence[str], *, record: bool = False,
                 snapshots_m: Sequence[float] = ()):
    """The table modes of :mod:`planner.tables.onboard` driving the plant in one simulator batch.

    Runs every designated time for each (scenario, mode) pair, ``scenarios[i]``
    with ``modes[i]``, stacked in that order (runs in a batch do not interact:
    the same results as one batch each, several times cheaper). The closed-loop
    proof and the margin report both drive the tables through here.

    Returns
    -------
    r0 : ndarray, shape (k n,)
        Ratio chosen at departure.
    ratios : ndarray, shape (k n, n_x)
        Ratio chosen at departure and at each later evaluation point.
    res : planner.physics.run_curve.BatchResult
        The simulator's result (``record`` and ``snapshots_m`` as in ``simulate``).
    """
    from planner.physics.run_curve import simulate

    designated_s = np.asarray(designated_s, float)
    n = designated_s.size
    stacked = _Stacked([(chooser(m), slice(i * n, (i + 1) * n)) for i, m in enumerate(modes)])
    arrive = np.tile(designated_s, len(modes))
    r0 = stacked.depart(tables, arrive)
    controller, decision_m, chosen = make_controller(tables, stacked, arrive)
    res = simulate(track, train, r0, load=np.repeat([sc.load for sc in scenarios], n),
                   traction_factor=np.repeat([sc.traction_factor for sc in scenarios], n),
                   controller=controller, decision_m=decision_m, record=record, snapshots_m=snapshots_m)
    ratios = np.column_stack([r0] + [np.broadcast_to(c, r0.shape) for c in chosen])
    if ratios.shape[1] != len(tables.eval_point_ids):
        raise RuntimeError(  # internal: the simulator skipped or repeated a decision
            f"{tables.origin}->{tables.destination}: {ratios.shape[1] - 1} decisions for "
            f"{len(tables.eval_point_ids) - 1} evaluation points")
    return r0, ratios, res


def table_runner(track, train, tables: RunningTimeTables, designated_s: np.ndarray, sc: Scenario,
                 mode: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Run a table mode of :mod:`planner.tables.onboard` in the simulator.

    Returns
    -------
    actual_s : ndarray, shape (n,)
        Simulated running time [s].
    ratios : ndarray, shape (n, n_x)
        Ratio chosen at departure and at each later evaluation point.
    stop_m : ndarray, shape (n,)
        Where each run came to a stand [m of running distance].
    """
    _, ratios, res = drive_tables(track, train, tables, designated_s, [sc], [mode])
    return np.asarray(res.time_s, float), ratios, np.asarray(res.stop_m, float)


MODE_RUNNERS: dict[str, Runner] = {"timekeeping": _timekeeping_runner}
"""Non-table modes: name -> runner(track, train, tables, designated_s, scenario, mode)."""


def register_runner(mode: str, runner: Runner) -> None:
    """Make ``mode`` selectable in :func:`closed_loop_interstation` and ``planner simulate --mode``.

    ``runner(track, train, tables, designated_s, scenario, mode) -> (actual_s, ratios)`` gets the
    simulator's :class:`planner.physics.track.Track` and ``TrainType``, the interstation's
    :class:`~planner.tables.onboard.RunningTimeTables` (for the evaluation points and the minimum),
    the designated running times (n,) [s] and the :class:`Scenario` (load, traction factor) to
    run under; it returns the simulated running times (n,) [s], the ratio in force after each
    evaluation point, shape (n, n_x) (NaN where the mode has no ratio, e.g. time-keeping), and
    where each run came to a stand (n,) [m of running distance]. Its on-board logic sees the
    nominal train; the plant runs under the scenario.
    """
    MODE_RUNNERS[mode] = runner


def modes() -> list[str]:
    """Every selectable mode name."""
    return list(CHOOSERS) + [m for m in MODE_RUNNERS if m not in CHOOSERS]


def _runner(mode: str) -> Runner:
    if mode in MODE_RUNNERS:
        return MODE_RUNNERS[mode]
    if mode in CHOOSERS:
        return table_runner
    raise InputError(f"--mode {mode!r} is unknown; use one of {', '.join(modes())}")


def _slowest(mode: str, table_slowest_s: float) -> float:
    """Slowest designated time a mode can meet [s]: the lowest grid ratio's for the table modes; no
    bound for the time-keeping mode, which cruises as slowly as the remaining time asks."""
    return float(table_slowest_s) if mode in CHOOSERS else math.inf


def closed_loop_interstation(
    line: Line,
    train_type: str,
    tables: RunningTimeTables,
    *,
    scenario: str = "nominal",
    mode: str = "nearest",
    extra_s: float = DEFAULT_EXTRA_S,
    step_s: float = DEFAULT_STEP_S,
    settings=None,
    scenario_name: str | None = None,
) -> ClosedLoopResult:
    """Closed-loop runs of one interstation for the whole designated-time sweep.

    Parameters
    ----------
    line : Line
        The line (the simulator needs the track; the on-board logic sees only ``tables``).
    train_type : str
    tables : RunningTimeTables
        Tables as read from the datasets.
    scenario : {"nominal", "perturbed"}
        (``scenario_name`` is accepted as an alias.)
    mode : str
        On-board mode (:func:`modes`).
    extra_s, step_s : float
        Sweep of designated times [s] (:func:`designated_times`).
    settings : planner.physics.track.SimSettings, optional

    Returns
    -------
    ClosedLoopResult
        :func:`closed_loop_batch` of the one scenario and mode.
    """
    return closed_loop_batch(line, train_type, tables, scenarios=[get_scenario(scenario_name or scenario)],
                             modes=[mode], extra_s=extra_s, step_s=step_s, settings=settings)[0]


class _Stacked:
    """Several choosers side by side in one batch, each driving its own slice of the runs.

    The simulator's cost per grid step is mostly fixed overhead, so running every
    scenario × mode of an interstation as one batch is several times cheaper than
    one batch each; each chooser still sees only its own runs, in the same order.
    """

    def __init__(self, parts):
        self.parts = parts  # [(chooser, slice)]

    def depart(self, tables, designated_s):
        return np.concatenate([np.asarray(ch.depart(tables, designated_s[sl]), float) for ch, sl in self.parts])

    def at_point(self, tables, k, ratio, remaining_s, speed_ms=None, powering=None):
        out = np.array(ratio, dtype=float, copy=True)
        for ch, sl in self.parts:
            v = None if speed_ms is None else speed_ms[sl]
            p = None if powering is None else powering[sl]
            out[sl] = ch.at_point(tables, k, ratio[sl], remaining_s[sl], v, p)
        return out


def closed_loop_batch(
    line: Line,
    train_type: str,
    tables: RunningTimeTables,
    *,
    scenarios: Sequence[str | Scenario] = ("nominal", "perturbed"),
    modes: Sequence[str] = ("nearest",),
    extra_s: float = DEFAULT_EXTRA_S,
    step_s: float = DEFAULT_STEP_S,
    settings=None,
) -> list[ClosedLoopResult]:
    """Every scenario × mode of one interstation, table modes in one simulator batch.

    Gives the same results as :func:`closed_loop_interstation` per (scenario, mode)
    (runs in a batch do not interact), in the order scenarios × modes. Modes that
    are not table modes (registered runners) run on their own.
    """
    from planner.physics.track import SimSettings, make_track

    scs = [get_scenario(s) for s in scenarios]
    for m in modes:
        _runner(m)
    # a mode that needs table (c) cannot run where the leg has none (its reference train stalls)
    unable = {m for m in modes if getattr(CHOOSERS.get(m), "NEEDS_TABLE_C", False)
              and tables.ref_remaining_s is None}
    table_modes = [m for m in modes if m not in MODE_RUNNERS and m in CHOOSERS and m not in unable]
    train = line.train_type(train_type)
    track = make_track(line, train_type, tables.origin, tables.destination,
                       settings=settings or SimSettings(), nodes_m=list(tables.eval_distance_m))
    designated = designated_times(tables, extra_s, step_s)
    n, n_x = len(designated), len(tables.eval_point_ids)
    combos = [(sc, m) for sc in scs for m in table_modes]
    out: dict[tuple[str, str], tuple] = {}
    if combos:
        t, ratios, stop, flags = drive_runs(track, train, tables, designated, [sc for sc, _ in combos],
                                            [m for _, m in combos])
        for i, (sc, m) in enumerate(combos):
            sl = slice(i * n, (i + 1) * n)
            out[(sc.name, m)] = (t[sl], ratios[sl], stop[sl], flags[i])
    nan = (np.full(n, np.nan), np.full((n, n_x), np.nan), np.full(n, np.nan))
    for sc in scs:
        for m in modes:
            if (sc.name, m) in out:
                continue
            if m in unable:
                out[(sc.name, m)] = (*nan, tables.flags or (LegFlag(
                    STALL, REFERENCE, math.nan,
                    f"mode {m} needs table (c), which this leg lacks: rebuild the tables with `planner tables`"),))
                continue
            try:
                out[(sc.name, m)] = (*_runner(m)(track, train, tables, designated, sc, m), ())
            except StallError as e:
                out[(sc.name, m)] = (*nan, (LegFlag.stall(e, sc.name),))
    ends = _ends(track, train, tables, scs)
    direction = line.direction_between(tables.origin, tables.destination)
    results = []
    for j, sc in enumerate(scs):
        for m in modes:
            actual, ratios, stop_m, flags = out[(sc.name, m)]
            results.append(ClosedLoopResult(
                line_id=line.line_id, direction=direction, train_type=train_type, origin=tables.origin,
                destination=tables.destination, scenario=sc.name, mode=m, designated_s=designated,
                actual_s=np.asarray(actual, float), ratios=np.asarray(ratios, float),
                eval_point_ids=tables.eval_point_ids, min_time_s=float(ends[j, 0]),
                max_time_s=_slowest(m, ends[j, 1]), stop_error_m=np.asarray(stop_m, float) - track.length_m,
                flags=tuple(flags),
            ))
    return results


def _ends(track, train, tables: RunningTimeTables, scs: Sequence[Scenario]) -> np.ndarray:
    """Per scenario, the time at the highest and at the lowest grid ratio [s], shape (n_sc, 2); NaN where
    that run stalls (each run alone then: a batch stops at its first stall)."""
    from planner.physics.run_curve import simulate

    r = np.array([tables.ratios[0], tables.ratios[-1]])
    load, tf = np.array([sc.load for sc in scs]), np.array([sc.traction_factor for sc in scs])
    try:
        return np.asarray(simulate(track, train, np.tile(r, len(scs)), load=np.repeat(load, 2),
                                   traction_factor=np.repeat(tf, 2)).time_s, float).reshape(len(scs), 2)
    except StallError:
        out = np.full((len(scs), 2), np.nan)
        for j in range(len(scs)):
            for i in range(2):
                try:
                    out[j, i] = float(simulate(track, train, r[i:i + 1], load=load[j], traction_factor=tf[j]).time_s[0])
                except StallError:
                    pass
        return out


def drive_runs(track, train, tables: RunningTimeTables, designated_s: np.ndarray,
               scenarios: Sequence[Scenario], modes: Sequence[str]):
    """:func:`drive_tables` that survives stalls: a stalled run is NaN and its group gets a flag.

    The batch runs as one; only when a run in it stalls (a batch stops at its first stall) each
    (scenario, mode) group runs apart, and in a group that stalls each designated time alone
    (runs in a batch do not interact, so the others' results are the same bits).

    Returns
    -------
    time_s, stop_m : ndarray, shape (k n,)
        Running time [s] and where the run came to a stand [m of running distance]; NaN where it stalled.
    ratios : ndarray, shape (k n, n_x)
        As :func:`drive_tables`; NaN rows where the run stalled.
    flags : list of tuple of LegFlag, length k
        Per group, its stall flag (the first stall met), or ().
    """
    designated_s = np.asarray(designated_s, float)
    try:
        _, ratios, res = drive_tables(track, train, tables, designated_s, scenarios, modes)
        return np.asarray(res.time_s, float), ratios, np.asarray(res.stop_m, float), [()] * len(modes)
    except StallError:
        pass
    n, n_x = designated_s.size, len(tables.eval_point_ids)
    t, st, ra, flags = [], [], [], []
    for sc, m in zip(scenarios, modes):
        try:
            _, r_g, res = drive_tables(track, train, tables, designated_s, [sc], [m])
            t.append(np.asarray(res.time_s, float)), st.append(np.asarray(res.stop_m, float)), ra.append(r_g)
            flags.append(())
            continue
        except StallError as e:
            flags.append((LegFlag.stall(e, sc.name),))
        t_g, s_g, r_g = np.full(n, np.nan), np.full(n, np.nan), np.full((n, n_x), np.nan)
        for i in range(n):
            try:
                _, r_i, res = drive_tables(track, train, tables, designated_s[i:i + 1], [sc], [m])
            except StallError:
                continue
            t_g[i], s_g[i], r_g[i] = float(res.time_s[0]), float(res.stop_m[0]), r_i[0]
        t.append(t_g), st.append(s_g), ra.append(r_g)
    return np.concatenate(t), np.concatenate(ra), np.concatenate(st), flags


# --- summary and datasets --------------------------------------------------------


def _stats(err: np.ndarray) -> tuple[float, float, float]:
    a = np.abs(err)
    if a.size == 0:
        return (float("nan"),) * 3
    return float(np.median(a)), float(np.percentile(a, 95)), float(a.max())


def _max_abs(x) -> float:
    """max |x| over the finite values (a stalled run has no stop error), NaN when there are none."""
    a = np.abs(np.asarray([] if x is None else x, float))
    a = a[np.isfinite(a)]
    return float(a.max()) if a.size else float("nan")


def summary_row(r: ClosedLoopResult) -> dict:
    """Error statistics of one result (summary dataset row, without partition columns)."""
    f = r.feasible
    med, p95, mx = _stats(r.error_s[f])
    inf = ~f & ~r.stalled
    flag = r.flags[0] if r.flags else None
    excess = float(np.max(np.abs(r.actual_s[inf] - np.clip(r.designated_s[inf], r.min_time_s, r.max_time_s)),
                          initial=0.0))
    return {
        "origin": r.origin, "destination": r.destination, "n_runs": int(f.size), "n_feasible": int(f.sum()),
        "median_abs_error_s": med, "p95_abs_error_s": p95, "max_abs_error_s": mx,
        "max_abs_stop_error_m": _max_abs(r.stop_error_m),
        "min_time_s": r.min_time_s, "infeasible_excess_max_s": excess,
        "n_stalled": int(r.stalled.sum()),
        "flag_kind": "" if flag is None else flag.kind,
        "flag_position_m": math.nan if flag is None else flag.position_m,
        "flag_reason": "; ".join(f.reason for f in r.flags),
    }


def overall(results: Sequence[ClosedLoopResult]) -> dict:
    """Statistics over every feasible run of ``results`` (for the CLI summary and the report)."""
    err = np.concatenate([r.error_s[r.feasible] for r in results]) if results else np.zeros(0)
    n = int(sum(r.designated_s.size for r in results))
    med, p95, mx = _stats(err)
    inf = [summary_row(r)["infeasible_excess_max_s"] for r in results]
    stops = [r.stop_error_m for r in results if r.stop_error_m is not None]
    return {"n_runs": n, "n_feasible": int(err.size), "median_abs_error_s": med, "p95_abs_error_s": p95,
            "max_abs_error_s": mx, "infeasible_excess_max_s": max(inf, default=0.0),
            "max_abs_stop_error_m": _max_abs(np.concatenate(stops)) if stops else float("nan")}


