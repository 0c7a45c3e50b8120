"""The nightly job's views: train graph page, "what changed since the last run", run overview page.

Two hooks called by :mod:`planner.job.pipeline`:

* :func:`line_views`, after a line's bundles: keep a copy of the line's tables
  in the run (``inputs/<line_id>/``, so a later run can name the rows that
  changed), and write its interactive train graph (``graph/<line_id>_graph.html``). The graph is made per
  section of the line, as cached units: each section's trajectories (:func:`graph_units`, keyed by what the
  section sees, the code and the run-curve step; run on a worker beside the bundles), then its trains' share of
  the page (:func:`page_units`: their JSON, their windows from the section's part of the ``occupation`` dataset,
  their predicted day from its part of ``delay_events``; keyed by the trajectories' and the section's conflicts
  unit's keys), so an edit remakes the sections it reaches. A worker puts the shares together in the line's
  order (:func:`graph_written`, taken by :func:`run_views` before the manifest), numbering the blocking resources
  and the predicted day's causes across the line and adding the run's conflicts and margin totals. Before it,
  the running-time tables per train and the speed–distance charts
  (:func:`planner.job.train_views.train_views`), which a selected train in the graph links to; the charts are
  drawn on the workers while the rest is written, and their pages are written by :func:`run_views` once the
  other pages are.
* :func:`run_views`, after the manifest: compare the run with the previous
  published one (:func:`planner.report.changes.compare_runs`), write the ``changes``
  dataset and put the section at the top of each margin report, add the
  datasets and timings to the manifest, then write the overview
  ``index.html`` (:mod:`planner.pages.overview`).
"""
from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

from planner.errors import JobError, PlannerError
from planner.io.memory import give_back
from planner.io.paths import check_path_id


def copy_inputs(line, stage: Path) -> Path:
    """Copy the line database's Parquet tables into ``stage/inputs/<line_id>/`` and check the copy's digest."""
    from planner.report.published_run import INPUTS_DIR, path_id
    from planner.line.loader import source_digest

    src = Path(line.source_path)
    dst = stage / INPUTS_DIR / path_id(line.line_id)
    if not line.source_path or not src.is_dir():
        raise JobError(f"line {line.line_id}: no line database folder to keep a copy of (source path "
                       f"{line.source_path!r}); load the line from its folder")
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(src.glob("*.parquet")):
        if f.is_file():
            shutil.copyfile(f, dst / f.name)
    if source_digest(dst) != line.source_digest:
        raise JobError(f"{src}: the line database changed while the job ran (its digest no longer matches what "
                       "was planned); run the job again")
    return dst


def _graph_unit(line, check: bool, lifted=None):
    """Thinned predicted trajectories of every train (with loop stops when the line has a network), each
    train's run with the restrictions that apply to it (``lifted``, :func:`planner.job.day.lifted_restrictions`)."""
    from planner.network.arrivals import train_curves
    from planner.report.train_graph import loop_stations, train_paths

    loops = {}
    if line.network is not None and check:
        from planner.network.routes import plan_routes

        loops = loop_stations(line, plan_routes(line, unrouted={}))  # the conflict step flags the unrouted
    try:
        return train_paths(line, train_curves(line, lifted), loops=loops)
    finally:
        give_back()  # the worker's pages of the whole line's run curves, for the units after it


def graph_units(job, sections) -> list:
    """The units of a line's train graph trajectories (:func:`_graph_unit`), one per section of the line
    (``sections``: :func:`planner.job.steps.line_section_inputs`; a train's trajectory is the same on its section
    as on the whole line), each keyed by what its section sees and the code."""
    from planner.report.train_graph import TOL_T_S, TOL_X_M
    from planner.job.units import code_digest
    from planner.job.day import lifted_key
    from planner.job.publish import digest
    from planner.job.units import Unit, nothing_kept

    check = bool(job.conflicts.enabled)
    # the trajectories stay in the cache: the train graph page's units read them (page_units), not the job
    return [Unit("graph", digest(["graph", code_digest(), s.seen, lifted_key(s.lifted), check, TOL_T_S, TOL_X_M]),
                 "graph", _graph_unit, (s.line, check, s.lifted), after=nothing_kept) for s in sections]


