"""The interactive train-graph page: one self-contained HTML file (inline data, CSS and script).

Takes the :class:`planner.report.train_graph.GraphData` of a line and a day and
gives the page (:func:`render_page`, :func:`write_page`): zoom to an hour, hover
a train for number, type, times and margin, click it for its blocking-time
stairway; each train late on the predicted day (:mod:`planner.report.graph_predicted`) has its predicted run
dashed beside its line, with a toggle. The data is compact JSON (:func:`page_payload`): trajectories thinned
and delta-coded in whole decisecond and metre steps (module doc of
:mod:`planner.report.train_graph` for the sizes).

The page is made from parts: what it says of a group of trains that needs nothing of the others
(:class:`TrainsPart`, :func:`trains_part`) and the rest (:class:`GraphFrame`). The whole of a
:class:`GraphData` is one part (:func:`render_page`); the nightly job makes a part per section of the line, a
cached unit each, and puts them together (:func:`render_parts`), which numbers the blocking resources and the
predicted day's causes across the parts and adds each train's margins: the same page.
"""
from __future__ import annotations

import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import line_title
from planner.report.graph_predicted import LATE_S, first_largest
from planner.report.train_graph import (COLOURS, CONFLICT_COLOUR, CONFLICT_MIN_PX, STAIR_B_COLOUR, STAIR_COLOUR, GraphData,
                                        hhmm, match_train, peak_window, day_window)

__all__ = ["GraphFrame", "TrainsPart", "page_frame", "page_json", "page_payload", "predicted_summary", "render_page",
           "render_parts", "trains_part", "write_page", "write_parts_page"]


def _delta(values: np.ndarray, scale: float) -> list[int]:
    """Integers of values × scale, delta-coded (first value absolute)."""
    q = np.round(np.asarray(values, dtype=float) * scale).astype(np.int64)
    if len(q) == 0:
        return []
    return np.concatenate([q[:1], np.diff(q)]).tolist()


def _num(x: float, nd: int = 1):
    if x is None or not math.isfinite(float(x)):
        return None
    r = round(float(x), nd)
    return int(r) if r == int(r) else r


