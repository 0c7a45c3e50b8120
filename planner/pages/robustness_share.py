"""A section's share of the robustness page (:mod:`planner.pages.robustness`): what the page shows of its trains.

A line checked in sections (:mod:`planner.network.sections`) has each section's rows of the day as it runs in
its own part of the datasets; a train, its events and its activities are in one section. :func:`share` makes
from a section's frames (``robustness_trains``, ``robustness_stations``, ``robustness_activities``,
``delay_events``, each possibly empty or None) everything the page needs of them: the sums behind the line's
figures, the groups of where delay starts, the section's candidates for each "largest" table (each table's top
rows over the line are among its sections' top rows) with their cells, and each train's delay distribution
rendered. The page puts the shares of the line's sections together (:func:`planner.pages.robustness.render_shares`),
so the nightly job makes a share per section as a cached unit and an edit remakes the sections it reaches.
"""
from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from planner.delay.predicted import LATE_S  # an event later than this is late [s]: every page's
from planner.line.units import clock, fixed
from planner.pages.robustness_chart import direction_order

TOP_LATE = 30
"""Late trains shown on the predicted day (the largest delays)."""
TOP_SPREAD = 20
"""Rows of the tables of where delay spreads."""
GROW_ROWS = 3
"""Events a train shown in the table of trains whose delay grows (where it grows most)."""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _pc(x, nd: int = 1) -> str:
    return "–" if x is None or not np.isfinite(x) else f"{100.0 * x:.{nd}f} %"


def _frame(df) -> pd.DataFrame:
    """``df`` with a fresh index; an empty frame for None."""
    return pd.DataFrame() if df is None else df.reset_index(drop=True)


def _text(s: pd.Series) -> pd.Series:
    """A column of strings, "" where missing."""
    return s.astype(object).where(s.notna(), "").astype(str)


def table(head, rows, left=(0,), cls: str = "", row_cls=None, wrap=(), short: bool = False) -> str:
    """A table (``head`` escaped here, cells HTML already); columns ``left`` left-aligned, ``wrap`` left-aligned
    text that wraps (a cause), the rest numbers; ``short``: without the optional ``</td>`` and ``</tr>`` (HTML
    infers them: a long table a third smaller)."""
    def cell(tag, i, c):
        k = "why" if i in wrap and tag == "td" else "l" if i in left or i in wrap else ""
        end = "" if short and tag == "td" else f"</{tag}>"
        return f"<{tag} class='{k}'>{c}{end}" if k else f"<{tag}>{c}{end}"
    h = "".join(cell("th", i, _e(x)) for i, x in enumerate(head))
    body = "".join((f"<tr class='{row_cls[k]}'>" if row_cls and row_cls[k] else "<tr>")
                   + "".join(cell("td", i, c) for i, c in enumerate(r)) + ("" if short else "</tr>")
                   for k, r in enumerate(rows))
    return f"<div class='tw'><table class='{cls}'><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table></div>"


def late_train_html(t: str, c: dict, at: slice) -> str:
    """A late train's stops on the predicted day, scheduled against predicted (``c``: the section's events in running
    order as column arrays, with their station's name and the delay each adds; ``at``: the train's rows)."""
    g = {k: v[at] for k, v in c.items()}
    w, last = int(np.argmax(g["delay_s"])), len(g["delay_s"]) - 1  # the first largest delay
    rows = [[_e(st), _e(ev), clock(sc), clock(pr), fixed(d, 1), fixed(own, 1), fixed(ko, 1), _e(why)]
            for st, ev, sc, pr, d, own, ko, why in zip(g["station"], g["event"], g["scheduled_s"], g["predicted_s"],
                                                     g["delay_s"], g["own_delay_s"], g["knock_on_s"], g["cause"])]
    cls = ["grow" if why else "" for why in g["cause"]]
    return (f"<details><summary>{_e(t)} <span class='via'>{_e(g['train_type'][w])} {_e(g['direction'][w])}"
            f"</span> — largest delay {fixed(g['delay_s'][w], 1)} s at {_e(g['station'][w])} ({_e(g['event'][w])}); "
            f"at {_e(g['station'][last])} {fixed(g['delay_s'][last], 1)} s late</summary>"
            + table(["station", "event", "scheduled", "predicted", "delay [s]", "own [s]", "knock-on [s]", "why"],
                    rows, left=(0, 1), wrap=(7,), cls="auto", row_cls=cls, short=True)
            + "</details>")


