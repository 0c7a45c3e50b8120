"""The line under a page's title that says which run and which operating day it shows, and links to the
run's other pages.

Every page of a published run (the overview, the margin report, the running-time tables, the
speed–distance charts) names its run id and operating day the same way, so a printed or
forwarded page still says what it is: :func:`run_words` gives the words, :func:`nav_html` the line.
"""
from __future__ import annotations

import html
from datetime import date

__all__ = ["day_words", "nav_html", "run_words"]


def day_words(day: dict | None) -> str:
    """``operating day Monday 2026-11-30, 03:00 to 03:00 the next day (Asia/Tokyo)`` from a day's record (the
    manifest's ``operating_day``: ``day``, ``start``, ``end`` local ISO text, ``time_zone``); "" without one.

    >>> day_words({"day": "2026-11-30", "start": "2026-11-30T03:00:00+09:00", "end": "2026-12-01T03:00:00+09:00",
    ...            "time_zone": "Asia/Tokyo"})
    'operating day Monday 2026-11-30, 03:00 to 03:00 the next day (Asia/Tokyo)'
    """
    if not day or not day.get("day"):
        return ""
    d = str(day["day"])
    try:
        words = f"operating day {date.fromisoformat(d).strftime('%A')} {d}"
    except ValueError:
        words = f"operating day {d}"
    start, end = str(day.get("start") or ""), str(day.get("end") or "")
    if len(start) >= 16 and len(end) >= 16:
        words += f", {start[11:16]} to {end[11:16]} the next day"
    if day.get("time_zone"):
        words += f" ({day['time_zone']})"
    return words


def run_words(run_id: str | None, day: dict | None, run_date: str | None = None) -> str:
    """``run r0001-… of 2026-11-27 · operating day …`` (:func:`day_words`); each part left out when unknown.

    >>> run_words("r0007-0123456789", None, "2026-11-27")
    'run r0007-0123456789 of 2026-11-27'
    """
    run = (f"run {run_id}" + (f" of {run_date}" if run_date else "")) if run_id else ""
    return " · ".join(x for x in (run, day_words(day)) if x)


def nav_html(links=(), run_id: str | None = None, day: dict | None = None, run_date: str | None = None) -> str:
    """``<p class='sub run'>`` with the links (label, href) to the run's other pages, then :func:`run_words`
    (escaped); "" when there is neither."""
    e = html.escape
    parts = [f"<a href='{e(h, quote=True)}'>{e(lbl)}</a>" for lbl, h in links]
    words = run_words(run_id, day, run_date)
    if words:
        parts.append(f"<span class='run'>{e(words)}</span>")
    return f"<p class='sub nav'>{' · '.join(parts)}</p>" if parts else ""
