"""The interactive train-graph page: one self-contained HTML file (inline data, CSS and script).

Takes the :class:`planner.report.train_graph.GraphData` of a line and a day and
gives the page (:func:`render_page`, :func:`write_page`): zoom to an hour, hover
a train for number, type, times and margin, click it for its blocking-time
stairway; each train late on the predicted day (:mod:`planner.report.graph_predicted`) has its predicted run
dashed beside its line, with a toggle. The data is compact JSON (:func:`page_payload`): trajectories thinned
and delta-coded in whole decisecond and metre steps (module doc of
:mod:`planner.report.train_graph` for the sizes).
"""
from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any, Iterator, Sequence

import numpy as np

from planner.line.model import line_title
from planner.report.graph_predicted import LATE_S, largest_delay
from planner.report.train_graph import (COLOURS, CONFLICT_COLOUR, CONFLICT_MIN_PX, STAIR_B_COLOUR, STAIR_COLOUR, GraphData,
                                        hhmm, start_window, time_window)

__all__ = ["page_json", "page_payload", "predicted_summary", "render_page", "write_page"]


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


def _trains(data: GraphData) -> Iterator[dict[str, Any]]:
    """Each train of the payload, in the data's order."""
    for tp in data.trains:
        calls = [[sid, _num(a), _num(d), int(s)] for sid, a, d, s in tp.calls]
        m = data.margins.get(tp.train_id)
        yield {
            "id": tp.train_id, "type": tp.train_type, "dir": tp.direction, "svc": tp.service,
            "t": _delta(tp.t_s, 10.0), "x": _delta(tp.x_m, 1.0), "calls": calls,
            "loops": list(tp.loop_stations),
            "m": None if m is None else {k: _num(v) for k, v in m.items()},
        }


def _windows(data: GraphData, res: dict[str, int]) -> Iterator[tuple[str, list]]:
    """Each train's blocking windows (train id, columns), by train id; ``res``: the resources' numbers, filled
    as they are met."""
    w = data.windows
    if w is None or not len(w):
        return
    order = {tp.train_id for tp in data.trains}
    w = w.sort_values(["train_id", "start_s"], kind="stable")
    # every column once as an array, each train's windows by row positions (not a frame per train)
    a = np.column_stack([w.start_s.to_numpy(), w.end_s.to_numpy(),
                         np.minimum(w.from_m, w.to_m).to_numpy(), np.maximum(w.from_m, w.to_m).to_numpy()])
    rid = w.resource_id.astype(str).to_numpy(object)
    rows = w.groupby("train_id", sort=True).indices
    for tid in sorted(rows):
        if tid not in order:
            continue
        g = a[rows[tid]]
        yield str(tid), [_delta(g[:, 0], 10.0), np.round((g[:, 1] - g[:, 0]) * 10).astype(int).tolist(),
                         _delta(g[:, 2], 1.0), np.round(g[:, 3] - g[:, 2]).astype(int).tolist(),
                         [res.setdefault(r, len(res)) for r in rid[rows[tid]].tolist()]]


def _conflicts(data: GraphData) -> list[list]:
    cons = []
    c = data.conflicts
    if c is not None and len(c):
        from planner.datasets.conflicts import with_place, place_text

        for r in with_place(c).itertuples(index=False):
            cons.append([int(r.conflict_id), str(r.train_a), str(r.train_b), _num(r.from_m, 0), _num(r.to_m, 0),
                         _num(r.overlap_start_s), _num(r.overlap_end_s), _num(r.delay_s), str(r.rule),
                         str(r.resource_id), str(r.decision), place_text(r) if r.station_id else "",
                         _num(r.headway_s), _num(r.min_headway_s)])
    return cons


def _predicted(data: GraphData) -> dict[str, Any]:
    """The late trains' predicted runs: per train its events' stations (indices of ``stations``), kinds (``a``
    arrival, ``d`` departure), predicted times (0.1 s, delta-coded), predicted − scheduled [0.1 s], the late
    events' indices and its causes (``[event index, index of causes]``); ``stops``: each station's stop marker
    per direction [m] (where a train's events stand)."""
    idx = {sid: i for i, (sid, _, _) in enumerate(data.stations)}
    stops: dict[str, list] = {"down": [None] * len(idx), "up": [None] * len(idx)}
    causes = {"": 0}
    trains = []
    for p in (data.predicted or {}).values():
        st = [idx[s] for s in p.station_ids]
        for i, x in zip(st, p.x_m):
            stops[p.direction][i] = _num(x, 0)
        t = np.round(p.t_s * 10.0)
        trains.append({"id": p.train_id, "st": st, "e": "".join("a" if e == "arrival" else "d" for e in p.events),
                       "t": _delta(p.t_s, 10.0), "o": (t - np.round(p.scheduled_s * 10.0)).astype(int).tolist(),
                       "late": p.late.tolist(),
                       "c": [[i, causes.setdefault(c, len(causes))] for i, c in enumerate(p.causes) if c]})
    return {"late_s": LATE_S, "stops": stops, "causes": list(causes), "trains": trains}


def predicted_summary(data: GraphData) -> str:
    """The predicted day in words (plain text): how many trains are late, the largest delay and where; "" when
    the graph has no predicted day."""
    if data.predicted is None:
        return ""
    if not data.predicted:
        return "no train late on the predicted day"
    p, i = largest_delay(data.predicted)
    n = len(data.predicted)
    return (f"{n} train{'s' if n != 1 else ''} late on the predicted day, the largest {p.delay_s[i]:.0f} s "
            f"({p.train_id} at {p.station_ids[i]}, {p.events[i]} {hhmm(p.t_s[i], True)})")


