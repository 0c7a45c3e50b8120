"""The nightly job: validate → tables → stopping patterns → closed loop → margins → bundles → conflicts → graph
→ changes → overview → publish.

One call, :func:`run_job`, regenerates everything a job file names and
publishes it atomically (:mod:`planner.job.publish`). Work is split into *units*
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

What does not depend on a step runs beside it, so that both cores stay busy:
the workers start while the lines are read; the stopping patterns share the
tables' pass of the workers, and the closed loop (with the line's conflicts, a
unit per section of the line) starts as soon as the last table is in, behind the
stops' last units; every unit's result is stored in the cache by the worker that
made it, and the tables and stopping patterns never come to this process: it
keeps their flags, a worker writes their datasets from the cache (the tables then
read back for the margins), and each closed-loop unit reads its leg's tables
there; the train graph's trajectories and the bundles (one after another on one worker,
each verified for the overview there once written, taken at the line's end) start
on the workers when the closed loop ends, while the writer thread writes the closed
loop and the margins take its rows from memory; the legs' speed–distance charts start
as soon as the margins are computed, and the train graph page is written
on a worker while the main process writes the tables page, and the writer thread draws
the margin report page (while this process mostly waits on the workers for the tables'
pages and the charts); the chart pages are written on the workers
while the line's bundles are finished. This process is the night's serial path (one interpreter
lock beside two busy workers), so it leaves to a worker or the writer thread
what it can.
A step's time in the summary is the sum of its intervals, so the steps add up
to more than the run's wall time.
"""
from __future__ import annotations

import dataclasses
import os
import shutil
from contextlib import ExitStack
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

from planner.io.atomic import deferred_fsync, in_this_context
from planner.io.parquet import place_in_run
from planner.io.memory import give_back, then_give_back
from planner.errors import JobError, PlannerError
from planner.job.config import Job
from planner.job.day import day_digest, plan_day, resolve_day
from planner.line.operating_day import day_over
from planner.line.model import DIRECTIONS, Line
from planner.job.cache import Cache
from planner.job.keys import signing_key_path
from planner.job.units import (
    Progress,
    Runner,
    Stored,
    Unit,
    _closed_loop_unit,
    _kill_point,
    _stops_unit,
    _tables_unit,
    code_digest,
    interstation_digest,
    interstation_inputs,
    stops_key,
    warm_worker,
)
from planner.job.steps import (
    bundles_step,
    closed_loop_written,
    conflicts_step,
    conflicts_units,
    line_section_inputs,
    count_rows,
    line_types,
    loops_seen,
    margins_step,
    result_params,
    partition_keys,
    start_written,
    stops_seen,
    tables_seen,
    start_bundles,
    write_staged,
)
from planner.job.publish import (
    clean_stale_staging,
    digest,
    job_lock,
    latest_run,
    manifest_head,
    next_run_id,
    output_root_errors,
    publish,
    staging_dir,
    write_manifest,
)