def _ordered(ev: pd.DataFrame) -> pd.DataFrame:
    """Events in running order: by train, then seq, arrival before departure."""
    k = (ev["event"] != "arrival").astype(int)
    return ev.assign(_k=k).sort_values(["train_id", "seq", "_k"], kind="stable").drop(columns="_k")


def _destinations(tr: pd.DataFrame) -> pd.DataFrame:
    """Each train's last arrival (its destination) in ``robustness_trains``, by train id."""
    arr = tr[tr["event"] == "arrival"]
    return arr.sort_values(["train_id", "seq"], kind="stable").groupby("train_id", sort=True).tail(1)


@dataclass
class RobustnessShare:
    """What the robustness page needs of a section's trains (module doc). Plain data: the nightly job stores it in
    its cache."""

    names: dict = field(default_factory=dict)
    """Station id → name, of the section's stations."""
    trains_rows: int = 0
    """Rows of its ``robustness_trains`` (0: no simulated day)."""
    arrivals: list = field(default_factory=list)
    """Its arrivals in ``robustness_trains``: their count and the sums of ``within_60s``, ``within_180s``,
    ``within_300s``, ``mean_delay_s`` and ``knock_on_s``."""
    activities: int = 0
    """Rows of its ``robustness_activities``."""
    events: int = 0
    """Rows of its ``delay_events``."""
    event_trains: int = 0
    """Trains with an event on the predicted day."""
    worst: list = field(default_factory=list)
    """The predicted day's largest delay (its first event): ``[delay, train, station]``; empty without events."""
    late: int = 0
    """Trains late at some event on the predicted day."""
    ends: dict = field(default_factory=dict)
    """Direction → ``[[first station, last station, trains], ...]``: where its trains start and end (the direction
    the page says they run)."""
    causes: list = field(default_factory=list)
    """Where its delay starts: ``[station, event, cause, train ids, their first scheduled times, largest delay,
    grows by up to]`` per place and cause."""
    growing: int = 0
    """Trains whose delay grows at some event."""
    grow_top: list = field(default_factory=list)
    """Its latest trains whose delay grows (at most :data:`TOP_LATE`): ``[largest delay, train, events left out,
    rows of cells]``."""
    late_top: list = field(default_factory=list)
    """Its latest trains (at most :data:`TOP_LATE`): ``[largest delay, train, HTML of their stops]``."""
    spread: int = 0
    """Its headways and connections."""
    spread_top: list = field(default_factory=list)
    """Those passing on the most delay (at most :data:`TOP_SPREAD`): ``[transmitted, first train, held train,
    place, cells]``."""
    knock: int = 0
    """Its trains with a destination."""
    knock_top: list = field(default_factory=list)
    """Its trains with the largest knock-on delay at their destination (at most :data:`TOP_SPREAD`):
    ``[knock-on, train, cells]``."""
    dist: list = field(default_factory=list)
    """Each train's delay distribution: ``[train type, direction, departure, train, HTML]``."""
    runs: int = 0
    """Its running activities."""
    legs: list = field(default_factory=list)
    """Its running activities per leg, direction and train type: ``[direction, type, from, to, count, mean slack,
    mean absorbed, mean passed on, mean binding share]``."""


