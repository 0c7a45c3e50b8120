"""The page ``report/<line>_robustness.html``: the operating day as it will run, and how punctual it is.

Sections, in the order a timetable planner reads them:

1. the head: line, operating day, days simulated and seed, the primary-delay rules; cards: the share of the
   line's arrivals within 1, 3 and 5 min, the mean arrival delay and its knock-on share, the predicted day's
   late trains and largest delay, its knock-on conflicts (and their places);
2. punctuality along the line: a chart per direction (:mod:`planner.pages.robustness_chart`) and the
   stations' figures;
3. the predicted day (no primary delay): where its delays start, the trains whose delay grows and why, and
   each late train's stops, scheduled against predicted (the 30 latest; the dataset has every one);
4. where delay spreads: the headways and connections that pass on the most delay, and the trains with the
   largest knock-on delay at their destination;
5. each train's delay distribution: its destination by default, every stop on opening it;
6. margins at work: the delay each leg's slack absorbs, per direction and train type;
7. how to read the page.

Everything is computed upstream (``planner.delay``, ``planner.datasets.delays``); this module renders the
frames it is given (``robustness_trains``, ``robustness_stations``, ``robustness_activities``,
``delay_events``), each possibly empty or None: with no simulated day (``days`` 0) the page says the Monte
Carlo did not run and still shows the predicted day. Inline CSS and SVG, no script, no network; the same
inputs give the same bytes.
"""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pandas as pd

from planner.delay.predicted import LATE_S  # an event later than this is late [s]: every page's

from planner.line.units import clock, fixed
from planner.pages.margin_report import CSS
from planner.pages.robustness_chart import direction_order, punctuality_chart
from planner.pages.svg_plot import LEGEND_CSS

TOP_LATE = 30
"""Late trains shown on the predicted day (the largest delays)."""
TOP_SPREAD = 20
"""Rows of the tables of where delay spreads."""
GROW_ROWS = 3
"""Events a train shown in the table of trains whose delay grows (where it grows most)."""
TOP_CAUSES = 20
"""Places where the predicted day's delay starts, shown."""
TOP_LEGS = 30
"""Legs shown open in the margins table (the rest under a ``<details>``)."""

EXTRA_CSS = """
table.auto{width:auto}td.why{white-space:normal;text-align:left;min-width:16em}tr.grow td{background:#fff4e0}
ul.rules{margin:2px 0 10px;padding-left:22px}ul.rules li{font-size:13.5px}
.card .n small{font-size:14px;font-weight:600;color:#555}.card .l{max-width:15em}
.toc a{margin-right:14px;font-size:14px}
.dist{font-size:12.5px;min-width:880px}
.dist .hd,.dist summary{display:grid;grid-template-columns:1.3em 6.2em 3.4em minmax(11em,1fr) 5.2em 5.2em
 repeat(4,4.1em) repeat(3,4.4em) 5.2em;column-gap:6px;align-items:baseline;padding:2px 4px}
.dist .hd{font-weight:600;background:#eef1f4;border:1px solid #dde1e5}
.dist details{margin:0;border:1px solid #e7eaed;border-top:0;background:#fff}
.dist summary{font-weight:400;font-size:12.5px;list-style:none}.dist summary::-webkit-details-marker{display:none}
.dist summary::before{content:"▸";color:#1f5fa8}.dist details[open]>summary::before{content:"▾"}
.dist details[open]>summary{background:#eef4fb}.dist summary:hover{background:#f3f6f9}
.dist .r{text-align:right;font-variant-numeric:tabular-nums}.dist table{width:auto;margin:2px 0 8px 2.2em}
.dist td:first-child{text-align:left}
.hi{color:#c62828;font-weight:600}.more{white-space:nowrap}
.sb{display:inline-block;height:11px;background:#d9dee4;vertical-align:middle;position:relative}
.ab{display:block;height:11px;background:#1f5fa8}
"""


def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _pc(x, nd: int = 1) -> str:
    """A share as percent (``93.4 %``), ``–`` for none."""
    t = fixed(None if x is None else 100.0 * float(x), nd)
    return t if t == "–" else f"{t} %"


