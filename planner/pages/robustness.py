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
Carlo did not run and still shows the predicted day. A line checked in sections is rendered from its sections'
shares (:mod:`planner.pages.robustness_share`, :func:`render_shares`): the whole line's frames are never read
together, and the nightly job makes each share once until its section changes. Inline CSS and SVG, no script,
no network; the same inputs give the same bytes.
"""
from __future__ import annotations

import heapq
from pathlib import Path
from typing import Sequence

import numpy as np
import pandas as pd

from planner.line.units import fixed
from planner.pages.margin_report import CSS
from planner.pages.robustness_chart import direction_order, punctuality_chart
from planner.pages.robustness_share import (GROW_ROWS, TOP_LATE, TOP_SPREAD, RobustnessShare, _e, _frame, _pc, _text,
                                            line_order, share, table as _table)
from planner.pages.svg_plot import LEGEND_CSS

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
def _travel(shares: Sequence[RobustnessShare], st: pd.DataFrame, names: dict) -> dict[str, str]:
    """direction → ``A → B, left to right`` from the positions of its trains' first and last events."""
    pos = dict(zip(_text(st["station_id"]), st["position_m"].astype(float))) if len(st) else {}
    ends: dict[str, list] = {}
    for sh in shares:
        for d, pairs in sh.ends.items():
            ends.setdefault(d, []).extend(pairs)
    out = {}
    if not pos or not ends:
        return out
    for d in direction_order(ends):
        a = np.array([pos.get(x, np.nan) for x, _, _ in ends[d]], dtype=float)
        b = np.array([pos.get(y, np.nan) for _, y, _ in ends[d]], dtype=float)
        n = np.array([k for _, _, k in ends[d]], dtype=float)
        ok = np.isfinite(a) & np.isfinite(b)
        if not ok.any():
            continue
        up = float(np.sum(n[ok] * np.sign(b[ok] - a[ok]))) >= 0
        sids = [s for s in {x for x, _, _ in ends[d]} | {y for _, y, _ in ends[d]} if s in pos]
        lo, hi = min(sids, key=lambda s: (pos[s], s)), max(sids, key=lambda s: (pos[s], s))
        a_, b_ = (lo, hi) if up else (hi, lo)
        out[d] = f"{names.get(a_, a_)} → {names.get(b_, b_)}, running {'left to right' if up else 'right to left'}"
    return out


# --- 1. the head -------------------------------------------------------------------------------------------------

def _line_figures(shares: Sequence[RobustnessShare], st: pd.DataFrame) -> dict | None:
    """Whole-line punctuality of the arrivals (from the events, else the stations weighted by arrivals)."""
    sums = np.array([sh.arrivals for sh in shares if sh.arrivals], dtype=float).reshape(-1, 6)
    n = int(sums[:, 0].sum())
    if n:
        s60, s180, s300, mean, knock = (float(x) for x in sums[:, 1:].sum(axis=0))
        return {60: s60 / n, 180: s180 / n, 300: s300 / n, "mean": mean / n,
                "knock": knock / mean if mean > 0 else 0.0, "n": n}
    if len(st) and float(st["arrivals"].sum()) > 0:
        w = st["arrivals"].astype(float)
        f = {m: float((st[f"within_{m}s"] * w).sum() / w.sum()) for m in (60, 180, 300)}
        tot = float((st["mean_delay_s"] * w).sum())
        return {**f, "mean": tot / float(w.sum()), "knock": float((st["knock_on_s"] * w).sum()) / tot if tot > 0
                else 0.0, "n": int(w.sum())}
    return None


def _head(line_name: str, s: dict, shares: Sequence[RobustnessShare], st, names: dict, nav: str) -> list[str]:
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
    f = _line_figures(shares, st) if days > 0 else None
    if f:
        for m, w in ((60, "1"), (180, "3"), (300, "5")):
            cards.append(("info", _pc(f[m]), f"of the line's arrivals at most {w} min late"))
        cards.append(("info", f"{fixed(f['mean'], 1)} <small>s</small>", "mean arrival delay"))
        cards.append(("info", _pc(f["knock"], 0), "of the arrival delay is knock-on (caused by other trains)"))
    events = sum(sh.events for sh in shares)
    n_tr = sum(sh.event_trains for sh in shares) if events else int(s.get("trains") or 0)
    if events:
        big, tid, sid = max((sh.worst for sh in shares if sh.worst), key=lambda w: w[0])  # the first largest
        late = sum(sh.late for sh in shares)
        where = f"largest {fixed(big, 1)} s: {tid} at {names.get(sid, sid)}" if late else "none late"
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

def _top(lists, n: int, key) -> list:
    """The first ``n`` of the sections' candidates (each list already in order) in the order ``key`` gives."""
    return list(heapq.merge(*lists, key=key))[:n]


