"""Speed–distance chart of one leg and scheduled time, as a self-contained page.

One page per (leg, train type, scheduled running time) of the timetable,
``charts/<line>/<direction>_<type>_<origin>-<destination>_<scheduled>s.html``,
pre-rendered by the nightly job (a published run is static files) and linked
from the per-train running-time table (:mod:`planner.pages.timetable`).

What it draws (an inline SVG written directly by :mod:`planner.pages.svg_plot`, its legend in HTML
under it; up legs with the chainage running right to left, so the train runs left to right):

* the run at the on-time ratio and the minimum run (ratio 1.0), the two
  recorded runs of :class:`planner.report.train_timetable.LegRun`; the minimum
  run as a wide light band under the on-time run, so both show where they
  coincide (an on-time ratio of 100 %);
* the **bad-day minimum run** (:func:`planner.report.leg_margin.bad_day_run`: the run the margin report's
  bad-day minimum is, made by the same functions), in both panels, with how it ends against the
  scheduled time ("… s late on a bad day" or "… s to spare");
* in a panel of its own, the time since departure along the leg of both runs
  against the scheduled running time: a late leg (its minimum run over the
  scheduled time) is said so above the chart, in red, and its on-time run is
  red with its lateness written at the arrival;
* the permanent speed limits that apply to the train (and the line maximum) and
  the on-board maximum it runs to (limit − the train's speed margin);
* apart from them (orange, hatched, named by id): the day's temporary speed
  restrictions (kind ``temporary``, from the daily feed) in force at some time
  of the run's operating day, which the run applies all day;
* the stopping pattern at the arrival stop, lowest and highest adhesion of the
  run's stopping-pattern sweep (its ``stop_samples`` rows of those levels,
  :func:`planner.datasets.stops.extreme_patterns`);
* the stopping pattern (stops and passes) as station lines, signals, ATS-P
  beacons and the evaluation points of the leg (``eval_points``);
* below: the gradient [‰] and the curves (radius) along the leg.

Its text is :data:`FONT` user units of a 1200-unit view box: 11 px or more when the page is 1000 px wide.

The page around the chart names the run and its operating day and links to the run's
other pages (:func:`planner.pages.run_head.nav_html`); the chart itself is a cached unit
of the nightly job, the page is written by every run.

The runs and the stopping patterns are thinned for drawing with :func:`planner.report.train_graph.simplify`
(0.2 km/h, 2 m) and the on-board maximum written as its steps only, which keeps a page near 20 kB.
Written directly, a chart costs ~3 ms of CPU against ~75 ms with matplotlib (its text layout, legends,
ticks and ``savefig``; 74 charts on the sample, thousands on a network), and the same inputs give the
same bytes.
"""
from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from planner.line.daily import TEMPORARY_KIND
from planner.line.model import sign
from planner.line.units import kmh, percent, shown

TOL_V_KMH = 0.2
TOL_X_M = 2.0


def _thin(x_m: np.ndarray, v_kmh: np.ndarray):
    from planner.report.train_graph import simplify

    k = simplify(v_kmh, x_m, TOL_V_KMH, TOL_X_M)
    return x_m[k] / 1000.0, v_kmh[k]


def _steps(segs, lo: float, hi: float, fill: float):
    """(x [km], y) of a piecewise-constant quantity over [lo, hi] with ``fill`` in the gaps."""
    xs, ys = [lo], [fill]
    for a, b, v in zip(segs.start_m, segs.end_m, segs.value):
        if b <= lo or a >= hi:
            continue
        a, b = max(a, lo), min(b, hi)
        xs += [a, a, b, b]
        ys += [fill, v, v, fill]
    xs.append(hi)
    ys.append(fill)
    return np.asarray(xs) / 1000.0, np.asarray(ys)


def temporary_limits(line, direction: str, train_type: str, lo: float, hi: float) -> list:
    """The day's temporary restrictions (kind ``temporary``, from the daily feed) that reach into [lo, hi] for
    this direction and train type, by position."""
    return sorted((s for s in line.limits_for(direction, train_type)
                   if s.kind == TEMPORARY_KIND and s.end_m > lo and s.start_m < hi), key=lambda s: (s.start_m, s.ident))