STEPS = ("validate", "tables", "stops", "closed_loop", "margins", "bundles", "conflicts", "graph", "changes",
         "overview", "publish")


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
    warnings: list[str] = field(default_factory=list)
    release: Any = None
    """The :class:`planner.bundle.container.Release` the run's bundles were issued with."""
    run_date: str = ""
    """The run's date, YYYY-MM-DD (a partition folder of every dataset, run_date=; the pages show it)."""
    wall_s: float = 0.0
    """Wall time of the whole run [s]: less than the steps' sum, as some steps run beside others."""
    reports: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)
    """Margin report of each line (kept for :func:`planner.job.views.run_views`, which puts the changes on top)."""
    chart_pages: list = field(default_factory=list, repr=False, compare=False)
    """Each line's speed–distance chart pages, being drawn (:class:`planner.job.train_views.ChartPages`;
    written by :func:`planner.job.views.run_views`)."""
    pending: list = field(default_factory=list, repr=False, compare=False)
    """Every :class:`planner.io.parallel.Background` of the run (waited for when the run fails)."""
    robustness: dict = field(default_factory=dict, repr=False, compare=False)
    """Each line's summary of the day as it runs (:func:`planner.job.robustness.day_as_it_runs`), for its page."""
    robustness_shares: dict = field(default_factory=dict, repr=False, compare=False)
    """Each line's robustness page shares being made, cache root, keys (:func:`planner.job.views.start_robustness`)."""
    previous: Any = field(default=None, repr=False, compare=False)
    """The previous run's dataset files that this run may reuse (:func:`planner.job.made.previous`)."""
    made: dict = field(default_factory=dict, repr=False, compare=False)
    """The record of the dataset files made from stored results, for the manifest (:mod:`planner.job.made`)."""
    bundle_inputs: dict = field(default_factory=dict, repr=False, compare=False)
    """Each bundle's inputs key, for the manifest (:mod:`planner.job.bundle_reuse`)."""
    graph_pages: list = field(default_factory=list, repr=False, compare=False)
    """Each line's train graph page, being written on a worker (:func:`planner.job.views.graph_written`; taken by
    :func:`planner.job.views.run_views`)."""
    bundle_rows: list = field(default_factory=list, repr=False, compare=False)
    """(file name, the overview's row) of each bundle of the run, verified on the worker that built it
    (:func:`planner.job.steps.build_bundles`)."""
    head: dict = field(default_factory=dict, repr=False, compare=False)
    """The manifest's fields known when the run starts (:func:`manifest_head`): what a line's comparison with the
    previous run reads of this run's manifest, before it is written."""
    base_dir: Path | None = None
    """The folder of the run this one is compared with: the latest published when it started (the output root is
    locked)."""
    margin_pages: dict = field(default_factory=dict, repr=False, compare=False)
    """Each line's margin report page but its changes (:func:`planner.job.views.margin_page`)."""
    comparing: dict = field(default_factory=dict, repr=False, compare=False)
    """Each line's comparison with :attr:`base`, being made on a worker (:func:`planner.job.views.start_compare`)."""
    bundle_changes: dict = field(default_factory=dict, repr=False, compare=False)
    """Each line's bundles compared with :attr:`base`'s, where they were built: (the rows, a failure or "")."""

    @property
    def base(self) -> str | None:
        """The id of the run this one is compared with (:attr:`base_dir`), or None."""
        return self.base_dir.name if self.base_dir is not None else None


def _renewal_due(last_manifest: dict, now_s: int) -> bool:
    """The published bundles have used half of their validity (or the run has no release record)."""
    from planner.bundle.manifest import parse_time

    rel = last_manifest.get("bundles_release")
    try:
        built, expires = parse_time(rel["built_at"]), parse_time(rel["expires"])
    except (TypeError, KeyError, PlannerError):
        return True
    return now_s >= built + (expires - built) // 2


def _inputs_digest(job: Job, lines: Sequence[Line | str], key_id: str, run_date: str = "") -> str:
    """Digest of everything a run depends on: code, parameters, line databases (each a Line or its
    :func:`planner.line.loader.source_digest`), signing key (its public id), and the run's date (a
    partition folder of every dataset, so one run id always has one date)."""
    return digest({"code": code_digest(), "params": result_params(job),
                   "lines": [ln if isinstance(ln, str) else ln.source_digest for ln in lines],
                   "key": key_id, "run_date": run_date, "day": day_digest(job)})


def _current_run(root: Path, inputs: str) -> tuple[str, dict] | None:
    """The latest run and its manifest when it was made from exactly ``inputs`` (its bundles may be due
    for renewal: the caller checks), else None."""
    last = latest_run(root)
    if not (last and last.endswith(inputs[:10]) and (root / last / "manifest.json").is_file()):
        return None
    import json

    try:
        m = json.loads((root / last / "manifest.json").read_text())
    except ValueError:  # a damaged manifest proves nothing: run again
        return None
    return (last, m) if isinstance(m, dict) and m.get("inputs_digest") == inputs else None