def _predicted(shares: Sequence[RobustnessShare], names: dict) -> list[str]:
    parts = ["<h2 id='predicted'>The predicted day</h2>"]
    if not sum(sh.events for sh in shares):
        return parts + ["<p>No event: no train runs on this day.</p>"]
    n_late = sum(sh.late for sh in shares)
    parts.append(f"<p class='sub'>The day with every delay carried forward and no primary delay: a late leg "
                 f"delays the next departure, a train held by another at a block waits. {n_late} of "
                 f"{sum(sh.event_trains for sh in shares)} trains are late at some event.</p>")
    if not n_late:
        return parts + ["<p class='ok'>Every train runs to time on the predicted day.</p>"]
    merged: dict[tuple, list] = {}  # a place and cause met in several sections: its trains together
    for sh in shares:
        for sid, kind, cause, ids, first_s, big, grows in sh.causes:
            m = merged.setdefault((sid, kind, cause), [[], -np.inf, -np.inf])
            m[0] += list(zip(first_s, ids))
            m[1], m[2] = max(m[1], big), max(m[2], grows)
    if merged:
        groups = []
        for (sid, kind, cause), (trains, big, gr) in merged.items():
            ids = [t for _, t in sorted(trains)]
            groups.append((-len(ids), -float(big), sid, kind, cause, ids, float(gr)))
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
        top = _top([sh.grow_top for sh in shares], TOP_LATE, key=lambda x: (-x[0], x[1]))
        n_grow = sum(sh.growing for sh in shares)
        cut = sum(x[2] for x in top)
        rows = [r for x in top for r in x[3]]
        more = (f"; the {len(top)} with the largest delays are shown, {n_grow - len(top)} more are in the dataset "
                "<code>delay_events</code>" if n_grow > len(top) else "")
        cut = (f" At most {GROW_ROWS} events a train, where its delay grows most ({cut} more under <i>late trains, "
               "stop by stop</i>)." if cut else "")
        parts.append(f"<h3>Trains whose delay grows</h3><p class='sub'>{n_grow} trains{more}. Times HH:MM:SS; "
                     f"<i>grows by</i>: the delay added at that event.{cut}</p>"
                     + _table(["train", "type, direction", "station", "event", "scheduled", "predicted", "delay [s]",
                               "grows by [s]", "of it knock-on [s]", "why"], rows, left=(0, 1, 2, 3), wrap=(9,),
                              cls="auto"))
    shown = _top([sh.late_top for sh in shares], TOP_LATE, key=lambda x: (-x[0], x[1]))
    more = (f"The {len(shown)} latest of {n_late} late trains; {n_late - len(shown)} more are in the "
            "dataset <code>delay_events</code>." if n_late > len(shown) else f"All {n_late} late trains.")
    parts.append(f"<h3>Late trains, stop by stop</h3><p class='sub'>{more} Open a train for its events, scheduled "
                 "and predicted side by side; an event whose delay grows is shaded.</p>")
    parts += [x[2] for x in shown]
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

def _spread(shares: Sequence[RobustnessShare], days: int) -> list[str]:
    parts = ["<h2 id='spread'>Where delay spreads</h2>"]
    if days <= 0 or not any(sh.activities or sh.trains_rows for sh in shares):
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    n = sum(sh.spread for sh in shares)
    if n:
        top = _top([sh.spread_top for sh in shares], TOP_SPREAD,
                   key=lambda x: (np.isnan(x[0]), -x[0] if not np.isnan(x[0]) else 0.0, x[1], x[2], x[3]))
        parts.append(f"<h3>Headways and connections passing on the most delay</h3><p class='sub'>The {len(top)} of "
                     f"{n:,} with the largest mean delay passed on per day: the first train's delay reaches the "
                     "second through the shared switch or section (or the connection).</p>"
                     + _table(["kind", "trains (first → held)", "place", "stations (first → held)", "slack [s]",
                               "transmitted [s/day]", "days binding", "absorbed [s/day]"], [x[4] for x in top],
                              left=(0, 1, 2, 3), cls="auto"))
    else:
        parts.append("<p>No headway or connection in the network.</p>")
    if any(sh.trains_rows for sh in shares):
        top = _top([sh.knock_top for sh in shares], TOP_SPREAD,
                   key=lambda x: (np.isnan(x[0]), -x[0] if not np.isnan(x[0]) else 0.0, x[1]))
        parts.append(f"<h3>Knock-on delay per train</h3><p class='sub'>The {len(top)} of "
                     f"{sum(sh.knock for sh in shares)} trains with the largest mean knock-on delay at their "
                     "destination.</p>"
                     + _table(["train", "type", "direction", "destination", "scheduled", "mean delay [s]",
                               "of it knock-on [s]", "knock-on share", "primary delay drawn on its run [s/day]"],
                              [x[2] for x in top], left=(0, 1, 2, 3), cls="auto"))
    return parts


