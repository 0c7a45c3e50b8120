"""The running-time tables of a line's trains as one self-contained page.

``timetable/<line>_timetable.html`` of a run: every train of the timetable, one
table each with an anchor ``#train-<id>`` (the train graph's click and the
margin report link there), rows from the ``train_timetable`` records
(:func:`planner.report.train_timetable.timetable_rows`). One page for all
trains rather than one per train: the sample's 356 trains make about 1.3 MB,
about what the train graph page is, and the browser's find and the index at the top work
across all of them. No scripts, inline CSS (the margin report's), no network.
"""
from __future__ import annotations

import html
import math
from itertools import groupby
from pathlib import Path
from typing import Iterable, Iterator, NamedTuple, Sequence

from planner.line.units import fixed
from planner.report.leg_flags import FLAG
from planner.report.train_timetable import clock

_e = html.escape
EXTRA_CSS = """
.tt{margin:6px 0 22px}.tt h3{margin:18px 0 4px}.tt h3 a.self{color:#999;text-decoration:none;font-weight:400}
td.pass{color:#666;font-style:italic}td.f{white-space:normal;min-width:54px}.late{color:#c62828}.early{color:#2e7d32}
.idx a{display:inline-block;min-width:52px;font-size:12.5px;margin:1px 3px}
.idx h3{margin:10px 0 2px}
:target h3{background:#fff4c2}
@media (max-width:1200px){main{padding:12px 12px 40px}.tt table{font-size:11px}.tt th,.tt td{padding:2px 3px}}
.top{font-size:12px;margin-left:10px}
"""


def _s(x, nd: int = 1, sign: bool = False) -> str:
    return fixed(x, nd, sign, none="")  # never "-0.0"


def _diff(computed, scheduled) -> str:
    """computed − scheduled, as a signed figure with a colour (late red, early green)."""
    if computed is None or scheduled is None or not (math.isfinite(computed) and math.isfinite(scheduled)):
        return ""
    d = round(computed - scheduled)
    cls = "late" if d > 0 else "early" if d < 0 else ""
    return f' <span class="{cls}">({d:+d})</span>' if d else ""


def _row(r: dict, rel: str) -> str:
    pas = r["activity"] == "passes"
    flag = r.get("leg_flag") or ""
    badge = (f' <span class="badge b-{_e(flag)}">{_e(FLAG[flag].badge if flag in FLAG else flag)}</span>'
             if flag and flag != "ok" else "")
    chart = (f'<a href="{_e(rel + r["chart"])}">chart</a>' if r.get("chart") and r.get("leg_flag") else "")
    cells = [
        f'<td class="l{" pass" if pas else ""}">{_e(r["station_id"])} {_e(r["station_name"])}</td>',
        f'<td class="l">{_e(r["activity"])}</td>',
        f'<td>{_e(r["scheduled_arrival"] or "")}</td>',
        f'<td>{"" if pas else _e(r["scheduled_departure"] or "")}</td>',
        f'<td>{_e(r["computed_arrival"] or "")}{_diff(r["computed_arrival_s"], r["scheduled_arrival_s"])}</td>',
        f'<td>{_e(r["minimum_arrival"] or "")}</td>',
        _predicted(r),
        f'<td>{_s(r["section_scheduled_s"], 0)}</td>',
        f'<td>{_s(r["section_minimum_s"])}</td>',
        f'<td>{_s(r["supplement_s"], 1, True)}</td>',
        f'<td>{_s(r["supplement_percent"], 1)}</td>',
        f'<td>{_s(r["ratio_on_time"] * 100 if r["ratio_on_time"] == r["ratio_on_time"] else None, 0)}</td>',
        f'<td>{_s(r["leg_margin_s"], 1, True)}</td>',
        f'<td class="f">{_s(r["leg_remaining_margin_s"], 1, True)}{badge}</td>',
        f"<td>{chart}</td>",
    ]
    return "<tr>" + "".join(cells) + "</tr>"


