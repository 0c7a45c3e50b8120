"""The changes against the previous operating day on the pages: a section of the "restrictions in force" page
and the operating day's paragraph at the top of the run overview.

Both read the run manifest's day record of a line (``operating_day.lines[i]``, plain data): its
``changes`` (:func:`planner.report.day_changes.compare_days`, with ``flagged_legs`` of the added trains
once the margins are known) and ``restrictions_effect`` (the legs the day's restrictions make impossible,
from the restrictions page). A line without a daily feed has neither, and no section.
"""
from __future__ import annotations

import html
from collections import Counter
from datetime import date
from typing import Any

from planner.report.day_changes import counts
from planner.report.leg_flags import FLAG


def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _n(k: int, one: str, many: str | None = None) -> str:
    return f"{k} {one if k == 1 else (many or one + 's')}"


def _flag(name: str) -> str:
    """A flag as the margin report's badge says it (``short on a bad day``)."""
    return FLAG[name].badge if name in FLAG else name.replace("_", " ")


def _first_up(s: str) -> str:
    return s[:1].upper() + s[1:]


def _per_type(legs: list[dict], sign: str = "+") -> str:
    """Time lost (or regained) per train type: ``E10: TKD→OHS +41.9 s, OHS→TKD +41.1 s``."""
    by: dict[str, list[str]] = {}
    for g in legs:
        by.setdefault(g["train_type"], []).append(f"{g['origin']}→{g['destination']} {sign}{abs(g['time_s']):.1f} s")
    return "<br>".join(f"<b>{_e(tt)}</b>: {_e(', '.join(v))}" for tt, v in by.items()) or "no leg"


def _restriction_row(what: str, r: dict, legs: list[dict], sign: str, day: str) -> list[str]:
    part = "" if r.get("whole_day", True) else f" (part of {_e(day)})"
    return [what, f"<b>{_e(r['restriction_id'])}</b>", f"{r['start_m']:.0f}–{r['end_m']:.0f}", f"{r['limit_kmh']:g}",
            _e(r["direction"]), _e(r.get("train_type") or "all"),
            _e(f"{r['valid_from']} → {r['valid_until']}") + part,
            "temporary beacon" if r["has_beacon"] else "DB-fed pattern", _e(r.get("reason", "")), _per_type(legs, sign)]


def _ids(ids: list[str], k: int = 8) -> str:
    return _e(", ".join(ids[:k]) + (" …" if len(ids) > k else ""))


def _trains_row(what: str, t: dict | None) -> list[str]:
    if t is None:
        return [what, "not compared", "", "", ""]
    by = "; ".join(f"{s['trains']} {s['train_type']} ({s['service_id'] or 'no service'})" for s in t["by_service"])
    legs = "".join(f"<li>{_e(g['train_type'])} {_e(g['direction'])} {_e(g['origin'])}→{_e(g['destination'])}: "
                   f"{g['trains']}</li>" for g in t["legs"])
    legs = (f"<details><summary>{_n(len(t['legs']), 'leg')}</summary><ul>{legs}</ul></details>" if t["legs"]
            else "")
    if "flagged_legs" not in t:
        flagged = "" if what != "added" or not t["count"] else "margins not available"
    elif not t["flagged_legs"]:
        flagged = "<span class='ok'>none flagged</span>" if t["count"] else ""
    else:
        flagged = "<br>".join(f"<span class='bad'>{_e(_flag(f['flag']))}</span> {_e(f['train_type'])} "
                              f"{_e(f['origin'])}→{_e(f['destination'])}: {_e(len(f['trains']))} "
                              f"({_ids(f['trains'], 4)})" for f in t["flagged_legs"])
    return [what, f"{t['count']}" + (f": {_ids(t['train_ids'])}" if t["count"] else ""), _e(by), legs, flagged]


def _kept(c: dict, prev: str) -> str:
    out = []
    for k in c.get("restrictions_kept") or ():
        a, b = k["whole_day_before"], k["whole_day_after"]
        how = "" if a == b else (f" (part of {prev}, the whole of this day)" if b else
                                 f" (the whole of {prev}, part of this day)")
        out.append(f"{k['restriction_id']}{how}")
    return "; ".join(out)


def section_html(day: dict | None) -> str:
    """The "Since the previous operating day" section of the restrictions page; empty without changes."""
    c = (day or {}).get("changes")
    if not c:
        return ""
    prev = f"{c['previous_weekday']} {c['previous_day']}"
    n = counts(c)
    kept = (f" In force both days: {_e(_kept(c, c['previous_weekday']))}."
            if c.get("restrictions_kept") else "")
    parts = [f"<h2 id='changes'>Since the previous operating day ({_e(prev)})</h2>",
             f"<p>{_e(_first_up(summary(c)))}.{kept}</p>"]
    if c.get("note"):
        parts.append(f"<p class='warn'>{_e(c['note'])}</p>")
    pw, this = c["previous_weekday"], "this day"
    rows = [_restriction_row("<span class='bad'>added</span>", r, r["legs"], "+", this)
            for r in c["restrictions_added"]]
    rows += [_restriction_row("<span class='ok'>lifted</span>", r, r["legs"], "−", pw)
             for r in c["restrictions_lifted"]]
    for x in c["restrictions_changed"]:
        rows.append(_restriction_row(f"changed ({_e(', '.join(x['fields']))}): was", x["before"], x["legs_before"],
                                     "+", pw))
        rows.append(_restriction_row("changed: now", x["after"], x["legs_after"], "+", this))
    if rows:
        from planner.pages.overview import _table

        parts.append(_table(["", "restriction", "stretch [m]", "km/h", "direction", "train type", "valid (local)",
                             "ATS-P", "reason", "minimum running time per train type: + lost (added), − regained "
                             "(lifted)"], rows, num=(2, 3))
                     + "<p class='sub'>Each restriction alone against the static line (ratio 1.0, load 0, nominal "
                     "traction), per interstation it reaches, as in the table above.</p>")
    if c.get("trains_compared") and (n["trains_added"] or n["trains_cancelled"]):
        from planner.pages.overview import _table

        parts.append(_table(["trains", "how many", "by train type (service)", "their legs (stop to stop: trains)",
                             "flagged legs of the added trains (margin report)"],
                            [_trains_row("added", c["trains_added"]), _trains_row("cancelled", c["trains_cancelled"])],
                            num=()))
    parts.append("<p class='sub'>Both days as the daily feed stands tonight: a restriction deleted from the feed "
                 "since yesterday's run is not listed as lifted.</p>")
    return "\n".join(parts)


