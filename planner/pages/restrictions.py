"""The "restrictions in force" page ``report/<line>_restrictions.html``: what a planner reads first the evening
before an operating day.

For each temporary restriction in force that day (the run manifest's ``operating_day`` record of the line):
its stretch, limit, direction and train type, validity (whole day or part), whether a beacon sends its
pattern or the on-board DB feeds it, and **the legs it slows with the time lost per train type**: the
minimum running time (ratio 1.0, load 0, nominal traction, the tables' conditions) with that restriction
alone against the static line, on every interstation whose window it reaches.

Then **the scheduled legs it reaches** (rows of the day's margin report, stop to stop, a rapid's leg over
several interstations included): the trains, the scheduled running time, the minimum without and with
the day's restrictions, the margin before and after, the bad-day margin and the closed-loop
arrival error of the on-board logic (nominal and bad day: its recovery); a leg whose margin the
restrictions turn negative "loses its margin", one whose margin stays ≥ 0 "still makes it". Each row's
trains are computed with the restrictions that apply to them by the time they pass (the row's
``restrictions``); a part-day restriction lifted while they run the leg is named, and not in their minimum.

The figures are computed in :mod:`planner.report.restriction_effects`; this module only renders them.
"""
from __future__ import annotations

import html
from pathlib import Path
from typing import Any

from planner.report.restriction_effects import restriction_losses, scheduled_legs


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(x, fmt: str = "{:+.1f}") -> str:
    from planner.line.units import fixed  # never -0.0

    return fixed(x, int(fmt.rsplit(".", 1)[1][0]), "+" in fmt, none="")


