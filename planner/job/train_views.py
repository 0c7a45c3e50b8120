"""The nightly job's per-train views: the ``train_timetable`` dataset, its page and the speed–distance charts.

Called by :func:`planner.job.views.line_views` once a line's margin report is
computed. From the report's rows (the on-time ratio and the minimum of every
timetabled leg × scheduled time) it plans each leg
(:func:`planner.report.train_timetable.planned_legs`: its window of the line, not
yet run); the legs' two runs are recorded on the workers, by the units that need
them (:func:`planner.report.train_timetable.record_leg`), and it writes

* the ``train_timetable`` dataset (a row per call of every train);
* ``timetable/<line>_timetable.html``, all trains on one page, ``#train-<id>``
  anchors (:mod:`planner.pages.timetable`);
* ``charts/<line>/<leg>.html``, one speed–distance chart page per leg ×
  train type × scheduled time the tables link to (:mod:`planner.pages.speed_chart`),
  drawn on the job's workers as cached units (:func:`_chart_key`), so a run after an edit redraws only
  the legs it reaches.

The dataset's rows and the tables on the page are made a cached unit per section of the line
(:func:`timetable_units`) and put together on a worker (:func:`timetable_written`), so an edit remakes the
tables of the sections it reaches.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np

from planner.io.memory import give_back

TIMETABLE_DIR = "timetable"


def timetable_href(line_id: str) -> str:
    """The running-time tables page of a line, relative to the run folder."""
    from planner.io.paths import check_path_id

    return f"{TIMETABLE_DIR}/{check_path_id(line_id, 'line id')}_timetable.html"


def _eval_points(job, line, train_type: str, origin: str, destination: str) -> list:
    """The leg's evaluation points as the tables define them (one definition: ``train_evaluation_points``)."""
    from planner.physics.track import SimSettings
    from planner.tables.eval_points import train_evaluation_points

    tp = job.tables
    pts = train_evaluation_points(line, train_type, origin, destination, after_departure_m=tp.eval_offset_m,
                                  interval_m=tp.eval_interval_m or None, auto_s=tp.eval_auto_s or None,
                                  settings=SimSettings(ds_m=tp.ds_m))
    return [(float(p.position_m), p.eval_point_id) for p in pts]


def _chart_task(win, key, row, ds_m, calls, pattern, evp, signals, bad=None):
    """Worker: one leg's chart, inline SVG (``win``: the leg's window, :func:`planner.report.train_timetable.legs`;
    the signals come from the whole line; ``pattern``: the stopping patterns at the arrival, or the stops step's
    stored unit of the arrival, read here for its lowest and highest adhesion level,
    :func:`planner.datasets.stops.extreme_patterns`), or an empty text for a leg that stalls at its on-time
    ratio (it has no chart and no page, as it has no computed times in the tables; a stored None would read as a
    missing entry). The leg's two runs are recorded here (:func:`planner.report.train_timetable.record_leg`, the
    same function on the same window as the tables' units, so the same bits). The page around the chart (the
    run's id and day, the trains) is put together apart (:func:`write_chart_pages`), so a leg whose chart is
    unchanged is not redrawn for a new run."""
    from planner.datasets.stops import extreme_patterns
    from planner.errors import PlannerError
    from planner.job.units import Stored
    from planner.pages.speed_chart import chart_svg
    from planner.report.leg_margin import bad_day_run
    from planner.report.train_timetable import record_leg

    if isinstance(pattern, Stored):
        pattern = extreme_patterns(pattern.load())
    try:
        run = record_leg(win, key, row, ds_m)
    except PlannerError:
        return ""
    # the bad day's run (``bad``: the rule's load, traction and whether its stop is at the bad day's adhesion)
    worst = bad_day_run(win, key[1], key[2], key[3], row, *bad, ds_m) if bad is not None else None
    return chart_svg(win, run, calls, pattern, evp, signals, bad_day=worst)


