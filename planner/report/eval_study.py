"""The evaluation-interval study (issue 22): arrival error and cost against interval and ratio grid.

The published target-speed-ratio method studies how the spacing of the
evaluation points and the step of the ratio grid change the arrival error.
This module runs that study on a line: for every *setting* (a ratio grid and
an evaluation interval, :mod:`planner.tables.eval_points`) it

1. builds the running-time tables (a)–(d) of every interstation, direction and
   train type, timing each task's CPU in its own worker process (so the figure
   does not depend on what else the machine runs);
2. runs the closed loop (:func:`planner.tables.closed_loop.closed_loop_batch`) for the
   designated times minimum … minimum + 60 s, every mode and scenario asked for;
3. counts what the choice costs: evaluation points, rows of each table dataset,
   and the bytes of every signed on-board bundle (:mod:`planner.bundle.container`, the
   line's own tables, these tables and, when given, the stopping patterns);
4. for the worst run of each mode and scenario, replays it and says which
   evaluation point last had *authority* (the last one where the row of
   table (b) the vehicle looked up spans more than the final error, i.e. where
   another choice could still have cancelled it) and the gap between the
   neighbouring table entries around the remaining time wanted there: the
   nearest rule can be off by up to half that gap.

The odometer is taken as exact (no position error is modelled), as everywhere
in the closed loop.

:func:`render_html` writes the study as one self-contained page in the style of
the margin report. ``benchmarks/bench_eval_interval.py`` runs it on the sample line.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from planner.tables.closed_loop import ClosedLoopResult, closed_loop_batch, get_scenario, overall
from planner.tables.eval_points import check_interval
from planner.line.model import Line
from planner.tables.ratios import leg_ratio_grid
from planner.tables.build import InterstationTables, interstation_tables, table_tasks
from planner.datasets.tables import datasets as table_datasets, write_tables

GRIDS: dict[str, str] = {
    "default": "1.0:0.7:0.1,0.7:floor:0.05",
    "10 %": "1.0:floor:0.1",
    "5 %": "1.0:floor:0.05",
    "2.5 %": "1.0:floor:0.025",
}
"""Ratio grids of the study by label (``default``: 10 % steps to 70 %, then 5 %, what the job uses)."""
INTERVALS: tuple[float | None, ...] = (None, 1000.0, 500.0, 200.0)
"""Evaluation intervals of the study [m]; None = beacons only (today's default)."""


@dataclass(frozen=True)
class Setting:
    """One point of the study: a ratio grid and an evaluation interval."""

    grid: str
    """Label of the ratio grid (a key of :data:`GRIDS`, or the spec itself)."""
    interval_m: float | None
    """Interval of the odometer evaluation points [m]; None = beacons only."""

    @property
    def ratios(self) -> str:
        return GRIDS.get(self.grid, self.grid)

    @property
    def label(self) -> str:
        return f"{self.grid} / {'beacons only' if self.interval_m is None else f'{self.interval_m:g} m'}"


@dataclass
class Worst:
    """The worst run of one mode and scenario, replayed point by point."""

    train_type: str
    origin: str
    destination: str
    designated_s: float
    error_s: float
    points: list[dict]
    """Per decision after departure: id, distance before the stop [m], ratio before and after,
    wanted remaining time [s], span of the row looked up [s], gap between the row's entries
    around the wanted time [s]."""
    authority: dict | None
    """The last of ``points`` whose row spans more than |error| (None if none does)."""


@dataclass
class SettingResult:
    """Figures of one setting."""

    setting: Setting
    n_ratios: int
    n_points: int
    n_interval_points: int
    rows: dict[str, int]
    """Rows per table dataset (eval_points, table_a … table_d)."""
    bundle_bytes: int
    """Sum of the bytes of every bundle of the line (each direction × train type)."""
    bundle_max_bytes: int
    """The largest single bundle [bytes]."""
    tables_cpu_s: float
    """CPU time of the table builds, summed over tasks (each timed in its worker) [s]."""
    tables_wall_s: float
    """Wall time of the table builds and closed loop together [s] (depends on the machine's load)."""
    stats: dict[tuple[str, str], dict]
    """(mode, scenario) → :func:`planner.tables.closed_loop.overall`."""
    worst: dict[tuple[str, str], Worst] = field(default_factory=dict)


def _task(line: Line, tt: str, o: str, d: str, grid, interval_m, scenarios, modes, settings):
    """Worker: one interstation's tables (CPU timed) and its closed loop."""
    c0 = time.process_time()
    tab = interstation_tables(line, tt, o, d, grid, eval_interval_m=interval_m, settings=settings)
    cpu = time.process_time() - c0
    loops = closed_loop_batch(line, tt, tab.onboard(), scenarios=scenarios, modes=modes, settings=settings)
    return tab, loops, cpu


def bundle_sizes(line: Line, tables_dir: Path, stops_dir: Path | None,
                 train_types: Sequence[str] | None = None) -> list[int]:
    """Bytes of every signed bundle of ``line`` from these folders (nothing is written)."""
    from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

    from planner.bundle.assemble import assemble
    from planner.bundle.container import bundle_bytes
    from planner.bundle.manifest import Release
    from planner.line.model import DIRECTIONS

    key = Ed25519PrivateKey.generate()  # signatures have a fixed size: the bytes do not depend on it
    release = Release.issue(0)  # a fixed build time: the version's digits, so the bytes, do not vary
    types = list(train_types) if train_types else [t.train_type for t in line.train_types]
    out = []
    for d in DIRECTIONS:
        for tt in types:
            tabs = assemble(line, d, tt, tables_dir=tables_dir, stops_dir=stops_dir)
            out.append(len(bundle_bytes(tabs, line_id=line.line_id, direction=d, train_type=tt, private_key=key,
                                        release=release, line_digest=line.source_digest or "")))
    return out


def replay(line: Line, train_type: str, tables, designated_s: float, scenario: str, mode: str,
           settings=None) -> Worst:
    """Run one designated time again and record, at every evaluation point, what the logic saw."""
    from planner.tables.onboard import chooser, grid_index, make_controller
    from planner.physics.track import SimSettings, make_track
    from planner.physics.run_curve import simulate

    sc = get_scenario(scenario)
    track = make_track(line, train_type, tables.origin, tables.destination, settings=settings or SimSettings(),
                       nodes_m=list(tables.eval_distance_m))
    ch = chooser(mode)
    arrive = np.array([float(designated_s)])
    r0 = np.asarray(ch.depart(tables, arrive), float)
    controller, decision_m, _ = make_controller(tables, ch, arrive)
    seen: list[tuple[float, float, float, float]] = []

    def ctl(s_m, state):
        new = controller(s_m, state)
        seen.append((float(s_m), float(state.t_s[0]), float(state.ratio[0]), float(np.asarray(new)[0])))
        return new

    res = simulate(track, line.train_type(train_type), r0, load=sc.load, traction_factor=sc.traction_factor,
                   controller=ctl, decision_m=decision_m)
    actual = float(np.asarray(res.time_s)[0])
    err = actual - float(designated_s)
    length = float(track.s_m[-1])
    pts = []
    ids = {float(s): i for i, s in enumerate(tables.eval_distance_m)}
    for s, t, rb, ra in seen:
        k = min(ids, key=lambda x: abs(x - s))
        k = ids[k]
        row = tables.remaining_s[k, int(grid_index(tables.ratios, np.array([rb]))[0])]
        want = float(designated_s) - t
        srt = np.sort(row)
        j = int(np.searchsorted(srt, want))
        gap = float(srt[j] - srt[j - 1]) if 0 < j < len(srt) else float("inf")
        pts.append({"eval_point_id": tables.eval_point_ids[k], "before_stop_m": length - s, "ratio_before": rb,
                    "ratio_after": ra, "wanted_s": want, "row_min_s": float(srt[0]), "row_max_s": float(srt[-1]),
                    "row_span_s": float(srt[-1] - srt[0]), "gap_s": gap})
    auth = [p for p in pts if p["row_span_s"] > abs(err)]
    return Worst(train_type, tables.origin, tables.destination, float(designated_s), err, pts,
                 auth[-1] if auth else None)


def run_setting(
    line: Line,
    setting: Setting,
    *,
    stops_dir: Path | None = None,
    modes: Sequence[str] = ("nearest", "adaptive"),
    scenarios: Sequence[str] = ("nominal", "perturbed"),
    train_types: Sequence[str] | None = None,
    interstations: Sequence[tuple[str, str]] | None = None,
    n_jobs: int = -1,
    settings=None,
    explain: bool = True,
    work_dir: Path | None = None,
) -> SettingResult:
    """Tables, closed loop, costs and the worst runs of one setting (module doc).

    Parameters
    ----------
    line : Line
    setting : Setting
    stops_dir : path, optional
        ``planner stops --out`` folder, so the bundle bytes include the stopping patterns.
    modes, scenarios : sequences of str
        Closed-loop modes and scenarios.
    train_types : sequence of str, optional
        Default every train type.
    interstations : sequence of (origin, destination), optional
        Only these interstations (a subset of the line); default all. Bundle bytes are only
        computed for the whole line (0 otherwise).
    n_jobs : int
        Worker processes (-1 = all cores, 1 = this process).
    explain : bool
        Replay the worst run of each mode and scenario (:func:`replay`).
    work_dir : path, optional
        Folder for the tables datasets (a temporary folder by default).
    """
    import tempfile

    from planner.io.parallel import map_tasks

    interval = check_interval(setting.interval_m, "interval")
    tasks = table_tasks(line, train_types)
    if interstations is not None:
        want = {tuple(x) for x in interstations}
        tasks = [t for t in tasks if (t[2], t[3]) in want]
    grids = [leg_ratio_grid(setting.ratios, line, t[0], t[2], t[3]) for t in tasks]  # each leg's floor
    order = sorted(range(len(tasks)), key=lambda i: -line.run_between(tasks[i][2], tasks[i][3]).length_m)
    w0 = time.perf_counter()
    # the longest interstations first, so the workers finish together; results come back in this order
    got = map_tasks(_task, [(line, tasks[i][0], tasks[i][2], tasks[i][3], grids[i], interval, list(scenarios),
                             list(modes), settings) for i in order], n_jobs)
    wall = time.perf_counter() - w0
    res: list = [None] * len(tasks)
    for i, g in zip(order, got):
        res[i] = g
    tabs: list[InterstationTables] = [g[0] for g in res]
    loops: list[ClosedLoopResult] = [r for g in res for r in g[1]]
    cpu = float(sum(g[2] for g in res))
    rows = {name: t.num_rows for name, t in table_datasets(tabs).items()}
    sizes = [0]
    if interstations is None:
        with tempfile.TemporaryDirectory() as tmp:
            d = Path(work_dir) if work_dir is not None else Path(tmp)
            write_tables(tabs, d)
            sizes = bundle_sizes(line, d, stops_dir, train_types)
    stats = {(m, sc): overall([r for r in loops if r.mode == m and r.scenario == get_scenario(sc).name])
             for m in modes for sc in scenarios}
    out = SettingResult(
        setting=setting, n_ratios=max(map(len, grids), default=0), n_points=sum(len(t.points) for t in tabs),
        n_interval_points=sum(p.kind == "interval" for t in tabs for p in t.points), rows=rows,
        bundle_bytes=int(sum(sizes)), bundle_max_bytes=int(max(sizes)), tables_cpu_s=cpu, tables_wall_s=wall,
        stats=stats,
    )
    if explain:
        by_key = {(t.train_type, t.origin, t.destination): t for t in tabs}
        for m in modes:
            for sc in scenarios:
                name = get_scenario(sc).name
                cand = [r for r in loops if r.mode == m and r.scenario == name and r.feasible.any()]
                if not cand:
                    continue
                r = max(cand, key=lambda r: np.max(np.abs(r.error_s[r.feasible])))
                i = int(np.argmax(np.where(r.feasible, np.abs(r.error_s), -1.0)))
                tab = by_key[(r.train_type, r.origin, r.destination)].onboard()
                out.worst[(m, sc)] = replay(line, r.train_type, tab, float(r.designated_s[i]), sc, m, settings)
    return out


def run_study(line: Line, settings_list: Sequence[Setting], *, progress: Callable[[SettingResult], None] | None = None,
              **kw) -> list[SettingResult]:
    """:func:`run_setting` for every setting, in order; ``progress`` is called after each."""
    out = []
    for s in settings_list:
        out.append(run_setting(line, s, **kw))
        if progress:
            progress(out[-1])
    return out


def default_settings(grids: Sequence[str] = tuple(GRIDS),
                     intervals: Sequence[float | None] = INTERVALS) -> list[Setting]:
    """Every grid × interval of the study, grids outer."""
    return [Setting(g, i) for g in grids for i in intervals]


def best_nearest(results: Sequence[SettingResult], base_bytes: int, max_factor: float = 2.0,
                 scenario_bounds: dict[str, float] | None = None) -> SettingResult | None:
    """The setting of the nearest rule with the smallest worst error relative to its bounds whose
    largest bundle stays under ``max_factor`` × ``base_bytes`` (today's largest bundle; None if none)."""
    bounds = scenario_bounds or {"nominal": 2.0, "perturbed": 3.0}
    ok = [r for r in results if 0 < r.bundle_max_bytes < max_factor * base_bytes]

    def score(r):
        return max(r.stats[("nearest", sc)]["max_abs_error_s"] / b for sc, b in bounds.items()
                   if ("nearest", sc) in r.stats)

    return min(ok, key=score) if ok else None


# --- the page ---------------------------------------------------------------------

def study_rows(results: Sequence[SettingResult], base_bytes: int | None = None) -> list[dict]:
    """One flat dict per setting: costs and error statistics (for printing and the page); the
    bundle factor is relative to ``base_bytes`` (default: the first result's largest bundle)."""
    base = base_bytes if base_bytes is not None else (results[0].bundle_max_bytes if results else 0)
    out = []
    for r in results:
        row = {"grid": r.setting.grid, "interval": "beacons" if r.setting.interval_m is None
               else f"{r.setting.interval_m:g} m", "ratios": r.n_ratios, "points": r.n_points,
               "table_b_rows": r.rows.get("table_b", 0), "table_rows": sum(r.rows.values()),
               "bundle_kb": r.bundle_max_bytes / 1024,
               "bundle_x": r.bundle_max_bytes / base if base and r.bundle_max_bytes else float("nan"),
               "cpu_s": r.tables_cpu_s}
        for (m, sc), st in r.stats.items():
            for k, short in (("median_abs_error_s", "med"), ("p95_abs_error_s", "p95"), ("max_abs_error_s", "max")):
                row[f"{m}/{sc}/{short}"] = st[k]
        out.append(row)
    return out


def format_table(results: Sequence[SettingResult], base_bytes: int | None = None) -> str:
    """The study as a plain-text table (what the benchmark prints)."""
    rows = study_rows(results, base_bytes)
    if not rows:
        return ""
    keys = [k for k in rows[0] if "/" in k]
    cases = list(dict.fromkeys(k.rsplit("/", 1)[0] for k in keys))
    head = (f"{'grid':7s} {'interval':9s} {'n_r':>3s} {'points':>6s} {'table_b':>8s} {'bundle':>9s} {'x':>5s} "
            f"{'cpu_s':>7s}  " + "  ".join(f"{c:^20s}" for c in cases))
    sub = " " * 60 + "  ".join(f"{'med':>6s} {'p95':>6s} {'max':>6s}" for _ in cases)
    lines = [head, sub]
    for w in rows:
        cells = "  ".join(f"{w[c + '/med']:6.2f} {w[c + '/p95']:6.2f} {w[c + '/max']:6.2f}" for c in cases)
        lines.append(f"{w['grid']:7s} {w['interval']:9s} {w['ratios']:3d} {w['points']:6d} {w['table_b_rows']:8d} "
                     f"{w['bundle_kb']:7.0f}kB {w['bundle_x']:5.2f} {w['cpu_s']:7.1f}  {cells}")
    return "\n".join(lines)


def format_worst(w: Worst, last: int = 4) -> str:
    """One worst run in words: where, how late, and the last points it looked at."""
    a = w.authority
    txt = (f"{w.train_type} {w.origin}->{w.destination} designated {w.designated_s:.0f} s: error {w.error_s:+.2f} s; ")
    if a is None:
        txt += "no evaluation point had a row spanning more than the error"
    else:
        txt += (f"last point with authority {a['eval_point_id']} ({a['before_stop_m']:.0f} m before the stop, "
                f"ratio {a['ratio_before']:.3g} -> {a['ratio_after']:.3g}, row {a['row_min_s']:.1f}-"
                f"{a['row_max_s']:.1f} s, ")
        if a["wanted_s"] < a["row_min_s"]:
            txt += f"wanted {a['wanted_s']:.1f} s: below the fastest entry, already late by " \
                   f"{a['row_min_s'] - a['wanted_s']:.2f} s)"
        elif a["wanted_s"] > a["row_max_s"]:
            txt += f"wanted {a['wanted_s']:.1f} s: above the slowest entry by {a['wanted_s'] - a['row_max_s']:.2f} s)"
        else:
            txt += f"wanted {a['wanted_s']:.1f} s between neighbouring entries {a['gap_s']:.2f} s apart)"
            miss = abs(w.error_s) - a["gap_s"] / 2.0
            if miss > 0.1:  # the grid explains at most half the gap: the rest is the row itself
                txt += (f"; the grid explains at most {a['gap_s'] / 2.0:.2f} s of it, the other {miss:.2f} s is "
                        f"the row not describing the train there (table (b) indexes its state by the ratio "
                        f"run before, {a['ratio_before']:.3g})")
    tail = "; ".join(f"{p['eval_point_id']}@{p['before_stop_m']:.0f}m r {p['ratio_before']:.3g}->{p['ratio_after']:.3g}"
                     f" want {p['wanted_s']:.1f} row {p['row_min_s']:.1f}-{p['row_max_s']:.1f} gap {p['gap_s']:.2f}"
                     for p in w.points[-last:])
    return txt + "\n      last points: " + tail


NEAREST_BOUNDS_S: dict[str, float] = {"nominal": 2.0, "perturbed": 3.0}
"""Issue 22: max |arrival error| of the nearest rule at its best setting, per scenario [s]."""
BUNDLE_FACTOR = 2.0
"""Issue 22: the nearest rule's best setting keeps the largest bundle under this × today's."""
ADAPTIVE_MAX_S = 1.0
"""Issue 22: max |arrival error| of the adaptive mode at every setting, both scenarios [s]."""
