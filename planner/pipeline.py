"""The nightly job: validate → tables → stopping patterns → closed loop → margins → bundles → conflicts → graph
→ changes → overview → publish.

One call, :func:`run_job`, regenerates everything a job file names and
publishes it atomically (:mod:`planner.publish`). Work is split into *units*
(an interstation × direction × train type for tables and the closed loop, a
station approach for stopping patterns, a line for margins and conflicts) and
every unit is keyed by the digest of exactly the inputs it depends on:

* the slice of the line database the unit can see (its interstation's stop
  markers, the gradients, curves, restrictions and beacons between them and
  one train length beyond, the train type, the line maximum),
* the job parameters of its step,
* the planner's own code (a digest of its source files), so that a new
  version never reuses results computed by an old one.

A unit whose key is in the cache (``OUTPUT_ROOT/.cache``) is not recomputed;
so a re-run with nothing changed computes nothing, and editing one speed
restriction recomputes only the interstations (and approaches) it reaches.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import signal
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from . import __version__
from .atomic import write_bytes_atomic
from .errors import JobError
from .job import Job
from .model import DIRECTIONS, Line
from .publish import (
    Cache, canonical_json, clean_stale_staging, digest, job_lock, latest_run, next_run_id, publish, staging_dir,
)

STEPS = ("validate", "tables", "stops", "closed_loop", "margins", "bundles", "conflicts", "graph", "changes",
         "overview", "publish")


# --- digests of exactly what a unit depends on -----------------------------------
_CODE_DIGEST: str | None = None


def code_digest() -> str:
    """SHA-256 over the planner package's source files (names and bytes) and its version."""
    global _CODE_DIGEST
    if _CODE_DIGEST is None:
        h = hashlib.sha256(__version__.encode())
        pkg = Path(__file__).resolve().parent
        for p in sorted(pkg.rglob("*.py")):
            h.update(p.relative_to(pkg).as_posix().encode() + b"\0")
            h.update(p.read_bytes())
        _CODE_DIGEST = h.hexdigest()
    return _CODE_DIGEST


def _segments_in(seg, lo: float, hi: float) -> list:
    return [
        (float(a), float(b), float(v))
        for a, b, v in zip(seg.start_m, seg.end_m, seg.value)
        if b > lo and a < hi
    ]


def interstation_inputs(line: Line, train_type: str, origin: str, destination: str) -> dict[str, Any]:
    """Everything of the line database that a run from ``origin`` to ``destination`` can see.

    The window is the stretch between the two stop markers widened by one
    train length on both sides: restrictions are held until the tail clears
    them and gradients/curves are averaged over the train's length, so
    anything within a train length behind the departure can matter.
    """
    ext = line.run_between(origin, destination)
    direction, a, b = ext.direction, ext.start_m, ext.end_m
    tt = line.train_type(train_type)
    lo, hi = min(a, b) - tt.length_m - 1.0, max(a, b) + tt.length_m + 1.0
    return {
        "direction": direction,
        "origin": [origin, a],
        "destination": [destination, b],
        "line_max_ms": line.max_speed_ms,
        "train": dataclasses.asdict(tt),
        "gradients": _segments_in(line.gradients, lo, hi),
        "curves": _segments_in(line.curves, lo, hi),
        "limits": [
            dataclasses.astuple(s) for s in line.limits_for(direction, train_type) if s.end_m > lo and s.start_m < hi
        ],
        "beacons": [
            dataclasses.astuple(x) for x in line.beacons_for(direction) if lo < x.position_m < hi
        ],
    }


# --- units of work -----------------------------------------------------------------
@dataclass(frozen=True)
class Unit:
    """One cacheable piece of work: ``fn(*args)`` whose result is keyed by ``key``."""

    step: str
    key: str
    label: str
    fn: Callable
    args: tuple


def _tables_unit(line, tt, o, d, grid, eval_offset_m, ds_m):
    from .run_curve import SimSettings
    from .tables import interstation_tables

    return interstation_tables(line, tt, o, d, grid, after_departure_m=eval_offset_m,
                               settings=SimSettings(ds_m=ds_m))


def _stops_unit(line, tt, o, d, adhesions_ms2, approach_m, ds_m):
    from .run_curve import SimSettings
    from .stops import approach_patterns

    return approach_patterns(line, tt, o, d, adhesions_ms2, approach_m, settings=SimSettings(ds_m=ds_m))