def render(line, day: dict | None, rows, ds_m: float = 1.0, scheduled: list[dict] | None = None) -> str:
    """The page as HTML; ``day``: the line's record in the run manifest's ``operating_day`` (with the
    window's keys of the day itself and its ``changes`` against the previous day), ``rows``: the day's margin
    rows; ``scheduled``: :func:`scheduled_legs` of them when already computed."""
    from planner.pages.day_changes import section_html
    from planner.pages.overview import CSS, _table

    recs = (day or {}).get("restrictions", [])
    title = f"Restrictions in force — {line.line_id}, operating day {(day or {}).get('day', '?')}"
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{_e(title)}</title>"
             f"<style>{CSS}</style></head><body><main><h1>{_e(title)}</h1>",
             f"<p class='sub'>{_e((day or {}).get('start', ''))} to {_e((day or {}).get('end', ''))}; "
             f"{len(recs)} temporary restriction(s) in force, each for the whole day in the tables and bundles "
             f"(on the safe side), per train by the time it passes in the margins, conflicts and train graph; "
             f"trains running {_e((day or {}).get('trains_running', '?'))}, not running "
             f"{len((day or {}).get('trains_not_running', []))}. <a href='../index.html'>run overview</a> · "
             f"<a href='{_e(line.line_id)}_margins.html'>margin report</a>"
             + (" · <a href='#changes'>since the previous day</a>" if (day or {}).get("changes") else "") + "</p>"]
    changes = section_html(day)
    if not recs:
        parts.append("<p>No temporary restriction is in force on this day.</p>" + changes + "</main></body></html>\n")
        return "\n".join(parts)
    losses = restriction_losses(line, ds_m)
    trows = []
    for r in recs:
        legs = losses.get(r["restriction_id"], [])
        slowed = "; ".join(f"{tt} {o}→{d}: {_num(t)} s" for tt, _, o, d, t in legs) or "no leg"
        trows.append([f"<b>{_e(r['restriction_id'])}</b>", f"{r['start_m']:.0f}–{r['end_m']:.0f}",
                      f"{r['limit_kmh']:g}", _e(r["direction"]), _e(r.get("track") or "every track"),
                      _e(r.get("train_type") or "all"),
                      _e(f"{r['valid_from']} → {r['valid_until']}") + ("" if r.get("whole_day") else
                                                                     " <b>(part of the day)</b>"),
                      "temporary beacon" if r["has_beacon"] else "DB-fed pattern", _e(r["reason"]), _e(slowed)])
    parts.append("<h2 id='restrictions'>Restrictions and the legs they slow</h2>"
                 + _table(["restriction", "stretch [m]", "km/h", "direction", "track", "train type", "valid (local)",
                           "ATS-P", "reason", "time lost per train type (minimum running time, that restriction "
                                              "alone)"], trows, num=(1, 2))
                 + "<p class='sub'>Time lost: ratio 1.0, load 0, nominal traction, the restriction alone against "
                 "the static line, per interstation its stretch (+ one train length) reaches.</p>")
    legs = scheduled_legs(line, rows, ds_m) if scheduled is None else scheduled
    lost = [x for x in legs if x["margin_after_s"] < 0 <= x["margin_before_s"]]
    lrows = []
    for x in legs:
        ids = x["train_ids"]
        verdict = _verdict(x, x in lost)
        lrows.append([_e(f"{x['train_type']} {x['origin']}→{x['destination']}"), _e(", ".join(x["restrictions"]) or "none"),
                      f"{x['n_trains']}: " + _e(", ".join(ids[:6]) + (" …" if len(ids) > 6 else "")),
                      _num(x["scheduled_s"], "{:.0f}"), _num(x["min_before_s"], "{:.1f}"),
                      _num(x["min_after_s"], "{:.1f}"), _num(x["margin_before_s"]), _num(x["margin_after_s"]),
                      *_no_stop_blank(x), verdict, _e(f"without {', '.join(x['lifted'])}" if x["lifted"] else "")])
    n_lost = sum(int(x["n_trains"] or 0) for x in lost)
    stuck: dict[tuple, list] = {}  # the worst a restriction can do: the vehicle's DB cannot stop the train there
    for x in legs:
        if x.get("unassessed_cause") == "no_stop":
            stuck.setdefault((x["train_type"], x["direction"], x["origin"], x["destination"]), []).append(x)
    if stuck:
        items = []
        for (tt, d, o, de), xs in stuck.items():
            ids = sorted({r for x in xs for r in x["restrictions"] + x["lifted"]})
            items.append(f"<li class='bad'><b>{_e(tt)} {_e(d)} {_e(o)}→{_e(de)}</b>, the restriction(s) on the leg: "
                         f"{_e(', '.join(ids) or 'none')}: {_e(xs[0].get('unassessed_reason') or '')}</li>")
        parts.append("<h2 id='no-stop'>Stops without a stopping pattern</h2><ul>" + "".join(items)
                     + "</ul><p class='sub'>The bundles of these trains hold no stopping pattern at that station for "
                     "those adhesion levels, for every train of the day (a part-day restriction counts for the whole "
                     "day in the bundles): their signed manifests name the stops and levels, and <code>planner bundle "
                     "verify --require-complete</code> refuses them. The margin report leaves these legs "
                     "unassessed.</p>")
    parts.append(f"<h2 id='trains'>Scheduled legs slowed: {len(lost)} leg row(s), {n_lost} train run(s) lose "
                 f"their margin</h2>"
                 + _table(["leg", "restrictions", "trains", "scheduled [s]", "minimum without [s]",
                           "minimum with [s]", "margin without [s]", "margin with [s]", "bad-day margin [s]",
                           "closed-loop arrival error [s]", "bad day [s]", "", "lifted while they pass"], lrows,
                          num=tuple(range(3, 11)))
                 + "<p class='sub'>Margin = scheduled − minimum running time. The closed-loop arrival error "
                 "(actual − scheduled, + late) is the on-board logic's run on the day's tables departing on time, "
                 "nominal and on the bad day: what is left after its recovery. Each row's trains are computed with "
                 "the restrictions in force at some instant of their run of the leg (departure to scheduled "
                 "arrival), for their direction and train type; <i>lifted while they pass</i>: the leg's "
                 "restrictions (in force for part of the day) that are not, so the row is computed without "
                 "them (its minimum and margin are the static line's there). The tables and bundles still "
                 "count a part-day restriction for the whole day.</p>")
    parts.append(changes)
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def _no_stop_blank(x: dict) -> list[str]:
    """The bad-day margin and the closed loop's arrival errors of a leg; a leg no stopping pattern stops has none
    (the vehicle's DB cannot stop the train there: a figure would be of a pattern that does not exist)."""
    if x.get("unassessed_cause") == "no_stop":
        return ["<span title='no stopping pattern stops the train: no figure'>–</span>"] * 3
    return [_num(x["remaining_margin_s"]), _num(x["arrival_error_s"]), _num(x["arrival_error_degraded_s"])]


def _verdict(x: dict, lost: bool) -> str:
    """One leg row's verdict, the margin report's own flags first (one story on every page): no stopping
    pattern, then the margin, then the bad day."""
    if x.get("unassessed_cause") == "no_stop":
        return "<span class='bad'>no stopping pattern</span>"
    if lost:
        return "<span class='bad'>loses its margin</span>"
    if x["margin_after_s"] < 0:
        return "<span class='bad'>had none</span>"
    if x.get("short_bad_day"):
        return "<span class='bad'>short on a bad day</span>"
    if x.get("unassessed"):
        return "<span class='bad'>unassessed</span>"
    if x.get("tight"):
        return "<span class='dev'>tight on a bad day</span>"
    return "<span class='ok'>still makes it</span>"


def write_page(line, day: dict | None, rows, out: Path, ds_m: float = 1.0, legs: list[dict] | None = None) -> Path:
    """Write the page atomically to ``out``."""
    from planner.io.atomic import write_bytes_atomic

    write_bytes_atomic(out, render(line, day, rows, ds_m, legs).encode("utf-8"))
    return out


__all__ = ["render", "write_page"]