def _frame(df) -> pd.DataFrame:
    """``df`` with a fresh index; an empty frame for None."""
    return pd.DataFrame() if df is None else df.reset_index(drop=True)


def _text(s: pd.Series) -> pd.Series:
    """A column of strings, "" where missing."""
    return s.astype(object).where(s.notna(), "").astype(str)


def _table(head, rows, left=(0,), cls: str = "", row_cls=None, wrap=(), short: bool = False) -> str:
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


def _ordered(ev: pd.DataFrame) -> pd.DataFrame:
    """Events in running order: by train, then seq, arrival before departure."""
    k = (ev["event"] != "arrival").astype(int)
    return ev.assign(_k=k).sort_values(["train_id", "seq", "_k"], kind="stable").drop(columns="_k")


def _destinations(tr: pd.DataFrame) -> pd.DataFrame:
    """Each train's last arrival (its destination) in ``robustness_trains``, by train id."""
    arr = tr[tr["event"] == "arrival"]
    return arr.sort_values(["train_id", "seq"], kind="stable").groupby("train_id", sort=True).tail(1)


def _travel(ev: pd.DataFrame, st: pd.DataFrame, names: dict) -> dict[str, str]:
    """direction → ``A → B, left to right`` from the positions of its trains' first and last events."""
    pos = dict(zip(_text(st["station_id"]), st["position_m"].astype(float))) if len(st) else {}
    out = {}
    if not pos or ev.empty:
        return out
    o = _ordered(ev)
    g = o.groupby("train_id", sort=True)
    first, last = g.head(1).set_index("train_id"), g.tail(1).set_index("train_id")
    for d in direction_order(first["direction"]):
        ids = first.index[first["direction"] == d]
        a = first.loc[ids, "station_id"].map(pos).to_numpy(float)
        b = last.loc[ids, "station_id"].map(pos).to_numpy(float)
        ok = np.isfinite(a) & np.isfinite(b)
        if not ok.any():
            continue
        up = float(np.sum(np.sign(b[ok] - a[ok]))) >= 0
        sids = [s for s in set(first.loc[ids, "station_id"]) | set(last.loc[ids, "station_id"]) if s in pos]
        lo, hi = min(sids, key=lambda s: (pos[s], s)), max(sids, key=lambda s: (pos[s], s))
        a_, b_ = (lo, hi) if up else (hi, lo)
        out[d] = f"{names.get(a_, a_)} → {names.get(b_, b_)}, running {'left to right' if up else 'right to left'}"
    return out


# --- 1. the head -------------------------------------------------------------------------------------------------

def _line_figures(tr: pd.DataFrame, st: pd.DataFrame) -> dict | None:
    """Whole-line punctuality of the arrivals (from the events, else the stations weighted by arrivals)."""
    arr = tr[tr["event"] == "arrival"] if len(tr) else tr
    if len(arr):
        tot = float(arr["mean_delay_s"].sum())
        return {**{m: float(arr[f"within_{m}s"].mean()) for m in (60, 180, 300)},
                "mean": float(arr["mean_delay_s"].mean()), "knock": float(arr["knock_on_s"].sum()) / tot if tot > 0
                else 0.0, "n": len(arr)}
    if len(st) and float(st["arrivals"].sum()) > 0:
        w = st["arrivals"].astype(float)
        f = {m: float((st[f"within_{m}s"] * w).sum() / w.sum()) for m in (60, 180, 300)}
        tot = float((st["mean_delay_s"] * w).sum())
        return {**f, "mean": tot / float(w.sum()), "knock": float((st["knock_on_s"] * w).sum()) / tot if tot > 0
                else 0.0, "n": int(w.sum())}
    return None