def _closed_loop_unit(line, tt, tables, scenarios, modes, horizon_s, step_s, ds_m):
    from .closed_loop import Scenario, closed_loop_batch
    from .run_curve import SimSettings

    return closed_loop_batch(line, tt, tables, scenarios=[Scenario(s.name, s.load, s.traction) for s in scenarios],
                             modes=modes, extra_s=horizon_s, step_s=step_s, settings=SimSettings(ds_m=ds_m))


def _call(fn, args):
    """joblib worker: module level, so it pickles to local processes and Dask workers alike."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args)


class Runner:
    """Runs units through the cache and the parallel backend, counting what it computed."""

    def __init__(self, job: Job, cache: Cache, progress: "Progress"):
        self.job = job
        self.cache = cache
        self.progress = progress
        self.computed: dict[str, int] = {}
        self.reused: dict[str, int] = {}

    def run(self, step: str, units: Sequence[Unit]) -> list:
        """Results of ``units`` in order; cached ones loaded, the rest computed in parallel."""
        from joblib import Parallel, delayed

        from .parallel import backend

        results: list = [None] * len(units)
        todo = []
        for i, u in enumerate(units):
            obj = self.cache.get("objects", u.key)
            if obj is None:
                todo.append(i)
            else:
                results[i] = obj
        self.reused[step] = self.reused.get(step, 0) + len(units) - len(todo)
        self.computed[step] = self.computed.get(step, 0) + len(todo)
        self.progress.start(step, len(units), done=len(units) - len(todo))
        if todo:
            p = self.job.parallel
            with backend(p.backend, n_jobs=p.n_jobs, scheduler=p.scheduler) as n_jobs:
                if n_jobs == 1 or len(todo) == 1:
                    gen = (_call(units[i].fn, units[i].args) for i in todo)
                else:
                    gen = Parallel(n_jobs=n_jobs, return_as="generator")(
                        delayed(_call)(units[i].fn, units[i].args) for i in todo
                    )
                for i, res in zip(todo, gen):
                    self.cache.put("objects", units[i].key, res)  # survives a later failure
                    _kill_point()
                    results[i] = res
                    self.progress.advance(step)
        self.progress.finish(step)
        return results


# --- test hook -----------------------------------------------------------------------
KILL_ENV = "PLANNER_TEST_KILL_AT"
"""Tests only: with ``N`` in this environment variable a run SIGKILLs its own process at its N-th
kill point (each unit just stored in the cache, then the staged run just before publishing), so
tests kill runs at deterministic moments instead of after a wall-clock delay. Unset normally."""
_kill_points = 0


def _kill_point() -> None:
    global _kill_points
    _kill_points += 1
    if os.environ.get(KILL_ENV) == str(_kill_points):
        os.kill(os.getpid(), signal.SIGKILL)


# --- progress ------------------------------------------------------------------------
class Progress:
    """A rich progress bar per step (counts and time left) plus the per-step timings."""

    def __init__(self, enabled: bool = True):
        self.timings: dict[str, float] = {}
        self._t0: dict[str, float] = {}
        self._ids: dict[str, Any] = {}
        self._bar = None
        if enabled:
            from rich.progress import (
                BarColumn, MofNCompleteColumn, Progress as RichProgress, TextColumn, TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = RichProgress(
                TextColumn("{task.description:<12}"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(), transient=False,
            )

    def __enter__(self):
        if self._bar:
            self._bar.start()
        return self

    def __exit__(self, *exc):
        if self._bar:
            self._bar.stop()

    def start(self, step: str, total: int, done: int = 0) -> None:
        self._t0.setdefault(step, time.perf_counter())
        if self._bar is not None:
            if step in self._ids:
                self._bar.update(self._ids[step], total=total, completed=done)
            else:
                self._ids[step] = self._bar.add_task(step, total=total, completed=done)

    def advance(self, step: str, n: int = 1) -> None:
        if self._bar is not None and step in self._ids:
            self._bar.advance(self._ids[step], n)

    def finish(self, step: str) -> None:
        self.timings[step] = round(time.perf_counter() - self._t0.get(step, time.perf_counter()), 3)
        if self._bar is not None and step in self._ids:
            t = self._bar.tasks[[x.id for x in self._bar.tasks].index(self._ids[step])]
            self._bar.update(self._ids[step], completed=t.total)

    @contextmanager
    def step(self, name: str, total: int = 1):
        self.start(name, total)
        yield
        self.finish(name)


# --- the job -----------------------------------------------------------------------------
@dataclass
class RunSummary:
    """What a job did: the published run, per-step timings, counts."""

    run_id: str | None
    run_dir: Path | None
    up_to_date: bool
    timings: dict[str, float] = field(default_factory=dict)
    computed: dict[str, int] = field(default_factory=dict)
    reused: dict[str, int] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    flags: dict[str, int] = field(default_factory=dict)
    bundles: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    reports: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    """Margin report of each line (kept for :func:`planner.views.run_views`, which puts the changes on top)."""


def signing_key_path(job: Job, notes: list[str]) -> Path:
    """The private key to sign bundles with: job file, else $PLANNER_SIGNING_KEY, else a development key."""
    from .signing import generate_keypair

    if job.bundles.signing_key:
        p = job.resolve(job.bundles.signing_key)
        if not p.is_file():
            raise JobError(f"{job.path}: [bundles] signing_key: {p} not found; "
                           "create one with `planner keys generate DIR`")
        return p
    env = os.environ.get("PLANNER_SIGNING_KEY")
    if env:
        p = Path(env)
        if not p.is_file():
            raise JobError(f"PLANNER_SIGNING_KEY: {p} not found")
        return p
    dev = job.resolve(job.job.output_root) / ".dev-key"
    key = dev / "signing_key.pem"
    if not key.is_file():
        generate_keypair(dev)
        notes.append(f"no signing key configured: created a DEVELOPMENT key {key} "
                     "(bundles signed with it are for testing only; set [bundles] signing_key)")
    else:
        notes.append(f"bundles signed with the development key {key} (set [bundles] signing_key for production)")
    return key


def _inputs_digest(job: Job, lines: Sequence[Line], key_id: str) -> str:
    """Digest of everything a run depends on: code, parameters, line databases, signing key (its public id)."""
    params = job.parameters()
    params["job"] = {k: v for k, v in params["job"].items() if k not in ("keep_runs", "output_root")}
    return digest({"code": code_digest(), "params": params, "lines": [ln.source_digest for ln in lines],
                   "key": key_id})


def run_job(job: Job, *, show_progress: bool = True) -> RunSummary:
    """Run a whole job and publish it; raise a :class:`PlannerError` (latest untouched) on failure."""
    from .loader import load_line

    root = job.resolve(job.job.output_root)
    with job_lock(root):
        clean_stale_staging(root)
        cache = Cache(root / ".cache")
        with Progress(show_progress) as prog:
            with prog.step("validate", len(job.job.lines)):
                lines = [load_line(job.resolve(p)) for p in job.job.lines]
                for line in lines:
                    for t in job.job.train_types:
                        line.train_type(t)
            from .signing import load_private_key, public_key_id

            notes: list[str] = []
            key = load_private_key(signing_key_path(job, notes))
            inputs = _inputs_digest(job, lines, public_key_id(key.public_key()))
            last = latest_run(root)
            if last and last.endswith(inputs[:10]) and (root / last / "manifest.json").is_file():
                import json

                m = json.loads((root / last / "manifest.json").read_text())
                if m.get("inputs_digest") == inputs:
                    return RunSummary(last, root / last, True, timings=prog.timings,
                                      notes=notes + [f"nothing changed since run {last}: it stays the latest"])
            run_id = next_run_id(root, inputs)
            stage = staging_dir(root, run_id)
            summary = RunSummary(run_id, None, False, notes=notes)
            runner = Runner(job, cache, prog)
            for line in lines:
                _run_line(job, line, stage, runner, summary, key)
            summary.computed, summary.reused = runner.computed, runner.reused
            _write_manifest(job, lines, stage, run_id, inputs, prog.timings, summary)
            from .views import run_views  # changes since the last run, overview page

            run_views(job, lines, stage, root, prog, summary)
            _kill_point()
            with prog.step("publish"):
                summary.run_dir = publish(root, stage, run_id, job.job.keep_runs)
            summary.timings = dict(prog.timings)
    return summary


def _types(job: Job, line: Line) -> list[str]:
    return list(job.job.train_types) or [t.train_type for t in line.train_types]


def _run_line(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary, key) -> None:
    from .ratios import ratio_grid
    from .stops import adhesion_levels
    from .units import KMH, KMH_S

    tp, code = job.tables, code_digest()
    grid = ratio_grid(tp.ratios, line_max_speed_ms=line.max_speed_ms,
                      min_target_speed_ms=tp.min_target_kmh * KMH)
    types = _types(job, line)
    tasks = [(t, d, a.station_id, b.station_id) for t in types for d in DIRECTIONS for a, b in line.interstations(d)]
    unit_in = {k: digest(interstation_inputs(line, k[0], k[2], k[3])) for k in tasks}

    # tables
    t_units = [
        Unit("tables", digest(["tables", code, unit_in[k], dataclasses.asdict(tp), list(map(float, grid))]),
             f"{k[0]} {k[2]}->{k[3]}", _tables_unit, (line, k[0], k[2], k[3], grid, tp.eval_offset_m, tp.ds_m))
        for k in tasks
    ]
    tables = runner.run("tables", t_units)
    from .tables import write_tables

    _count(summary, write_tables(tables, stage))

    # stopping patterns, one unit per arrival
    sp = job.stops
    levels = adhesion_levels(sp.adhesion_kmh_s)
    adh_ms2 = [a * KMH_S for a in levels]
    s_units = [
        Unit("stops", digest(["stops", code, unit_in[k], dataclasses.asdict(sp), tp.ds_m]),
             f"{k[0]} {k[3]}", _stops_unit, (line, k[0], k[2], k[3], adh_ms2, sp.approach_m, tp.ds_m))
        for k in tasks
    ]
    stops = runner.run("stops", s_units)
    from .stops import write_stops

    _count(summary, write_stops(stops, stage))
    summary.flags["infeasible_stops"] = summary.flags.get("infeasible_stops", 0) + sum(
        len(r.patterns) - r.n_feasible for r in stops)
    for r in stops:  # one line per approach, not per adhesion level
        bad = [a for a, p in zip(r.adhesion_kmh_s, r.patterns) if not p.feasible]
        if bad:
            first = next(p for p in r.patterns if not p.feasible)
            levels = f"{bad[0]:g}" if len(bad) == 1 else f"{bad[0]:g}…{bad[-1]:g}"
            summary.notes.append(
                f"{line.line_id}: no stopping pattern at {r.station_id} ({r.direction}, {r.train_type}, from "
                f"{r.origin}) for adhesion {levels} km/h/s ({len(bad)} of {len(r.patterns)} levels): {first.reason}")

    # closed loop: every scenario and mode of an interstation in one batch
    cp = job.closed_loop
    c_units = [
        Unit("closed_loop",
             digest(["closed_loop", code, u.key, [dataclasses.asdict(sc) for sc in cp.scenarios], list(cp.modes),
                     cp.horizon_s, cp.step_s]),
             u.label, _closed_loop_unit,
             (line, tab.train_type, tab.onboard(), cp.scenarios, list(cp.modes), cp.horizon_s, cp.step_s, tp.ds_m))
        for u, tab in zip(t_units, tables)
    ]
    loops = [r for batch in runner.run("closed_loop", c_units) for r in batch]
    from .closed_loop import write_closed_loop

    _count(summary, write_closed_loop(loops, stage))

    conflicts = None
    if job.conflicts.enabled and line.network is not None:
        conflicts = _conflicts_step(job, line, stage, runner, summary)
    _margins_step(job, line, stage, runner, summary,
                  [u.key for u in t_units] + [u.key for u in s_units] + [u.key for u in c_units], grid, conflicts)
    _bundles_step(job, line, stage, runner, summary, key)
    from .views import line_views  # inputs copy, train graph page

    line_views(job, line, stage, runner, summary)


def _count(summary: RunSummary, files: Iterable[Path]) -> None:
    """Add the rows of written dataset files to the summary, per dataset (the folder above ``line=``)."""
    import pyarrow.parquet as pq

    for f in map(Path, files):
        parts = f.parts
        name = next(parts[i - 1] for i, p in enumerate(parts) if p.startswith("line="))
        summary.rows[name] = summary.rows.get(name, 0) + pq.ParquetFile(f).metadata.num_rows


def _line_unit(runner: Runner, step: str, key: str, fn: Callable, *args):
    """A line-level unit: loaded from the cache when its key is there, else computed here."""
    return runner.run(step, [Unit(step, key, step, fn, args)])[0]


def _margins_unit(line, job_margins, types, stage, stops_levels, approach_m, ratios, eval_offset_m, ds_m, n_jobs):
    from .margins import MarginRule, compute_margins
    from .run_curve import SimSettings

    return compute_margins(
        line, rule=MarginRule.from_section(job_margins), train_types=types, tables_dir=stage, stops_dir=stage,
        closed_loop_dir=stage, ratios=ratios, adhesion_kmh_s=stops_levels, approach_m=approach_m,
        after_departure_m=eval_offset_m, conflicts=False, settings=SimSettings(ds_m=ds_m), n_jobs=n_jobs,
    )


def _margins_step(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary,
                  unit_keys: list[str], grid, conflicts) -> None:
    from .margins import write_margins
    from .report import write_html

    key = digest(["margins", code_digest(), line.source_digest, unit_keys, job.parameters()])
    n_jobs = 1 if job.parallel.backend == "dask" else job.parallel.n_jobs
    report = _line_unit(runner, "margins", key, _margins_unit, line, job.margins, _types(job, line), stage,
                        job.stops.adhesion_kmh_s, job.stops.approach_m, list(map(float, grid)),
                        job.tables.eval_offset_m, job.tables.ds_m, n_jobs)
    if conflicts is not None:
        report.conflicts, report.conflicts_note = conflicts, ""
    elif not job.conflicts.enabled:
        report.conflicts_note = "not checked ([conflicts] enabled = false in the job file)"
    else:
        report.conflicts_note = "the line database has no track network (nodes.parquet, edges.parquet)"
    _count(summary, write_margins(report, stage))
    write_html(report, line, stage / "report" / f"{line.line_id}_margins.html")
    summary.reports[line.line_id] = report
    for flag in ("infeasible", "tight", "unreachable"):  # legs flagged by the margin report
        summary.flags[flag] = summary.flags.get(flag, 0) + int(report.rows[flag].sum() if len(report.rows) else 0)


def _bundles_step(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary, key) -> None:
    """Signed bundles for every direction × train type, and the public key that verifies them."""
    from cryptography.hazmat.primitives import serialization

    from .bundle import build_line

    out = stage / "bundles"
    with runner.progress.step("bundles", 2 * len(_types(job, line))):
        infos = build_line(line, out, key, tables_dir=stage, stops_dir=stage, train_types=_types(job, line),
                           on_built=lambda info: runner.progress.advance("bundles"))
    pem = key.public_key().public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
    write_bytes_atomic(out / "signing_key.pub.pem", pem)
    summary.bundles += [Path(i.path).name for i in infos]


def _conflicts_unit(line, params):
    from .network import check_conflicts

    return check_conflicts(line, params)


def _conflicts_step(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary):
    """Route conflicts of the line's whole timetable; returns the conflicts table for the report."""
    from .network import write_conflicts

    params = {k: v for k, v in dataclasses.asdict(job.conflicts).items() if k != "enabled"}
    key = digest(["conflicts", code_digest(), line.source_digest, params, job.tables.ds_m])
    report = _line_unit(runner, "conflicts", key, _conflicts_unit, line, params)
    _count(summary, write_conflicts(report, stage))
    summary.flags["conflicts"] = summary.flags.get("conflicts", 0) + int(
        report.conflicts["conflict_id"].nunique() if len(report.conflicts) else 0)
    return report.conflicts


def _write_manifest(job: Job, lines, stage: Path, run_id: str, inputs: str, timings, summary: RunSummary) -> None:
    import platform

    import numpy
    import pyarrow

    manifest = {
        "run_id": run_id,
        "job": job.job.name,
        "inputs_digest": inputs,
        "code_digest": code_digest(),
        "software": {"planner": __version__, "python": platform.python_version(),
                     "numpy": numpy.__version__, "pyarrow": pyarrow.__version__},
        "lines": [{"line_id": ln.line_id, "path": Path(p).as_posix(), "source_digest": ln.source_digest}
                  for ln, p in zip(lines, job.job.lines)],
        "parameters": job.parameters(),
        "timings_s": dict(timings),
        "units_computed": dict(summary.computed),
        "units_reused": dict(summary.reused),
        "rows": dict(sorted(summary.rows.items())),
        "flags": dict(sorted(summary.flags.items())),
        "bundles": sorted(summary.bundles),
    }
    write_bytes_atomic(stage / "manifest.json", canonical_json(manifest) + b"\n")
    from .catalog import readme

    write_bytes_atomic(stage / "README.md", readme().encode())


__all__ = ["STEPS", "RunSummary", "code_digest", "interstation_inputs", "run_job"]