def start_charts(job, line, stage: Path, report, runner, run_id: str | None = None, day: dict | None = None,
                 run_date: str | None = None, wait: bool = False) -> "ChartPages":
    """Plan each leg from the margin report's rows (:func:`planner.report.train_timetable.planned_legs`) and
    start their speed–distance charts on the workers (cached units: an unchanged leg's chart is not redrawn;
    ``wait``: drawn before this returns); the pages are written by :meth:`ChartPages.finish`. The nightly job
    calls it as soon as the line's margins are computed, so the charts are drawn while it writes the margins,
    the bundles' key and the other pages. No leg is run here: the charts' and the tables' units record the runs
    they draw and tabulate, on the workers."""
    from planner.job.units import Unit, nothing_kept
    from planner.line.model import DIRECTIONS
    from planner.report.train_timetable import chart_name, planned_legs

    lid = line.line_id
    ds_m = job.tables.ds_m
    with runner.progress.step("timetable"):
        legs = planned_legs(line, report.rows)
    give_back()  # what the margins' results left free
    from planner.job.cache import Cache
    from planner.job.units import Stored, stops_key
    from planner.report.margins import margin_options

    # each arrival's stopping patterns: the stops step's unit of the interstation that ends there, read by the
    # chart's worker (the patterns of every stop were 200 MB in the job process on the 100x line); none where the
    # run has not stored it (the tables and charts of a margin report made on its own)
    root = str(runner.cache.root)
    stored = Cache(runner.cache.root)
    arriving = {d: {b.station_id: a.station_id for a, b in line.interstations(d)} for d in DIRECTIONS}

    def pattern(d: str, t: str, de: str):
        o = arriving.get(d, {}).get(de)
        k = stops_key(job, line, t, o, de) if o is not None else None
        return Stored(root, "stops", k) if k is not None and stored.present("stops", k) else None

    rule = margin_options(job, line)["rule"]
    bad = (float(rule.bad_load), float(rule.bad_traction), bool(rule.bad_day_adhesion))
    units, pages = [], []
    back = "../../" + timetable_href(lid)
    nav = [("running-time tables", back), ("margin report", f"../../report/{lid}_margins.html"),
           ("train graph", f"../../graph/{lid}_graph.html"), ("overview", "../../index.html")]
    # each direction's signal chainages once, in the line's order (a scan of the line's signals per leg was 4 s of
    # the job process on the 100x line)
    sig_at = {d: np.array([s.position_m for s in line.signals if s.direction == d], float) for d in DIRECTIONS}
    for key, (run, win) in sorted(legs.items(), key=lambda kv: kv[0]):  # run: the leg's Leg (not run yet)
        d, t, o, de = key[:4]
        passes = list(run.row.get("passes") if run.row.get("passes") is not None else [])
        calls = [(sid, stops, line.station(sid).stop_m(d) if stops else line.station(sid).position_m)
                 for sid, stops in [(o, True)] + [(p, False) for p in passes] + [(de, True)]]
        trains = sorted(run.row.get("train_ids") if run.row.get("train_ids") is not None else [])
        lo, hi = run.span_m
        at = sig_at.get(d, np.empty(0))  # the direction's signals on the leg, in the line's order
        signals = at[(at >= lo) & (at <= hi)].tolist()
        rest = (calls, pattern(d, t, de), _eval_points(job, line, t, o, de), signals)
        # drawn on a worker and kept in the cache, from where a worker writes its page (ChartPages.finish): the
        # job keeps nothing of a chart (unless it waits for the SVGs here)
        units.append(Unit("charts", _chart_key(line, run, ds_m, rest, bad), "charts", _chart_task,
                          (win, key, run.row, ds_m) + rest + (bad,), after=None if wait else nothing_kept))
        pages.append((stage / chart_name(lid, key), win, run, calls, trains))
    drawn = runner.run("charts", units) if wait else runner.start("charts", units)
    return ChartPages(drawn, pages, back, nav, run_id, day, run_date, legs=legs,
                      stored=None if wait else (str(runner.cache.root), [u.key for u in units]),
                      backend=(job.parallel.backend, job.parallel.n_jobs),
                      chart_keys={k: u.key for k, u in zip(sorted(legs), units)})