def _head(line_name: str, s: dict, tr, st, ev, names: dict, nav: str) -> list[str]:
    days = int(s.get("days") or 0)
    day = str(s.get("day") or "")
    title = f"The day as it will run — {line_name}" + (f", operating day {day}" if day else "")
    parts = ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             "<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>{_e(title)}</title><style>{CSS}{LEGEND_CSS}{EXTRA_CSS}</style></head><body><main>{nav}",
             f"<h1>{_e(title)}</h1>"]
    restr = [str(r) for r in s.get("restrictions") or []]
    facts = [f"<b>{days:,} simulated days</b> (seed {_e(s.get('seed', ''))})" if days > 0 else
             "<b>no simulated day</b>",
             f"{int(s.get('trains') or 0):,} trains, {int(s.get('events') or 0):,} events, "
             f"{int(s.get('activities') or 0):,} activities",
             f"minimum dwell {_e(fixed(s.get('min_dwell_s'), 0))} s",
             "temporary restrictions in force: " + (_e(", ".join(restr)) if restr else "none")]
    parts.append(f"<p class='sub'>{' · '.join(facts)}</p>")
    if int(s.get("dropped") or 0):
        parts.append(f"<p class='warn'>{int(s['dropped'])} headway(s) left out of the network: each closed a cycle "
                     "(an order of trains no timetable can keep).</p>")
    rules = [str(r) for r in s.get("rules") or []]
    if days > 0:
        parts.append("<p class='sub' style='margin:0'>Primary delays drawn on each simulated day:</p><ul class='rules'>"
                     + "".join(f"<li>{_e(r)}</li>" for r in rules or ["none"]) + "</ul>")
    else:
        parts.append("<p class='warn'><b>The Monte Carlo did not run</b> (0 simulated days): this page shows the "
                     "predicted day only. Punctuality, where delay spreads, the delay distributions and the margins "
                     "at work need simulated days (<code>[robustness] days</code>, or <code>planner robustness "
                     "--days N</code>).</p>")
    cards = []
    f = _line_figures(tr, st) if days > 0 else None
    if f:
        for m, w in ((60, "1"), (180, "3"), (300, "5")):
            cards.append(("info", _pc(f[m]), f"of the line's arrivals at most {w} min late"))
        cards.append(("info", f"{fixed(f['mean'], 1)} <small>s</small>", "mean arrival delay"))
        cards.append(("info", _pc(f["knock"], 0), "of the arrival delay is knock-on (caused by other trains)"))
    n_tr = int(ev["train_id"].nunique()) if len(ev) else int(s.get("trains") or 0)
    if len(ev):
        worst = ev.loc[ev["delay_s"].astype(float).idxmax()]
        late = int(ev.loc[ev["delay_s"] > LATE_S, "train_id"].nunique())
        big = float(worst["delay_s"])
        where = f"largest {fixed(big, 1)} s: {worst['train_id']} at {names.get(worst['station_id'], worst['station_id'])}" if late else "none late"
        cards.append(("warn" if late else "ok", f"{late} <small>of {n_tr}</small>",
                      f"trains late on the predicted day (no primary delay); {where}"))
    k = int(s.get("knock_on_conflicts") or 0)
    cards.append(("warn" if k else "ok", str(k), "knock-on conflicts on the predicted day"))
    parts.append("<div class='cards'>" + "".join(
        f"<div class='card {c}'><div class='n'>{n}</div><div class='l'>{_e(l)}</div></div>" for c, n, l in cards)
        + "</div>")
    places = [str(p) for p in s.get("knock_on_places") or []]
    if places:
        more = f" … and {len(places) - 12} more" if len(places) > 12 else ""
        parts.append(f"<p class='sub'>Knock-on conflicts at: {_e('; '.join(places[:12]))}{_e(more)}.</p>")
    parts.append("<p class='toc'><a href='#punctuality'>punctuality along the line</a><a href='#predicted'>the "
                 "predicted day</a><a href='#spread'>where delay spreads</a><a href='#distribution'>each train's "
                 "delays</a><a href='#margins'>margins at work</a><a href='#read'>how to read this</a></p>")
    return parts


# --- 2. punctuality ----------------------------------------------------------------------------------------------