def share(trains, stations, activities, events, days: int) -> RobustnessShare:
    """A section's :class:`RobustnessShare` from its frames (module doc); ``days``: the simulated days."""
    tr, st, acts, ev = _frame(trains), _frame(stations), _frame(activities), _frame(events)
    names: dict = {}
    for f in (st, tr):
        if len(f):
            names.update(zip(_text(f["station_id"]), _text(f["station_name"])))
    out = RobustnessShare(names=names, trains_rows=len(tr), activities=len(acts), events=len(ev))
    if len(tr):
        arr = tr[tr["event"] == "arrival"]
        out.arrivals = [len(arr), *(float(arr[c].sum()) for c in ("within_60s", "within_180s", "within_300s",
                                                                    "mean_delay_s", "knock_on_s"))]
    _ends(out, ev if len(ev) else tr)
    if len(ev):
        _predicted(out, ev, names)
    if days > 0:
        _spread(out, acts, tr, names)
        if len(tr):
            out.dist = _distribution(tr)
        _margins(out, acts, tr, ev)
    return out


def _ends(out: RobustnessShare, ev: pd.DataFrame) -> None:
    if ev.empty:
        return
    o = _ordered(ev)
    g = o.groupby("train_id", sort=True)
    first, last = g.head(1).set_index("train_id"), g.tail(1).set_index("train_id")
    pairs = pd.DataFrame({"direction": _text(first["direction"]), "a": _text(first["station_id"]),
                          "b": _text(last.loc[first.index, "station_id"])})
    for (d, a, b), n in pairs.groupby(["direction", "a", "b"], sort=True).size().items():
        out.ends.setdefault(d, []).append([a, b, int(n)])


def _predicted(out: RobustnessShare, ev: pd.DataFrame, names: dict) -> None:
    w = ev.loc[ev["delay_s"].astype(float).idxmax()]  # the first in the dataset's order
    out.worst = [float(w["delay_s"]), str(w["train_id"]), str(w["station_id"])]
    ev = _ordered(ev.assign(cause=_text(ev["cause"]), station_id=_text(ev["station_id"]),
                            train_id=_text(ev["train_id"])))
    ev = ev.assign(grows=ev["delay_s"] - ev.groupby("train_id", sort=False)["delay_s"].shift(1).fillna(0.0))
    out.event_trains = int(ev["train_id"].nunique())
    ev = ev.assign(station=ev["station_id"].map(lambda s: names.get(s, s)))
    worst = ev.groupby("train_id", sort=True)["delay_s"].max()
    late = worst[worst > LATE_S]
    out.late = len(late)
    rank = sorted(late.index, key=lambda t: (-float(late[t]), t))
    # each train's events are one block of rows (running order): its rows by slicing, not by a search per train
    c = {k: ev[k].to_numpy() for k in ("train_id", "train_type", "direction", "station", "event", "scheduled_s",
                                       "predicted_s", "delay_s", "own_delay_s", "knock_on_s", "cause", "grows")}
    ids = c["train_id"]
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    block = {ids[a]: slice(a, b) for a, b in zip(starts, np.r_[starts[1:], len(ids)])}
    grown = c["cause"] != ""
    grow = ev[grown]
    if len(grow):
        for (sid, kind, cause), g in grow.groupby(["station_id", "event", "cause"], sort=True):
            once = g.sort_values(["scheduled_s", "train_id"], kind="stable").drop_duplicates("train_id")
            out.causes.append([sid, kind, cause, once["train_id"].tolist(), [float(x) for x in once["scheduled_s"]],
                               float(g["delay_s"].max()), float(g["grows"].max())])
        out.growing = int(grow["train_id"].nunique())
        has = set(grow["train_id"])
        for t in [t for t in rank if t in has][:TOP_LATE]:
            at = block[t]
            mine = np.flatnonzero(grown[at]) + at.start
            # where its delay grows most (the first of equal ones), shown in running order
            keep = np.sort(mine[np.argsort(-c["grows"][mine].astype(float), kind="stable")[:GROW_ROWS]])
            rows = [[f"<b>{_e(t)}</b>", _e(f"{c['train_type'][i]} {c['direction'][i]}"), _e(c["station"][i]),
                     _e(c["event"][i]), clock(c["scheduled_s"][i]), clock(c["predicted_s"][i]),
                     fixed(c["delay_s"][i], 1), fixed(c["grows"][i], 1), fixed(c["knock_on_s"][i], 1),
                     _e(c["cause"][i])] for i in keep]
            out.grow_top.append([float(late[t]), t, len(mine) - len(keep), rows])
    for t in rank[:TOP_LATE]:
        out.late_top.append([float(late[t]), t, late_train_html(t, c, block[t])])