def _limit_steps(line, direction: str, train_type: str, lo: float, hi: float):
    """The permanent limit that applies at each point (the lowest of the overlapping ones, else the line maximum);
    the day's temporary restrictions are drawn apart (:func:`temporary_limits`)."""
    lims = [s for s in line.limits_for(direction, train_type)
            if s.kind != TEMPORARY_KIND and s.end_m > lo and s.start_m < hi]
    cuts = sorted({lo, hi, *[min(max(s.start_m, lo), hi) for s in lims], *[min(max(s.end_m, lo), hi) for s in lims]})
    top = line.max_speed_ms if np.isfinite(line.max_speed_ms) else line.train_type(train_type).max_speed_ms
    xs, ys = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        m = 0.5 * (a + b)
        v = min([s.limit_ms for s in lims if s.start_m <= m < s.end_m] + [top])
        xs += [a, b]
        ys += [kmh(v), kmh(v)]
    return np.asarray(xs) / 1000.0, np.asarray(ys)


W, H = 1200.0, 816.0
"""The chart's size in user units (its ``viewBox``; it is drawn at the width of the page: about 0.8 px a unit in a
1000 px window, so its text is :data:`FONT` units, 11 px or more there)."""
FONT = 15.0
"""The size of the chart's text (ticks, axis labels, station and restriction labels) in user units."""
SPEED_BOX = (80.0, 56.0, 1100.0, 380.0)
TIME_BOX = (80.0, 456.0, 1100.0, 150.0)
GRADIENT_BOX = (80.0, 626.0, 1100.0, 120.0)
"""(left, top, width, height) of the speed panel, the time panel and the gradient panel under them."""
COLOURS = {"minimum": "#1f5fa8", "minimum_band": "#9dbde6", "on_time": "#2e7d32", "late": "#c62828", "limit": "#9e9e9e", "vmax": "#8c8c8c",
               "temporary": "#e65100", "signal": "#37474f", "beacon": "#6a1b9a", "eval": "#f2b705",
               "gradient": "#8d6e63", "curve": "#5a7da8", "bad_day": "#ad1457"}
"""Colour of each thing drawn (the stopping patterns': :data:`PATTERN_STYLES`)."""
PATTERN_STYLES = (("#c62828", "lowest"), ("#ef8f00", "highest"))
"""Colour and name of the stopping pattern at the lowest and highest adhesion."""


def _speed_panel(fig, line, run, calls, pattern, eval_points, signals, xlim, legend):
    """The upper panel: limits, runs, patterns, restrictions, stations, signals, beacons, points; ``legend``
    gets (swatch, label) of what is drawn."""
    from planner.pages.svg_plot import swatch

    d, tt, _, _, sched = run.key[:5]
    x = run.position_m
    lo, hi = float(np.min(x)), float(np.max(x))
    lx, ly = _limit_steps(line, d, tt, lo, hi)
    temps = temporary_limits(line, d, tt, lo, hi)
    top = float(np.nanmax(ly)) * (1.3 if temps else 1.14)  # room for the restrictions' ids under the stations
    p = fig.panel(SPEED_BOX, xlim, (0.0, top), x_inverted=d == "up", ylabel="speed [km/h]", xticks=False,
                  ytarget=7, font=FONT)
    c = COLOURS
    hatch = fig.hatch("tsr", fill="#fff3e8", stroke="#f2b48a") if temps else None
    for s in temps:  # under the curves: an opaque hatched band, the limit line over it
        p.span(max(s.start_m, lo) / 1000.0, min(s.end_m, hi) / 1000.0, fill=hatch, y0=0.0, y1=top * 0.8)
    p.polyline(lx, ly, color=c["limit"], width=1.0, dash=(3.7, 1.6))
    legend.append((swatch("line", color=c["limit"], width=1.0, dash=(3.7, 1.6)), "permanent speed limit"))
    p.steps_mid(x / 1000.0, kmh(run.vmax_ms), color=c["vmax"], width=1.1)
    legend.append((swatch("line", color=c["vmax"], width=1.1), "on-board maximum (limit − margin)"))
    t_r, t_m = float(run.t_s[0][-1]), float(run.t_s[1][-1])
    # the minimum run as a wide light band under the on-time run: where they coincide (ratio 100 %) both show
    p.polyline(*_thin(x, kmh(run.v_ms[1])), color=c["minimum_band"], width=5.0)
    legend.append((swatch("line", color=c["minimum_band"], width=5.0), f"minimum run: ratio 100 % — {t_m:.1f} s"))
    p.polyline(*_thin(x, kmh(run.v_ms[0])), color=c["on_time"], width=1.6)
    legend.append((swatch("line", color=c["on_time"], width=1.6),
                   f"on-time departure: ratio {percent(run.ratio)} — {t_r:.1f} s (scheduled {sched:.0f} s)"))
    for (a, (px, pv)), (col, what) in zip(sorted((pattern or {}).items()), PATTERN_STYLES):
        p.polyline(*_thin(np.asarray(px, float), np.asarray(pv, float)), color=col, width=1.3, dash=(5.2, 2.6))
        legend.append((swatch("line", color=col, width=1.3, dash=(5.2, 2.6)),
                       f"stopping pattern, {what} adhesion {a:.2g} km/h/s"))
    for s in temps:
        a, b, v = max(s.start_m, lo) / 1000.0, min(s.end_m, hi) / 1000.0, kmh(s.limit_ms)
        p.polyline([a, a, b, b], [top * 0.8, v, v, top * 0.8], color=c["temporary"], width=1.8)
        p.text(0.5 * (a + b), top * 0.8, [s.restriction_id, f"{v:.0f} km/h"], size=FONT, color="#bf360c", bold=True,
               va="bottom", box=("white", c["temporary"]))
    if temps:
        legend.append((swatch("patch", color="#fff3e8", hatch="#f2b48a"), "temporary speed restriction (the day's "
                       "feed), hatched, with its id and limit"))
    for sid, stops, pos in calls:
        p.vline(pos / 1000.0, color="#000", width=1.0 if stops else 0.7, dash=None if stops else (1.0, 1.65))
        p.text(pos / 1000.0, top * 0.985, f"{sid}{'' if stops else ' (pass)'}", size=FONT,
               box=("white" if stops else "#f3f3f3", "#000"))
    sig = signals if signals is not None else [s.position_m for s in line.signals
                                               if s.direction == d and lo <= s.position_m <= hi]
    if len(sig):
        p.markers(np.asarray(sig, float) / 1000.0, np.full(len(sig), top * 0.07), "v", size=8, fill=c["signal"])
        legend.append((swatch("marker", shape="v", color=c["signal"]), "signal"))
    bea = [b.position_m for b in line.beacons_for(d, within=(lo, hi))]
    if bea:
        p.markers(np.asarray(bea, float) / 1000.0, np.full(len(bea), top * 0.03), "|", size=9, fill=c["beacon"],
                  width=1.5)
        legend.append((swatch("marker", shape="|", color=c["beacon"], width=1.5), "ATS-P / TASC beacon"))
    if eval_points:
        ep = np.asarray([q for q, _ in eval_points], float)
        p.markers(ep / 1000.0, np.full(len(ep), top * 0.11), "D", size=7, fill=c["eval"], stroke="#8d6e00",
                  width=0.8)
        legend.append((swatch("marker", shape="D", color=c["eval"], edge="#8d6e00"), "evaluation point"))
    return p