def _punctuality(st, travel, days: int) -> list[str]:
    parts = ["<h2 id='punctuality'>Punctuality along the line</h2>"]
    if days <= 0 or st.empty:
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    parts.append("<p class='sub'>Share of the arrivals at each station at most 1, 3 and 5 min late over the "
                 "simulated days, per direction.</p>")
    parts.append(punctuality_chart(st, travel))
    rows = []
    for d in direction_order(st["direction"]):
        sub = st[st["direction"] == d].sort_values(["position_m", "station_id"], kind="stable")
        for r in sub.itertuples():
            rows.append([_e(d), _e(f"{r.station_name} ({r.station_id})"), fixed(r.position_m / 1000.0, 1),
                         f"{int(r.arrivals)}", _pc(r.within_60s), _pc(r.within_180s), _pc(r.within_300s),
                         fixed(r.mean_delay_s, 1), fixed(r.knock_on_s, 1)])
    parts.append("<details><summary>The stations' figures</summary>" + _table(
        ["direction", "station", "km", "arrivals a day", "≤ 1 min", "≤ 3 min", "≤ 5 min", "mean delay [s]",
         "of it knock-on [s]"], rows, left=(0, 1), cls="auto") + "</details>")
    return parts


# --- 3. the predicted day ----------------------------------------------------------------------------------------

def _predicted(ev: pd.DataFrame, names: dict) -> list[str]:
    parts = ["<h2 id='predicted'>The predicted day</h2>"]
    if ev.empty:
        return parts + ["<p>No event: no train runs on this day.</p>"]
    ev = _ordered(ev.assign(cause=_text(ev["cause"]), station_id=_text(ev["station_id"]),
                            train_id=_text(ev["train_id"])))
    ev = ev.assign(grows=ev["delay_s"] - ev.groupby("train_id", sort=False)["delay_s"].shift(1).fillna(0.0))
    sname = ev["station_id"].map(lambda s: names.get(s, s))
    ev = ev.assign(station=sname)
    worst = ev.groupby("train_id", sort=True)["delay_s"].max()
    late = worst[worst > LATE_S]
    rank = sorted(late.index, key=lambda t: (-float(late[t]), t))
    parts.append(f"<p class='sub'>The day with every delay carried forward and no primary delay: a late leg "
                 f"delays the next departure, a train held by another at a block waits. {len(late)} of "
                 f"{ev['train_id'].nunique()} trains are late at some event.</p>")
    if not len(late):
        return parts + ["<p class='ok'>Every train runs to time on the predicted day.</p>"]
    grow = ev[ev["cause"] != ""]
    if len(grow):
        keys = ["station_id", "event", "cause"]
        groups = []
        for (sid, kind, cause), g in grow.groupby(keys, sort=True):
            ids = list(dict.fromkeys(g.sort_values(["scheduled_s", "train_id"], kind="stable")["train_id"]))
            groups.append((-len(ids), -float(g["delay_s"].max()), sid, kind, cause, ids, float(g["grows"].max())))
        groups.sort(key=lambda x: x[:5])
        rows = [[_e(_station(sid, names)), _e(kind), f"<span class='ids'>{_ids(ids)}</span>",
                 f"{len(ids)}", fixed(-big, 1), fixed(gr, 1), _e(cause)]
                for n, big, sid, kind, cause, ids, gr in groups[:TOP_CAUSES]]
        more = (f" The {TOP_CAUSES} shown are those with the most trains; {len(groups) - TOP_CAUSES} more are in the "
                f"dataset <code>delay_events</code>." if len(groups) > TOP_CAUSES else "")
        parts.append("<h3>Where its delay starts</h3><p class='sub'>Each event whose delay grows over the event "
                     f"before it, grouped by place and cause.{more}</p>"
                     + _table(["station", "event", "trains", "count", "largest delay there [s]", "grows by up to [s]",
                               "why"], rows, left=(0, 1), wrap=(2, 6), cls="auto"))
        rows, cls = [], []
        top = [t for t in rank if (grow["train_id"] == t).any()][:TOP_LATE]
        n_grow = int(grow["train_id"].nunique())
        cut = 0
        for t in top:
            g = grow[grow["train_id"] == t]
            keep = g.sort_values("grows", ascending=False, kind="stable").index[:GROW_ROWS]
            cut += len(g) - len(keep)
            for r in g.loc[g.index.isin(keep)].itertuples():
                rows.append([f"<b>{_e(t)}</b>", _e(f"{r.train_type} {r.direction}"), _e(r.station), _e(r.event),
                             clock(r.scheduled_s), clock(r.predicted_s), fixed(r.delay_s, 1), fixed(r.grows, 1),
                             fixed(r.knock_on_s, 1), _e(r.cause)])
        more = (f"; the {len(top)} with the largest delays are shown, {n_grow - len(top)} more are in the dataset "
                "<code>delay_events</code>" if n_grow > len(top) else "")
        cut = (f" At most {GROW_ROWS} events a train, where its delay grows most ({cut} more under <i>late trains, "
               "stop by stop</i>)." if cut else "")
        parts.append(f"<h3>Trains whose delay grows</h3><p class='sub'>{n_grow} trains{more}. Times HH:MM:SS; "
                     f"<i>grows by</i>: the delay added at that event.{cut}</p>"
                     + _table(["train", "type, direction", "station", "event", "scheduled", "predicted", "delay [s]",
                               "grows by [s]", "of it knock-on [s]", "why"], rows, left=(0, 1, 2, 3), wrap=(9,),
                              cls="auto"))
    shown_ids = rank[:TOP_LATE]
    more = (f"The {len(shown_ids)} latest of {len(late)} late trains; {len(late) - len(shown_ids)} more are in the "
            "dataset <code>delay_events</code>." if len(late) > len(shown_ids) else f"All {len(late)} late trains.")
    parts.append(f"<h3>Late trains, stop by stop</h3><p class='sub'>{more} Open a train for its events, scheduled "
                 "and predicted side by side; an event whose delay grows is shaded.</p>")
    for t in shown_ids:
        g = ev[ev["train_id"] == t]
        w = g.loc[g["delay_s"].idxmax()]
        last = g.iloc[-1]
        rows = [[_e(r.station), _e(r.event), clock(r.scheduled_s), clock(r.predicted_s),
                 fixed(r.delay_s, 1), fixed(r.own_delay_s, 1), fixed(r.knock_on_s, 1), _e(r.cause)]
                for r in g.itertuples()]
        cls = ["grow" if c else "" for c in g["cause"]]
        parts.append(f"<details><summary>{_e(t)} <span class='via'>{_e(w['train_type'])} {_e(w['direction'])}"
                     f"</span> — largest delay {fixed(w['delay_s'], 1)} s at {_e(w['station'])} ({_e(w['event'])}); "
                     f"at {_e(last['station'])} {fixed(last['delay_s'], 1)} s late</summary>"
                     + _table(["station", "event", "scheduled", "predicted", "delay [s]", "own [s]", "knock-on [s]",
                               "why"], rows, left=(0, 1), wrap=(7,), cls="auto", row_cls=cls, short=True)
                     + "</details>")
    return parts