def _spread(out: RobustnessShare, acts: pd.DataFrame, tr: pd.DataFrame, names: dict) -> None:
    a = acts[acts["activity"].isin(["headway", "connection"])] if len(acts) else acts
    out.spread = len(a)
    if len(a):
        a = a.assign(where=_text(a["place"])).sort_values(
            ["transmitted_s", "from_train", "to_train", "where"], ascending=[False, True, True, True], kind="stable")
        for r in a.head(TOP_SPREAD).itertuples():
            cells = [_e(r.activity), f"<b>{_e(r.from_train)}</b> → <b>{_e(r.to_train)}</b>", _e(r.where),
                     _e(f"{names.get(r.from_station, r.from_station)} → {names.get(r.to_station, r.to_station)}"),
                     fixed(r.slack_s, 1), fixed(r.transmitted_s, 1), _pc(r.binding_share, 0), fixed(r.absorbed_s, 1)]
            out.spread_top.append([float(r.transmitted_s), str(r.from_train), str(r.to_train), str(r.where), cells])
    if len(tr):
        dst = _destinations(tr)
        out.knock = len(dst)
        dst = dst.sort_values(["knock_on_s", "train_id"], ascending=[False, True], kind="stable")
        prim = tr.groupby("train_id", sort=True)["primary_s"].sum()
        for r in dst.head(TOP_SPREAD).itertuples():
            cells = [f"<b>{_e(r.train_id)}</b>", _e(r.train_type), _e(r.direction), _e(r.station_name),
                     clock(r.scheduled_s), fixed(r.mean_delay_s, 1), fixed(r.knock_on_s, 1),
                     _pc(r.knock_on_s / r.mean_delay_s if r.mean_delay_s > 0 else 0.0, 0), fixed(prim[r.train_id], 1)]
            out.knock_top.append([float(r.knock_on_s), str(r.train_id), cells])


def _q(x, limit: float) -> str:
    t = fixed(x, 0)
    return f"<span class='hi'>{t}</span>" if x > limit else t


def _each(values, fn) -> list:
    """``[fn(v) for v in values]``, each distinct value formatted once (most of a page's columns hold few: shares of
    the days, percentiles, times of day, station names)."""
    done: dict = {}
    out = []
    for v in values:
        t = done.get(v)
        if t is None:
            t = done[v] = fn(v)
        out.append(t)
    return out


_TABLE_HEAD = ("<table><thead><tr><th class='l'>station</th>"
               "<th></th><th>scheduled</th><th>mean [s]</th><th>p50</th><th>p90</th><th>p99</th><th>≤ 1 min [%]</th>"
               "<th>≤ 3 min [%]</th><th>≤ 5 min [%]</th><th>knock-on [s]</th><th>predicted day [s]</th></tr>"
               "</thead>")