def write_chart_pages(pages: list, root: str, keys: list, page: dict) -> int:
    """Worker: the chart pages ``pages`` (:class:`ChartPages`), each chart's SVG read from the work cache at ``root``
    (its unit's key in ``keys``; this run stored or found every one, checked by its digest like every read), with the
    run's id, day and date (``page``) around it. A leg without a chart (it stalls at its on-time ratio:
    :func:`_chart_task`) has no page. Returns the pages written."""
    from planner.job.units import Stored
    from planner.pages.speed_chart import chart_page, write_chart

    n = 0
    for (p, win, run, calls, trains), key in zip(pages, keys):
        svg = Stored(root, "charts", key).load()
        if not svg:
            continue
        write_chart(p, chart_page(win, run, calls, trains, svg, page["back"], nav=page["nav"],
                                  run_id=page["run_id"], day=page["day"], run_date=page["run_date"]))
        n += 1
    give_back()
    return n


def train_views(job, line, stage: Path, report, runner, summary, run_id: str | None = None,
                day: dict | None = None, later: list | None = None, charts: "ChartPages | None" = None,
                legs_known: Callable[[dict], None] | None = None,
                parts: "list[TimetablePart] | None" = None) -> dict[str, list]:
    """Dataset, page and charts of a line's trains (module doc); ``run_id`` and ``day`` (the operating day's
    record) are named at the top of each page.

    The charts start on the workers first (:func:`start_charts`, unless ``charts`` were started already); the
    dataset's rows and the tables page's pieces are made meanwhile, a unit per section of the line (``parts``:
    :func:`timetable_parts`; default the whole line as one), and put together on a worker
    (:func:`timetable_written`). With a list ``later`` the chart pages are left to the :class:`ChartPages`,
    appended to it (the job writes its other pages while the charts are drawn, then calls
    :meth:`ChartPages.finish`); else they are written before this returns.

    Returns ``{train_id: [(label "ORIGIN→DESTINATION", chart path relative to the run folder)]}``, each train's
    legs with a chart in running order, its trains in the line's timetable order (the train graph links them);
    ``legs_known`` is called with it as soon as it is known (the job starts the train graph page with it).
    """
    from planner.io.parallel import background
    from planner.io.atomic import deferring
    from planner.job.steps import count_rows, write_staged

    if charts is None:
        charts = start_charts(job, line, stage, report, runner, run_id, day, getattr(summary, "run_date", None),
                              wait=later is None)
    page = dict(run_id=run_id, day=day, run_date=getattr(summary, "run_date", None))
    types = sorted(set(report.rows["train_type"]))  # the job's train types ([job] train_types)
    if parts is None:
        from planner.job.day import line_digest

        parts = [TimetablePart(line, "0", line_digest(line), None)]
    units = timetable_units(line, charts.legs, charts.chart_keys, types, stage, parts, ds_m=job.tables.ds_m)
    runner.run("timetable", units)  # on the workers, while they draw the charts (the step's first interval)
    with runner.progress.step("timetable"):  # then put together on a worker (its next)
        legs, files = background(write_staged, (deferring(), timetable_written, str(runner.cache.root),
                                                 [u.key for u in units], stage, line.line_id, line.name, page),
                                 name=job.parallel.backend, n_jobs=job.parallel.n_jobs).result()
        legs = {t.train_id: legs[t.train_id] for t in line.trains if t.train_id in legs}  # the line's order
        if legs_known is not None:
            legs_known(legs)
        count_rows(summary, files)
    if later is None:
        charts.finish()
    else:
        later.append(charts)
    return legs


@dataclasses.dataclass(frozen=True)
class TimetablePart:
    """A section of the line as its tables unit sees it (:func:`timetable_units`): its line
    (:func:`planner.network.sections.section_line`), its part name (its rows of the day as it runs are that part
    of ``delay_events``), the digest of what it holds (:func:`planner.job.steps.line_section_inputs`) and the key
    of the unit that computed its day as it runs (its conflicts unit; None: the key digests the part's file as it
    is)."""

    line: object
    part: str
    seen: str
    predicted_key: str | None