def _gradient_panel(fig, line, d: str, lo: float, hi: float, calls, xlim, legend):
    """The lower panel: the gradient in the running direction [‰] and the curves with their radius."""
    from planner.pages.svg_plot import swatch

    c = COLOURS
    gx, gy = _steps(line.gradients, lo, hi, 0.0)
    g = sign(d) * gy * 1000.0
    g_lo, g_hi = min(0.0, float(np.min(g))), max(0.0, float(np.max(g)))
    pad = 0.05 * (g_hi - g_lo) if g_hi > g_lo else 1.0
    p = fig.panel(GRADIENT_BOX, xlim, (g_lo - pad, g_hi + pad), x_inverted=d == "up", ylabel="gradient [‰]",
                  xlabel="chainage [km]", ytarget=4, font=FONT)
    curves = [(max(a, lo), min(b, hi), r) for a, b, r in zip(line.curves.start_m, line.curves.end_m,
                                                             line.curves.value) if b > lo and a < hi]
    for a, b, _ in curves:
        p.span(a / 1000.0, b / 1000.0, fill=c["curve"], opacity=0.18)
    p.fill_between(gx, 0.0, g, color=c["gradient"], opacity=0.35, edge_width=0.8)
    p.hline(0.0, color="#666", width=0.6)
    for _, stops, pos in calls:
        p.vline(pos / 1000.0, color="#000", width=1.0 if stops else 0.7, dash=None if stops else (1.0, 1.65))
    for a, b, r in curves:
        p.text(0.5 * (a + b) / 1000.0, 0.96, f"R{r:.0f}", size=FONT, color="#34507a", y_frac=True)
    legend.append((swatch("patch", color=c["gradient"], opacity=0.35), "gradient in the running direction [‰] "
                   "(+ rising)"))
    if curves:
        legend.append((swatch("patch", color=c["curve"], opacity=0.4), "curve (radius [m])"))
    return p


def late_s(t_s: float, scheduled_s: float) -> bool:
    """Whether a run of ``t_s`` arrives after its scheduled running time (by more than the tables' tolerance)."""
    from planner.report.margin_rule import TIME_TOL_S

    return t_s - scheduled_s > TIME_TOL_S