def _predicted(r: dict) -> str:
    """The predicted day's times at a stop, its delay, and why it grew here (in the cell's title)."""
    a, d = r.get("predicted_arrival"), r.get("predicted_departure")
    if not a and not d:
        return "<td></td>"
    times = " / ".join(x for x in (a, d) if x)
    delay = r.get("delay_s")
    from planner.delay.predicted import LATE_S

    late = delay is not None and delay == delay and delay > LATE_S
    why = r.get("delay_cause") or ""
    mark = f' <span class="late" title="{_e(why)}">+{round(delay)}{" ⓘ" if why else ""}</span>' if late else ""
    return f"<td>{_e(times)}{mark}</td>"


HEAD = ("<tr><th class='l'>station</th><th class='l'>call</th><th>scheduled arrival / pass</th>"
        "<th>scheduled departure</th><th>computed arrival / pass (vs scheduled [s])</th>"
        "<th>minimum run arrival / pass</th><th>predicted arrival / departure (delay [s])</th>"
        "<th>section scheduled [s]</th><th>section minimum [s]</th>"
        "<th>supple&shy;ment [s]</th><th>supple&shy;ment [%]</th><th>ratio on time [%]</th><th>leg margin [s]</th>"
        "<th>bad-day margin [s]</th><th>speed–distance</th></tr>")


def render_page(line_id: str, line_name: str, records: Sequence[dict], *, links: Sequence[tuple[str, str]] = (),
                run_id: str | None = None, day: dict | None = None, run_date: str | None = None,
                graph_href: str = "") -> str:
    """The page (module doc); ``records`` as :func:`timetable_rows` gives them, ``links``: (label, href) at the top,
    with the run's id, date and operating day (``day``: its record, :func:`planner.pages.run_head.nav_html`);
    ``graph_href``: the line's train graph page, which each train links to (``#train=<id>``: its run there)."""
    return "".join(page_parts(line_id, line_name, records, links=links, run_id=run_id, day=day, run_date=run_date,
                              graph_href=graph_href))


def page_parts(line_id: str, line_name: str, records: Sequence[dict], *, links: Sequence[tuple[str, str]] = (),
               run_id: str | None = None, day: dict | None = None, run_date: str | None = None,
               graph_href: str = "") -> Iterator[str]:
    """:func:`render_page`'s text in pieces, a train's section at a time: what :func:`write_page` writes without
    holding the whole page (tens of megabytes, several times over while joined, on a line of thousands of
    trains). The head (:func:`page_head`), each train's table in page order (:func:`train_pieces`), :data:`END`."""
    pieces = train_pieces(records, graph_href)
    yield page_head(line_id, line_name, [(p.train_id, p.direction) for p in pieces], links=links, run_id=run_id,
                    day=day, run_date=run_date)
    for p in pieces:
        yield p.html
    yield END


END = "</main></body></html>\n"
"""The page's last piece."""


class TrainPiece(NamedTuple):
    """A train's table on the page, with its place there: trains of direction ``down`` first, then by their
    scheduled departure, then by id (:func:`page_order`)."""

    down: bool
    departure_s: float
    train_id: str
    direction: str
    html: str


def page_order(p) -> tuple:
    """Where a train's table (a :class:`TrainPiece`, or the same fields) stands on the page."""
    return (not p.down, p.departure_s, p.train_id)