def _distribution(tr: pd.DataFrame) -> list:
    t = _ordered(tr)
    t = t.assign(**{c: _text(t[c]) for c in ("train_id", "train_type", "direction", "station_name", "event")})
    # a train's stops: its first event (the departure from its origin) and its arrivals; rows of a train are
    # together (in running order), so each column is formatted once for the whole share, a column at a time
    ids = t["train_id"].to_numpy(object)
    first = np.ones(len(t), dtype=bool)
    first[1:] = ids[1:] != ids[:-1]
    t = t[first | (t["event"].to_numpy(object) == "arrival")]
    ids = t["train_id"].to_numpy(object)
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    ends = np.r_[starts[1:], len(t)]
    col = {c: t[c].to_numpy() for c in t.columns}
    name = _each(col["station_name"], _e)
    sched = _each(col["scheduled_s"].astype(float).tolist(), clock)
    mean, knock = (_each(col[c].astype(float).tolist(), fixed) for c in ("mean_delay_s", "knock_on_s"))
    pct = {c: _each(col[c].astype(float).tolist(), lambda x, c=c: _q(x, 180)) for c in ("p50_s", "p90_s", "p99_s")}
    share_ = {c: _each(col[c].astype(float).tolist(), lambda x: fixed(100.0 * x, 1))
              for c in ("within_60s", "within_180s", "within_300s")}
    pred = _each(col["predicted_delay_s"].astype(float).tolist(), fixed)
    kind = ["arr." if e == "arrival" else "dep." for e in col["event"]]
    # a row of a train's stops: no end tags, shares without their % (a third smaller)
    rows = ["<tr><td>" + "<td>".join(r) for r in zip(
        name, kind, sched, mean, pct["p50_s"], pct["p90_s"], pct["p99_s"], share_["within_60s"],
        share_["within_180s"], share_["within_300s"], knock, pred)]
    out = []
    for o, e in zip(starts, ends):
        d = e - 1
        if d > o:  # its destination's figures
            figures = [mean[d], pct["p50_s"][d], pct["p90_s"][d], pct["p99_s"][d],
                       *(x if x == "–" else f"{x} %" for x in (share_["within_60s"][d], share_["within_180s"][d],
                                                             share_["within_300s"][d])), knock[d]]
            arrive = sched[d]
        else:
            figures, arrive = ["–"] * 8, "–"
        cells = [f"<b>{_e(ids[o])}</b>", _e(col["direction"][o]),
                 _e(f"{col['station_name'][o]} → {col['station_name'][d]}"), sched[o], arrive, *figures]
        # the summary's first grid cell is its ::before marker
        summ = "".join(f"<span class=r>{c}</span>" if i > 4 else f"<span>{c}</span>" for i, c in enumerate(cells))
        out.append([str(col["train_type"][o]), str(col["direction"][o]), float(col["scheduled_s"][o]), str(ids[o]),
                    f"<details><summary>{summ}</summary>{_TABLE_HEAD}<tbody>{''.join(rows[o:e])}</tbody></table>"
                    "</details>"])
    return out


def _margins(out: RobustnessShare, acts: pd.DataFrame, tr: pd.DataFrame, ev: pd.DataFrame) -> None:
    runs = acts[acts["activity"] == "run"] if len(acts) else acts
    out.runs = len(runs)
    if runs.empty:
        return
    src = tr if len(tr) else ev
    info = src.drop_duplicates("train_id").set_index("train_id")[["train_type", "direction"]] if len(src) else None
    runs = runs.assign(train_type=runs["from_train"].map(info["train_type"]) if info is not None else "",
                       direction=runs["from_train"].map(info["direction"]) if info is not None else "")
    runs = runs.assign(train_type=_text(runs["train_type"]), direction=_text(runs["direction"]))
    keys = ["direction", "train_type", "from_station", "to_station"]
    g = runs.groupby(keys, sort=True).agg(n=("from_train", "size"), slack=("slack_s", "mean"),
                                          absorbed=("absorbed_s", "mean"), passed=("transmitted_s", "mean"),
                                          binding=("binding_share", "mean")).reset_index()
    out.legs = [[str(r.direction), str(r.train_type), str(r.from_station), str(r.to_station), int(r.n),
                 float(r.slack), float(r.absorbed), float(r.passed), float(r.binding)] for r in g.itertuples()]


def line_order(directions) -> dict[str, int]:
    """Each direction's place in the page's order (:func:`planner.pages.robustness_chart.direction_order`)."""
    return {d: i for i, d in enumerate(direction_order(set(directions)))}


__all__ = ["RobustnessShare", "line_order", "share"]