def _station(sid: str, names: dict) -> str:
    """``Name (ID)``, or the id alone when it has no other name."""
    name = names.get(sid, sid)
    return f"{name} ({sid})" if name != sid else sid


def _ids(ids, first: int = 6) -> str:
    text = ", ".join(_e(t) for t in ids[:first])
    if len(ids) > first:
        text += f" <span class='more' title='{_e(', '.join(ids))}'>… {len(ids) - first} more</span>"
    return text


# --- 4. where delay spreads --------------------------------------------------------------------------------------

def _spread(acts: pd.DataFrame, tr: pd.DataFrame, names: dict, days: int) -> list[str]:
    parts = ["<h2 id='spread'>Where delay spreads</h2>"]
    if days <= 0 or (acts.empty and tr.empty):
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    a = acts[acts["activity"].isin(["headway", "connection"])] if len(acts) else acts
    if len(a):
        a = a.assign(where=_text(a["place"])).sort_values(
            ["transmitted_s", "from_train", "to_train", "where"], ascending=[False, True, True, True], kind="stable")
        rows = [[_e(r.activity), f"<b>{_e(r.from_train)}</b> → <b>{_e(r.to_train)}</b>", _e(r.where),
                 _e(f"{names.get(r.from_station, r.from_station)} → {names.get(r.to_station, r.to_station)}"),
                 fixed(r.slack_s, 1), fixed(r.transmitted_s, 1), _pc(r.binding_share, 0), fixed(r.absorbed_s, 1)]
                for r in a.head(TOP_SPREAD).itertuples()]
        parts.append(f"<h3>Headways and connections passing on the most delay</h3><p class='sub'>The {len(rows)} of "
                     f"{len(a):,} with the largest mean delay passed on per day: the first train's delay reaches the "
                     "second through the shared switch or section (or the connection).</p>"
                     + _table(["kind", "trains (first → held)", "place", "stations (first → held)", "slack [s]",
                               "transmitted [s/day]", "days binding", "absorbed [s/day]"], rows, left=(0, 1, 2, 3),
                              cls="auto"))
    else:
        parts.append("<p>No headway or connection in the network.</p>")
    if len(tr):
        dst = _destinations(tr)
        dst = dst.sort_values(["knock_on_s", "train_id"], ascending=[False, True], kind="stable")
        prim = tr.groupby("train_id", sort=True)["primary_s"].sum()
        rows = [[f"<b>{_e(r.train_id)}</b>", _e(r.train_type), _e(r.direction), _e(r.station_name),
                 clock(r.scheduled_s), fixed(r.mean_delay_s, 1), fixed(r.knock_on_s, 1),
                 _pc(r.knock_on_s / r.mean_delay_s if r.mean_delay_s > 0 else 0.0, 0), fixed(prim[r.train_id], 1)]
                for r in dst.head(TOP_SPREAD).itertuples()]
        parts.append(f"<h3>Knock-on delay per train</h3><p class='sub'>The {len(rows)} of {len(dst)} trains with the "
                     "largest mean knock-on delay at their destination.</p>"
                     + _table(["train", "type", "direction", "destination", "scheduled", "mean delay [s]",
                               "of it knock-on [s]", "knock-on share", "primary delay drawn on its run [s/day]"],
                              rows, left=(0, 1, 2, 3), cls="auto"))
    return parts