# --- 5. each train's delay distribution --------------------------------------------------------------------------

_DIST_HEAD = ["", "train", "dir.", "from → to", "departs", "arrives", "mean [s]", "p50", "p90", "p99", "≤ 1 min",
              "≤ 3 min", "≤ 5 min", "knock-on [s]"]


def _distribution(shares: Sequence[RobustnessShare], days: int) -> list[str]:
    parts = ["<h2 id='distribution'>Each train's delay distribution</h2>"]
    if days <= 0 or not any(sh.trains_rows for sh in shares):
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    parts.append("<p class='sub'>One line per train: its arrival at its destination over the simulated days (mean, "
                 "percentiles p50 / p90 / p99 in seconds, share of days within 1 / 3 / 5 min, mean knock-on). Open "
                 "a train for every stop (its arrivals and its departure from the origin). Trains by type, then "
                 "direction and departure; a p90 or p99 over 3 min in red.</p>")
    head = "<div class='hd'>" + "".join(f"<span{' class=r' if i > 5 else ''}>{_e(h)}</span>"
                                        for i, h in enumerate(_DIST_HEAD)) + "</div>"
    trains = [x for sh in shares for x in sh.dist]
    order_of = line_order(x[1] for x in trains)
    trains.sort(key=lambda x: (x[0], order_of[x[1]], x[2], x[3]))
    out: dict[str, list[str]] = {}
    for x in trains:
        out.setdefault(x[0], []).append(x[4])
    for tt in sorted(out):
        parts.append(f"<h3>{_e(tt)} · {len(out[tt])} trains</h3><div class='tw'><div class='dist'>{head}"
                     f"{''.join(out[tt])}</div></div>")
    return parts


# --- 6. margins at work ------------------------------------------------------------------------------------------

def _margins(shares: Sequence[RobustnessShare], names: dict, days: int) -> list[str]:
    parts = ["<h2 id='margins'>Margins at work</h2>"]
    if days <= 0 or not sum(sh.runs for sh in shares):
        return parts + ["<p>No simulated day: the Monte Carlo did not run.</p>"]
    legs: dict[tuple, list] = {}  # a leg of several sections: its means weighted by each one's count
    for sh in shares:
        for d, tt, a, b, n, *means in sh.legs:
            got = legs.get((d, tt, a, b))
            if got is None:
                legs[(d, tt, a, b)] = [n, *means]
            else:
                total = got[0] + n
                legs[(d, tt, a, b)] = [total, *((x * got[0] + y * n) / total for x, y in zip(got[1:], means))]
    keys = ["direction", "train_type", "from_station", "to_station"]
    g = pd.DataFrame([[*k, *v] for k, v in sorted(legs.items())],
                     columns=[*keys, "n", "slack", "absorbed", "passed", "binding"])
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


def render_shares(line_name: str, summary: dict, stations, shares: Sequence[RobustnessShare], *,
                  nav: str = "") -> str:
    """The page as HTML from the line's ``robustness_stations`` frame (may be empty or None) and its sections'
    shares (:func:`planner.pages.robustness_share.share`, in the sections' order); ``nav``: the run's nav line
    (HTML, as given)."""
    s = dict(summary or {})
    days = int(s.get("days") or 0)
    st = _frame(stations)
    names: dict = dict(zip(_text(st["station_id"]), _text(st["station_name"]))) if len(st) else {}
    for sh in shares:
        names.update(sh.names)
    parts = _head(str(line_name), s, shares, st, names, nav)
    parts += _punctuality(st, _travel(shares, st, names), days)
    parts += _predicted(shares, names)
    parts += _spread(shares, days)
    parts += _distribution(shares, days)
    parts += _margins(shares, names, days)
    parts.append(READ)
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def render(line_name: str, summary: dict, trains, stations, activities, events, *, nav: str = "") -> str:
    """The page as HTML (module doc) from the whole line's frames, which may be empty or None: one share."""
    days = int((summary or {}).get("days") or 0)
    return render_shares(line_name, summary, stations, [share(trains, stations, activities, events, days)], nav=nav)


def write_page(path, line_name, summary, trains, stations, activities, events, *, nav: str = "") -> Path:
    """Write the page atomically to ``path``."""
    from planner.io.atomic import write_bytes_atomic

    path = Path(path)
    write_bytes_atomic(path, render(line_name, summary, trains, stations, activities, events, nav=nav).encode("utf-8"))
    return path


__all__ = ["render", "render_shares", "write_page"]