def _payload_parts(data: GraphData) -> Iterator[tuple[str, Any, type | None]]:
    """The payload's keys in order, each with its value (None), or with an iterable of its items to be made one
    at a time and the container they make (``list``: ``trains``' items; ``dict``: ``windows``' (key, value)
    pairs)."""
    lo, hi = data.day_s
    yield "line", {"id": data.line_id, "name": data.line_name, "start_m": data.start_m, "end_m": data.end_m}, None
    yield "day", [math.floor(lo / 3600) * 3600, math.ceil(hi / 3600) * 3600], None
    yield "stations", [[sid, name, x] for sid, name, x in data.stations], None
    yield "colours", {f"{d} {s}": c for (d, s), c in COLOURS.items()}, None
    yield "conflict", {"colour": CONFLICT_COLOUR, "stair_a": STAIR_COLOUR, "stair_b": STAIR_B_COLOUR,
                       "min_px": CONFLICT_MIN_PX}, None
    yield "trains", _trains(data), list
    res: dict[str, int] = {}
    yield "windows", _windows(data, res), dict
    yield "resources", list(res), None  # after the windows, which number them
    yield "conflicts", _conflicts(data), None
    yield "restrictions", [[rid, _num(a, 0), _num(b, 0), _num(t0), _num(t1), lim, d]
                           for rid, a, b, t0, t1, lim, d in data.restrictions], None
    if data.predicted:  # only when a train is late: a page without a predicted day stays as it was
        yield "predicted", _predicted(data), None
    yield "notes", data.notes, None


def page_payload(data: GraphData) -> dict[str, Any]:
    """The compact JSON the page script draws from (times in 0.1 s, chainages in m, delta-coded)."""
    out: dict[str, Any] = {}
    for key, value, made in _payload_parts(data):
        out[key] = value if made is None else made(value)
    return out


def _dumps(x: Any) -> str:
    return json.dumps(x, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def page_json(data: GraphData, extra: dict[str, Any]) -> str:
    """``json.dumps`` of :func:`page_payload` with ``extra``'s keys after its own, the same text, made a train at a
    time: the whole payload as Python lists was the train graph's worker's largest use of memory on a line
    ten times the sample (the JSON text itself is a tenth of it)."""
    out = []
    for key, value, made in _payload_parts(data):
        if made is None:
            text = _dumps(value)
        elif made is list:
            text = "[" + ",".join(_dumps(t) for t in value) + "]"
        else:
            text = "{" + ",".join(_dumps(k) + ":" + _dumps(v) for k, v in value) + "}"
        out.append(_dumps(key) + ":" + text)
    out += [_dumps(k) + ":" + _dumps(v) for k, v in extra.items()]
    return "{" + ",".join(out) + "}"


def _asset(name: str) -> str:
    """A file of ``planner/pages/assets`` (package data: the page's stylesheet and script)."""
    from importlib.resources import files

    return files("planner.pages").joinpath("assets", name).read_text(encoding="utf-8")


PAGE_CSS = _asset("train_graph.css")
PAGE_JS = _asset("train_graph.js")


def render_page(data: GraphData, *, t0: float | None = None, t1: float | None = None,
                train: str | None = None, run_label: str = "", timetable_href: str | None = None,
                charts: dict[str, list[tuple[str, str]]] | None = None,
                links: Sequence[tuple[str, str]] = ()) -> str:
    """The interactive train graph as one self-contained HTML page (inline data, CSS and script).

    Parameters
    ----------
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
    payload: dict[str, Any] = {}  # the keys after page_payload's (page_json)
    sel = data.train(train) if train else None
    if t0 is not None or t1 is not None:
        lo, hi = time_window(data, t0, t1)
        name = "chosen"
    elif sel is not None:
        lo, hi = sel.start_s - 600.0, sel.end_s + 600.0
        name = sel.train_id
    else:
        lo, hi = start_window(data)
        name = "morning peak"
    payload["view"] = payload["start_view"] = [lo, hi]
    payload["start_view_name"] = name
    payload["select"] = sel.train_id if sel is not None else None
    if timetable_href:
        payload["tt"] = timetable_href
    if charts:  # each leg's link once, trains by index (a leg is run by many trains)
        legs = sorted({tuple(x) for v in charts.values() for x in v})
        at = {x: i for i, x in enumerate(legs)}
        payload["charts"] = {"legs": [list(x) for x in legs],
                             "by_train": {k: [at[tuple(x)] for x in v] for k, v in charts.items()}}
    # no "<" in the script element's text (JSON has one only inside strings, where \u003c is the same): neither a
    # "</script" nor a "<!--" (which makes the parser look past the element's end) can come from the data
    js = page_json(data, payload).replace("<", "\\u003c")
    n = len(data.trains)
    svc = {k: sum(1 for t in data.trains if (t.direction, t.service) == k) for k in COLOURS}
    nc = int(data.conflicts.conflict_id.nunique()) if data.conflicts is not None and len(data.conflicts) else 0
    nc_text = f"{nc} conflicts" if data.conflicts is not None else "conflicts not checked"
    e = html.escape
    title = line_title(data.line_name, data.line_id)
    keys = " ".join(f"<span><span class='key' style='border-color:{c}'></span>{e(d)} {e(s)} ({svc[(d, s)]})</span>"
                    for (d, s), c in COLOURS.items())
    notes = "".join(f"<li>{e(x)}</li>" for x in data.notes)
    late = bool(data.predicted)
    pred = predicted_summary(data)
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
        "<datalist id='train-ids'>" + "".join(f"<option value='{e(t.train_id)}'>" for t in data.trains) + "</datalist>"
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