def timetable_parts(sections, conflict_units=None) -> list[TimetablePart]:
    """The :class:`TimetablePart` of each section (:func:`planner.job.steps.line_section_inputs`), with its
    conflicts unit (``conflict_units``, in the same order; None: the run computes no day as it runs)."""
    keys = [u.key for u in conflict_units] if conflict_units else [None] * len(sections)
    return [TimetablePart(s.line, s.part, s.seen, k) for s, k in zip(sections, keys)]


def timetable_units(line, legs: dict, chart_keys: dict, types: list, stage: Path, parts: list,
                    ds_m: float = 1.0) -> list:
    """The units of the line's running-time tables, one per section (``parts``): each runs its trains' legs
    (``legs``: :func:`planner.report.train_timetable.planned_legs`) and makes their rows of the
    ``train_timetable`` dataset and their tables on the page (:func:`_timetable_unit`), keyed by what they are
    made from: the section's line, its day as it runs, the line's station chainages (where a run's times are
    kept) and the runs of its trains' legs, each by its chart's key (the leg's window of the line, the code,
    the step and the row's figures: the chart is drawn from the same run) and the fields of its margins row
    that the tables read (:func:`planner.report.train_timetable.row_fields`). An edit recomputes the sections
    whose legs or trains it reaches; the others' rows and pieces come from the cache as they are."""
    import hashlib

    from planner.datasets.delays import part_path
    from planner.job.leg_memo import plain
    from planner.job.publish import digest
    from planner.job.units import Unit, code_digest, nothing_kept
    from planner.report.train_timetable import row_fields, station_chainages, train_legs

    fields = row_fields()
    wanted = set(types)
    by_leg: dict[tuple, list] = {}  # a leg's first five key fields -> its runs' keys (rows with restrictions lifted)
    for k in legs:
        by_leg.setdefault(k[:5], []).append(k)
    code = code_digest()
    at = station_chainages(line)
    at_seen = hashlib.sha256(at.tobytes()).hexdigest()
    units = []
    for p in parts:
        mine = {key for tr in p.line.trains if tr.train_type in wanted for _a, _b, key in train_legs(tr)}
        keys = sorted(k for leg in mine for k in by_leg.get(leg, ()))
        predicted = p.predicted_key
        if predicted is None:
            f = part_path(stage, "delay_events", line.line_id, p.part)
            predicted = hashlib.sha256(f.read_bytes()).hexdigest() if f.is_file() else None
        key = digest(["timetable", code, line.line_id, p.seen, predicted, list(types), at_seen, float(ds_m),
                      [[repr(k), chart_keys[k], plain([legs[k][0].row.get(f) for f in fields])] for k in keys]])
        units.append(Unit("timetable", key, f"timetable {p.part}", _timetable_unit,
                          (p.line, {k: legs[k] for k in keys}, list(types), str(stage), p.part, at, ds_m),
                          after=nothing_kept))
    return units


