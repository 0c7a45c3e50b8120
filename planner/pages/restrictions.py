"""The "restrictions in force" page ``report/<line>_restrictions.html``: what a planner reads first the evening
before an operating day.

For each temporary restriction in force that day (the run manifest's ``operating_day`` record of the line):
its stretch, limit, direction and train type, validity (whole day or part), whether a beacon sends its
pattern or the on-board DB feeds it, and **the legs it slows with the time lost per train type**: the
minimum running time (ratio 1.0, load 0, nominal traction, the tables' conditions) with that restriction
alone against the static line, on every interstation whose window it reaches.

Then **the scheduled legs it reaches** (rows of the day's margin report, stop to stop, a rapid's leg over
several interstations included): the trains, the scheduled running time, the minimum without and with
the day's restrictions, the margin before and after, the bad-day remaining margin and the closed-loop
arrival error of the on-board logic (nominal and bad day: its recovery); a leg whose margin the
restrictions turn negative "loses its margin", one whose margin stays ≥ 0 "still makes it".

The day's line is the static line plus the temporary restrictions (kind ``temporary``,
:func:`planner.job.day.day_line`); the static line is the same without them. Times come from the one
integrator (:func:`planner.physics.run_curve.simulate`) on the leg's :meth:`Line.window`.
"""
from __future__ import annotations

import dataclasses
import html
import math
from pathlib import Path
from typing import Any, Sequence

TEMPORARY = "temporary"  # planner.line.daily.TEMPORARY_KIND (the line floor's name for them)


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _without(line, keep: Sequence[str] = ()):
    """``line`` without its temporary restrictions, except those whose id is in ``keep``."""
    return dataclasses.replace(line, speed_limits=tuple(
        s for s in line.speed_limits if s.kind != TEMPORARY or s.restriction_id in keep))


def min_time_s(line, train_type: str, origin: str, destination: str, ds_m: float = 1.0) -> float:
    """Minimum running time [s]: ratio 1.0, load 0, nominal traction (table (a) at ratio 1.0)."""
    from planner.physics.run_curve import simulate
    from planner.physics.track import SimSettings, make_track

    w = line.window(origin, destination, train_type)
    track = make_track(w, train_type, origin, destination, settings=SimSettings(ds_m=ds_m))
    return float(simulate(track, w.train_type(train_type), 1.0).time_s[0])


def reaches_leg(line, sl, train_type: str, direction: str, origin: str, destination: str) -> bool:
    """Whether speed limit ``sl`` concerns a run origin → destination of ``train_type`` (its window)."""
    lo, hi = line.window_m(origin, destination, train_type)
    return sl.applies(direction, train_type) and sl.end_m > lo and sl.start_m < hi


def restriction_losses(line, ds_m: float = 1.0) -> dict[str, list[tuple[str, str, str, str, float]]]:
    """Per temporary restriction id: (train type, direction, origin, destination, time lost [s]) on every
    interstation it reaches, with that restriction alone against the static line."""
    static = _without(line)
    temps = [s for s in line.speed_limits if s.kind == TEMPORARY]
    out: dict[str, list] = {s.restriction_id: [] for s in temps}
    for tt in (t.train_type for t in line.train_types):
        for d in ("down", "up"):
            for a, b in line.interstations(d):
                hit = [s for s in temps if reaches_leg(line, s, tt, d, a.station_id, b.station_id)]
                if not hit:
                    continue
                base = min_time_s(static, tt, a.station_id, b.station_id, ds_m)
                for s in hit:
                    t = min_time_s(_without(line, (s.restriction_id,)), tt, a.station_id, b.station_id, ds_m)
                    out[s.restriction_id].append((tt, d, a.station_id, b.station_id, t - base))
    return out