# --- 5. each train's delay distribution --------------------------------------------------------------------------

_DIST_HEAD = ["", "train", "dir.", "from → to", "departs", "arrives", "mean [s]", "p50", "p90", "p99", "≤ 1 min",
              "≤ 3 min", "≤ 5 min", "knock-on [s]"]


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


def _distribution(tr: pd.DataFrame, days: int) -> list[str]:
    parts = ["<h2 id='distribution'>Each train's delay distribution</h2>"]
    if days <= 0 or tr.empty:
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    parts.append("<p class='sub'>One line per train: its arrival at its destination over the simulated days (mean, "
                 "percentiles p50 / p90 / p99 in seconds, share of days within 1 / 3 / 5 min, mean knock-on). Open "
                 "a train for every stop (its arrivals and its departure from the origin). Trains by type, then "
                 "direction and departure; a p90 or p99 over 3 min in red.</p>")
    t = _ordered(tr)
    t = t.assign(**{c: _text(t[c]) for c in ("train_id", "train_type", "direction", "station_name", "event")})
    # a train's stops: its first event (the departure from its origin) and its arrivals; rows of a train are
    # together (in running order), so each column is formatted once for the whole page, a column at a time
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
    share = {c: _each(col[c].astype(float).tolist(), lambda x: fixed(100.0 * x, 1))
             for c in ("within_60s", "within_180s", "within_300s")}
    pred = _each(col["predicted_delay_s"].astype(float).tolist(), fixed)
    kind = ["arr." if e == "arrival" else "dep." for e in col["event"]]
    # a row of a train's stops: no end tags, shares without their % (a third smaller)
    rows = ["<tr><td>" + "<td>".join(r) for r in zip(
        name, kind, sched, mean, pct["p50_s"], pct["p90_s"], pct["p99_s"], share["within_60s"],
        share["within_180s"], share["within_300s"], knock, pred)]
    head = "<div class='hd'>" + "".join(f"<span{' class=r' if i > 5 else ''}>{_e(h)}</span>"
                                        for i, h in enumerate(_DIST_HEAD)) + "</div>"
    dirs = direction_order(set(col["direction"][starts].tolist()))
    types = col["train_type"][starts].tolist()
    order_of = {d: i for i, d in enumerate(dirs)}
    trains = sorted(range(len(starts)), key=lambda k: (types[k], order_of[col["direction"][starts[k]]],
                                                       float(col["scheduled_s"][starts[k]]), ids[starts[k]]))
    table_head = ("<table><thead><tr><th class='l'>station</th>"
                  "<th></th><th>scheduled</th><th>mean [s]</th><th>p50</th><th>p90</th><th>p99</th><th>≤ 1 min [%]</th>"
                  "<th>≤ 3 min [%]</th><th>≤ 5 min [%]</th><th>knock-on [s]</th><th>predicted day [s]</th></tr>"
                  "</thead>")
    out: dict[str, list[str]] = {}
    for k in trains:
        o, d = starts[k], ends[k] - 1
        if d > o:  # its destination's figures
            figures = [mean[d], pct["p50_s"][d], pct["p90_s"][d], pct["p99_s"][d],
                       *(x if x == "–" else f"{x} %" for x in (share["within_60s"][d], share["within_180s"][d],
                                                             share["within_300s"][d])), knock[d]]
            arrive = sched[d]
        else:
            figures, arrive = ["–"] * 8, "–"
        cells = [f"<b>{_e(ids[o])}</b>", _e(col["direction"][o]),
                 _e(f"{col['station_name'][o]} → {col['station_name'][d]}"), sched[o], arrive, *figures]
        # the summary's first grid cell is its ::before marker
        summ = "".join(f"<span class=r>{c}</span>" if i > 4 else f"<span>{c}</span>" for i, c in enumerate(cells))
        out.setdefault(types[k], []).append(f"<details><summary>{summ}</summary>{table_head}"
                                            f"<tbody>{''.join(rows[o:ends[k]])}</tbody></table></details>")
    for tt in sorted(out):
        parts.append(f"<h3>{_e(tt)} · {len(out[tt])} trains</h3><div class='tw'><div class='dist'>{head}"
                     f"{''.join(out[tt])}</div></div>")
    return parts