def _time_panel(fig, run, calls, xlim, legend, bad_end_s: float = 0.0):
    """The middle panel: time since departure along the leg for both runs, and the scheduled running time, so a
    run that arrives late ends above the scheduled line, and where along the leg it loses the time shows; on a
    late leg (the minimum run itself over the scheduled time) the on-time run is red and its lateness written."""
    from planner.pages.svg_plot import swatch

    d, sched = run.key[0], float(run.key[4])
    x = run.position_m / 1000.0
    t_r, t_m = np.asarray(run.t_s[0], float), np.asarray(run.t_s[1], float)
    top = max(sched, float(t_r[-1]), float(t_m[-1]), bad_end_s) * 1.08
    p = fig.panel(TIME_BOX, xlim, (0.0, top), x_inverted=d == "up", ylabel="time [s]", xticks=False,
                  ytarget=4, font=FONT)
    c = COLOURS
    for _, stops, pos in calls:
        p.vline(pos / 1000.0, color="#000", width=1.0 if stops else 0.7, dash=None if stops else (1.0, 1.65))
    p.hline(sched, color="#555", width=1.0, dash=(6.0, 3.0))
    p.text(0.005, sched, f"time since departure; scheduled {sched:.0f} s", size=FONT, color="#333", anchor="start",
           va="bottom", x_frac=True, dy=-2)
    k = np.unique(np.linspace(0, len(x) - 1, min(len(x), 600)).astype(int))  # time is smooth: 600 points draw it
    p.polyline(x[k], t_m[k], color=c["minimum_band"], width=5.0)
    late = late_s(float(t_m[-1]), sched)
    p.polyline(x[k], t_r[k], color=c["late"] if late else c["on_time"], width=1.6)
    if late:
        p.text(float(x[-1]), float(t_r[-1]), f"{float(t_r[-1]) - sched:.1f} s late", size=FONT, color=c["late"],
               anchor="end", va="bottom", bold=True, dy=-4)
        legend.append((swatch("line", color=c["late"], width=1.6), "on-time departure on a late leg (time panel)"))
    legend.append((swatch("line", color="#555", width=1.0, dash=(6.0, 3.0)), "scheduled running time"))
    return p


def _bad_day(sp, tp, bad_day, sched: float, row, legend) -> None:
    """The bad-day minimum run in both panels: its speed over the leg and its time since departure, with how it
    ends against the scheduled time (the margin report's remaining margin)."""
    from planner.pages.svg_plot import swatch

    x, v, t = (np.asarray(a, float) for a in bad_day)
    col = COLOURS["bad_day"]
    sp.polyline(*_thin(x, v), color=col, width=1.4, dash=(7.0, 2.5, 1.5, 2.5))
    tp.polyline(x / 1000.0, t, color=col, width=1.4, dash=(7.0, 2.5, 1.5, 2.5))
    end = float(t[-1])
    short = late_s(end, sched)
    words = (f"{end - sched:.1f} s late on a bad day" if short else f"{sched - end:.1f} s to spare on a bad day")
    # under the scheduled line's own words, at the left where the runs are still low: clear of the end labels
    tp.text(0.005, sched, f"bad-day minimum {end:.1f} s: {words}", size=FONT, color=col, anchor="start", va="top",
            x_frac=True, bold=bool(short), dy=3)
    legend.append((swatch("line", color=col, width=1.4, dash=(7.0, 2.5, 1.5, 2.5)),
                   f"bad-day minimum run (the margin report's bad day: its load, traction and stop) — {end:.1f} s: "
                   f"{words}"))