def _timetable_unit(line, legs: dict, types: list, stage: str, part: str, at: np.ndarray, ds_m: float) -> dict:
    """Worker: a section's rows of the ``train_timetable`` dataset and its trains' tables on the page
    (:func:`planner.pages.timetable.train_pieces`), from its legs' runs (recorded here, each kept at the line's
    station chainages ``at``: :func:`planner.report.train_timetable.leg_times_of`) and its part of the predicted
    day. Stored in the cache as arrays: the table, the pieces' UTF-8 bytes one after the other with where each
    ends, their places on the page, and each train's legs with a chart."""
    import pyarrow as pa

    from planner.datasets.delays import read_part
    from planner.io.parquet import PARTITION_COLS, conform
    from planner.pages.timetable import train_pieces
    from planner.report.train_timetable import TIMETABLE_SCHEMA, leg_times_of, timetable_rows, timetable_table

    lid = line.line_id
    runs = leg_times_of(legs, at, ds_m)
    pred = read_part(Path(stage), "delay_events", lid, part, ["train_id", "seq", "event", "predicted_s", "cause"])
    recs = timetable_rows(line, runs, set(types), pred)
    schema = pa.schema([pa.field(c, pa.string()) for c in PARTITION_COLS] + list(TIMETABLE_SCHEMA))
    table = conform(timetable_table(line, runs, set(types), recs), schema)
    legs: dict[str, list] = {}
    for r in recs:
        if r["chart"] and r["leg_flag"]:  # the stop that ends a leg
            legs.setdefault(r["train_id"], []).append([f"{r['leg_origin']}→{r['station_id']}", r["chart"]])
    pieces = train_pieces(recs, graph_href=f"../graph/{lid}_graph.html")
    del recs
    html = [q.html.encode("utf-8") for q in pieces]
    return {"table": table, "html": np.frombuffer(b"".join(html), np.uint8),
            "ends": np.cumsum([len(h) for h in html], dtype=np.int64),
            "down": np.array([q.down for q in pieces], np.uint8),
            "departure_s": np.array([q.departure_s for q in pieces], np.float64),
            "train_ids": [q.train_id for q in pieces], "directions": [q.direction for q in pieces],
            "legs": [[t, v] for t, v in legs.items()]}


def timetable_written(root: str, keys: list, stage: Path, lid: str, name: str, page: dict
                      ) -> tuple[dict[str, list], list]:
    """Worker: the line's ``train_timetable`` dataset and its page (``page``: the run's id, day and date named at
    its top), put together from its sections' stored units (``keys``, :func:`timetable_units`): the rows of every
    section as one dataset, the trains' tables merged into page order behind the page's head. Returns each
    train's legs with a chart (:func:`train_views`) and the files written."""
    import pyarrow as pa

    from planner.job.units import Stored
    from planner.pages.timetable import END, TrainPiece, page_head, page_order, write_page
    from planner.report.train_timetable import write_timetable_table

    got = [Stored(root, "timetable", k).load() for k in keys]
    files = write_timetable_table(pa.concat_tables([g["table"] for g in got]), stage)
    legs = {t: [tuple(x) for x in v] for g in got for t, v in g["legs"]}
    order = sorted((page_order(TrainPiece(bool(g["down"][i]), float(g["departure_s"][i]), t, "", "")), j, i)
                   for j, g in enumerate(got) for i, t in enumerate(g["train_ids"]))
    links = [("overview", "../index.html"), ("margin report", f"../report/{lid}_margins.html"),
             ("train graph", f"../graph/{lid}_graph.html")]
    head = page_head(lid, name, [(got[j]["train_ids"][i], got[j]["directions"][i]) for _o, j, i in order],
                     links=links, **page)

    def chunks():
        yield head
        for _o, j, i in order:
            ends = got[j]["ends"]
            yield got[j]["html"][(int(ends[i - 1]) if i else 0):int(ends[i])].tobytes()
        yield END

    write_page(stage / timetable_href(lid), chunks())
    return legs, files