def line_views(job, line, stage: Path, runner, summary, shares, charts=None, bday=None, parts=None) -> None:
    """Running-time tables and train graph page of one line (module doc); ``shares``: the train
    graph page's units, started (:meth:`planner.job.units.Runner.start` of :func:`page_units`), and their keys;
    ``bday``: its operating day (:func:`planner.job.day.bundle_day`, None without a daily feed); ``charts``: the
    line's speed–distance charts if started already (:func:`planner.job.train_views.start_charts`); ``parts``: its
    sections as the tables' units see them (:func:`planner.job.train_views.timetable_parts`). The train graph page
    is put together on a worker (:func:`graph_written`, in ``summary.graph_pages``) while this process writes the
    run's other pages."""
    from planner.io.parallel import background
    from planner.job.train_views import train_views

    check = bool(job.conflicts.enabled)
    from planner.job.day import restriction_blocks, window

    label = _run_label(job, summary)
    blocks = restriction_blocks(line, bday)  # the day's restrictions, drawn on the train graph
    head = graph_head(line)
    started, keys = shares

    def start_page(legs: dict) -> None:
        """The train graph page starts on a worker as soon as the legs' chart links are known (with the tables'
        dataset and page, written on a worker) and its shares are made: on a large line it is the run's last long
        unit."""
        started.results()  # every section's share stored (made while the tables were)
        summary.pending.remove(started)
        with runner.progress.step("graph"):  # the page's own time is counted where run_views takes it
            page = background(graph_written, (str(runner.cache.root), keys, stage, head, legs, label, check, blocks),
                              name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
        summary.pending.append(page)
        summary.graph_pages.append(page)

    # the chart pages are written by run_views, once the rest of the run's pages are: the charts are drawn meanwhile
    train_views(job, line, stage, summary.reports[line.line_id], runner, summary,  # tables, charts
                run_id=summary.run_id, day=window(job).record() if job.day.day else None,
                later=summary.chart_pages, charts=charts, legs_known=start_page, parts=parts)
    summary.pending += [c for c in summary.chart_pages[-1:] if c not in summary.pending]
    give_back()  # the pages of the legs' runs (planner.io.memory)


def page_units(stage: Path, root: str, sections, g_units: list, conflict_units=None) -> list:
    """The units of a line's train graph page, one per section (``sections``, with their trajectories' units
    ``g_units``, :func:`graph_units`, and their conflicts units ``conflict_units``; None: the run checks no
    conflicts): each makes its trains' share of the page (:func:`_page_unit`), keyed by its trajectories' key
    and its conflicts unit's (its occupation windows and predicted day), so an edit remakes the sections it
    reaches. The page is put together from them on a worker (:func:`graph_written`)."""
    from planner.job.publish import digest
    from planner.job.units import Stored, Unit, code_digest, nothing_kept

    keys = [u.key for u in conflict_units] if conflict_units else [None] * len(sections)
    return [Unit("graph", digest(["graph page", code_digest(), g.key, k]), f"graph page {s.part}", _page_unit,
                 (s.line, Stored(root, "graph", g.key), str(stage), s.part, k is not None), after=nothing_kept)
            for s, g, k in zip(sections, g_units, keys)]


def _page_unit(line, trajectories, stage: str, part: str, checked: bool):
    """Worker: a section's share of the train graph page (:func:`planner.pages.train_graph.trains_part`): its
    trains' trajectories (``trajectories``: the stored result of its :func:`graph_units` unit), and with
    ``checked`` its part of the run's occupation windows and predicted day (``delay_events``)."""
    from planner.datasets.conflicts import read_occupation_part
    from planner.datasets.delays import read_part
    from planner.pages.train_graph import trains_part
    from planner.report.graph_predicted import PREDICTED_COLUMNS, predicted_paths
    from planner.report.train_graph import WINDOW_COLUMNS, GraphData

    paths = trajectories.load()
    occ = ev = None
    if checked:
        occ = read_occupation_part(Path(stage), line.line_id, part, list(WINDOW_COLUMNS))
        ev = read_part(Path(stage), "delay_events", line.line_id, part, list(PREDICTED_COLUMNS))
    predicted = None if ev is None else predicted_paths(line, ev, paths)
    try:
        return trains_part(GraphData(line.line_id, line.name, float(line.start_m), float(line.end_m), [], paths,
                                     occ, predicted=predicted))
    finally:
        give_back()


@dataclass(frozen=True)
class GraphHead:
    """What the train graph page's worker needs of the line (:func:`graph_written`): not the line itself, which on
    a network is large."""

    line_id: str
    name: str
    start_m: float
    end_m: float
    stations: list
    network: bool
    order: list


def graph_head(line) -> GraphHead:
    """The :class:`GraphHead` of ``line``."""
    from planner.report.train_graph import line_stations

    return GraphHead(line.line_id, line.name, float(line.start_m), float(line.end_m), line_stations(line),
                     line.network is not None, [t.train_id for t in line.trains])


def graph_written(root: str, keys: list, stage: Path, head: GraphHead, legs: dict, label: str, check: bool,
                  blocks=()) -> None:
    """Worker: write ``graph/<line>_graph.html``, the line's train graph put together from its sections' shares
    (``keys``: :func:`page_units`' stored results) in the line's timetable order, with the run's conflicts and
    margin totals, each train linked to its legs' charts (``legs``, from
    :func:`planner.job.train_views.train_views`) and the day's restrictions as time–location blocks (``blocks``,
    :func:`planner.job.day.restriction_blocks`)."""
    from planner.job.train_views import timetable_href
    from planner.job.units import Stored
    from planner.pages.train_graph import GraphFrame, write_parts_page
    from planner.report.published_run import path_id, read_line_dataset
    from planner.report.train_graph import graph_notes, margins_by_train

    parts = [Stored(root, "graph", k).load() for k in keys]
    con = read_line_dataset(stage, "conflicts", head.line_id)
    drawn = head.network and (stage / "occupation").is_dir() and con is not None  # windows and conflicts given
    margins = margins_by_train(read_line_dataset(stage, "margin_totals", head.line_id))
    notes = graph_notes(head.network, drawn, margins)
    if check and head.network and not drawn:
        notes.append("the run has no occupation/conflicts datasets for this line")
    frame = GraphFrame(head.line_id, head.name, head.start_m, head.end_m, head.stations,
                       con if drawn else None, margins, notes, list(blocks))
    write_parts_page(frame, parts, stage / "graph" / f"{path_id(head.line_id)}_graph.html", order=head.order,
                     run_label=label, timetable_href="../" + timetable_href(head.line_id),
                     charts={t: [(lbl, "../" + h) for lbl, h in v] for t, v in legs.items()},
                     links=graph_links(head.line_id))
    del parts, frame
    give_back()  # the pages of the graph's data, for the work after it on this worker


def graph_links(line_id: str) -> list[tuple[str, str]]:
    """The run's pages a line's train graph links to at its top (relative to ``graph/``)."""
    from planner.report.published_run import path_id
    from planner.job.train_views import timetable_href

    return [("overview", "../index.html"), ("margin report", f"../report/{path_id(line_id)}_margins.html"),
            ("running-time tables", "../" + timetable_href(line_id))]


def _run_label(job, summary) -> str:
    """The run and its operating day, as the run's pages name them under their title."""
    from planner.job.day import window
    from planner.pages.run_head import run_words

    return run_words(summary.run_id, window(job).record() if job.day.day else None, getattr(summary, "run_date", None))


def _failure_text(e: BaseException) -> str:
    what = f"{type(e).__name__}: {e}" if not isinstance(e, PlannerError) else str(e)
    return " ".join(what.split())[:300]


def _comparison_failed(base: str, e: BaseException, summary) -> str:
    """One line for a comparison that failed; the run says it and publishes without the changes."""
    what = _failure_text(e)
    summary.warnings.append(f"changes: comparing with run {base} failed ({what}); "
                            "this run is published without its list of changes")
    return what


def start_compare(job, line, stage: Path, summary) -> None:
    """Start comparing the line's margins, conflicts and inputs with the previous published run (``summary.base``)
    on a worker, as soon as its margins are written: read there, not in this process, and done long before the
    changes step takes it (:func:`_changes`). Its bundles are compared where they are built
    (:func:`compare_bundles`). Nothing when there is no previous run."""
    from planner.io.parallel import background

    if summary.base is None:
        return
    b = background(compare_line, (summary.base_dir, stage, summary.head, line.line_id),
                   name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
    summary.pending.append(b)
    summary.comparing[line.line_id] = b


def compare_line(base_dir: Path, stage: Path, head: dict, line_id: str):
    """Worker: the line's changes against the run ``base_dir`` but its bundles'
    (:func:`planner.report.changes.compare_runs`; ``head``: this run's manifest as far as it is known), and what went
    wrong in one line (empty when nothing did)."""
    from planner.report.changes import compare_runs

    try:
        return compare_runs(base_dir, stage, lines=[line_id], new_manifest=head, bundles=False)[0], ""
    except Exception as e:  # noqa: BLE001 - see _changes
        return None, _failure_text(e)


def compare_bundles(line_id: str, base_dir: Path, stage: Path, run_id: str) -> tuple[list, str]:
    """Worker: the rows of the line's bundles that changed against the run ``base_dir``'s
    (:func:`planner.report.bundle_changes.bundle_changes`), and what went wrong in one line (empty when nothing
    did). Made where the bundles were built, once each is verified."""
    from planner.report.bundle_changes import bundle_changes
    from planner.report.changes import LineChanges

    ch = LineChanges(line_id, base_dir.name, run_id)
    try:
        bundle_changes(ch, base_dir, stage)
    except Exception as e:  # noqa: BLE001 - see _changes
        return [], _failure_text(e)
    return ch.rows, ""


def _changes(lines, summary) -> tuple[dict, str]:
    """Each line's changes against the previous published run (:func:`start_compare`, :func:`compare_bundles`),
    and the first failure (empty when none).

    Whatever goes wrong in the comparison (a damaged old run, a bug in the comparison itself) is
    reported in one line and marks the comparison as failed: the run's own outputs are complete,
    so it still publishes (the changes step can never block a night). No line lists changes then.
    """
    if summary.base is None:
        return {}, ""
    found, failures = {}, []
    for line in lines:
        started = summary.comparing.pop(line.line_id, None)
        if started is None:  # the run failed before: not reached
            continue
        ch, what = started.result()
        summary.pending.remove(started)
        rows, b_what = summary.bundle_changes.get(line.line_id, ([], ""))
        failures += [w for w in (what, b_what) if w]
        if ch is not None:
            ch.extend(rows)
            found[line.line_id] = ch
    if failures:
        summary.warnings.append(f"changes: comparing with run {summary.base} failed ({failures[0]}); "
                                "this run is published without its list of changes")
        return {}, failures[0]
    return found, ""


def _write_line_changes(ch, stage: Path) -> int:
    """Write one line's ``changes`` dataset; its row count. A failed write leaves no part file behind."""
    import pyarrow.parquet as pq

    from planner.report.changes import write_changes
    from planner.report.published_run import path_id

    try:
        return sum(pq.ParquetFile(f).metadata.num_rows for f in write_changes(ch, stage))
    except BaseException:
        shutil.rmtree(stage / "changes" / f"line={path_id(ch.line_id)}", ignore_errors=True)
        raise


def _restrictions_pages(job, lines, stage: Path, manifest: dict, summary) -> None:
    """``report/<line>_restrictions.html`` of each line with a daily feed (:mod:`planner.pages.restrictions`);
    adds to the line's day record in ``manifest`` what the restrictions do to the impossible legs and which
    legs of the trains added since the previous day are flagged (:mod:`planner.report.day_changes`)."""
    from planner.pages.restrictions import write_page
    from planner.report.restriction_effects import effect, scheduled_legs
    from planner.report.day_changes import flagged_legs
    from planner.report.leg_flags import FLAGS

    day = manifest.get("operating_day") or {}
    for line, rec in zip(lines, day.get("lines", [])):
        if rec.get("feed") is None:
            continue
        rep = summary.reports.get(line.line_id)
        rows = None if rep is None else rep.rows
        legs = scheduled_legs(line, rows, job.tables.ds_m)
        if rows is not None:
            rec["restrictions_effect"] = effect(legs, rows)
            added = (rec.get("changes") or {}).get("trains_added")
            if added is not None:
                added["flagged_legs"] = flagged_legs(rec["changes"], rows, FLAGS)
        write_page(line, {**{k: day.get(k) for k in ("day", "start", "end", "time_zone")}, **rec}, rows,
                   stage / "report" / f"{check_path_id(line.line_id, 'line id')}_restrictions.html",
                   job.tables.ds_m, legs)


def _robustness_pages(job, lines, stage: Path, manifest: dict, summary) -> list:
    """Start ``report/<line>_robustness.html`` of each line whose conflict check computed the day as it runs
    (:func:`robustness_page`, once its sections' shares are stored) on a worker, while this process writes the
    run's other pages; the handles to wait for."""
    from planner.io.parallel import background
    from planner.pages.run_head import nav_html

    started = []
    for line in lines:
        s = summary.robustness.get(line.line_id)
        if s is None:
            continue
        shares, cache, keys = summary.robustness_shares.pop(line.line_id)
        shares.results()  # every share stored (taken as they come, while the other pages were written)
        summary.pending.remove(shares)
        lid = check_path_id(line.line_id, "line id")
        nav = nav_html([("overview", "../index.html"), ("margin report", f"{lid}_margins.html"),
                        ("train graph", f"../graph/{lid}_graph.html")],
                       manifest.get("run_id"), manifest.get("operating_day"), manifest.get("run_date"))
        od = manifest.get("operating_day") or {}
        day = od.get("day") or ""
        rec = next((x for x in od.get("lines", []) if x.get("line_id") == line.line_id), {})
        s = {**s, "restrictions": [r["restriction_id"] for r in rec.get("restrictions") or []], "day": day}
        page = background(robustness_page, (cache, keys, stage, line.line_id, line.name, s, nav),
                          name=job.parallel.backend, n_jobs=job.parallel.n_jobs)
        summary.pending.append(page)
        started.append(page)
    return started


def start_robustness(runner, summary, line_id: str, stage: Path, parts: list) -> None:
    """Start the units of a line's robustness page (:func:`robustness_units`) when its conflict check computed the
    day as it runs; :func:`run_views` puts the page together from them (:func:`robustness_page`)."""
    if line_id in summary.robustness:
        units = robustness_units(line_id, stage, parts, int(summary.robustness[line_id].get("days") or 0))
        started = runner.start("robustness", units)
        summary.pending.append(started)
        summary.robustness_shares[line_id] = (started, str(runner.cache.root), [u.key for u in units])


def robustness_units(line_id: str, stage: Path, parts: list, days: int) -> list:
    """The units of a line's robustness page, one per section (``parts``:
    :func:`planner.job.train_views.timetable_parts`, each with its conflicts unit's key): each makes its section's
    share of the page (:func:`planner.pages.robustness_share.share`) from its part of the day as it runs'
    datasets, keyed by the code and its conflicts unit's key (which made those files), so an edit remakes the
    sections it reaches."""
    from planner.job.publish import digest
    from planner.job.units import Unit, code_digest, nothing_kept

    code = code_digest()
    return [Unit("robustness", digest(["robustness page", code, p.predicted_key, days]), f"robustness {p.part}",
                 _robustness_unit, (line_id, str(stage), p.part, days), after=nothing_kept) for p in parts]


def _robustness_unit(line_id: str, stage: str, part: str, days: int):
    """Worker: a section's share of the robustness page, from its part of the datasets in the staged run."""
    from planner.datasets.delays import SCHEMAS, read_part
    from planner.pages.robustness_share import share

    frames = [read_part(Path(stage), n, line_id, part, [f.name for f in SCHEMAS[n]]) for n in
              ("robustness_trains", "robustness_stations", "robustness_activities", "delay_events")]
    try:
        return share(*frames, days)
    finally:
        del frames
        give_back()


def robustness_page(root: str, keys: list, stage: Path, line_id: str, name: str, summary: dict, nav: str) -> None:
    """Worker: write a line's robustness page (:mod:`planner.pages.robustness`) from its sections' shares stored in
    the work cache at ``root`` (``keys``: :func:`robustness_units`) and its stations' figures (the
    ``robustness_stations`` dataset in the staged run, a few rows per station). The whole line's rows are never
    read together (at a hundred times the sample, 35,600 trains' rows: 1.6 GB of a worker's memory)."""
    from planner.io.atomic import write_bytes_atomic
    from planner.job.units import Stored
    from planner.pages.robustness import render_shares
    from planner.report.published_run import read_line_dataset

    lid = check_path_id(line_id, "line id")
    shares = [Stored(root, "robustness", k).load() for k in keys]
    text = render_shares(name, summary, read_line_dataset(stage, "robustness_stations", line_id), shares, nav=nav)
    del shares
    write_bytes_atomic(stage / "report" / f"{lid}_robustness.html", text.encode("utf-8"))
    del text
    give_back()


CHANGES_HERE = "<!-- planner: the changes since the previous run -->"
"""Where the margin report page, drawn before the comparison is in (:func:`margin_page`), gets its changes section
(an HTML comment: no text of the page's data can be one, as it is escaped)."""


def margin_page_path(line, stage: Path) -> Path:
    return stage / "report" / f"{check_path_id(line.line_id, 'line id')}_margins.html"


def margin_page(line, stage: Path, summary) -> None:
    """Draw the line's margin report page (its charts are most of its time) while the workers draw its legs' charts,
    all but its changes section (:data:`CHANGES_HERE`), which :func:`run_views` puts in once the comparison is in."""
    from planner.job.train_views import timetable_href
    from planner.pages.margin_charts import chart_sections
    from planner.pages.margin_report import page_text, stop_markers
    from planner.pages.run_head import nav_html

    rep = summary.reports.get(line.line_id)
    if rep is None:
        return
    head = summary.head
    tables = "../" + timetable_href(line.line_id)
    nav = nav_html([("overview", "../index.html"), ("train graph", f"../graph/{line.line_id}_graph.html"),
                    ("running-time tables per train", tables)],
                   head.get("run_id"), head.get("operating_day"), head.get("run_date"))
    summary.margin_pages[line.line_id] = page_text(
        rep, line, margin_page_path(line, stage), datasets_root=stage, top=CHANGES_HERE,
        charts=chart_sections(rep, stop_markers(line)), nav=nav, trains_href=tables)


def run_views(job, lines, stage: Path, root: Path, prog, summary) -> None:
    """Changes since the previous run, report sections, manifest additions and the overview page (module doc)."""
    from planner.io.atomic import write_bytes_atomic
    from planner.report.changes import CATEGORIES
    from planner.pages.changes import changes_html
    from planner.pages.overview import write_overview
    from planner.job.publish import canonical_json

    manifest_path = stage / "manifest.json"
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    base = summary.base
    rows: dict[str, int] = {}
    counts: dict[str, dict[str, int]] = {}
    with prog.step("changes", len(lines)):
        # the robustness pages start on the workers, and this process writes the restrictions pages (their findings go
        # into the manifest), while the comparison (started with the margins) ends
        robustness = _robustness_pages(job, lines, stage, manifest, summary)
        _restrictions_pages(job, lines, stage, manifest, summary)
        found, failure = _changes(lines, summary)
        for line in lines:
            ch = found.get(line.line_id)
            if ch is not None:
                try:
                    n = _write_line_changes(ch, stage)
                except Exception as e:  # noqa: BLE001 - the comparison must never block publishing
                    failure = failure or _comparison_failed(base, e, summary)
                    ch = None
                else:
                    rows["changes"] = rows.get("changes", 0) + n
                    counts[line.line_id] = {c: len(ch.of(c)) for c in CATEGORIES}
            if base is None:
                note = "This is the first run in this output folder: nothing to compare with."
            elif failure:
                note = f"Comparing with run {base} failed, so this run lists no changes: {failure}"
            else:
                note = f"Line {line.line_id} could not be compared with run {base}."
            page = summary.margin_pages.pop(line.line_id, None)  # drawn while the workers drew its charts
            if page is not None:
                write_bytes_atomic(margin_page_path(line, stage),
                                   page.replace(CHANGES_HERE, changes_html(ch, first_run_note=note), 1).encode("utf-8"))
            prog.advance("changes")
    # the speed–distance charts' pages, being written on the workers since the line waited for its bundles (written
    # here if they were not started: charts kept in this process)
    for pages in summary.chart_pages:
        pages.finish()
    with prog.step("graph"):  # each line's train graph page, written on a worker meanwhile
        for page in summary.graph_pages:
            page.result()
    for page in robustness:  # and the robustness pages
        page.result()
        summary.pending.remove(page)
    with prog.step("overview"):  # its bundles verified where they were built, in the order of their file names
        brows = [row for _, row in sorted(summary.bundle_rows)]
    summary.rows.update(rows)
    manifest["rows"] = dict(sorted({**manifest.get("rows", {}), **rows}.items()))
    manifest["changes"] = {"base_run": base, "lines": counts,
                           "status": "first run" if base is None else "failed" if failure else "compared"}
    if failure:
        manifest["changes"]["error"] = failure
    if summary.robustness:
        manifest["robustness"] = {lid: {k: r[k] for k in ("days", "seed", "late_trains", "max_delay_s",
                                                          "knock_on_conflicts", "within_60s", "within_180s")
                                        if k in r} for lid, r in sorted(summary.robustness.items())}
    manifest["timings_s"] = dict(prog.timings)
    manifest["units_computed"] = dict(summary.computed)
    manifest["units_reused"] = dict(summary.reused)
    write_bytes_atomic(manifest_path, canonical_json(manifest) + b"\n")
    with prog.step("overview"):
        # notes name the development key by its path: keep the page free of absolute paths
        notes = [n.replace(str(root), job.job.output_root) for n in summary.warnings + summary.notes]
        write_overview(stage, manifest, notes=notes, bundles=brows)


__all__ = ["copy_inputs", "graph_links", "graph_written", "line_views", "page_units", "run_views"]