def _named(rs: list[dict], k: int = 4) -> str:
    ids = [r["restriction_id"] for r in rs]
    return ", ".join(ids[:k]) + (f" and {len(ids) - k} more" if len(ids) > k else "")


def summary(c: dict) -> str:
    """One sentence: what changed (``TSR-2026-101 lifted; 92 trains added``)."""
    n = counts(c)
    r = [f"{_named(c[k])} {k.split('_')[1]}" for k in ("restrictions_added", "restrictions_lifted",
                                                          "restrictions_changed") if n[k]]
    rs = "; ".join(r) if r else "no restriction added or lifted"
    if not c.get("trains_compared"):
        return rs + "; trains not compared"
    t = [f"{_n(n['trains_added'], 'train')} added"] if n["trains_added"] else []
    t += [f"{_n(n['trains_cancelled'], 'train')} cancelled"] if n["trains_cancelled"] else []
    flagged = (c.get("trains_added") or {}).get("flagged_legs")
    if flagged:
        kinds = Counter(_flag(f["flag"]) for f in flagged)
        t[0] += f" ({_n(len(flagged), 'of their legs', 'of their legs')} flagged: " + ", ".join(
            f"{v} {k}" for k, v in kinds.items()) + ")"
    return rs + "; " + (", ".join(t) if t else "the same trains run")


def _effect(eff: dict) -> str:
    """What the restrictions do to the impossible legs, in words."""
    m, k, runs = eff["impossible"], eff["impossible_by_restrictions"], eff["train_runs_by_restrictions"]
    if not m:
        return "no leg is impossible"
    if not k:
        return f"none of the {_n(m, 'impossible leg')} is the restrictions' doing"
    who = f"the {_n(m, 'impossible leg')}" if k == m else f"{k} of the {_n(m, 'impossible leg')}"
    return (f"{who} {'is' if k == 1 else 'are'} the restrictions' doing ({_n(runs, 'train run')}; possible "
            f"without them)")


def overview_html(day: dict | None) -> str:
    """The operating day at the top of the run overview, for someone who has never seen one: what the day is,
    what is in force, what the restrictions do to the flags, and what changed since the day before."""
    if not day or not day.get("day") or not any(x.get("feed") for x in day.get("lines", [])):
        return ""  # a job without daily feeds plans the static line: no day to explain
    d = date.fromisoformat(day["day"])
    h = int(day.get("start_hour", 0))
    parts = [f"<h2 id='day'>Operating day {_e(f'{d:%A} {d.isoformat()}')}</h2>",
             f"<p class='sub'>This run plans one operating day: {h:02d}:00 to {h:02d}:00 the next morning, local time "
             f"({_e(day.get('time_zone', ''))}). Everything the run computes uses what is in force that day: the "
             "trains its calendar runs and the temporary speed restrictions of the line's daily feed, which the "
             "tables, stopping patterns and bundles count for the whole day (on the safe side) and the margins, "
             "conflicts and train graph apply per train, by the time it passes.</p>"]
    for rec in day.get("lines", []):
        lid = rec["line_id"]
        if rec.get("feed") is None:
            parts.append(f"<p><b>{_e(lid)}</b>: no daily feed: the static line, every timetable train.</p>")
            continue
        nr, nrun = len(rec.get("restrictions", [])), rec.get("trains_running", 0)
        nnot = len(rec.get("trains_not_running", []))
        text = (f"<b>{_e(lid)}</b> — {_e(f'{d:%A} {d.isoformat()}')}: {_n(nr, 'temporary restriction')} in force, "
                f"{_n(nrun, 'train')} run" + (f" ({nnot} of the timetable do not)" if nnot else "") + "; ")
        eff = rec.get("restrictions_effect")
        text += _effect(eff) if eff is not None else "margins not assessed"
        text += f": see <a href='report/{_e(lid)}_restrictions.html'>restrictions in force</a>."
        c = rec.get("changes")
        if c:
            text += (f"<br>Since {_e(c['previous_weekday'])} {_e(c['previous_day'])}: {_e(summary(c))} "
                     f"(<a href='report/{_e(lid)}_restrictions.html#changes'>what changed</a>).")
            if c.get("note"):
                text += f" {_e(c['note'])}."
        parts.append(f"<p>{text}</p>")
    return "\n".join(parts)


__all__ = ["overview_html", "section_html", "summary"]
