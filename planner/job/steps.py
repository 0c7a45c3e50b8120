"""The nightly job's line steps after the closed loop: the margins, the bundles and the route conflicts.

Each step's unit (keyed by the digest of exactly what it depends on, as every unit of
:mod:`planner.job.pipeline`), the module-level functions its workers run, its datasets and
what it adds to the run's summary (rows, flags, bundles). :func:`planner.job.pipeline._run_line`
calls them in the line's order.
"""
from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

from planner.io.atomic import write_bytes_atomic
from planner.io.memory import give_back, then_give_back
from planner.job.config import Job
from planner.job.day import lifted_key, line_digest
from planner.job.publish import digest
from planner.job.units import Runner, Unit, code_digest
from planner.line.model import Line

if TYPE_CHECKING:
    from planner.job.pipeline import RunSummary


def result_params(job: Job) -> dict[str, Any]:
    """The job parameters that can change a result: all but where runs go, how many are kept, and the
    run's date and the operating day (they go into the inputs digest on their own)."""
    params = job.parameters()
    params.pop("day", None)
    params["job"] = {k: v for k, v in params["job"].items() if k not in ("keep_runs", "output_root", "run_date")}
    return params


def line_types(job: Job, line: Line) -> list[str]:
    return list(job.job.train_types) or [t.train_type for t in line.train_types]


def count_rows(summary: RunSummary, files: Iterable[Path]) -> None:
    """Add the rows of written dataset files to the summary, per dataset (the folder above ``line=``)."""
    import pyarrow.parquet as pq

    for f in map(Path, files):
        parts = f.parts
        name = next(parts[i - 1] for i, p in enumerate(parts) if p.startswith("line="))
        summary.rows[name] = summary.rows.get(name, 0) + pq.ParquetFile(f).metadata.num_rows


def line_unit(runner: Runner, step: str, key: str, fn: Callable, *args):
    """A line-level unit: loaded from the cache when its key is there, else computed here."""
    return runner.run(step, [Unit(step, key, step, fn, args)])[0]


def margins_unit(line, options, types, stage, n_jobs, given=None, lifted=None, closed_loop=None, memo=None):
    from planner.report.margins import compute_margins

    # conflicts come from their own step (conflicts_step); ``given``: the tables read beforehand;
    # ``closed_loop``: the closed loop's rows, being written to ``stage`` meanwhile; ``memo``: each leg group
    # a unit of its own in the work cache (planner.job.leg_memo)
    return compute_margins(line, **(options | {"conflicts": False}), train_types=types, tables_dir=stage,
                           stops_dir=stage, closed_loop_dir=stage, n_jobs=n_jobs, given=given, lifted=lifted,
                           closed_loop=closed_loop, memo=memo)


def margins_step(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary,
                  unit_keys: list[str], conflicts, given=None, lifted=None, closed_loop=None):
    """The line's margin report (cached as one unit), kept in ``summary.reports`` with its flags counted; its
    datasets are the caller's to write (:func:`planner.report.margin_datasets.write_margins`: the nightly job
    writes them on its writer thread while the legs' charts start)."""
    from planner.report.margins import margin_options

    key = digest(["margins", code_digest(), line_digest(line), lifted_key(lifted or {}), unit_keys,
                  result_params(job)])
    n_jobs = job.parallel.n_jobs  # the legs on the local workers, or on the run's Dask cluster (map_tasks)
    from planner.job.leg_memo import KIND, LegMemo

    memo = LegMemo(runner.cache.root, enabled=runner.cache.enabled)
    before = runner.computed.get("margins", 0)
    report = line_unit(runner, "margins", key, margins_unit, line, margin_options(job, line), line_types(job, line),
                        stage, n_jobs, given, lifted, closed_loop, memo)
    if runner.computed.get("margins", 0) > before and report.legs:  # made now: its legs are this run's units
        runner.computed[KIND] = runner.computed.get(KIND, 0) + report.legs["computed"]
        runner.reused[KIND] = runner.reused.get(KIND, 0) + report.legs["hits"]
        for kind, k, why in report.legs["rejected"]:
            runner.cache.rejected_elsewhere(kind, k, why)
    if conflicts is not None:
        report.conflicts, report.conflicts_note = conflicts, ""
    elif not job.conflicts.enabled:
        report.conflicts_note = "not checked ([conflicts] enabled = false in the job file)"
    else:
        report.conflicts_note = "the line database has no track network (nodes.parquet, edges.parquet)"
    # the page itself is written once, by job.views.run_views, with what changed since the last run on top
    # (its charts are drawn there: tens of milliseconds, less than sending the report to a worker)
    from planner.report.leg_flags import FLAGS

    summary.reports[line.line_id] = report
    for flag in FLAGS:  # legs the margin report flags, each flag its own card on the overview
        summary.flags[flag] = summary.flags.get(flag, 0) + int(report.rows[flag].sum() if len(report.rows) else 0)
    return report


def build_bundles(line: Line, out: Path, key_path: Path, release, stage: Path, types: list[str], day=None) -> list:
    """Every bundle of the line for the operating day ``day`` (:func:`planner.job.day.bundle_day`; runs on a
    worker: module level, the key read from its file there)."""
    from planner.bundle.container import build_line

    give_back()  # what a unit before it on this worker freed (a line's conflicts, once its result was sent)
    return then_give_back(build_line, line, out, key_path, release=release, tables_dir=stage, stops_dir=stage,
                          train_types=types, day=day)  # and the pages of the line's tables, for the units after it