def _probably_current(job: Job, root: Path, run_date: str, built_at_s: int, use_cache: bool) -> bool:
    """Whether the latest run already has this job's inputs and needs no renewal, judged from the line
    folders' bytes alone (no validation, no key made): cheap, and asked before the workers start, so
    that a run with nothing to do starts none. False when unsure; the check after validation decides."""
    from planner.bundle.signing import load_private_key, public_key_id
    from planner.line.loader import source_digest

    if not use_cache:
        return False
    configured = job.bundles.signing_key or os.environ.get("PLANNER_SIGNING_KEY")
    if not configured and not (root / ".dev-key" / "signing_key.pem").is_file():
        return False  # a development key would be made: a first run
    try:
        key = load_private_key(signing_key_path(job, [])[0])
        inputs = _inputs_digest(job, [source_digest(job.resolve(p)) for p in job.job.lines],
                                public_key_id(key.public_key()), run_date)
    except (PlannerError, OSError, ValueError):
        return False
    found = _current_run(root, inputs)
    return found is not None and not _renewal_due(found[1], built_at_s)


def resolve_run_date(job: Job) -> str:
    """The run's date, YYYY-MM-DD: ``[job] run_date``, else today's UTC date (read once, at the start of the run)."""
    if job.job.run_date:
        return job.job.run_date
    import datetime

    return datetime.datetime.now(datetime.timezone.utc).date().isoformat()


def _distinct_line_ids(job: Job, lines) -> None:
    """Folders may have any name, but line ids name the outputs: two lines may not share one."""
    seen: dict[str, str] = {}
    for p, line in zip(job.job.lines, lines):
        if line.line_id in seen:
            raise JobError(f"job lines {seen[line.line_id]!r} and {p!r} both hold line_id {line.line_id!r}; "
                           f"outputs are named by line_id, so give each line its own id (line.parquet)")
        seen[line.line_id] = p


def run_job(job: Job, *, show_progress: bool = True, use_cache: bool = True) -> RunSummary:
    """Run a whole job and publish it; raise a :class:`PlannerError` (latest untouched) on failure.

    ``use_cache=False`` (``planner run --no-cache``) trusts no cache entry: every
    unit is recomputed, the fresh results replace the entries, and a new run is
    published even when nothing changed since ``latest``.
    """
    import time

    t0 = time.perf_counter()
    root = job.resolve(job.job.output_root)
    with output_root_errors(root):
        summary = _run_job(job, root, show_progress, use_cache)
    summary.wall_s = round(time.perf_counter() - t0, 3)
    return summary