def chart_svg(line, run, calls, pattern=None, eval_points=None, signals=None, bad_day=None) -> str:
    """The chart of one leg: an inline SVG (:mod:`planner.pages.svg_plot`) and its legend in HTML under it.

    ``run``: a :class:`planner.report.train_timetable.LegRun`; ``calls``: ``(station_id, stops, chainage_m)``
    of the leg's path from origin to destination (the stop marker of a stop, the station of a pass); ``pattern``: ``{adhesion_kmh_s: (position_m, speed_kmh)}``;
    ``eval_points``: ``[(position_m, id)]``; ``signals``: their chainages (default the line's on the leg);
    ``bad_day``: the bad-day minimum run ``(position_m, speed_kmh, time_s)``
    (:func:`planner.report.leg_margin.bad_day_run`), or None. The same inputs give the same bytes.
    """
    from planner.pages.svg_plot import Figure, legend_html

    d, tt, o, de, sched = run.key[:5]
    row = run.row
    x = run.position_m
    lo, hi = float(np.min(x)), float(np.max(x))
    m = 0.05 * (hi - lo) / 1000.0  # matplotlib's margins: the leg's ends off the frame
    xlim = (lo / 1000.0 - m, hi / 1000.0 + m)
    fig = Figure(W, H, ident="sc")
    legend: list = []
    sp = _speed_panel(fig, line, run, calls, pattern, eval_points, signals, xlim, legend)
    tp = _time_panel(fig, run, calls, xlim, legend, float(bad_day[2][-1]) if bad_day is not None else 0.0)
    if bad_day is not None:
        _bad_day(sp, tp, bad_day, float(sched), row, legend)
    _gradient_panel(fig, line, d, lo, hi, calls, xlim, legend)
    t_r = float(run.t_s[0][-1])
    margin = float(row["margin_s"])
    late = late_s(-margin, 0.0)
    verdict = (f"late: the minimum run itself takes {-margin:.1f} s more than scheduled; no departure arrives on "
               "time" if late else
               f"at the on-time ratio {percent(run.ratio)} the run takes {t_r:.1f} s, {t_r - float(sched):.1f} s more "
               "than scheduled (the tables' ratio steps)" if late_s(t_r, float(sched)) else "")
    title = (f"{tt} {d} {o} → {de} ({(hi - lo) / 1000:.2f} km): scheduled {sched:.0f} s, minimum "
             f"{float(row['min_running_time_s']):.1f} s, margin {shown(margin, sign=True)} s")
    fig.title(8, 22, title, size=FONT + 2)
    if verdict:
        fig.title(8, 42, verdict, size=FONT + 1, color=COLOURS["late"] if late else "#444", bold=late)
    title += f" ({verdict})" if verdict else ""
    return fig.svg(label=f"speed–distance chart: {title}") + legend_html(legend)


def chart_page(line, run, calls, trains, svg: str, back: str, *, nav=(), run_id: str | None = None,
               day: dict | None = None, run_date: str | None = None) -> str:
    """The chart page: the run's other pages (``nav``: (label, href)), its id and operating day (``day``: its
    record), title, what is drawn, the day's temporary restrictions on the leg, the trains that run the leg at
    this time (links back to their tables, ``back``)."""
    from planner.pages.margin_report import CSS
    from planner.pages.run_head import nav_html
    from planner.pages.svg_plot import LEGEND_CSS

    d, tt, o, de, sched = run.key[:5]
    e = html.escape
    links = ", ".join(f'<a href="{e(back)}#train-{e(t)}">{e(t)}</a>' for t in trains)
    title = f"{tt} {d} {o} → {de}, scheduled {sched:.0f} s"
    temps = temporary_limits(line, d, tt, *run.span_m)
    tsr = "; ".join(f"<b>{e(s.restriction_id)}</b> {kmh(s.limit_ms):.0f} km/h on km {s.start_m / 1000:.3f}–"
                    f"{s.end_m / 1000:.3f}" + ("" if s.has_beacon else " (no beacon: the on-board database feeds it)")
                    for s in temps)
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{e(title)} — speed–distance</title>'
            f'<meta name="viewport" content="width=device-width, initial-scale=1"><style>{CSS}{LEGEND_CSS}</style></head><body><main>'
            + nav_html(nav or [(f"running-time tables of line {line.line_id}", back)], run_id, day, run_date)
            + f"<h1>Speed–distance: {e(title)}</h1>"
            f'<p class="sub">Run at the on-time ratio {percent(run.ratio)} (the ratio the on-board logic picks when the '
            f"train leaves on time) and the minimum run (ratio 100 %), both at the tables' conditions (empty, full "
            f"traction), from the departure stop marker to the arrival stop marker.</p>"
            f'<div class="fig">{svg}</div>'
            + (f'<p class="caption">Temporary speed restrictions of the day on this leg (orange, hatched), in force '
               f"while these trains run it, so in their runs (the tables and bundles count a restriction in force at "
               f"any time of the operating day for the whole day, on the safe side): {tsr}.</p>" if tsr else
               '<p class="caption">No temporary speed restriction of the day is in force on this leg while these '
               'trains run it.</p>')
            + f'<p class="caption">Trains that run this leg with this scheduled time: {links or "none"}.</p>'
            "</main></body></html>\n")


def write_chart(path: Path, text: str) -> Path:
    from planner.io.atomic import write_bytes_atomic

    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, text.encode("utf-8"))
    return path


__all__ = ["chart_svg", "chart_page", "write_chart"]