class ChartPages:
    """A line's speed–distance chart pages (:func:`train_views`): written from the cache on the workers once the
    charts are drawn (each as its chart arrives where the job holds the SVGs)."""

    def __init__(self, started, pages: list, back: str, nav: list, run_id, day, run_date, legs: dict | None = None,
                 stored: tuple[str, list] | None = None, backend: tuple[str, int] = ("local", 1),
                 chart_keys: dict | None = None):
        self.started, self.pages = started, pages  # a list of the charts' SVGs, or Runner.start's handle
        self.chart_keys = chart_keys or {}  # each leg's chart's key: what its run is made from (timetable_units)
        self.page = dict(back=back, nav=nav, run_id=run_id, day=day, run_date=run_date)
        self.legs = legs  # the legs planned (report.train_timetable.planned_legs), for the tables' units
        self.stored = stored  # (cache root, the charts' keys): the SVGs are in the cache, not here
        self.backend = backend  # where the pages are written from the cache: the job's (name, n_jobs)
        self.writing: list | None = None  # the pages being written on the workers (start)

    def _write(self, _g: int, i: int, svg: str) -> None:
        from planner.pages.speed_chart import chart_page, write_chart

        if not svg:  # a leg that stalls at its on-time ratio: no chart, no page (_chart_task)
            return
        p, win, run, calls, trains = self.pages[i]
        kw = self.page
        write_chart(p, chart_page(win, run, calls, trains, svg, kw["back"], nav=kw["nav"], run_id=kw["run_id"],
                                  day=kw["day"], run_date=kw["run_date"]))

    def start(self) -> None:
        """With the SVGs in the cache (``stored``): wait for the charts still being drawn and start writing the pages
        on the workers, half of the pages each (what a page holds never comes to the job process); :meth:`finish`
        waits for them. The job starts them while it waits for the line's bundles."""
        if self.stored is None or isinstance(self.started, list) or self.writing is not None:
            return
        from planner.io.parallel import background

        self.started.results()  # every chart drawn and stored (the job keeps nothing of them)
        root, keys = self.stored
        name, n_jobs = self.backend
        n = 2 if len(self.pages) > 1 else 1
        self.writing = [background(write_chart_pages, (self.pages[i::n], root, keys[i::n], self.page), name=name,
                                   n_jobs=n_jobs) for i in range(n)]

    def finish(self) -> None:
        """Write every page, waiting for the charts still being drawn (:meth:`start`, unless started)."""
        if isinstance(self.started, list):
            for i, svg in enumerate(self.started):
                self._write(0, i, svg)
            return
        if self.stored is None:
            self.started.results(each=self._write)
            return
        self.start()
        parts, self.writing = self.writing, []
        failed = []
        for b in parts:  # both waited for, so that neither writes into a run that is being given up
            try:
                b.result()
            except BaseException as e:  # noqa: BLE001 - raised below, once the other has ended
                failed.append(e)
        if failed:
            raise failed[0]

    def discard(self) -> None:
        """The run failed: wait for the charts being drawn, and for the pages being written, write nothing more."""
        if not isinstance(self.started, list):
            self.started.discard()
        for b in self.writing or ():
            b.discard()


def _chart_key(line, run, ds_m: float, rest, bad=None) -> str:
    """The cache key of a chart: the code, what the leg's window of the line holds (so, with the code, the step
    and the ratio, both runs), the row's figures the chart prints and everything else it draws (``rest``: calls,
    pattern, points, signals)."""
    import hashlib
    import json

    import numpy as np

    from planner.job.publish import digest
    from planner.job.units import code_digest, interstation_digest

    from planner.report.train_timetable import leg_line

    d, t, o, de, sched = run.key[:5]
    from planner.job.units import Stored

    h = hashlib.sha256()
    calls, pattern, evp, signals = rest
    if isinstance(pattern, Stored):  # the arrival's stops unit, by its key (what its patterns are made from)
        h.update(f"stops {pattern.key}".encode())
    for a, (px, pv) in sorted((pattern if isinstance(pattern, dict) else {}).items()):
        h.update(json.dumps(float(a)).encode())
        h.update(np.ascontiguousarray(px, float).tobytes() + np.ascontiguousarray(pv, float).tobytes())
    figures = [float(run.row[c]) for c in ("min_running_time_s", "margin_s")] + [run.ratio, float(sched), float(ds_m)]
    # the bad-day run: the rule, and the row's start and adhesion it is drawn from
    figures += [list(bad) if bad is not None else None] + [
        None if run.row.get(c) is None else float(run.row[c])
        for c in ("pattern_start_m", "adhesion_min_kmh_s", "degraded_min_running_time_s")]
    return digest(["chart", code_digest(), interstation_digest(leg_line(line, run.key), t, o, de), h.hexdigest(), figures,
                   [list(map(str, c[:2])) + [float(c[2])] for c in calls], [[float(p), str(i)] for p, i in evp or []],
                   [float(x) for x in signals]])


__all__ = ["TimetablePart", "start_charts", "timetable_href", "timetable_parts", "timetable_units", "train_views"]