def _run_job(job: Job, root: Path, show_progress: bool, use_cache: bool) -> RunSummary:
    from planner.line.loader import load_line

    from planner.bundle.manifest import build_time_s
    from planner.io.dask_pool import dask_run
    from planner.io.parallel import for_output_root, started_workers

    run_date = resolve_run_date(job)  # the only clock read: before any computation, part of the inputs digest
    job = resolve_day(job)  # [day] day, else the next operating day by the clock, read here at the start too
    built_at_s = build_time_s()  # the run's build time: $SOURCE_DATE_EPOCH (reproducible rebuilds) or now
    # the staged run's files are flushed to disk once, by publish(), before it becomes visible
    with job_lock(root), deferred_fsync(), for_output_root(root), ExitStack() as stack:
        current = _probably_current(job, root, run_date, built_at_s, use_cache)
        if job.parallel.backend == "dask" and not current:  # one client for the whole run (dask_run)
            stack.enter_context(dask_run(job.parallel.scheduler, job.parallel.dask_lost_timeout_s))
        stack.enter_context(started_workers(warm_worker, name=job.parallel.backend,
                                            n_jobs=1 if current else job.parallel.n_jobs))
        # the workers start (and import what the units and charts need) while this process reads the lines;
        # the first step's units queue behind that, and leaving the context takes the handles
        clean_stale_staging(root)
        cache = Cache(root / ".cache", enabled=use_cache)
        with Progress(show_progress) as prog:
            with prog.step("validate", len(job.job.lines)):
                lines = [load_line(job.resolve(p)) for p in job.job.lines]
                _distinct_line_ids(job, lines)
                for line in lines:
                    for t in job.job.train_types:
                        line.train_type(t)
            from planner.bundle.manifest import Release
            from planner.bundle.signing import load_private_key, public_key_id

            notes: list[str] = [f"{p}: {n}; `planner line upgrade {p}` rewrites the folder"
                                for p, ln in zip(job.job.lines, lines) for n in ln.upgrade_notes]
            # the day's feeds validated against their lines before any unit; each line as it is that day
            day, lines, bundle_days, lifted = plan_day(job, lines, notes)
            key_path, development = signing_key_path(job, notes)
            key = load_private_key(key_path)
            release = Release.issue(built_at_s, valid_days=job.bundles.valid_days, development=development)
            over = day_over(day, built_at_s)  # a warning of the run (stderr; the overview says it from the manifest)
            inputs = _inputs_digest(job, lines, public_key_id(key.public_key()), run_date)
            found = _current_run(root, inputs) if use_cache else None
            if found is not None:
                last, m = found
                if not _renewal_due(m, release.built_at_s):
                    return RunSummary(last, root / last, True, timings=prog.timings,
                                      notes=notes + [f"nothing changed since run {last}: it stays the latest"])
                notes.append(f"nothing changed since run {last}, but its bundles are past half their validity: "
                             "re-issued")
            run_id = next_run_id(root, inputs)
            stage = staging_dir(root, run_id)
            summary = RunSummary(run_id, None, False, notes=notes, run_date=run_date, warnings=[over] if over else [])
            summary.head = manifest_head(job, lines, run_id, inputs, run_date, day)
            latest = latest_run(root)  # the output root is locked: still the latest when the run publishes
            summary.base_dir = root / latest if latest is not None else None
            runner = Runner(job, cache, prog)
            summary.release = release
            from planner.job.made import previous

            summary.previous = previous(root, use_cache)  # its files no edit touched are this run's (job.made)
            try:
                # a writer thread: a step's datasets are written while the workers compute the next
                with ThreadPoolExecutor(max_workers=1, thread_name_prefix="planner-write") as writes:
                    for line, bday, off in zip(lines, bundle_days, lifted):
                        _run_line(job, line, stage, runner, summary, key, key_path, writes, bday, off,
                                  {"operating_day": day})
                summary.computed, summary.reused = runner.computed, runner.reused
                if cache.rejected:  # once per run, with the count
                    summary.warnings.append(cache.rejected_note())
                write_manifest(stage, prog.timings, summary)
                from planner.job.views import run_views  # changes since the last run, overview page

                run_views(job, lines, stage, root, prog, summary)  # takes the speed charts drawn meanwhile
                # the run's id and date are its datasets' top partition folders, not columns in their files: a file's
                # bytes depend on its rows alone (a rename per line and dataset, nothing rewritten)
                place_in_run(stage, run_id, run_date)
            except BaseException:
                for pending in summary.pending:  # work on a worker: let it finish first
                    pending.discard()
                shutil.rmtree(stage, ignore_errors=True)  # a failed run leaves nothing in the output root
                raise
            _kill_point()
            with prog.step("publish"):
                summary.run_dir = publish(root, stage, run_id, job.job.keep_runs)
            summary.timings = dict(prog.timings)
    return summary


def _on_writer(writes: ThreadPoolExecutor, fn: Callable, *args):
    """Start ``fn(*args)`` on the run's writer thread (a step's datasets written, or read back, while
    the workers compute the next step: Arrow works without the GIL); the future gives the result. In
    this thread's context (:func:`planner.io.atomic.in_this_context`), so the staged run's deferred flush
    holds there too. The pages the thread's Arrow work freed are given back after each call
    (:func:`planner.io.memory.give_back`): the whole line's tables pass through it beside the closed loop."""
    return writes.submit(in_this_context(then_give_back), fn, *args)


