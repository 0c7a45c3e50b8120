"""The margin-time report as one self-contained HTML page (docs/design.md §6, §9).

:func:`render_html` turns a :class:`planner.report.margins.MarginReport` into a
single HTML document that needs no network: inline CSS, charts as inline SVG
written by :mod:`planner.pages.margin_charts` (with :mod:`planner.pages.svg_plot`; their legends in
HTML), no scripts. It is deterministic (same report, same bytes): no timestamps, SVG ids fixed by
the code.

Sections, in the order a timetable planner reads them:

1. headline: the run's other pages, its id and operating day (in a run), line,
   directions, train types, the conditions assumed, counts of flags, the flagged
   legs with their trains, totals per direction and train type, and what stands out;
2. margin per interstation along the line, one chart per direction with a
   row per train type: the margin (scheduled − minimum), the margin that
   remains on a bad day, the bad-day margin (scheduled − bad-day minimum), the supplement the
   rule asks for, flagged legs coloured;
3. run curves of one leg (default: the least remaining margin): minimum, as
   scheduled (closed loop), degraded with its low-adhesion stopping pattern,
   and where along the leg the time is lost;
4. stopping time against adhesion for every approach of that train type;
5. the legs in a table, flagged ones first;
6. totals per train (collapsed);
7. route conflicts, when the conflict check gave rows;
8. how the numbers are made.
"""
from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np

from planner.line.model import line_title  # noqa: F401 - the pages import it from here too
from planner.line.units import clock, fixed, hms, percent, shown

from planner.pages.margin_charts import chart_sections
from planner.pages.svg_plot import LEGEND_CSS
from planner.report.leg_flags import FLAG, FLAGS, FLAGS_SHOWN, added_up, any_flag, flag_of, flags_of

CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,Helvetica,Arial,sans-serif;margin:0;color:#1d2327;background:#f6f7f9}
main{max-width:1320px;margin:0 auto;padding:18px 28px 60px}
h1{font-size:26px;margin:8px 0 2px}h2{font-size:20px;margin:34px 0 8px;border-bottom:2px solid #d5d9de;padding-bottom:4px}
h3{font-size:16px;margin:18px 0 6px}
p,li{line-height:1.45;font-size:14px}.sub{color:#555;margin:0 0 14px;font-size:14px}
.cards{display:flex;flex-wrap:wrap;gap:12px;margin:14px 0}
.card{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:10px 16px;min-width:150px}
.card .n{font-size:28px;font-weight:700}.card .l{font-size:13px;color:#555}
.card.bad{border-left:6px solid #c62828}.card.warn{border-left:6px solid #ef8f00}
.card.purple{border-left:6px solid #6a1b9a}.card.ok{border-left:6px solid #2e7d32}.card.info{border-left:6px solid #5a7da8}
.fig{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:8px;margin:10px 0}
.fig svg{width:100%;height:auto;display:block}
.caption{font-size:13px;color:#444;margin:4px 4px 2px}
.tw{overflow-x:auto;max-width:100%}
table{border-collapse:collapse;background:#fff;font-size:12px;width:100%}
th,td{border:1px solid #dde1e5;padding:3px 5px;text-align:right;white-space:nowrap}
th{background:#eef1f4;position:sticky;top:0;font-weight:600;white-space:normal;vertical-align:bottom}
td.l,th.l{text-align:left}td.why{white-space:normal}td.fl,td.lg{white-space:normal}td.fl{min-width:6.5em}
.nw{white-space:nowrap}.via{color:#777;white-space:nowrap}.ids{color:#333}.more{border-bottom:1px dotted #777;cursor:help}
.nav .run{color:#333}
@media (max-width:1300px){td.cost{white-space:normal;min-width:7em}}
@media (max-width:1100px){main{padding:12px 12px 40px}table{font-size:11px}th,td{padding:2px 3px}td.w{white-space:normal}}
tr.unassessed td{background:#e3e7ea}tr.impossible td{background:#f8d7d3}tr.short_bad_day td{background:#fdecea}
tr.tight td{background:#fff4e0}tr.unreachable td{background:#f3e5f5}tr.inaccurate td{background:#fff8e1}
tr.sep td{background:#d5d9de;text-align:left;font-weight:600}
.badge{display:inline-block;border-radius:4px;padding:0 5px;margin:1px 0;color:#fff;font-size:11px;font-weight:600}
""" + "".join(f".b-{f.name}{{background:{f.colour}}}" for f in FLAGS_SHOWN) + """
.b-short{background:#fff;color:#8a5a00;border:1px solid #c89b3c}
.neg{color:#c62828;font-weight:600}
details{margin:10px 0}summary{cursor:pointer;font-weight:600;font-size:14px}
.note{background:#fff;border:1px solid #d5d9de;border-radius:8px;padding:8px 16px}
code{font-size:12.5px}
"""


# --- small formatting helpers ------------------------------------------------------

def _e(x) -> str:
    return html.escape(str(x), quote=True)


def _f(x, nd: int = 1, sign: bool = False) -> str:
    """Number for a table cell; '–' for NaN/None; a non-zero value never shown as 0.0 (a margin of −0.03 s,
    flagged impossible, reads −0.03: :func:`planner.line.units.shown`)."""
    return shown(x, nd, sign)


def _hms(t: float) -> str:
    return clock(t) or "–"


def _leg(r) -> str:
    """The leg, the stations it passes, and the day's temporary restrictions its trains run with (a leg whose
    trains pass partly while a part-day restriction is lifted has a row with it and one without)."""
    via = f" <span class='via'>(passes {len(r.passes)})</span>" if len(r.passes) else ""
    temp = getattr(r, "restrictions", None)
    temp = [] if temp is None else list(temp)
    tsr = f" <span class='via'>(with {_e(', '.join(map(str, temp)))})</span>" if temp else ""
    return f"<span class='nw'>{_e(r.origin)} → {_e(r.destination)}</span>{via}{tsr}"


def _ids(r) -> list[str]:
    ids = getattr(r, "train_ids", None)
    return [str(t) for t in ids] if ids is not None else []


def trains_html(ids, href: str = "", first: int = 6) -> str:
    """A leg's trains: the first ``first`` (each a link to its running-time table when ``href``, the tables
    page) and ``… N more``, which names them all on hover."""
    ids = list(ids)
    one = (lambda t: f"<a href='{_e(href)}#train-{_e(t)}'>{_e(t)}</a>") if href else _e
    text = ", ".join(one(t) for t in ids[:first])
    if len(ids) > first:
        text += f" <span class='more' title='{_e(', '.join(ids))}'>… {len(ids) - first} more</span>"
    return text


# --- tables ------------------------------------------------------------------------

LOSS_COLUMNS = ("degraded_loss_load_s", "degraded_loss_traction_s", "degraded_loss_stop_s", "degraded_loss_stop_model_s")
"""The shares of the bad day's cost (degraded − minimum) in the ``margins`` dataset: load, traction, stop, stop model."""


def cost_breakdown(r, nd: int = 1) -> str:
    """``cost = load + traction + stop ± stop model`` of a margin row [s], the shown parts adding up to the shown cost."""
    cost = r.degraded_min_running_time_s - r.min_running_time_s
    parts = [getattr(r, c) for c in LOSS_COLUMNS]
    if not all(math.isfinite(x) for x in [cost] + parts):
        return f"{_f(cost, nd)} = " + " + ".join(_f(x, nd) for x in parts)
    t, shown = added_up(cost, parts, nd)
    text = f"{fixed(t, nd)} = {fixed(shown[0], nd)}"
    for x in shown[1:]:
        v = fixed(x, nd, True)
        text += f" − {v[1:]}" if v.startswith("-") else f" + {v.lstrip('+')}"
    return text


def flagged_summary(sched, trains_href: str = "") -> str:
    """The flagged legs on the first screen: what each lacks, where the bad day's time goes and which trains
    run it (linked to their running-time tables when ``trains_href``)."""
    # unassessed legs have their own section, listed first; this one lists the legs judged
    f = sched[any_flag(sched) & ~sched.unassessed.astype(bool)]
    if f.empty:
        return "<p><b>No leg is flagged</b>: every timetabled leg keeps its time on a bad day.</p>"
    f = f.sort_values(["remaining_margin_s", "direction", "train_type", "origin"], kind="stable")
    med = float(sched.margin_percent.median())
    out = [f"<h3 id='flagged'>Flagged legs ({len(f)} of {len(sched)}; the median margin of the day is {med:.1f} %)</h3>"
           "<div class='tw'><table class='flagged'><tr><th class='l'>flag</th>"
           "<th class='l'>dir</th><th class='l'>type</th><th class='l'>leg</th><th>trains</th><th>scheduled [s]</th>"
           "<th>margin [s] (%)</th><th>bad-day cost [s]: load + traction + stop + stop model</th>"
           "<th>bad-day margin [s]</th></tr>"]
    for r in f.itertuples(index=False):
        flag = flag_of(r)
        why = getattr(r, "flag_reason", "") or ""
        ids = _ids(r)
        out.append(
            f"<tr class='{flag}'><td class='l fl'>{_badges(r)}</td>"
            f"<td class='l'>{_e(r.direction)}</td><td class='l'>{_e(r.train_type)}</td><td class='l lg'>{_leg(r)}</td>"
            f"<td>{r.n_trains}</td><td>{_f(r.scheduled_running_time_s, 0)}</td>"
            f"<td>{_f(r.margin_s, 1, True)} ({_f(r.margin_percent, 1)})</td>"
            f"<td class='cost'>{cost_breakdown(r)}</td><td>{_f(r.remaining_margin_s, 1, True)}</td></tr>"
            f"<tr class='{flag}'><td colspan='9' class='l why'>{'↳ ' + _e(why) + '<br>' if why else ''}"
            f"<span class='ids'>trains: {trains_html(ids, trains_href) or '–'}</span></td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def bad_day_shares(sched, rule, adh) -> str:
    """Each effect's share of the bad day's cost, summed over every train run of the day."""
    if sched.empty:
        return ""
    w = sched.n_trains.to_numpy(float)
    parts = [("load", "degraded_loss_load_s", rule.bad_day_load,
              f"load {rule.degraded_load:.0%}"),
             ("traction", "degraded_loss_traction_s", rule.bad_day_traction,
              f"traction ×{rule.degraded_traction:g}"),
             ("adhesion (the stop)", "degraded_loss_stop_s", rule.bad_day_adhesion,
              f"adhesion {rule.bad_adhesion_kmh_s(adh):g} km/h/s" if rule.bad_day_adhesion else "stopping brake"),
             ("stop model", "degraded_loss_stop_model_s", True,
              "stopping pattern against the tables' stopping brake, not a bad-day effect")]
    vals = [float(np.nansum(sched[c].to_numpy(float) * w)) for _, c, _, _ in parts]
    tot = sum(vals)
    cells = []
    for (name, _c, on, what), v in zip(parts, vals):
        share = f"{100 * v / tot:.0f} %" if tot > 0 else "–"
        state = what if on else "off"
        cells.append(f"<b>{_e(name)}</b> ({_e(state)}): {v / 3600:.2f} h, {share}")
    return ("<p class='sub'>Where a bad day's time goes, summed over every train run of the day: "
            + " · ".join(cells) + f" (together {tot / 3600:.2f} h, the whole bad-day cost). Each effect is switched "
            "on or off and valued in the job file (<code>[margins]</code> <code>bad_day_*</code>, "
            "<code>degraded_*</code>).</p>")


ROW_HEAD = ("<tr><th class='l'>flags</th><th class='l'>dir</th><th class='l'>type</th><th class='l'>leg</th>"
            "<th>trains</th><th>km</th><th>minimum [s]</th><th>min ↑10 s</th><th>scheduled [s]</th>"
            "<th>margin [s] (%)</th><th>rule asks [s]</th><th>bad-day minimum [s]</th>"
            "<th>bad-day margin [s]</th><th>bad-day cost: load + traction + stop + stop model [s]</th>"
            "<th>ratio at on-time departure</th><th>arrival error nominal / bad day [s]</th>"
            "<th>energy at that ratio vs 100 %</th></tr>")


def _badges(r) -> str:
    """The row's flags as badges, worst first, each with what it says on hover."""
    tip = f" title='{_e(r.flag_reason)}'" if getattr(r, "flag_reason", "") else ""
    return " ".join(f"<span{tip} class='badge b-{f}'>{_e(FLAG[f].badge)}</span>" for f in flags_of(r))


def _row_html(r) -> str:
    flag = flag_of(r)
    badges = _badges(r)
    if np.isfinite(r.scheduled_running_time_s) and not bool(r.supplement_met):
        badges += " <span class='badge b-short'>supplement short</span>"
    rem = r.remaining_margin_s
    rem_s = _f(rem, 1, sign=True)
    if math.isfinite(rem) and rem < 0:
        rem_s = f"<span class='neg'>{rem_s}</span>"
    ids = _ids(r)
    run_by = f"{len(ids)} train{'s' if len(ids) != 1 else ''}: " + ", ".join(ids[:12]) + (
        f" … {len(ids) - 12} more" if len(ids) > 12 else "")
    tip = "; ".join(x for x in (run_by, getattr(r, "flag_reason", "") or (r.unassessed_reason if r.unassessed else ""),
                                r.note) if x)
    cls = f" class='{flag}'" if flag != "ok" else ""
    return (
        f"<tr{cls} title='{_e(tip)}'><td class='l fl'>{badges}</td><td class='l'>{_e(r.direction)}</td>"
        f"<td class='l'>{_e(r.train_type)}</td><td class='l lg'>{_leg(r)}</td><td>{r.n_trains}</td>"
        f"<td>{r.length_m / 1000:.2f}</td><td>{_f(r.min_running_time_s)}</td>"
        f"<td>{_f(r.min_running_time_rounded_s, 0)}</td><td>{_f(r.scheduled_running_time_s, 0)}</td>"
        f"<td class='w'>{_f(r.margin_s, 1, True)} ({_f(r.margin_percent, 1)})</td>"
        f"<td>{_f(r.supplement_required_s)}</td><td>{_f(r.degraded_min_running_time_s)}</td>"
        f"<td>{rem_s}</td><td class='cost'>{cost_breakdown(r)}</td>"
        f"<td>{percent(r.ratio_on_time)}</td>"
        f"<td class='w'>{_f(r.arrival_error_s, 1, True)} / {_f(r.arrival_error_degraded_s, 1, True)}</td>"
        f"<td class='w'>{energy_change(r.energy_saved_percent)}</td></tr>"
    )


def rows_table(rows) -> str:
    """All legs: unassessed ones first (with their reason), then flagged ones (least remaining margin first),
    then the rest in running order."""
    una = rows[rows.unassessed.astype(bool)]
    assessed = rows.drop(una.index)
    flagged = assessed[any_flag(assessed)].sort_values(
        ["remaining_margin_s", "direction", "train_type"], kind="stable")
    rest = assessed.drop(flagged.index)
    out = ["<div class='tw'><table>", ROW_HEAD]
    if len(una):
        out.append(f"<tr class='sep'><td colspan='17'>Unassessed legs ({len(una)}): no bad-day minimum could be "
                   "computed, so short on a bad day and tight are unknown</td></tr>")
        for r in una.itertuples(index=False):
            out.append(_row_html(r))
            out.append(f"<tr class='unassessed'><td colspan='17' class='l'>↳ {_e(r.unassessed_reason)}</td></tr>")
    out.append(f"<tr class='sep'><td colspan='17'>Flagged legs ({len(flagged)}), least bad-day margin first</td></tr>")
    out += [_row_html(r) for r in flagged.itertuples(index=False)]
    out.append(f"<tr class='sep'><td colspan='17'>Other legs ({len(rest)}), in running order</td></tr>")
    out += [_row_html(r) for r in rest.itertuples(index=False)]
    out.append("</table></div>")
    return "\n".join(out)


def totals_table(totals, scopes=("line", "type")) -> str:
    t = totals[totals.level.isin(scopes)].copy()
    t["o"] = t.level.map({"line": 0, "type": 1})
    t = t.sort_values(["direction", "o", "train_type"], kind="stable")
    out = ["<div class='tw'><table><tr><th class='l'>direction</th><th class='l'>train type</th><th>trains</th>"
           "<th>train runs of a leg</th>"
           "<th>sum of minimum running times [h:mm:ss]</th><th>sum of scheduled [h:mm:ss]</th>"
           "<th>sum of margins [h:mm:ss]</th>"
           "<th>margin %</th><th>sum of bad-day margins [h:mm:ss]</th><th>least bad-day margin, one leg [s]</th>"
           "<th>train runs on an impossible leg</th><th>… on a leg short on a bad day</th><th>… on a tight leg</th>"
           "<th>… on an unreachable leg</th>"
           "<th>… on a leg short of the rule</th><th>energy saved [kWh]</th></tr>"]
    for r in t.itertuples(index=False):
        bold = " style='font-weight:600'" if r.level == "line" else ""
        out.append(
            f"<tr{bold}><td class='l'>{_e(r.direction)}</td><td class='l'>"
            f"{'all types' if r.level == 'line' else _e(r.train_type)}</td><td>{r.n_trains}</td><td>{r.n_legs}</td>"
            f"<td>{hms(r.min_running_time_s)}</td><td>{hms(r.scheduled_running_time_s)}</td>"
            f"<td>{hms(r.margin_s)}</td><td>{_f(r.margin_percent)}</td><td>{hms(r.remaining_margin_s, sign=True)}</td>"
            f"<td>{_f(r.min_remaining_margin_s, 1, True)}</td><td>{r.n_impossible}</td><td>{r.n_short_bad_day}</td>"
            f"<td>{r.n_tight}</td>"
            f"<td>{r.n_unreachable}</td><td>{r.n_supplement_short}</td><td>{r.energy_saved_kwh:.0f}</td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def train_table(totals) -> str:
    t = totals[totals.level == "train"].copy()
    t = t.sort_values(["n_impossible", "n_infeasible", "min_remaining_margin_s", "train_id"],
                      ascending=[False, False, True, True],
                      kind="stable")
    out = ["<div class='tw'><table><tr><th class='l'>train</th><th class='l'>dir</th><th class='l'>type</th>"
           "<th class='l'>from → to</th><th>departs</th><th>legs</th><th>minimum [s]</th><th>scheduled [s]</th>"
           "<th>margin [s]</th><th>margin %</th><th>remaining [s]</th><th>worst leg [s]</th>"
           "<th>impossible</th><th>short on a bad day</th><th>tight</th><th>unreachable</th></tr>"]
    for r in t.itertuples(index=False):
        worst = next((f for f in ("impossible", "short_bad_day", "tight") if getattr(r, f"n_{f}")), "")
        cls = f" class='{worst}'" if worst else ""
        out.append(
            f"<tr{cls}><td class='l'>{_e(r.train_id)}</td><td class='l'>{_e(r.direction)}</td>"
            f"<td class='l'>{_e(r.train_type)}</td><td class='l'>{_e(r.origin)} → {_e(r.destination)}</td>"
            f"<td>{_hms(r.first_departure_s)}</td><td>{r.n_legs}</td><td>{r.min_running_time_s:.0f}</td>"
            f"<td>{r.scheduled_running_time_s:.0f}</td><td>{_f(r.margin_s, 0)}</td><td>{_f(r.margin_percent)}</td>"
            f"<td>{_f(r.remaining_margin_s, 0, True)}</td><td>{_f(r.min_remaining_margin_s, 1, True)}</td>"
            f"<td>{r.n_impossible}</td><td>{r.n_short_bad_day}</td><td>{r.n_tight}</td><td>{r.n_unreachable}</td></tr>")
    out.append("</table></div>")
    return "\n".join(out)


def conflicts_section(report) -> str:
    con = report.conflicts
    if con is None:
        return (f"<h2 id='conflicts'>Route conflicts</h2><p>Not checked: {_e(report.conflicts_note)}.</p>"
                if report.conflicts_note else "")
    if len(con) == 0:
        return "<h2 id='conflicts'>Route conflicts</h2><p>The conflict check found no overlapping occupation windows.</p>"
    from planner.datasets.conflicts import conflict_list, largest

    c = conflict_list(con)
    by_rule = ", ".join(f"{v} {_e(k)}" for k, v in c["rule"].value_counts().sort_index().items())
    n_res = len(con.groupby(["resource_kind", "resource_id"]).size())
    head = (f"<p>{len(c)} conflict{'s' if len(c) != 1 else ''} between {len(c.groupby(['train_a', 'train_b']))} "
            f"pairs of trains on {n_res} resource{'s' if n_res != 1 else ''} ({by_rule}); "
            f"{int(c.deadlock.sum())} would deadlock. The decisions delay the waiting trains by "
            f"{c.delay_s.sum():.0f} s in all, at most {c.delay_s.max():.1f} s. The {min(len(c), 10)} largest delays "
            f"(of equal delays the earliest), in time order; a conflict spans one or more consecutive sections or "
            f"switches. <i>Minimum headway</i>: the first train's blocking time on the resource, the least time "
            f"after it that the second may enter without a conflict; <i>headway</i>: how much later it enters as "
            f"planned.</p>")

    def table(df) -> str:
        out = ["<div class='tw'><table><tr><th>#</th><th>at</th><th class='l'>first</th><th class='l'>waits</th>"
               "<th class='l'>where</th><th class='l'>resource</th><th class='l'>interlocking</th><th>resources</th>"
               "<th>overlap [s]</th><th>headway [s]</th><th>min. headway [s]</th>"
               "<th>delay [s]</th><th class='l'>rule</th><th class='l'>decision</th></tr>"]
        for cid, r in df.iterrows():
            out.append(f"<tr><td>{cid}</td><td>{_hms(r.t0)}</td><td class='l'>{_e(r.train_a)}</td>"
                       f"<td class='l'>{_e(r.train_b)}</td><td class='l'>{_e(r.place)}</td>"
                       f"<td class='l'>{_e(r.resource)}</td>"
                       f"<td class='l'>{_e(r.interlocking)}</td><td>{r.n}</td><td>{r.overlap_s:.1f}</td>"
                       + "".join(f"<td>{v:.1f}</td>" if v == v else "<td>–</td>" for v in (r.headway_s, r.min_headway_s))
                       + f"<td>{r.delay_s:.1f}</td><td class='l'>{_e(r.rule)}</td><td class='l' style='white-space:normal;min-width:16em'>{_e(r.decision)}</td></tr>")
        out.append("</table></div>")
        return "\n".join(out)

    return ("<h2 id='conflicts'>Route conflicts</h2>" + head + table(largest(c, 10))
            + (f"<details><summary>All {len(c)} conflicts in time order</summary>{table(c.sort_values('t0', kind='stable'))}"
               "</details>" if len(c) > 10 else ""))


# --- the page -------------------------------------------------------------------------

def energy_change(saved_percent: float) -> str:
    """Energy at the on-time ratio against ratio 100 %, in words: ``12 % saved``, ``3 % more``, ``±0 %``.

    Examples
    --------
    >>> energy_change(12.3), energy_change(-4.2), energy_change(-0.2), energy_change(float("nan"))
    ('12 % saved', '4 % more', '±0 %', '–')
    """
    if saved_percent is None or not math.isfinite(saved_percent):
        return "–"
    if abs(saved_percent) < 0.5:
        return "±0 %"
    return f"{saved_percent:.0f} % saved" if saved_percent > 0 else f"{-saved_percent:.0f} % more"


def render_html(report, markers: dict[str, dict[str, float]], datasets_href: str = ".", top: str = "",
                charts: list[str] | None = None, *, nav: str = "", trains_href: str = "") -> str:
    """The whole report page as one HTML string (module doc for the sections).

    Parameters
    ----------
    report : planner.report.margins.MarginReport
    markers : dict
        ``{direction: {station_id: stop-marker chainage [m]}}`` for the charts
        (:func:`stop_markers`).
    datasets_href : str
        Relative path from the page's folder to the folder holding the ``margins`` and
        ``margin_totals`` datasets (``..`` in a published run, ``.`` for ``planner margins --out``).
    top : str
        An HTML section put first, under the title (the nightly job's "what
        changed since the last run", :func:`planner.pages.changes.changes_html`).
    charts : list of str, optional
        The chart sections, :func:`chart_sections` of the same report and markers, when
        they were drawn beforehand (the nightly job draws them on a worker); else drawn here.
    nav : str
        The line above the title: links to the run's other pages, its run id and operating day
        (:func:`planner.pages.run_head.nav_html`).
    trains_href : str
        The running-time tables page (relative to this page): each flagged leg's trains link to their tables.
    """
    rows = report.rows
    sched = rows[rows.scheduled_running_time_s.notna()]
    trains = report.totals[report.totals.level == "train"]
    rule, adh = report.rule, report.adhesion_kmh_s
    parts = _headline(report, sched, trains, top, nav)
    parts.append("<ul>" + "".join(f"<li>{x}</li>" for x in _findings(sched, trains)) + "</ul>")
    parts.append(flagged_summary(sched, trains_href))
    parts.append(bad_day_shares(sched, rule, adh))
    parts.append("<h3>Totals per direction and train type (every timetabled train run, the whole day)</h3>")
    parts.append(totals_table(report.totals))
    parts += chart_sections(report, markers) if charts is None else charts
    parts.append("<h2 id='legs'>Every leg</h2>")
    parts.append(
        "<p class='caption'>One row per leg and scheduled time (trains with the same leg and time share a row). "
        "<i>min ↑10 s</i>: the minimum rounded up to the 10-second timetable unit. <i>bad-day cost</i>: bad-day "
        "minimum − minimum, and its four shares: what the bad day's load and traction cost up to the pattern start, "
        "what the low-adhesion stop costs against the best adhesion, and the stop model (the nominal run's stopping "
        "pattern against the tables' constant stopping brake; negative when the pattern stops sooner). "
        "<i>ratio</i>: the target-speed ratio the vehicle picks at an on-time "
        "departure. <i>arrival error</i>: closed loop of the on-board logic, positive = late. <i>energy saved</i>: "
        "traction energy at that ratio against ratio 100 %. Hover a row for the trains that run it and its notes; a flag badge for what the flag says.</p>")
    parts.append(rows_table(rows))
    parts.append(f"<details><summary>Totals per train ({len(trains)} trains; with impossible legs first, then legs short on a bad day)</summary>"
                 f"{train_table(report.totals)}</details>")
    parts.append(conflicts_section(report))
    parts.append(_method(report, datasets_href))
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def _headline(report, sched, trains, top: str, nav: str = "") -> list[str]:
    """The page's head, the ``nav`` line, title, conditions, the ``top`` section and the flag cards."""
    rows = report.rows
    sched = rows[rows.scheduled_running_time_s.notna()]
    counts = {f: int(np.sum(any_flag(rows if f in ("unassessed", "inaccurate") else sched, (f,)))) for f in FLAGS}
    n_short = int((~sched.supplement_met).sum())
    rule = report.rule
    adh = report.adhesion_kmh_s
    types = ", ".join(sorted(rows.train_type.unique()))
    dirs = ", ".join(d for d in ("down", "up") if d in set(rows.direction))
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>Margin report — {_e(line_title(report.line_name, report.line_id))}</title>"
             f"<style>{CSS}{LEGEND_CSS}</style></head><body><main>{nav}"]
    parts.append(f"<h1>Running-time margins — {_e(line_title(report.line_name, report.line_id))}</h1>")
    parts.append(
        f"<p class='sub'>Directions {dirs} · train types {types} · {len(sched)} timetabled legs "
        f"(stop to next stop) run by {len(trains)} trains · "
        f"minimum = ratio 100 %, empty, nominal traction · <b>bad day</b> = {_e(rule.describe(adh))} "
        f"(adhesion sweep {adh[0]:g}–{adh[-1]:g} km/h/s) · supplement rule {rule.supplement_percent:g} % + "
        f"{rule.supplement_min_per_100km:g} min/100 km · tight below {rule.tight_threshold_s:g} s remaining</p>")
    if top:
        parts.append(top)
    # cards count distinct legs (train type × stop → next stop × scheduled time); the totals table
    # below counts train runs, and says so
    words = {"tight": f"legs tight: less than {rule.tight_threshold_s:g} s left on a bad day",
             "inaccurate": f"legs inaccurate: the closed loop misses the arrival by more than "
                           f"{rule.arrival_error_threshold_s:g} s"}
    cards = [(f.severity if counts[f.name] else "ok", counts[f.name], words.get(f.name, f.card)) for f in FLAGS_SHOWN]
    cards += [
        ("warn" if n_short else "ok", n_short, "legs with a margin below the supplement rule"),
        ("info", f"{len(sched)}", "legs checked (train type × stop → next stop × scheduled time), "
                                  f"run {int(sched.n_trains.sum())} times a day"),
    ]
    parts.append("<div class='cards'>" + "".join(
        f"<div class='card {c}'><div class='n'>{n}</div><div class='l'>{_e(l)}</div></div>" for c, n, l in cards)
        + "</div>")
    return parts


def _findings(sched, trains) -> list[str]:
    """What stands out among the legs that could be assessed, as list items (HTML)."""
    find = []
    una = sched[sched.unassessed.astype(bool)]
    if len(una):  # first: a leg no figure speaks for, the worst being a stop the vehicle's DB cannot make
        ns = una[una.unassessed_cause.astype(str) == "no_stop"] if "unassessed_cause" in una else una.iloc[:0]
        stuck = sorted({f"{r.train_type} {r.direction} {r.origin} → {r.destination}" for r in ns.itertuples()})
        find.append(f"{len(una)} of {len(sched)} legs are <b>unassessed</b>: no bad-day minimum (<a href='#legs'>every "
                    "leg</a> says why)" + (f"; among them, no stopping pattern stops the train on "
                                           f"{_e(', '.join(stuck))}: their bundles hold no pattern there"
                                           if stuck else "") + ".")
    # what stands out (among the legs that could be assessed)
    if (~sched.unassessed.astype(bool)).any():
        w = sched.sort_values("remaining_margin_s", kind="stable").iloc[0]
        find.append(f"Least margin on a bad day: <b>{_e(w.train_type)} {_e(w.direction)} {_e(w.origin)} → "
                    f"{_e(w.destination)}</b>, scheduled {w.scheduled_running_time_s:.0f} s against a minimum of "
                    f"{w.min_running_time_s:.1f} s and a bad-day minimum of {w.degraded_min_running_time_s:.1f} s "
                    f"({_f(w.remaining_margin_s, 1, True)} s).")
        find.append(f"Median margin {sched.margin_s.median():.1f} s ({sched.margin_percent.median():.1f} %); "
                    f"a bad day costs a median {sched.degraded_loss_load_s.median():.1f} s for the load, "
                    f"{sched.degraded_loss_traction_s.median():.1f} s for the weak traction and "
                    f"{sched.degraded_loss_stop_s.median():.1f} s in the stop (low adhesion), so the median "
                    f"bad-day margin is {_f(sched.remaining_margin_s.median(), 1, True)} s.")
        tr = trains[trains.bad_day_shortfall_s > 0]
        if len(tr):
            w = tr.sort_values(["bad_day_shortfall_s", "train_id"], ascending=[False, True], kind="stable").iloc[0]
            find.append(f"{len(tr)} of {len(trains)} trains lose time on a bad day; adding what each leg lacks "
                        f"would lengthen their runs by a median {tr.bad_day_shortfall_s.median():.0f} s "
                        f"(at most {w.bad_day_shortfall_s:.0f} s, train {_e(w.train_id)} {_e(w.origin)} → "
                        f"{_e(w.destination)}).")
        imp = sched[any_flag(sched, ("impossible",))]
        if len(imp):
            find.append(f"{len(imp)} of {len(sched)} legs are <b>impossible</b>: scheduled below the minimum running "
                        f"time, by {(-imp.margin_s).median():.1f} s (median) and {(-imp.margin_s).max():.1f} s at "
                        "most; no driving makes them, on any day.")
        short = sched[any_flag(sched, ("short_bad_day",))]
        if len(short):
            main = short.bad_day_cause.value_counts()
            find.append(f"{len(short)} of {len(sched)} legs are <b>short on a bad day</b>: they meet the minimum but "
                        f"would run late on a bad day even at ratio 100 %, by "
                        f"{(-short.remaining_margin_s).median():.1f} s (median) and "
                        f"{(-short.remaining_margin_s).max():.1f} s at most; the largest share of the bad day's cost: "
                        + ", ".join(f"{_e(k.replace('_', ' '))} on {v} leg{'s' if v != 1 else ''}"
                                    for k, v in main.items() if k) + ".")
        e = sched[np.isfinite(sched.energy_saved_kwh)]
        if len(e):
            w_tr = e.energy_saved_kwh * e.n_trains
            tot = (e.energy_at_full_ratio_kwh * e.n_trains).sum()
            verb = "saves" if w_tr.sum() >= 0 else "costs"
            find.append(f"Running at the ratio the margin allows instead of 100 % {verb} "
                        f"{abs(w_tr.sum()):.0f} kWh of traction energy over the day "
                        f"({abs(100 * w_tr.sum() / tot):.1f} %).")
        cl = sched.arrival_error_s.abs()
        find.append(f"The on-board logic (nearest ratio) arrives within {cl.max():.1f} s of the scheduled time "
                    f"on every leg under nominal conditions (median {cl.median():.1f} s); under the bad-day load "
                    f"and traction (stopping brake as planned) it is up to {sched.arrival_error_degraded_s.max():.1f} s late.")
    return find


def _approach_words(approach_m) -> str:
    """Where a pattern starts without a TASC beacon, in words (the job's ``[stops] approach_m``)."""
    if isinstance(approach_m, (int, float)):
        return f"{approach_m:g} m before the marker"
    return ("the line's approach_m before the marker where it sets one, else where the train, at its minimum "
            "run's speed, must start braking at the lowest adhesion, plus 10 %")


def _method(report, datasets_href: str) -> str:
    """How the numbers are made, with links to the datasets."""
    rule, adh = report.rule, report.adhesion_kmh_s
    return (
        "<h2>How the numbers are made</h2><div class='note'><ul>"
        "<li><b>Minimum</b>: table (a) at ratio 100 % — full notch to the on-board maximum, constant-speed "
        "hold, service-brake curves to lower limits and the stopping brake to the marker; empty train, nominal "
        "traction (the conditions of the running-time tables).</li>"
        f"<li><b>Bad-day minimum</b>: the same run at load {rule.bad_load:.0%} and traction "
        f"×{rule.bad_traction:g} up to the pattern start (TASC beacon, else {_approach_words(report.approach_m)}; moved back where the lowest adhesion needs more room), then "
        + (f"the minimum-time jerk-limited stopping pattern at {rule.bad_adhesion_kmh_s(adh):g} km/h/s adhesion "
           "(deceleration limit min(comfort, adhesion, the train's brake) plus the gradient's part, the on-board maximum as speed "
           "limit, the vehicle's jerk limit)." if rule.bad_day_adhesion else
           "the stopping brake of the running-time tables (the adhesion effect is off in the job file).")
        + " Each effect (load, traction, adhesion) is switched and valued in the job file's <code>[margins]</code>; "
        "its share is the load alone against the nominal run, then the traction on top of it, then the stop at "
        "the bad day's adhesion against the best of the sweep. The fourth share, the <i>stop model</i>, is no "
        "effect of the bad day: the minimum (table (a)) stops with the constant stopping brake, the bad day with "
        "the jerk-limited stopping pattern, so it is the nominal run with that pattern (best adhesion) − the "
        "minimum. The four add up to the bad-day cost; each row's shares are rounded so that the shown "
        "numbers add up too.</li>"
        "<li><b>Flags</b>: <i>unassessed</i> — the bad-day minimum could not be computed (the row says why, e.g. "
        "no stopping pattern at the lowest adhesion); whether it is short on a bad day or tight is unknown (null in "
        "the dataset); <i>impossible</i> — scheduled below the minimum: no driving makes it, on any day; "
        "<i>short on a bad day</i> — meets the minimum but not the bad-day minimum, so it runs late on a bad day "
        "(the row says by how much and which share of the bad day's cost is largest); <i>tight</i> — neither, "
        f"but less than {rule.tight_threshold_s:g} s left; <i>unreachable</i> — scheduled above the slowest table "
        "time (lowest ratio), so the vehicle would arrive early; <i>inaccurate</i> — the closed loop misses the "
        f"designated arrival by more than {rule.arrival_error_threshold_s:g} s on the leg. <i>supplement short</i> — the margin is below the "
        "rule (not a flag).</li>"
        "<li><b>Ratio and arrival error</b>: the on-board nearest rule on table (a) with designated time = "
        "scheduled; the closed loop re-chooses at every evaluation point from table (b).</li>"
        f"<li>The datasets <a href='{_e(datasets_href)}/margins/'><code>margins</code></a> and "
        f"<a href='{_e(datasets_href)}/margin_totals/'><code>margin_totals</code></a> "
        f"({'in this folder' if datasets_href == '.' else 'in the run folder, one level up from this page'}) "
        "hold every number with its unit in the column name.</li></ul></div>")


def stop_markers(line) -> dict[str, dict[str, float]]:
    """``{direction: {station_id: stop-marker chainage [m]}}`` of a line."""
    return {d: {s.station_id: s.stop_m(d) for s in line.stations} for d in ("down", "up")}


def write_html(report, line, path: str | Path, datasets_root: str | Path | None = None, top: str = "",
               charts: list[str] | None = None, **kw) -> Path:
    """Write the page to ``path`` atomically (temp file in the same folder, then rename).

    ``datasets_root``: the folder holding the ``margins`` datasets (default: the page's folder);
    the page links to it by a relative path. ``top``, ``charts`` and ``kw`` (``nav``, ``trains_href``) as in
    :func:`render_html`.
    """
    from planner.io.atomic import write_bytes_atomic

    path = Path(path)
    write_bytes_atomic(path, page_text(report, line, path, datasets_root, top, charts, **kw).encode("utf-8"))
    return path


def page_text(report, line, path: str | Path, datasets_root: str | Path | None = None, top: str = "",
              charts: list[str] | None = None, **kw) -> str:
    """The page :func:`write_html` writes to ``path``, as text."""
    import os

    href = "." if datasets_root is None else Path(os.path.relpath(Path(datasets_root), Path(path).parent)).as_posix()
    return render_html(report, stop_markers(line), datasets_href=href, top=top, charts=charts, **kw)
