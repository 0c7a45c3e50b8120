"""The nightly job's line steps after the closed loop: the margins, the bundles and the route conflicts.

Each step's unit (keyed by the digest of exactly what it depends on, as every unit of
:mod:`planner.job.pipeline`), the module-level functions its workers run, its datasets and
what it adds to the run's summary (rows, flags, bundles). :func:`planner.job.pipeline._run_line`
calls them in the line's order.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable

from planner.io.atomic import write_bytes_atomic
from planner.io.memory import give_back, then_give_back
from planner.job.config import Job
from planner.job.day import lifted_key, line_digest
from planner.job.publish import digest
from planner.job.units import Placed, Runner, Unit, code_digest, kept_beside
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
        # the footer alone: read_metadata is ~2x as fast as opening a ParquetFile (0.16 against 0.38 ms a file: 4,500
        # files on the 100x line)
        summary.rows[name] = summary.rows.get(name, 0) + pq.read_metadata(f).num_rows


def line_unit(runner: Runner, step: str, key: str, fn: Callable, *args):
    """A line-level unit: loaded from the cache when its key is there, else computed here."""
    return runner.run(step, [Unit(step, key, step, fn, args)])[0]


def margins_unit(line, options, types, stage, n_jobs, given=None, lifted=None, closed_loop=None, memo=None):
    from planner.report.margins import compute_margins

    # conflicts come from their own step (conflicts_step); ``given``: the tables (or their stored results);
    # ``closed_loop``: what the margins read of the closed loop, made where it was written; ``memo``: each leg group
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
    from planner.job.leg_memo import LegUnits

    # each leg group a unit of the run (stored and read back on the workers, counted with the run's units)
    report = line_unit(runner, "margins", key, margins_unit, line, margin_options(job, line), line_types(job, line),
                        stage, n_jobs, given, lifted, closed_loop, LegUnits(runner))
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


def build_bundles(line: Line, out: Path, key_path: Path, release, stage: Path, types: list[str], day=None,
                  reuse=None, verify: dict | None = None, compare: tuple | None = None
                  ) -> tuple[list, dict, list, tuple]:
    """Every bundle of the line for the operating day ``day``
    (:func:`planner.job.day.bundle_day`; runs on a worker: module level, the key read from its file there);
    ``reuse``: a :class:`planner.job.bundle_reuse.BundleReuse`, the steps' tables of a bundle whose datasets did not
    change taken from the previous run's; ``verify``: the run's operating day (``{"operating_day": …}``), at whose
    start each bundle, once written, is read back and verified as a vehicle would for the overview
    (:func:`planner.pages.overview.bundle_row`, with the public key written beside the bundles before);
    ``compare``: the previous run's folder and this run's id, whose bundles the line's are then compared with
    (:func:`planner.job.views.compare_bundles`: the bundles' bytes are read where they were written, while the job
    process writes the line's pages). Returns (the bundles, each one's inputs key for the manifest, the overview's
    row of each, the comparison's rows and failure)."""
    from planner.bundle.container import build_line

    give_back()  # what a unit before it on this worker freed (a line's conflicts, once its result was sent)
    infos = then_give_back(build_line, line, out, key_path, release=release, tables_dir=stage, stops_dir=stage,
                           train_types=types, day=day, reused=reuse)  # and the pages of the line's tables after it
    rows = []
    if verify is not None:
        from planner.pages.overview import bundle_row

        at_s = (verify.get("operating_day") or {}).get("start_utc_s")
        rows = [then_give_back(bundle_row, Path(i.path), out / "signing_key.pub.pem", at_s) for i in infos]
    changes: tuple = ([], "")
    if compare is not None:
        from planner.job.views import compare_bundles

        base_dir, run_id = compare
        changes = then_give_back(compare_bundles, line.line_id, Path(base_dir), Path(stage), run_id)
    return infos, dict(reuse.keys) if reuse is not None else {}, rows, changes


def write_staged(deferred: bool, fn, *args):
    """Worker: ``fn(*args)``, a step's datasets written into the staged run and, when ``deferred`` (the job's
    :func:`planner.io.atomic.deferring`), flushed with the rest of the run when it is published, as the job's own
    writes are; the worker's pages given back afterwards."""
    from planner.io.atomic import deferred_fsync

    give_back()  # what a unit before it on this worker freed
    if not deferred:
        return then_give_back(fn, *args)
    with deferred_fsync():
        return then_give_back(fn, *args)


@kept_beside
def tables_seen(r):
    """What the job keeps of an interstation's tables (made where the result is): the leg and its flags
    (:class:`~planner.tables.flags.FlaggedLeg`). The tables stay in the cache, from where a worker writes their
    datasets and each closed-loop unit reads its leg's (:class:`planner.job.units.Stored`)."""
    from planner.tables.flags import FlaggedLeg

    return FlaggedLeg(r.train_type, r.direction, r.origin, r.destination, tuple(r.flags))


@dataclasses.dataclass(frozen=True)
class StopsSeen:
    """What the job keeps of an approach's stopping patterns (:func:`stops_seen`, made where the result is): its
    verdicts. The patterns themselves stay in the cache, from where a worker writes their datasets
    (:func:`start_written`), so they never come to the job process."""

    infeasible: int
    """Adhesion levels without a pattern."""
    no_stop: Any
    """The leg flagged no_stop (:func:`planner.stopping.sweep.no_stop_leg`), or None."""
    warnings: tuple
    """What the sweep says where every level stops (an approach moved back from a TASC beacon); else none."""


@kept_beside
def stops_seen(r) -> StopsSeen:
    """:class:`StopsSeen` of an :class:`~planner.stopping.sweep.ApproachResult`."""
    from planner.stopping.sweep import no_stop_leg

    every = r.n_feasible == len(r.patterns)
    return StopsSeen(len(r.patterns) - r.n_feasible, no_stop_leg(r), tuple(r.warnings) if every else ())


PART_UNITS = 32
"""Interstations per file of a partition of the tables', stopping patterns' and closed loop's datasets: an edit
rewrites the part of each partition it touches, and the others are the previous run's files
(:mod:`planner.job.made`). The sample's partitions (a dozen interstations) are one file each; the 100x line's
about 38."""


def partition_keys(line_id: str, tasks: list, units: list) -> list[tuple]:
    """The keys of a line's interstation units (``tasks``: (train type, direction, origin, destination) each) by
    the dataset partition their rows go to, as :func:`planner.io.parquet.by_partition` groups the results, and
    in parts of at most :data:`PART_UNITS` units: ``(partition, part name, keys)`` each, the partitions in sorted
    order, each partition's parts and units in the line's order (the parts' names sort in that order,
    :func:`planner.network.sections.part_names`). Every writer of a group writes its files as ``part-<part name>``,
    so that no part's file is another's."""
    from planner.network.sections import part_names

    groups: dict = {}
    for (t, d, _o, _de), u in zip(tasks, units):
        groups.setdefault((line_id, d, t), []).append(u.key)
    out = []
    for g in sorted(groups):
        keys = groups[g]
        chunks = [keys[i:i + PART_UNITS] for i in range(0, len(keys), PART_UNITS)]
        out += [(g, name, chunk) for name, chunk in zip(part_names(len(chunks)), chunks)]
    return out


def made_key(step: str, partition: tuple, part: str, keys: list[str]) -> str:
    """What a group of a step's dataset files depends on (:mod:`planner.job.made`): the code, the step (its
    writer), the partition and part, and the keys of the units whose results it holds."""
    return digest(["made", code_digest(), step, list(partition), part, list(keys)])


def write_stored(writer: Callable, root: str, step: str, groups: list[tuple], stage: Path, prev=None) -> tuple:
    """Worker: ``writer(results, stage, part)`` for each part of each partition in turn (``groups``:
    :func:`partition_keys`), its results read from the work cache at ``root``, checked by their digests like
    every read, one part in memory at a time; or, for a part whose inputs did not change since the previous run
    (``prev``: :class:`planner.job.made.Previous`), that run's files, checked by their digests. This run stored
    every result (with ``--no-cache`` too: such a run reads nothing it did not write itself); one missing or
    damaged fails the run, naming it. Returns (the files, ``{group key: record}`` for the manifest)."""
    from planner.job.made import made_once
    from planner.job.units import Stored

    written, made = [], {}
    for partition, part, keys in groups:
        def write(keys=keys, part=part) -> list:
            return writer([Stored(root, step, k).load() for k in keys], stage, part)

        key = made_key(step, partition, part, keys)
        files, made[key] = made_once(key, prev, stage, write)
        written += files
    return written, made


@kept_beside
def loops_seen(batch):
    """What the job keeps of an interstation's closed loop (every scenario and mode, made where the results are): its
    flagged runs' legs and flags (:class:`~planner.tables.flags.FlaggedLeg`). The runs stay in the cache, from where a
    worker writes their datasets and makes what the margins read of them (:func:`closed_loop_written`)."""
    from planner.tables.flags import FlaggedLeg

    return [FlaggedLeg(r.train_type, r.direction, r.origin, r.destination, tuple(r.flags)) for r in batch if r.flags]


def closed_loop_written(root: str, line_id: str, groups: list[tuple], stage: Path, rule, times: list[dict],
                        prev=None) -> tuple:
    """Worker: the line's ``closed_loop`` and ``closed_loop_summary`` datasets, written from the closed-loop units'
    stored results (``groups``: their keys by partition and part, :func:`partition_keys`), one part in memory at
    a time, and what the margins read of them (:class:`~planner.report.margin_datasets.ClosedLoopFacts` at each
    part's legs' ``times``, :func:`planner.report.margin_legs.looked_up_by_leg`; the margin ``rule``'s scenarios).

    A part whose inputs did not change since the previous run (``prev``, :mod:`planner.job.made`) is that run's
    files, and its facts are the entry stored in the work cache when they were made (kind
    ``closed_loop_facts``, keyed by the files' key, the rule and the part's times; checked by its digest like
    every read): its results are not read. Returns (the files, the facts, ``{group key: record}``, the entries
    rejected here: ``(kind, key, why)`` each, for the run's one warning, :meth:`Cache.rejected_elsewhere`)."""
    from planner.datasets.closed_loop import datasets, write_closed_loop
    from planner.job.cache import Cache
    from planner.job.made import made_once
    from planner.job.units import Stored
    from planner.report.margin_datasets import ClosedLoopFacts

    cache = Cache(Path(root), enabled=prev is not None)  # --no-cache: no previous run, and no entry read either
    files, facts, made = [], ClosedLoopFacts(), {}
    for (partition, part, keys), part_times in zip(groups, times, strict=True):
        key = made_key("closed_loop", partition, part, keys)
        fkey = digest(["closed_loop_facts", key, dataclasses.asdict(rule), sorted(part_times.items())])

        @functools.cache
        def tables(keys=keys) -> dict:  # the part's rows, read once if its files or its facts need them
            return datasets([r for k in keys for r in Stored(root, "closed_loop", k).load()])

        got, made[key] = made_once(key, prev, stage, lambda part=part, tables=tables: write_closed_loop(
            tables(), stage, part))
        files += got
        mine = cache.get("closed_loop_facts", fkey)
        if not isinstance(mine, ClosedLoopFacts):
            mine = ClosedLoopFacts()
            mine.add(tables(), line_id, rule, part_times)
            cache.put("closed_loop_facts", fkey, mine)
        facts.update(mine)
        tables.cache_clear()
    return files, facts, made, cache.rejected_why


def start_written(job: Job, stage: Path, summary: RunSummary, cache, step: str, groups: list[tuple]):
    """Write a step's datasets (the tables', the stopping patterns') on a worker, from the results its units stored
    (``groups``: their keys by partition and part, :func:`partition_keys`): the results never come to the job
    process; ``.result()``: the files and their record (:func:`write_stored`)."""
    from planner.datasets.stops import write_stops
    from planner.datasets.tables import write_tables
    from planner.io.parallel import background
    from planner.io.atomic import deferring

    writer = {"tables": write_tables, "stops": write_stops}[step]
    b = background(write_staged, (deferring(), write_stored, writer, str(cache.root), step, groups, stage,
                                  summary.previous),
                   name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
    summary.pending.append(b)
    return b


def start_bundles(job: Job, line: Line, stage: Path, runner: Runner, summary: RunSummary, key, key_path: Path,
                  bday=None, verify: dict | None = None):
    """Start the line's bundles on a worker, one after another, each verified there once written (``verify``:
    :func:`build_bundles`), the public key that verifies them written first: one worker, so that the other goes on
    with the units this process waits for (the bundles are taken last, :func:`bundles_step`). The step's time
    runs from here to when they are written."""
    from cryptography.hazmat.primitives import serialization
    from planner.io.parallel import background
    from planner.job.bundle_reuse import BundleReuse
    from planner.line.model import DIRECTIONS

    types = line_types(job, line)
    runner.progress.start("bundles", len(DIRECTIONS) * len(types))
    out = stage / "bundles"
    pem = key.public_key().public_bytes(serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo)
    write_bytes_atomic(out / "signing_key.pub.pem", pem)
    prev = summary.previous
    mine = f"line={line.line_id}"  # the line's files (the tables' and stops' are in the record by now)
    reuse = BundleReuse(stage, line.line_id, {rel: sha for files in summary.made.values() for rel, sha in files
                                              if rel.split("/")[1] == mine},
                        key_path, prev.run_dir if prev is not None else None, prev.bundles if prev is not None else {})
    compare = (str(summary.base_dir), summary.run_id) if summary.base_dir is not None else None
    b = background(build_bundles, (line, out, key_path, summary.release, stage, types, bday, reuse, verify, compare),
                   name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
    summary.pending.append(b)
    return b


def bundles_step(runner: Runner, summary: RunSummary, line_id: str, bundles) -> None:
    """Signed bundles for every direction × train type (:func:`start_bundles`), each with its overview row when
    verified (:attr:`RunSummary.bundle_rows`)."""
    infos, keys, rows, changes = bundles.result()
    summary.pending.remove(bundles)
    summary.bundle_changes[line_id] = changes
    summary.bundle_inputs.update(keys)
    names = [Path(i.path).name for i in infos]
    summary.bundle_rows += list(zip(names, rows))
    summary.bundles += names
    runner.progress.advance("bundles", len(infos))
    runner.progress.finish("bundles")


def conflicts_unit(line, params, lifted=None, job=None, stream=()):
    """A section's conflict check (the whole line's when it is one section) and its day as it runs; ``stream``:
    the section's own draws (:func:`planner.network.sections.stream_of`)."""
    from planner.datasets.conflicts import conflict_report
    from planner.network.arrivals import train_curves
    from planner.network.check import check_timetable

    def compute():
        check = check_timetable(line, params, curves=train_curves(line, lifted))
        if job is None:
            return conflict_report(check), None
        from planner.delay.network import ARRIVAL
        from planner.job.robustness import day_as_it_runs

        # the day as it will run, on this worker from the check it has (chunks of days one after the other:
        # the other workers are busy with the line's other units)
        runs = day_as_it_runs(check, line, job, n_jobs=1, stream=stream)
        directions = {t.train_id: t.direction for t in check.trains}
        arrivals = int((runs[0].net.ev_kind == ARRIVAL).sum())
        return conflict_report(check, runs[0].windows), (directions, *runs, arrivals)

    # the worker's pages of the section's run curves given back, for the units after it
    return then_give_back(compute)


@dataclasses.dataclass(frozen=True)
class SectionInputs:
    """What a section's units (its conflicts and day as it runs, its train graph trajectories) are given and
    keyed by: its line (:func:`planner.network.sections.section_line`), its trains' lifted restrictions, its own
    draws, the digest of what it sees and the name of its dataset files."""

    line: Line
    lifted: dict
    stream: tuple
    seen: str
    part: str


def line_section_inputs(job: Job, line: Line, lifted=None, cache=None) -> list[SectionInputs]:
    """The sections of a line (:mod:`planner.network.sections`, the job's connections joining theirs) with what
    their units see: where a section is the whole line, the line's own key (:func:`planner.job.day.line_digest`),
    else the digest of its stretch's content (not of the line folder's bytes, which an edit elsewhere changes).
    ``cache``: the run's work cache, where the sections are kept (:func:`line_sections_kept`)."""
    from planner.job.robustness import connections
    from planner.network.sections import part_names, restricted, section_line, stream_of

    texts = {t.train_id: repr(t) for t in line.trains}  # each train's text, digested by the sections and by each
    sections = line_sections_kept(line, list(connections(job)), cache, texts)
    out = []
    for sec, part in zip(sections, part_names(len(sections))):
        sline = section_line(line, sec)
        seen = line_digest(line) if sline is line else section_digest(sline, texts)
        out.append(SectionInputs(sline, restricted(lifted, sec), stream_of(sec, line), seen, part))
    return out


def line_sections_kept(line: Line, connections: list, cache=None, texts: dict | None = None) -> list:
    """:func:`planner.network.sections.plan_sections` of ``line``, kept in the work ``cache`` (kind ``sections``) under
    the digest of all it reads: the line but its speed limits (its routes and sections do not depend on speeds,
    and a restriction is the edit of every day), the trains by their text, the connections and the code. On a
    100x line the routes of 35,600 trains take 4.6 s of the job process, the key 0.9 s: an edit of a speed limit
    and each day's restrictions reuse them. ``texts``: each train's ``repr`` by id, when the caller has them."""
    from planner.job.leg_memo import plain
    from planner.network.sections import plan_sections

    if cache is None:
        return plan_sections(line, connections)
    texts = texts if texts is not None else {t.train_id: repr(t) for t in line.trains}
    rest = dataclasses.replace(line, trains=(), speed_limits=(), source_digest="", source_path="", upgrade_notes=())
    key = digest(["sections", code_digest(), plain(rest), _trains_digest(line.trains, texts), plain(connections)])
    kept = cache.get("sections", key)
    if kept is not None:
        return kept
    sections = plan_sections(line, connections)
    cache.put("sections", key, sections)
    return sections


def _trains_digest(trains, texts: dict) -> str:
    """SHA-256 of the trains' texts (strings and numbers only, a float's text exact), one a line."""
    return hashlib.sha256("\n".join(texts[t.train_id] for t in trains).encode()).hexdigest()


def section_digest(sline: Line, texts: dict | None = None) -> str:
    """Digest of a section's line, its content (module doc of :mod:`planner.network.sections`): the trains by
    their text (strings and numbers only, a float's text exact; ``texts``: each train's by id, when the caller has
    them), the rest as plain data (arrays by value), the folder's digest and path left out."""
    from planner.job.leg_memo import plain

    rest = dataclasses.replace(sline, trains=(), source_digest="", source_path="", upgrade_notes=())
    texts = texts if texts is not None else {t.train_id: repr(t) for t in sline.trains}
    return digest([plain(rest), _trains_digest(sline.trains, texts)])


def conflicts_units(job: Job, line: Line, stage: Path, sections: list[SectionInputs], previous=None) -> list[Unit]:
    """The units of the line's route conflicts and of the day as it will run, one per section of the line
    (``sections``: :func:`line_section_inputs`; trains that share no track with the others' are checked on their
    own, and each unit sees and digests its stretch alone, so an edit recomputes the sections it reaches). Each
    checks its trains' timetable (each train's run with the restrictions that apply to it,
    :func:`planner.job.day.lifted_restrictions`) and computes their day as it will run
    (:func:`planner.job.robustness.day_as_it_runs`: the predicted day, and the simulated days of
    ``[robustness]``). Its large datasets (occupation windows, the day's events) are written into ``stage`` where
    the unit is made or read back (:func:`section_written`), a part per section; the job keeps the small rest,
    which :func:`conflicts_step` puts together. A section's files that its unit's key says did not change since
    the previous run (``previous``: :class:`planner.job.made.Previous`) are that run's (:mod:`planner.job.made`)."""
    from planner.io.atomic import deferring
    from planner.job.robustness import key_of

    params = {k: v for k, v in dataclasses.asdict(job.conflicts).items() if k != "enabled"}
    common = [code_digest(), params, job.tables.ds_m, key_of(job), job.day.day]
    units = []
    for s in sections:
        key = digest(["conflicts", s.seen, lifted_key(s.lifted), list(s.stream), *common])
        made = made_key("conflicts", (line.line_id,), s.part, [key])
        units.append(Unit("conflicts", key, f"conflicts {s.part}", conflicts_unit,
                          (s.line, params, s.lifted, job, s.stream),
                          after=Placed(section_kept, functools.partial(
                              write_staged, deferring(), section_written, stage,
                              _Stations(line.line_id, s.line.stations), s.part, made,
                              previous.of([made]) if previous is not None else None))))
    return units


@kept_beside
def section_kept(result) -> tuple:
    """What the job keeps of a section's unit (stored beside it): its conflicts, headways and unrouted frames, and
    the robustness summary with the count of arrivals it is over, or None."""
    report, runs = result
    return report.conflicts, report.headways, report.unrouted, None if runs is None else (runs[3], runs[5])


def section_written(stage: Path, line: "_Stations", part: str, made: str, previous, load) -> tuple:
    """Write a section's occupation windows and the datasets of its day as it runs into the staged run (part
    ``part`` of each), from its result (``load()``), or link the previous run's files without decoding the result
    (``made``: their key, ``previous``: that run's record, :func:`planner.job.made.made_once`); returns (the files,
    their record ``(made, record)``)."""
    from planner.datasets.conflicts import write_occupation
    from planner.datasets.delays import write_day
    from planner.job.made import made_once

    def write() -> list:
        report, runs = load()
        files = write_occupation(report.occupation, stage, part)
        if runs is not None:
            directions, pday, stats, _summary, held, _arrivals = runs
            files += write_day(pday, stats, held, line, directions, stage, part)[0]
        return files

    files, record = made_once(made, previous, stage, write)
    return [str(f) for f in files], (made, record)


@dataclasses.dataclass(frozen=True)
class _Stations:
    """What :func:`planner.datasets.delays.write_day` reads of a section's line: its id and stations (the unit's
    ``after`` carries this, not the section's line)."""

    line_id: str
    stations: tuple


def conflicts_step(summary: RunSummary, kept: list, line: Line, stage: Path):
    """Put the sections' results together (``kept``: each section's :func:`section_kept` and
    :func:`section_written`): the line's conflicts numbered in time order across its sections, its headways and unrouted trains written as one dataset each; count the
    route conflicts found, the trains the network cannot carry (a flag and a note each: the night goes on
    without them) and the datasets' rows; returns the conflicts table for the report."""
    import pandas as pd

    from planner.datasets.conflicts import renumbered, write_conflict_tables
    from planner.job.robustness import merged_summary

    kept, placed = [k[0] for k in kept], [k[1] for k in kept]  # section_kept's, section_written's
    conflicts = renumbered([k[0] for k in kept])
    heads = pd.concat([k[1] for k in kept], ignore_index=True).sort_values(
        ["from_m", "to_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
    unrouted = [k[2] for k in kept if k[2] is not None and len(k[2])]  # each section's, in the sections' order
    unrouted = pd.concat(unrouted, ignore_index=True) if unrouted else None
    files = write_conflict_tables(line.line_id, conflicts, heads, unrouted, stage)
    count_rows(summary, files + [f for p in placed for f in p[0]])
    summary.made.update(p[1] for p in placed)
    parts = [k[3] for k in kept if k[3] is not None]
    if parts:
        summary.robustness[line.line_id] = merged_summary(parts)  # the robustness page's head (job.views)
    summary.flags["conflicts"] = summary.flags.get("conflicts", 0) + int(
        conflicts["conflict_id"].nunique() if len(conflicts) else 0)
    reasons = list(unrouted["reason"]) if unrouted is not None else []
    summary.flags["unrouted"] = summary.flags.get("unrouted", 0) + len(reasons)
    summary.notes += [f"not routed, left out of the conflict check: {why}" for why in reasons]
    return conflicts