def write_stamped(stamp: tuple | None, fn, *args):
    """Worker: ``fn(*args)``, a step's datasets written into the staged run, stamped with the run's id and date
    (:func:`planner.io.parquet.current_stamp` of the job's process) and flushed with the rest of the run when
    it is published, as the job's own writes are; the worker's pages given back afterwards."""
    from planner.io.atomic import deferred_fsync
    from planner.io.parquet import stamping

    give_back()  # what a unit before it on this worker freed
    if stamp is None:
        return then_give_back(fn, *args)
    with stamping(*stamp), deferred_fsync():
        return then_give_back(fn, *args)


def start_stops_written(job: Job, stage: Path, summary: RunSummary, stops: list):
    """Write the line's stopping-pattern datasets on a worker (their samples, a partition at a time, were the
    job process's largest passing use of memory on a line ten times the sample); ``.result()``: the files."""
    from planner.datasets.stops import write_stops
    from planner.io.parallel import background
    from planner.io.parquet import current_stamp

    b = background(write_stamped, (current_stamp(), write_stops, stops, stage), name=job.parallel.backend,
                   n_jobs=job.parallel.n_jobs)
    summary.pending.append(b)
    return b


def start_bundles(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary, key_path: Path,
                   bday=None):
    """Start the line's bundles on a worker; the step's time runs from here to when they are written."""
    from planner.io.parallel import background

    runner.progress.start("bundles", 2 * len(line_types(job, line)))
    b = background(build_bundles, (line, stage / "bundles", key_path, summary.release, stage, line_types(job, line), bday),
                   name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
    summary.pending.append(b)
    return b


def bundles_step(stage: Path, runner: Runner, summary: RunSummary, key, bundles) -> None:
    """Signed bundles for every direction × train type (:func:`start_bundles`), and the public key that
    verifies them."""
    from cryptography.hazmat.primitives import serialization

    out = stage / "bundles"
    infos = bundles.result()
    runner.progress.advance("bundles", len(infos))
    runner.progress.finish("bundles")
    pem = key.public_key().public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
    write_bytes_atomic(out / "signing_key.pub.pem", pem)
    summary.bundles += [Path(i.path).name for i in infos]


def conflicts_unit(line, params, lifted=None, job=None):
    from planner.datasets.conflicts import conflict_report
    from planner.network.arrivals import train_curves
    from planner.network.check import check_timetable

    def compute():
        check = check_timetable(line, params, curves=train_curves(line, lifted))
        if job is None:
            return conflict_report(check), None
        from planner.job.robustness import day_as_it_runs

        # the day as it will run, on this worker from the check it has (chunks of days one after the other:
        # the other workers are busy with the line's other units)
        runs = day_as_it_runs(check, line, job, n_jobs=1)
        directions = {t.train_id: t.direction for t in check.trains}
        return conflict_report(check, runs[0].windows), (directions, *runs)

    # the worker's pages of the whole line's run curves given back, for the units after it
    return then_give_back(compute)


def conflicts_unit_of(job: Job, line: Line, stage: Path, lifted=None) -> Unit:
    """The unit of the line's route conflicts (its whole timetable; each train's run with the restrictions
    that apply to it: ``lifted``, :func:`planner.job.day.lifted_restrictions`) and of the day as it will run
    (:func:`planner.job.robustness.day_as_it_runs`: the predicted day, and the simulated days of
    ``[robustness]``). The job keeps its conflicts table, the robustness summary and the datasets' files: the
    datasets are written into ``stage`` where they are made (:func:`conflicts_written`), so its occupation
    windows (tens of megabytes on a line ten times the sample) never come to the job process."""
    from planner.io.parquet import current_stamp
    from planner.job.robustness import key_of

    params = {k: v for k, v in dataclasses.asdict(job.conflicts).items() if k != "enabled"}
    key = digest(["conflicts", code_digest(), line_digest(line), lifted_key(lifted or {}), params, job.tables.ds_m,
                  key_of(job), job.day.day])
    return Unit("conflicts", key, "conflicts", conflicts_unit, (line, params, lifted, job),
                after=functools.partial(write_stamped, current_stamp(), conflicts_written, stage, line))


def conflicts_written(stage: Path, line, result) -> tuple:
    """Write a conflict report's datasets, and those of the day as it runs, into the staged run; (its conflicts
    table, the files written, the reasons of the trains it could not route, the robustness summary)."""
    from planner.datasets.conflicts import write_conflicts
    from planner.datasets.delays import write_day

    report, runs = result
    reasons = list(report.unrouted["reason"]) if report.unrouted is not None else []
    files = [str(f) for f in write_conflicts(report, stage)]
    summary = None
    if runs is not None:
        directions, pday, stats, summary, held = runs
        files += [str(f) for f in write_day(pday, stats, held, line, directions, stage)[0]]
    return report.conflicts, files, reasons, summary


def conflicts_step(summary: RunSummary, kept: tuple, line_id: str = ""):
    """Count the route conflicts found, the trains the network cannot carry (a flag and a note each: the night
    goes on without them) and their datasets' rows (``kept``: :func:`conflicts_written` of the unit of
    :func:`conflicts_unit_of`); returns the conflicts table for the report."""
    conflicts, files, unrouted, robustness = kept
    count_rows(summary, files)
    if robustness is not None:
        summary.robustness[line_id] = robustness  # the robustness page's head (job.views)
    summary.flags["conflicts"] = summary.flags.get("conflicts", 0) + int(
        conflicts["conflict_id"].nunique() if len(conflicts) else 0)
    summary.flags["unrouted"] = summary.flags.get("unrouted", 0) + len(unrouted)
    summary.notes += [f"not routed, left out of the conflict check: {why}" for why in unrouted]
    return conflicts