def _dumps(x: Any) -> str:
    return json.dumps(x, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def _utf8(texts: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Texts as their UTF-8 bytes one after the other, and where each ends."""
    b = [t.encode("utf-8") for t in texts]
    return np.frombuffer(b"".join(b), np.uint8).copy(), np.cumsum([len(x) for x in b], dtype=np.int64)


def _text(buf: np.ndarray, ends: np.ndarray, i: int) -> str:
    return buf[(int(ends[i - 1]) if i else 0):int(ends[i])].tobytes().decode("utf-8")


@dataclass(frozen=True, eq=False)
class TrainsPart:
    """A group of trains' share of the page's data (:func:`trains_part`): what the page says of them that needs
    nothing of the other trains, in the group's order. The whole line's page is one part; the nightly job makes
    one per section of the line, a cached unit each, and puts them together (:func:`write_parts_page`): what
    numbers things across the line (the blocking resources, the predicted day's causes) and the margins are
    added then.

    ``text``/``ends``: each train's JSON object up to its margins (``…,"m":``), as UTF-8 one after the other;
    ``win_ids``: the trains with blocking windows, by id, each's first four columns as JSON text
    (``win_text``/``win_ends``, ``[…],[…],[…],[…]``) and its windows' resources (``res_codes`` into
    ``resources``, ``res_ends`` where each train's end); ``predicted``: each late train of the predicted day
    (None: no predicted day given) as ``[id, direction, station ids, stop markers, events, times, offsets,
    late events, causes [[event, cause]], [largest delay, its station, event, time]]``."""

    ids: tuple[str, ...]
    directions: tuple[str, ...]
    services: tuple[str, ...]
    start_s: np.ndarray
    end_s: np.ndarray
    text: np.ndarray
    ends: np.ndarray
    win_ids: tuple[str, ...]
    win_text: np.ndarray
    win_ends: np.ndarray
    resources: tuple[str, ...]
    res_codes: np.ndarray
    res_ends: np.ndarray
    predicted: list | None


def trains_part(data: GraphData) -> TrainsPart:
    """The :class:`TrainsPart` of the trains of ``data`` (their paths, windows and predicted day)."""
    texts = []
    for tp in data.trains:
        calls = [[sid, _num(a), _num(d), int(s)] for sid, a, d, s in tp.calls]
        texts.append(_dumps({"id": tp.train_id, "type": tp.train_type, "dir": tp.direction, "svc": tp.service,
                             "t": _delta(tp.t_s, 10.0), "x": _delta(tp.x_m, 1.0), "calls": calls,
                             "loops": list(tp.loop_stations)})[:-1] + ',"m":')
    text, ends = _utf8(texts)
    del texts
    win_ids, win_texts, res_codes, res_ends = [], [], [], []
    res: dict[str, int] = {}
    w = data.windows
    if w is not None and len(w):
        drawn = {tp.train_id for tp in data.trains}
        w = w.sort_values(["train_id", "start_s"], kind="stable")
        # every column once as an array, each train's windows by row positions (not a frame per train)
        a = np.column_stack([w.start_s.to_numpy(), w.end_s.to_numpy(),
                             np.minimum(w.from_m, w.to_m).to_numpy(), np.maximum(w.from_m, w.to_m).to_numpy()])
        rid = w.resource_id.astype(str).to_numpy(object)
        rows = w.groupby("train_id", sort=True).indices
        for tid in sorted(rows):
            if tid not in drawn:
                continue
            g = a[rows[tid]]
            win_ids.append(str(tid))
            win_texts.append(_dumps([_delta(g[:, 0], 10.0), np.round((g[:, 1] - g[:, 0]) * 10).astype(int).tolist(),
                                     _delta(g[:, 2], 1.0), np.round(g[:, 3] - g[:, 2]).astype(int).tolist()])[1:-1])
            res_codes += [res.setdefault(r, len(res)) for r in rid[rows[tid]].tolist()]
            res_ends.append(len(res_codes))
    win_text, win_ends = _utf8(win_texts)
    predicted = None
    if data.predicted is not None:
        predicted = []
        for p in data.predicted.values():
            t = np.round(p.t_s * 10.0)
            i = int(np.argmax(p.delay_s))
            predicted.append([p.train_id, p.direction, list(p.station_ids), [_num(x, 0) for x in p.x_m],
                              "".join("a" if e == "arrival" else "d" for e in p.events), _delta(p.t_s, 10.0),
                              (t - np.round(p.scheduled_s * 10.0)).astype(int).tolist(), p.late.tolist(),
                              [[k, c] for k, c in enumerate(p.causes) if c],
                              [float(p.delay_s[i]), p.station_ids[i], p.events[i], float(p.t_s[i])]])
    return TrainsPart(tuple(tp.train_id for tp in data.trains), tuple(tp.direction for tp in data.trains),
                      tuple(tp.service for tp in data.trains),
                      np.array([tp.start_s for tp in data.trains], float),
                      np.array([tp.end_s for tp in data.trains], float), text, ends, tuple(win_ids), win_text,
                      win_ends, tuple(res), np.array(res_codes, np.int64), np.array(res_ends, np.int64), predicted)


@dataclass
class GraphFrame:
    """What the page shows besides its trains (:class:`TrainsPart`): the line, its stations, the conflicts, each
    train's margins, the restrictions and the notes (:func:`page_frame`)."""

    line_id: str
    line_name: str
    start_m: float
    end_m: float
    stations: list
    conflicts: Any = None
    margins: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    restrictions: list = field(default_factory=list)


def page_frame(data: GraphData) -> GraphFrame:
    """The :class:`GraphFrame` of ``data``."""
    return GraphFrame(data.line_id, data.line_name, data.start_m, data.end_m, data.stations, data.conflicts,
                      data.margins, data.notes, data.restrictions)


class _Page:
    """The trains of a page's parts in page order (``order``: train ids; None: the parts' own order, one part after
    the other) and their windows by train id."""

    def __init__(self, parts: Sequence[TrainsPart], order: Sequence[str] | None = None):
        self.parts = list(parts)
        seq = [(j, i) for j, p in enumerate(self.parts) for i in range(len(p.ids))]
        if order is not None:
            at = {t: k for k, t in enumerate(order)}
            seq.sort(key=lambda ji: at[self.parts[ji[0]].ids[ji[1]]])
        self.seq = seq
        self.win = sorted((t, j, i) for j, p in enumerate(self.parts) for i, t in enumerate(p.win_ids))
        self.ids = [self.parts[j].ids[i] for j, i in seq]
        self.late = self._late()

    def column(self, name: str) -> np.ndarray:
        return np.array([getattr(self.parts[j], name)[i] for j, i in self.seq])

    @property
    def day_s(self) -> tuple[float, float]:
        """First departure and last arrival of the day [s after midnight] (:attr:`GraphData.day_s`)."""
        if not self.seq:
            return 0.0, 86400.0
        return (min(float(p.start_s.min()) for p in self.parts if len(p.ids)),
                max(float(p.end_s.max()) for p in self.parts if len(p.ids)))

    def _late(self) -> list | None:
        """The late trains in page order (None: no predicted day)."""
        if all(p.predicted is None for p in self.parts):
            return None
        late = {r[0]: r for p in self.parts for r in p.predicted or ()}
        return [late[t] for t in self.ids if t in late]


def _conflicts(c) -> list[list]:
    cons = []
    if c is not None and len(c):
        from planner.datasets.conflicts import with_place, place_text

        for r in with_place(c).itertuples(index=False):
            cons.append([int(r.conflict_id), str(r.train_a), str(r.train_b), _num(r.from_m, 0), _num(r.to_m, 0),
                         _num(r.overlap_start_s), _num(r.overlap_end_s), _num(r.delay_s), str(r.rule),
                         str(r.resource_id), str(r.decision), place_text(r) if r.station_id else "",
                         _num(r.headway_s), _num(r.min_headway_s)])
    return cons


def _predicted(frame: GraphFrame, late: list) -> dict[str, Any]:
    """The late trains' predicted runs: per train its events' stations (indices of ``stations``), kinds (``a``
    arrival, ``d`` departure), predicted times (0.1 s, delta-coded), predicted − scheduled [0.1 s], the late
    events' indices and its causes (``[event index, index of causes]``); ``stops``: each station's stop marker
    per direction [m] (where a train's events stand)."""
    idx = {sid: i for i, (sid, _, _) in enumerate(frame.stations)}
    stops: dict[str, list] = {"down": [None] * len(idx), "up": [None] * len(idx)}
    causes = {"": 0}
    trains = []
    for tid, direction, sids, xs, e, t, o, late_ev, cs, _largest in late:
        st = [idx[s] for s in sids]
        for i, x in zip(st, xs):
            stops[direction][i] = x
        trains.append({"id": tid, "st": st, "e": e, "t": t, "o": o, "late": late_ev,
                       "c": [[i, causes.setdefault(c, len(causes))] for i, c in cs]})
    return {"late_s": LATE_S, "stops": stops, "causes": list(causes), "trains": trains}


def _predicted_words(late: list | None) -> str:
    """The predicted day in words (:func:`predicted_summary`) from the late trains in page order."""
    if late is None:
        return ""
    if not late:
        return "no train late on the predicted day"
    best = late[first_largest([r[9][0] for r in late])]  # the first of equals, in the graph's order
    d, sid, event, t = best[9]
    n = len(late)
    return (f"{n} train{'s' if n != 1 else ''} late on the predicted day, the largest {d:.0f} s "
            f"({best[0]} at {sid}, {event} {hhmm(t, True)})")


def predicted_summary(data: GraphData) -> str:
    """The predicted day in words (plain text): how many trains are late, the largest delay and where; "" when
    the graph has no predicted day."""
    return _predicted_words(_Page([trains_part(data)]).late)


def _payload_texts(frame: GraphFrame, page: _Page) -> Iterator[tuple[str, str]]:
    """The payload's keys in order, each with its JSON text (the trains' and windows' made one at a time)."""
    lo, hi = page.day_s
    yield "line", _dumps({"id": frame.line_id, "name": frame.line_name, "start_m": frame.start_m,
                          "end_m": frame.end_m})
    yield "day", _dumps([math.floor(lo / 3600) * 3600, math.ceil(hi / 3600) * 3600])
    yield "stations", _dumps([[sid, name, x] for sid, name, x in frame.stations])
    yield "colours", _dumps({f"{d} {s}": c for (d, s), c in COLOURS.items()})
    yield "conflict", _dumps({"colour": CONFLICT_COLOUR, "stair_a": STAIR_COLOUR, "stair_b": STAIR_B_COLOUR,
                              "min_px": CONFLICT_MIN_PX})
    parts = page.parts

    def margins(t: str) -> str:
        m = frame.margins.get(t)
        return _dumps(None if m is None else {k: _num(v) for k, v in m.items()})

    yield "trains", "[" + ",".join(_text(parts[j].text, parts[j].ends, i) + margins(parts[j].ids[i]) + "}"
                                   for j, i in page.seq) + "]"
    res: dict[str, int] = {}  # the resources numbered as the windows meet them, by train id

    def windows(j: int, i: int) -> str:
        p = parts[j]
        codes = p.res_codes[(int(p.res_ends[i - 1]) if i else 0):int(p.res_ends[i])].tolist()
        nums = [res.setdefault(p.resources[c], len(res)) for c in codes]
        return "[" + _text(p.win_text, p.win_ends, i) + "," + _dumps(nums) + "]"

    yield "windows", "{" + ",".join(_dumps(t) + ":" + windows(j, i) for t, j, i in page.win) + "}"
    yield "resources", _dumps(list(res))
    yield "conflicts", _dumps(_conflicts(frame.conflicts))
    yield "restrictions", _dumps([[rid, _num(a, 0), _num(b, 0), _num(t0), _num(t1), lim, d]
                                  for rid, a, b, t0, t1, lim, d in frame.restrictions])
    late = page.late
    if late:  # only when a train is late: a page without a predicted day stays as it was
        yield "predicted", _dumps(_predicted(frame, late))
    yield "notes", _dumps(frame.notes)


def _page_json(frame: GraphFrame, page: _Page, extra: dict[str, Any]) -> str:
    return "{" + ",".join([_dumps(k) + ":" + v for k, v in _payload_texts(frame, page)]
                          + [_dumps(k) + ":" + _dumps(v) for k, v in extra.items()]) + "}"


def page_json(data: GraphData, extra: dict[str, Any]) -> str:
    """The JSON the page script draws from (times in 0.1 s, chainages in m, delta-coded), with ``extra``'s keys
    after its own; made a train at a time: the whole payload as Python lists was the train graph's worker's
    largest use of memory on a line ten times the sample (the JSON text itself is a tenth of it)."""
    return _page_json(page_frame(data), _Page([trains_part(data)]), extra)


def page_payload(data: GraphData) -> dict[str, Any]:
    """:func:`page_json` as Python objects."""
    return json.loads(page_json(data, {}))


def _asset(name: str) -> str:
    """A file of ``planner/pages/assets`` (package data: the page's stylesheet and script)."""
    from importlib.resources import files

    return files("planner.pages").joinpath("assets", name).read_text(encoding="utf-8")


PAGE_CSS = _asset("train_graph.css")
PAGE_JS = _asset("train_graph.js")


def render_page(data: GraphData, **kw) -> str:
    """:func:`render_parts` of the whole of ``data``, one part."""
    return render_parts(page_frame(data), [trains_part(data)], **kw)


def render_parts(frame: GraphFrame, parts: Sequence[TrainsPart], *, order: Sequence[str] | None = None,
                 t0: float | None = None, t1: float | None = None,
                 train: str | None = None, run_label: str = "", timetable_href: str | None = None,
                 charts: dict[str, list[tuple[str, str]]] | None = None,
                 links: Sequence[tuple[str, str]] = ()) -> str:
    """The interactive train graph as one self-contained HTML page (inline data, CSS and script).

    Parameters
    ----------
    frame, parts : GraphFrame, sequence of TrainsPart
        The line and the trains (:func:`page_frame`, :func:`trains_part`).
    order : sequence of str, optional
        The trains' ids in the order the page lists them (default: the parts' own, one after the other).
    t0, t1 : float, optional
        Initial time window [s after midnight]. Default: the selected train's run with ten minutes either
        side, else :func:`planner.report.train_graph.start_window` (the morning peak, two hours); the
        whole day is one click away, and ``#train=ID`` in the address opens on that train.
    train : str, optional
        Train selected when the page opens (its stairway shown); matched as
        :func:`planner.report.train_graph.match_train` does.
    run_label : str
        The run and its operating day (:func:`planner.pages.run_head.run_words`), under the title.
    timetable_href : str, optional
        The line's running-time tables page (a run's ``timetable/<line>_timetable.html``, relative to this
        page): a selected train gets a link to its table there (``#train-<id>``).
    charts : dict, optional
        ``train_id`` → ``[(label, href)]`` of its legs' speed–distance charts (relative to this page):
        a selected train gets a link to each.
    links : sequence of (label, href)
        The run's other pages, at the top (overview, margin report, running-time tables).
    """
    payload: dict[str, Any] = {}  # the keys after the data's own (page_json)
    page = _Page(parts, order)
    found = match_train(page.ids, train) if train else None
    if train and found is None:
        raise InputError(f"--train {train}: no such train on line {frame.line_id} "
                         f"(e.g. {', '.join(page.ids[:3])})")
    if t0 is not None or t1 is not None:
        lo, hi = day_window(page.day_s, t0, t1)
        name = "chosen"
    elif found is not None:
        j, i = page.seq[page.ids.index(found)]
        lo, hi = float(parts[j].start_s[i]) - 600.0, float(parts[j].end_s[i]) + 600.0
        name = found
    else:
        lo, hi = peak_window(page.day_s, page.column("start_s"), page.column("end_s"))
        name = "morning peak"
    payload["view"] = payload["start_view"] = [lo, hi]
    payload["start_view_name"] = name
    payload["select"] = found
    if timetable_href:
        payload["tt"] = timetable_href
    if charts:  # each leg's link once, trains by index (a leg is run by many trains)
        legs = sorted({tuple(x) for v in charts.values() for x in v})
        at = {x: i for i, x in enumerate(legs)}
        payload["charts"] = {"legs": [list(x) for x in legs],
                             "by_train": {k: [at[tuple(x)] for x in v] for k, v in charts.items()}}
    # no "<" in the script element's text (JSON has one only inside strings, where \u003c is the same): neither a
    # "</script" nor a "<!--" (which makes the parser look past the element's end) can come from the data
    js = _page_json(frame, page, payload).replace("<", "\\u003c")
    n = len(page.ids)
    kinds = list(zip(page.column("directions"), page.column("services")))
    svc = {k: sum(1 for x in kinds if x == k) for k in COLOURS}
    con = frame.conflicts
    nc = int(con.conflict_id.nunique()) if con is not None and len(con) else 0
    nc_text = f"{nc} conflicts" if con is not None else "conflicts not checked"
    e = html.escape
    title = line_title(frame.line_name, frame.line_id)
    keys = " ".join(f"<span><span class='key' style='border-color:{c}'></span>{e(d)} {e(s)} ({svc[(d, s)]})</span>"
                    for (d, s), c in COLOURS.items())
    notes = "".join(f"<li>{e(x)}</li>" for x in frame.notes)
    late_trains = page.late
    late = bool(late_trains)
    pred = _predicted_words(late_trains)
    pred_html = f" · <b id='predicted-summary'>{e(pred)}</b>" if pred else ""
    runs = ("each line is the train front's run as timetabled, dashed its predicted day" if late
            else "each line is the train front's predicted run")
    pred_keys = ("<span><span class='key dashed'></span>dashed: predicted (delays carried forward)</span>"
                 "<span><span class='dot'></span>late event</span>" if late else "")
    pred_box = "<label><input type='checkbox' id='show-predicted' checked> predicted</label>" if late else ""
    pred_info = ("A line is the train's run from the run curves as timetabled: a run slower than scheduled makes "
                 "it late, the next stop's dwell absorbs it. Dashed lines: the predicted day, each late train's run "
                 "with every delay carried forward (a late arrival delays the departure, never before arrival + the "
                 "minimum dwell; a train held by another at a block waits), drawn where it is late; a dot marks each "
                 "event more than "
                 f"{LATE_S:g} s late. Hover one for the scheduled and predicted time, the delay and its cause. "
                 if late else "")
    nav = " · ".join(f"<a href='{e(h)}'>{e(lbl)}</a>" for lbl, h in links)
    top = " · ".join(x for x in (nav, f"<span id='run'>{e(run_label)}</span>" if run_label else "") if x)
    return (
        "<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>Train graph — {e(title)}</title><style>{PAGE_CSS}</style></head><body>"
        f"<header>{f'<p class=sub id=top>{top}</p>' if top else ''}<h1>Train graph — {e(title)}</h1>"
        f"<p class='sub'>{n} trains · {nc_text}{pred_html} · stations at their chainage, time along the axis; "
        f"{runs}</p></header>"
        "<div class='bar'><span>view: <span id='hours'></span></span>"
        "<span>showing <b id='range'></b></span></div>"
        "<div class='bar'>"
        f"{keys} <span><span class='box' style='background:{CONFLICT_COLOUR}'></span>conflict (click)</span>"
        f"<span>▭ loop stop</span>{pred_keys}"
        "<label><input type='checkbox' id='show-down' checked> down</label>"
        "<label><input type='checkbox' id='show-up' checked> up</label>"
        f"<label><input type='checkbox' id='show-conflicts' checked> conflicts</label>{pred_box}"
        "<label>train <input type='text' id='find' placeholder='e.g. 1001D' list='train-ids'></label>"
        "<span>selected: <b id='selinfo'>none</b> <a id='tt-link' href='#' style='display:none'></a>"
        "<span id='chart-links' style='display:none'> · speed–distance:</span></span></div>"
        "<datalist id='train-ids'>" + "".join(f"<option value='{e(t)}'>" for t in page.ids) + "</datalist>"
        "<div id='wrap'><svg id='graph' xmlns='http://www.w3.org/2000/svg' role='img' "
        "aria-label='time-distance train graph'></svg><div id='tip'></div></div>"
        "<div id='info'><p>Hover a train for its number, type, times and margin; click it (or type its number, in "
        "any case) for its blocking-time stairway: one box per section or switch from the window's opening (entry − "
        "route setting − approach) to its closing (tail clear + release)"
        f"{', and a link to its running-time table and speed–distance charts' if timetable_href else ''}. "
        "Magenta boxes: two trains' windows overlap (a conflict); click "
        f"one for both trains' stairways (<span class='box' style='background:{STAIR_COLOUR};opacity:.6'></span>the "
        f"train that goes first, <span class='box' style='background:{STAIR_B_COLOUR};opacity:.6'></span>the one that "
        f"waits, its path dashed) with the overlap. {pred_info}The page opens on the morning peak; <i>whole day</i> shows "
        "every train, an hour's button that hour. Open it at <code>#train=ID</code> for a train's run or at "
        "<code>#conflict=N</code> for a conflict. "
        "Mouse wheel zooms the time axis, drag pans, double-click shows the whole day. "
        "A <i>rapid</i> passes at least one station; a <i>local</i> stops at every one.</p>"
        f"{('<ul>' + notes + '</ul>') if notes else ''}</div>"
        f"<script type='application/json' id='graph-data'>{js}</script>"
        f"<script>{PAGE_JS}</script></body></html>\n"
    )


def write_page(data: GraphData, path: str | Path, **kw) -> Path:
    """Write :func:`render_page` to ``path`` atomically."""
    from planner.io.atomic import write_bytes_atomic

    write_bytes_atomic(path, render_page(data, **kw).encode("utf-8"))
    return Path(path)


def write_parts_page(frame: GraphFrame, parts: Sequence[TrainsPart], path: str | Path, **kw) -> Path:
    """Write :func:`render_parts` to ``path`` atomically."""
    from planner.io.atomic import write_bytes_atomic

    write_bytes_atomic(path, render_parts(frame, parts, **kw).encode("utf-8"))
    return Path(path)