# --- 6. margins at work ------------------------------------------------------------------------------------------

def _margins(acts: pd.DataFrame, tr: pd.DataFrame, ev: pd.DataFrame, names: dict, days: int) -> list[str]:
    parts = ["<h2 id='margins'>Margins at work</h2>"]
    runs = acts[acts["activity"] == "run"] if len(acts) else acts
    if days <= 0 or runs.empty:
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    src = tr if len(tr) else ev
    info = src.drop_duplicates("train_id").set_index("train_id")[["train_type", "direction"]] if len(src) else None
    runs = runs.assign(train_type=runs["from_train"].map(info["train_type"]) if info is not None else "",
                       direction=runs["from_train"].map(info["direction"]) if info is not None else "")
    runs = runs.assign(train_type=_text(runs["train_type"]), direction=_text(runs["direction"]))
    keys = ["direction", "train_type", "from_station", "to_station"]
    g = runs.groupby(keys, sort=True).agg(n=("from_train", "size"), slack=("slack_s", "mean"),
                                          absorbed=("absorbed_s", "mean"), passed=("transmitted_s", "mean"),
                                          binding=("binding_share", "mean")).reset_index()
    g = g.sort_values(["absorbed", *keys], ascending=[False, True, True, True, True], kind="stable")
    def pos(v) -> float:
        return float(v) if np.isfinite(v) and v > 0 else 0.0

    top = max([pos(v) for v in g["slack"]] + [pos(v) for v in g["absorbed"]] + [1e-9])
    rows = []
    for r in g.itertuples():
        sw, aw = 150.0 * pos(r.slack) / top, 150.0 * pos(r.absorbed) / top
        bar = f"<span class='sb' style='width:{sw:.0f}px'><span class='ab' style='width:{aw:.0f}px'></span></span>"
        slack = fixed(r.slack, 1)
        rows.append([_e(f"{names.get(r.from_station, r.from_station)} → {names.get(r.to_station, r.to_station)}"),
                     _e(r.direction), _e(r.train_type), f"{r.n}", f"<span class='hi'>{slack}</span>" if r.slack < 0
                     else slack, fixed(r.absorbed, 1), _pc(r.absorbed / r.slack, 0) if r.slack > 0 else "–",
                     fixed(r.passed, 1), _pc(r.binding, 0), bar])
    head = ["leg", "direction", "type", "trains", "mean slack [s]", "mean absorbed [s/day]", "of the slack",
            "passed on [s/day]", "days binding", "absorbed (blue) within the slack (grey)"]
    parts.append(f"<p class='sub'>Each leg's running activities (departure → next arrival) grouped by direction and "
                 f"train type, the most delay absorbed first: the slack (scheduled − minimum running time) and the "
                 f"mean delay per day it took back. A negative slack (red) makes delay on every day.</p>"
                 + _table(head, rows[:TOP_LEGS], left=(0, 1, 2, 9), cls="auto"))
    if len(rows) > TOP_LEGS:
        parts.append(f"<details><summary>The other {len(rows) - TOP_LEGS} legs</summary>"
                     + _table(head, rows[TOP_LEGS:], left=(0, 1, 2, 9), cls="auto") + "</details>")
    return parts