def train_pieces(records: Sequence[dict], graph_href: str = "") -> list[TrainPiece]:
    """Each train's table of the page, in page order (:func:`page_order`). A train's table depends on its own
    records alone, so the pages of a line's sections are the same pieces, merged in this order
    (:mod:`planner.job.train_views`)."""
    from urllib.parse import quote

    by_train = {k: list(g) for k, g in groupby(records, key=lambda r: r["train_id"])}
    out = []
    for t, rs in by_train.items():
        first, last = rs[0], rs[-1]
        n_stop = sum(r["activity"] in ("stops",) for r in rs)
        n_pass = sum(r["activity"] == "passes" for r in rs)
        tot_sup = sum(r["supplement_s"] for r in rs if r["supplement_s"] == r["supplement_s"])
        html = (
            f'<section class="tt" id="train-{_e(t)}"><h3>{_e(t)} · {_e(first["train_type"])} {_e(first["direction"])}: '
            f'{_e(first["station_id"])} {_e(first["scheduled_departure"] or "")} → {_e(last["station_id"])} '
            f'{_e(last["scheduled_arrival"] or "")} <a class="self" href="#train-{_e(t)}">#</a>'
            + (f'<a class="top" href="{_e(graph_href)}#train={_e(quote(t, safe=""))}">in the train graph</a>'
               if graph_href else "") + f'<a class="top" href="#top">index</a></h3>'
            f'<p class="caption">{n_stop} intermediate stops, {n_pass} passes; running-time supplement over the '
            f"whole run {tot_sup:.1f} s.</p>"
            f'<div class="tw"><table>{HEAD}{"".join(_row(r, "../") for r in rs)}</table></div></section>')
        out.append(TrainPiece(first["direction"] == "down", first.get("scheduled_departure_s") or 0.0, t,
                              first["direction"], html))
    return sorted(out, key=page_order)


def page_head(line_id: str, line_name: str, trains: Sequence[tuple[str, str]], *,
              links: Sequence[tuple[str, str]] = (), run_id: str | None = None, day: dict | None = None,
              run_date: str | None = None) -> str:
    """The page's head: its title, the run's id, date and day, what the tables show and the index of
    ``trains`` (train id, direction; in page order)."""
    from planner.pages.margin_report import CSS, line_title
    from planner.pages.run_head import nav_html

    idx = []
    for d in ("down", "up"):
        ids = [t for t, td in trains if td == d]
        if ids:
            idx.append(f"<h3>{d} ({len(ids)} trains)</h3><div>" + "".join(
                f'<a href="#train-{_e(t)}">{_e(t)}</a>' for t in ids) + "</div>")
    title = f"Running-time tables — {line_title(line_name, line_id)}"
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{_e(title)}</title>'
            f'<meta name="viewport" content="width=device-width, initial-scale=1"><style>{CSS}{EXTRA_CSS}</style>'
            f'</head><body><main id="top">{nav_html(links, run_id, day, run_date)}'
            f"<h1>{_e(title)}</h1>"
            '<p class="sub">Every train of the timetable, every station of its path. <b>Computed</b>: each leg (stop '
            "to next stop) run from its scheduled departure at the ratio the on-board logic picks for an on-time "
            "departure (the nearest table (a) time to the scheduled one); a train leaves each stop at its scheduled "
            "time, so the computed departure is the scheduled one; <b>minimum</b>: the same leg at ratio "
            "100 %. Both at the tables' conditions (empty, full traction). <b>Supplement</b>: scheduled − minimum "
            "time of the section from the previous call; a leg's supplements add up to its margin. The bad-day margin "
            "and the flag are the margin report's. <b>Predicted</b>: the day as it will run, every delay carried forward (a late arrival delays the departure, "
            "never before arrival + the minimum dwell; a train held by another waits), with the delay and, on "
            "hover, why it grew at that stop. The same rows are the <code>train_timetable</code> dataset.</p>"
            f'<div class="note idx">{"".join(idx)}</div>')


def write_page(path: Path, text: str | Iterable[str | bytes]) -> Path:
    """Write the page (its text, or pieces of it written as they come: :func:`page_parts`' text, or UTF-8 bytes
    a train's table kept in the work cache) atomically to ``path``."""
    from planner.io.atomic import write_bytes_atomic, write_chunks_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(text, str):
        write_bytes_atomic(path, text.encode("utf-8"))
    else:
        write_chunks_atomic(path, (part.encode("utf-8") if isinstance(part, str) else part for part in text))
    return path


__all__ = ["END", "TrainPiece", "page_head", "page_order", "page_parts", "render_page", "train_pieces", "write_page",
           "clock"]