def _run_line(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary, key, key_path: Path,
              writes: ThreadPoolExecutor, bday=None, lifted=None, verify: dict | None = None) -> None:
    """One line's units; ``lifted``: the restrictions lifted per train (:func:`planner.job.day.lifted_restrictions`),
    for the per-train units (margins, conflicts, train graph). ``verify``: what of the manifest the overview's
    verification of the bundles reads (the operating day); each bundle is verified on the worker that built it,
    once written (:attr:`RunSummary.bundle_rows`)."""
    from planner.stopping.sweep import adhesion_levels
    from planner.line.units import KMH, KMH_S

    tp, code = job.tables, code_digest()
    types = line_types(job, line)
    tasks = [(t, d, a.station_id, b.station_id) for t in types for d in DIRECTIONS for a, b in line.interstations(d)]
    unit_in = {k: interstation_digest(line, k[0], k[2], k[3]) for k in tasks}
    # each unit ships only the slice of the line it can see (the slice its key digests), so what a
    # parallel task costs to send does not grow with the line
    windows = {k: line.window(k[2], k[3], k[0]) for k in tasks}

    # tables; the floor of each leg's grid (ratio × the train's highest maximum on the leg = min_target_kmh) is
    # made by its unit from its slice of the line, which its key digests with the grid's settings
    ratios = (tp.ratios, tp.min_target_kmh * KMH)
    t_units = [
        Unit("tables", digest(["tables", code, unit_in[k], dataclasses.asdict(tp)]),
             f"{k[0]} {k[2]}->{k[3]}", _tables_unit,
             (windows[k], k[0], k[2], k[3], ratios, tp.eval_offset_m, tp.ds_m, tp.eval_interval_m,
              tp.eval_auto_s), after=tables_seen)  # the job keeps the flags; the tables stay in the cache
        for k in tasks
    ]
    # stopping patterns, one unit per arrival
    sp = job.stops
    levels = adhesion_levels(sp.adhesion_kmh_s)
    adh_ms2 = [a * KMH_S for a in levels]
    s_units = [
        Unit("stops", stops_key(job, line, k[0], k[2], k[3]),
             f"{k[0]} {k[3]}", _stops_unit, (windows[k], k[0], k[2], k[3], adh_ms2, sp.approach_m, tp.ds_m),
             after=stops_seen)  # the job keeps the verdicts; the patterns are written from the cache
        for k in tasks
    ]
    # closed loop: every scenario and mode of an interstation in one batch; the line's conflicts depend
    # on the line alone, so they run beside it (first: the longest unit; planned below, once the tables run)
    side: list = []
    checks_conflicts = job.conflicts.enabled and line.network is not None
    cp = job.closed_loop
    ahead: dict[str, Any] = {}

    root = str(runner.cache.root)

    def tables_in() -> None:
        """Every table of the line is in (stored): its closed loop (and the line's conflicts) start on the workers
        behind the stops' last units, each closed-loop unit reading its leg's tables from the cache, and the
        tables' datasets are written on a worker from the cache while the stops come in (then read back for the
        margins). No table passes through this process."""
        ahead["c_units"] = [
            Unit("closed_loop",
                 digest(["closed_loop", code, u.key, [dataclasses.asdict(sc) for sc in cp.scenarios],
                         list(cp.modes), cp.horizon_s, cp.step_s]),
                 u.label, _closed_loop_unit,
                 (windows[k], k[0], Stored(root, "tables", u.key), cp.scenarios, list(cp.modes), cp.horizon_s,
                  cp.step_s, tp.ds_m), after=loops_seen)  # the job keeps the flags; the runs stay in the cache
            for k, u in zip(tasks, t_units)
        ]
        ahead["loop"] = runner.start_steps(side + [("closed_loop", ahead["c_units"])], wait=False)
        summary.pending.append(ahead["loop"])  # a run failing meanwhile waits for it (and caches what it did)
        ahead["tables_written"] = start_written(job, stage, summary, runner.cache, "tables",
                                                partition_keys(line.line_id, tasks, t_units))

    # the stops do not depend on the tables: one pass of the workers, the stops' short units filling the
    # tables' last ones; the closed loop starts as soon as the last table is in (tables_in), so no worker
    # waits between the two passes
    pass1 = runner.start_steps([("tables", t_units), ("stops", s_units)], wait=False)
    # meanwhile (5 s at 100x), the line's sections (trains sharing no track with others'): the units of its conflicts,
    # its day as it runs and its train graph are per section, each keyed by its stretch
    try:
        sections = line_section_inputs(job, line, lifted, runner.cache)
        if checks_conflicts:
            side.insert(0, ("conflicts", conflicts_units(job, line, stage, sections, summary.previous)))
        from planner.report.margin_legs import looked_up_by_leg

        by_leg = looked_up_by_leg(line, types, lifted)  # the closed loop's times per leg, meanwhile too
    except BaseException:
        pass1.discard()  # the units started are let finish (and cached) before the run fails
        raise
    tables_left = len(t_units)

    def arrived(g: int, _i: int, _res) -> None:
        nonlocal tables_left
        if g == 0:
            tables_left -= 1
            if not tables_left:
                tables_in()

    tables, stops = pass1.results(each=arrived)
    if "loop" not in ahead:  # a line without interstations
        tables_in()
    stops_written = start_written(job, stage, summary, runner.cache, "stops", partition_keys(line.line_id, tasks, s_units))
    tables_files, made = ahead["tables_written"].result()
    summary.made.update(made)
    summary.pending.remove(ahead.pop("tables_written"))
    # each margin leg reads its tables from the cache on the worker that computes it (the vehicle's view of them,
    # the numbers their datasets hold): the line's tables are never read back whole, nor sent to a cluster
    given = ({(k[1], k[0], k[2], k[3]): Stored(root, "tables", u.key) for k, u in zip(tasks, t_units)}, {})
    summary.flags["infeasible_stops"] = summary.flags.get("infeasible_stops", 0) + sum(r.infeasible for r in stops)
    no_stop = [r.no_stop for r in stops if r.no_stop is not None]  # legs flagged no_stop: record_verdicts notes them
    for r in stops:  # every level stops: what the sweep still says (an approach moved back from a TASC beacon)
        summary.notes += [f"{line.line_id}: {w}" for w in r.warnings]

    # what the rest of the line needs of the tables and stops (the verdicts: record_verdicts); the rest is let
    # go before the closed loop's results come in, so that the whole line's results are not held through the
    # later steps
    flagged_tables = [r for r in tables if r.flags]
    c_units = ahead.pop("c_units")
    del tables, stops, pass1  # the started pass holds every result and unit (its windows) too
    loop = ahead.pop("loop")
    *side_results, loop_batches = loop.results()
    summary.pending.remove(loop)  # taken: nothing left to wait for on a failure, and its results are let go
    del loop
    got = {step: res for (step, _), res in zip(side, side_results)}
    unit_keys = [u.key for u in t_units] + [u.key for u in s_units] + [u.key for u in c_units]
    flagged = [flagged_tables, no_stop, [f for batch in loop_batches for f in batch]]
    # the closed loop's datasets are written on a worker from the cache, which makes there what the margins read of
    # them (the errors at the timetable's times, the worst per leg): the runs never come to this process
    from planner.io.parallel import background
    from planner.io.atomic import deferring
    from planner.report.margins import margin_options

    loop_groups = partition_keys(line.line_id, tasks, c_units)
    leg_of = {u.key: (k[1], k[0], k[2], k[3]) for k, u in zip(tasks, c_units)}  # (direction, type, from, to)
    loop_times = [{leg_of[k]: by_leg[leg_of[k]] for k in keys if leg_of[k] in by_leg} for _, _, keys in loop_groups]
    loops_written = background(write_staged, (deferring(), closed_loop_written, root, line.line_id, loop_groups,
                                               stage, margin_options(job, line)["rule"], loop_times,
                                               summary.previous),
                               name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
    summary.pending.append(loops_written)
    del side_results, loop_batches, t_units, s_units, c_units, windows
    # the train graph's trajectories (stored for the page's worker) start next; the bundles need the tables and
    # stops datasets only: built from when they are written, beside the margins (the worker loads the key from
    # its file; both datasets are counted, so written, before)
    from planner.job.views import graph_units, line_views, page_units, start_robustness

    g_units = graph_units(job, sections)
    graph = runner.start("graph", g_units)
    from planner.job.train_views import start_charts, timetable_parts

    tt_parts = timetable_parts(sections, dict(side).get("conflicts"))  # the tables' units, a section each
    # the train graph page's shares, a section each, started once the trajectories they draw are stored
    p_units = page_units(stage, root, sections, g_units, dict(side).get("conflicts"))
    del sections
    summary.pending.append(graph)
    count_rows(summary, tables_files)
    stops_files, made = stops_written.result()
    summary.made.update(made)
    count_rows(summary, stops_files)
    summary.pending.remove(stops_written)
    bundles = start_bundles(job, line, stage, runner, summary, key, key_path, bday, verify)  # taken last
    give_back()  # the pages of what was let go (planner.io.memory)

    conflicts = None
    if checks_conflicts:
        conflicts = conflicts_step(summary, got.pop("conflicts"), line, stage)
        start_robustness(runner, summary, line.line_id, stage, tt_parts)  # the robustness page's shares
    loop_files, loop_facts, made, rejected = loops_written.result()
    summary.made.update(made)
    for kind, entry, why in rejected:  # facts of a part whose entry was not trusted: made again from its rows
        runner.cache.rejected_elsewhere(kind, entry, why)
    summary.pending.remove(loops_written)
    count_rows(summary, loop_files)
    report = margins_step(job, line, stage, runner, summary, unit_keys, conflicts, given, lifted, loop_facts)
    del given, loop_facts  # the tables' references and what the margins read of the closed loop
    # the legs' speed–distance charts start on the workers now (their pages are written last), while the margins'
    # datasets are written on the writer thread and this process writes the line's pages
    from planner.job.day import window
    from planner.report.margin_datasets import write_margins

    charts = start_charts(job, line, stage, report, runner, summary.run_id,
                          window(job).record() if job.day.day else None, summary.run_date)
    summary.pending.append(charts)
    margins_written = _on_writer(writes, write_margins, report, stage)
    give_back()
    from planner.job.verdicts import record_verdicts

    record_verdicts(line.line_id, summary, *flagged, report)

    count_rows(summary, margins_written.result())  # the train graph page reads the margin totals
    from planner.job.views import copy_inputs, start_compare

    copy_inputs(line, stage)  # the run's copy of the line database, which the comparison reads
    start_compare(job, line, stage, summary)  # with the previous run, on a worker: its margins are written
    graph.results()  # every section's trajectories stored: the page's units read them (views.page_units)
    summary.pending.remove(graph)
    del graph, g_units
    shares = runner.start("graph", p_units)  # made while the tables are, then put together (views.graph_written)
    summary.pending.append(shares)
    from planner.job.views import margin_page

    # the margin report page (pure Python, ~5 s at 100x) drawn on the writer thread while this process waits on the
    # workers for the tables' pages and the charts in line_views: neither writes what the other reads
    page = _on_writer(writes, margin_page, line, stage, summary)
    line_views(job, line, stage, runner, summary, (shares, [u.key for u in p_units]), charts, bday, tt_parts)
    page.result()
    for pages in summary.chart_pages[-1:]:  # the line's chart pages written while its bundles are finished
        pages.start()
    bundles_step(runner, summary, line.line_id, bundles)


__all__ = ["STEPS", "RunSummary", "code_digest", "interstation_inputs", "run_job"]