def scheduled_legs(line, rows, ds_m: float = 1.0) -> list[dict]:
    """The margin report's rows (a DataFrame) whose leg a temporary restriction reaches, with the minimum
    without them and the margin it had."""
    temps = [s for s in line.speed_limits if s.kind == TEMPORARY]
    static = _without(line)
    out, cache = [], {}
    if rows is None or not len(rows) or not temps:
        return out
    for r in rows.to_dict("records"):
        sched = r.get("scheduled_running_time_s")
        if sched is None or (isinstance(sched, float) and math.isnan(sched)):
            continue
        k = (r["train_type"], r["direction"], r["origin"], r["destination"])
        ids = [s.restriction_id for s in temps if reaches_leg(line, s, *k)]
        if not ids:
            continue
        if k not in cache:
            cache[k] = (min_time_s(static, k[0], k[2], k[3], ds_m), min_time_s(line, k[0], k[2], k[3], ds_m))
        before, after = cache[k]
        out.append({**{c: r.get(c) for c in ("train_type", "direction", "origin", "destination", "n_trains",
                                             "remaining_margin_s", "arrival_error_s", "arrival_error_degraded_s")},
                    "train_ids": [] if r.get("train_ids") is None else list(r["train_ids"]), "restrictions": ids,
                    "scheduled_s": float(sched),
                    "min_before_s": before, "min_after_s": after, "margin_before_s": float(sched) - before,
                    "margin_after_s": float(sched) - after})
    out.sort(key=lambda x: (x["margin_after_s"] >= 0, x["margin_after_s"]))
    return out


def windows_of(day: dict) -> dict[str, tuple[int, int]]:
    """Restriction id → its validity [UTC epoch s], from the manifest record's local texts."""
    from planner.line.daily import parse_local

    tz = day.get("time_zone") or "UTC"
    out = {}
    for r in day.get("restrictions", []):
        a, b = parse_local(r["valid_from"], late=False, tz=tz)[0], parse_local(r["valid_until"], late=True, tz=tz)[0]
        if a is not None and b is not None:
            out[r["restriction_id"]] = (a, b)
    return out


def passing_while_lifted(line, leg: dict, windows: dict, day: str, tz: str) -> list[str]:
    """The leg's trains that run it (departure to scheduled arrival) entirely while every restriction of the
    leg is lifted: the whole-day rule understates their margin (docs/operating-day.md)."""
    from datetime import date

    from planner.line.operating_day import timetable_instant

    trains = {t.train_id: t for t in line.trains}
    out = []
    for tid in leg["train_ids"]:
        t = trains.get(tid)
        dep = next((c.departure_s for c in t.calls if c.station_id == leg["origin"]), None) if t else None
        if dep is None or math.isnan(dep):
            continue
        t0 = timetable_instant(date.fromisoformat(day), tz, dep)
        t1 = t0 + leg["scheduled_s"]
        if all(rid in windows and (t1 <= windows[rid][0] or t0 >= windows[rid][1]) for rid in leg["restrictions"]):
            out.append(tid)
    return out


def _num(x, fmt: str = "{:+.1f}") -> str:
    from planner.line.units import fixed  # never -0.0

    return fixed(x, int(fmt.rsplit(".", 1)[1][0]), "+" in fmt, none="")