# --- 7. how to read ----------------------------------------------------------------------------------------------

READ = """<h2 id='read'>How to read this</h2><div class='note'><ul>
<li><b>Delay</b>: actual − scheduled time of an event (an arrival or a departure), never negative.</li>
<li><b>The predicted day</b>: the deterministic day with <i>no</i> primary delay, every known delay carried forward
(a leg the day's restrictions make longer than scheduled, the minimum dwell, a train held by another at a block).
On a feasible, conflict-free timetable every predicted delay is 0.</li>
<li><b>Primary delay</b>: drawn at random for each event of each simulated day from the rules in the head;
delays then propagate over the network of runs, dwells, headways and connections.</li>
<li><b>Punctuality</b>: the share of arrivals × simulated days at most 1, 3 or 5 min late (exact shares).</li>
<li><b>Knock-on</b> delay: the part of an event's delay its train would not have running alone on the line (the
same primary delays, no headways, no connections): the delay other trains cause.</li>
<li><b>Transmitted</b> (passed on): on the days an activity sets its later event's delay, that delay; averaged per
day. <b>Days binding</b>: the share of days it sets it.</li>
<li><b>Slack</b>: scheduled − minimum time of an activity. <b>Absorbed</b>: min(the delay its first event
has, its slack) where both are positive, averaged per day.</li>
<li><b>Quantiles</b> p50 / p90 / p99 are the upper edge of the delay's histogram bin (10 s bins to 10 min, 60 s
beyond): up to 10 s high (60 s beyond 10 min). Means carry a standard error (dataset
<code>robustness_trains</code>, <code>sem_s</code>).</li>
<li>Every figure is in the datasets <code>delay_events</code>, <code>robustness_trains</code>,
<code>robustness_stations</code> and <code>robustness_activities</code>; the page shows the largest.</li>
</ul></div>"""


def render(line_name: str, summary: dict, trains, stations, activities, events, *, nav: str = "") -> str:
    """The page as HTML (module doc); frames may be empty or None; ``nav``: the run's nav line (HTML, as given)."""
    s = dict(summary or {})
    days = int(s.get("days") or 0)
    tr, st, acts, ev = _frame(trains), _frame(stations), _frame(activities), _frame(events)
    names: dict = {}
    for f in (st, tr):
        if len(f):
            names.update(zip(_text(f["station_id"]), _text(f["station_name"])))
    parts = _head(str(line_name), s, tr, st, ev, names, nav)
    parts += _punctuality(st, _travel(ev if len(ev) else tr, st, names), days)
    parts += _predicted(ev, names)
    parts += _spread(acts, tr, names, days)
    parts += _distribution(tr, days)
    parts += _margins(acts, tr, ev, names, days)
    parts.append(READ)
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def write_page(path, line_name, summary, trains, stations, activities, events, *, nav: str = "") -> Path:
    """Write the page atomically to ``path``."""
    from planner.io.atomic import write_bytes_atomic

    path = Path(path)
    write_bytes_atomic(path, render(line_name, summary, trains, stations, activities, events, nav=nav).encode("utf-8"))
    return path


__all__ = ["render", "write_page"]