def render(line, day: dict | None, rows, ds_m: float = 1.0) -> str:
    """The page as HTML; ``day``: the line's record in the run manifest's ``operating_day`` (with the
    window's keys of the day itself), ``rows``: the day's margin rows."""
    from planner.pages.overview import CSS, _table

    recs = (day or {}).get("restrictions", [])
    title = f"Restrictions in force — {line.line_id}, operating day {(day or {}).get('day', '?')}"
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>{_e(title)}</title>"
             f"<style>{CSS}</style></head><body><main><h1>{_e(title)}</h1>",
             f"<p class='sub'>{_e((day or {}).get('start', ''))} to {_e((day or {}).get('end', ''))}; "
             f"{len(recs)} temporary restriction(s) in force, each for the whole day in the tables and bundles "
             f"(on the safe side); trains running {_e((day or {}).get('trains_running', '?'))}, not running "
             f"{len((day or {}).get('trains_not_running', []))}. <a href='../index.html'>run overview</a> · "
             f"<a href='{_e(line.line_id)}_margins.html'>margin report</a></p>"]
    if not recs:
        parts.append("<p>No temporary restriction is in force on this day.</p></main></body></html>\n")
        return "\n".join(parts)
    losses = restriction_losses(line, ds_m)
    trows = []
    for r in recs:
        legs = losses.get(r["restriction_id"], [])
        slowed = "; ".join(f"{tt} {o}→{d}: {_num(t)} s" for tt, _, o, d, t in legs) or "no leg"
        trows.append([f"<b>{_e(r['restriction_id'])}</b>", f"{r['start_m']:.0f}–{r['end_m']:.0f}",
                      f"{r['limit_kmh']:g}", _e(r["direction"]), _e(r.get("train_type") or "all"),
                      _e(f"{r['valid_from']} → {r['valid_until']}") + ("" if r.get("whole_day") else
                                                                     " <b>(part of the day)</b>"),
                      "temporary beacon" if r["has_beacon"] else "DB-fed pattern", _e(r["reason"]), _e(slowed)])
    parts.append("<h2 id='restrictions'>Restrictions and the legs they slow</h2>"
                 + _table(["restriction", "stretch [m]", "km/h", "direction", "train type", "valid (local)",
                           "ATS-P", "reason", "time lost per train type (minimum running time, that restriction "
                                              "alone)"], trows, num=(1, 2))
                 + "<p class='sub'>Time lost: ratio 1.0, load 0, nominal traction, the restriction alone against "
                 "the static line, per interstation its stretch (+ one train length) reaches.</p>")
    legs = scheduled_legs(line, rows, ds_m)
    lost = [x for x in legs if x["margin_after_s"] < 0 <= x["margin_before_s"]]
    wins = windows_of(day or {})
    lrows = []
    for x in legs:
        ids = x["train_ids"]
        lifted = passing_while_lifted(line, x, wins, day["day"], day.get("time_zone") or "UTC") \
            if (day or {}).get("day") else []
        verdict = ("<span class='bad'>loses its margin</span>" if x in lost else
                   "<span class='bad'>had none</span>" if x["margin_after_s"] < 0 else
                   "<span class='ok'>still makes it</span>")
        lrows.append([_e(f"{x['train_type']} {x['origin']}→{x['destination']}"), _e(", ".join(x["restrictions"])),
                      f"{x['n_trains']}: " + _e(", ".join(ids[:6]) + (" …" if len(ids) > 6 else "")),
                      _num(x["scheduled_s"], "{:.0f}"), _num(x["min_before_s"], "{:.1f}"),
                      _num(x["min_after_s"], "{:.1f}"), _num(x["margin_before_s"]), _num(x["margin_after_s"]),
                      _num(x["remaining_margin_s"]), _num(x["arrival_error_s"]), _num(x["arrival_error_degraded_s"]),
                      verdict, _e(f"{len(lifted)}: {', '.join(lifted[:4])}{' …' if len(lifted) > 4 else ''}"
                                  if lifted else "0")])
    n_lost = sum(int(x["n_trains"] or 0) for x in lost)
    parts.append(f"<h2 id='trains'>Scheduled legs slowed: {len(lost)} leg row(s), {n_lost} train run(s) lose "
                 f"their margin</h2>"
                 + _table(["leg", "restrictions", "trains", "scheduled [s]", "minimum without [s]",
                           "minimum with [s]", "margin without [s]", "margin with [s]", "bad-day remaining [s]",
                           "closed-loop arrival error [s]", "bad day [s]", "", "run it while lifted"], lrows,
                          num=tuple(range(3, 11)))
                 + "<p class='sub'>Margin = scheduled − minimum running time. The closed-loop arrival error "
                 "(actual − scheduled, + late) is the on-board logic's run on the day's tables departing on time, "
                 "nominal and on the bad day: what is left after its recovery. <i>Run it while lifted</i>: trains "
                 "that run the leg (departure to scheduled arrival) entirely outside the validity of its "
                 "restrictions (one in force for part of the day): the tables count it for the whole day, so their "
                 "margin here is understated (the safe side).</p>")
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def write_page(line, day: dict | None, rows, out: Path, ds_m: float = 1.0) -> Path:
    """Write the page atomically to ``out``."""
    from planner.io.atomic import write_bytes_atomic

    write_bytes_atomic(out, render(line, day, rows, ds_m).encode("utf-8"))
    return out


__all__ = ["min_time_s", "passing_while_lifted", "render", "restriction_losses", "scheduled_legs", "write_page"]
