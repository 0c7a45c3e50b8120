"""Speed–distance chart of one leg and scheduled time, as a self-contained page.

One page per (leg, train type, scheduled running time) of the timetable,
``charts/<line>/<direction>_<type>_<origin>-<destination>_<scheduled>s.html``,
pre-rendered by the nightly job (a published run is static files) and linked
from the per-train running-time table (:mod:`planner.pages.timetable`).

What it draws (matplotlib through :func:`planner.report.plots.pyplot`, inline SVG):

* the run at the on-time ratio and the minimum run (ratio 1.0), the two
  recorded runs of :class:`planner.report.train_timetable.LegRun`;
* the permanent speed limits that apply to the train (and the line maximum) and
  the on-board maximum it runs to (limit − the train's speed margin);
* apart from them (orange, hatched, named by id): the day's temporary speed
  restrictions (kind ``temporary``, from the daily feed) in force at some time
  of the run's operating day, which the run applies all day;
* the stopping pattern at the arrival stop, lowest and highest adhesion of the
  run's stopping-pattern sweep (``stop_samples``);
* the stopping pattern (stops and passes) as station lines, signals, ATS-P
  beacons and the evaluation points of the leg (``eval_points``);
* below: the gradient [‰] and the curves (radius) along the leg.

The page around the chart names the run and its operating day and links to the run's
other pages (:func:`planner.pages.run_head.nav_html`); the chart itself is a cached unit
of the nightly job, the page is written by every run.

Curves are thinned for drawing with :func:`planner.report.train_graph.simplify`
(0.2 km/h, 2 m), which keeps a page near 60 kB.
"""
from __future__ import annotations

import html
import threading
from pathlib import Path

import numpy as np

from planner.line.daily import TEMPORARY_KIND
from planner.line.model import sign
from planner.line.units import fixed, kmh

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


_REUSED = threading.local()


def reused_subplots(name: str, *args, **kwargs):
    """``plt.subplots(*args, **kwargs)`` made once per thread and ``name``, then given again emptied.

    For a chart drawn many times over (the speed–distance chart of every leg): making the figure, its
    axes and their ticks anew took a fifth to a third of such a chart's CPU time. Emptied means as new for a chart that
    sets the same axes properties each time: every line, text, collection, patch and legend removed,
    the data limits, autoscaling, colour cycle, axis labels and the x direction reset, so the figure
    draws the same bytes as a new one (``tests/test_speed_chart.py`` draws charts in turn and compares
    each with one drawn on a new figure). Save it with ``planner.report.plots.inline_svg(fig, close=False)``.
    """
    from planner.report.plots import pyplot

    plt = pyplot()
    made = getattr(_REUSED, "figures", None)
    if made is None:
        made = _REUSED.figures = {}
    got = made.get(name)
    if got is None or not plt.fignum_exists(got[0].number):
        got = made[name] = plt.subplots(*args, **kwargs)
        return got
    fig, axes = got
    for ax in np.ravel(axes):
        for artist in [*ax.lines, *ax.texts, *ax.collections, *ax.patches]:
            artist.remove()
        if ax.legend_ is not None:
            ax.legend_.remove()
        ax.set_prop_cycle(None)
        ax.dataLim.set_points(np.array([[np.inf, np.inf], [-np.inf, -np.inf]]))  # Bbox.null()
        ax.ignore_existing_data_limits = True
        ax.set_autoscale_on(True)
        ax.set_xlabel("")
        ax.set_ylabel("")
        if ax.xaxis_inverted():
            ax.invert_xaxis()
        if ax.yaxis_inverted():
            ax.invert_yaxis()
    for ax in np.ravel(axes):
        ax.autoscale_view()
    return got


def chart_svg(line, run, calls, pattern=None, eval_points=None, signals=None) -> str:
    """The chart of one leg (inline SVG).

    ``run``: a :class:`planner.report.train_timetable.LegRun`; ``calls``: ``(station_id, stops, chainage_m)``
    of the leg's path from origin to destination (the stop marker of a stop, the station of a pass); ``pattern``: ``{adhesion_kmh_s: (position_m, speed_kmh)}``;
    ``eval_points``: ``[(position_m, id)]``; ``signals``: their chainages (default the line's on the leg).
    """
    from planner.report.plots import inline_svg

    d, tt, o, de, sched = run.key[:5]
    row = run.row
    x = run.position_m
    lo, hi = float(np.min(x)), float(np.max(x))
    # one figure per process, emptied for each chart (a job draws one chart per leg): same bytes, less time
    fig, (ax, ax2) = reused_subplots("speed_chart", 2, 1, figsize=(15.5, 7.0), sharex=True,
                                     gridspec_kw={"height_ratios": [4, 1.3]})
    lx, ly = _limit_steps(line, d, tt, lo, hi)
    ax.plot(lx, ly, color="#9e9e9e", lw=1.0, ls="--", label="permanent speed limit")
    ax.step(x / 1000.0, kmh(run.vmax_ms), where="mid", color="0.55", lw=1.1, label="on-board maximum (limit − margin)")
    t_r, t_m = float(run.t_s[0][-1]), float(run.t_s[1][-1])
    ax.plot(*_thin(x, kmh(run.v_ms[1])), color="#1f5fa8", lw=1.8, label=f"minimum run: ratio 100 % — {t_m:.1f} s")
    ax.plot(*_thin(x, kmh(run.v_ms[0])), color="#2e7d32", lw=1.6,
            label=f"on-time departure: ratio {run.ratio:.0%} — {t_r:.1f} s\n  (scheduled {sched:.0f} s)")
    for (a, (px, pv)), (col, what) in zip(sorted((pattern or {}).items()),
                                          (("#c62828", "lowest"), ("#ef8f00", "highest"))):
        ax.plot(np.asarray(px) / 1000.0, pv, color=col, lw=1.3, ls=(0, (4, 2)),
                label=f"stopping pattern, {what} adhesion {a:.2g} km/h/s")
    temps = temporary_limits(line, d, tt, lo, hi)
    top = float(np.nanmax(ly)) * (1.3 if temps else 1.14)  # room for the restrictions' ids under the stations
    ax.set_ylim(0, top)
    for k, s in enumerate(temps):
        a, b, v = max(s.start_m, lo) / 1000.0, min(s.end_m, hi) / 1000.0, kmh(s.limit_ms)
        # an opaque fill: an alpha would fade the hatch with it
        ax.axvspan(a, b, ymax=0.8, facecolor="#fff3e8", hatch="//", edgecolor="#f2b48a", lw=0)
        ax.plot([a, a, b, b], [top * 0.8, v, v, top * 0.8], color="#e65100", lw=1.8,
                label="temporary speed restriction (the day's feed)" if k == 0 else None)
        ax.text(0.5 * (a + b), top * 0.8, f"{s.restriction_id}\n{v:.0f} km/h", ha="center", va="bottom",
                fontsize=8, color="#bf360c", fontweight="bold",
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="#e65100", lw=0.6, alpha=0.9))
    for sid, stops, p in calls:
        ax.axvline(p / 1000.0, color="k", lw=1.0 if stops else 0.7, ls="-" if stops else ":")
        ax2.axvline(p / 1000.0, color="k", lw=1.0 if stops else 0.7, ls="-" if stops else ":")
        ax.text(p / 1000.0, top * 0.985, f" {sid}{'' if stops else ' (pass)'} ", ha="center", va="top", fontsize=9,
                bbox=dict(boxstyle="round,pad=0.2", fc="white" if stops else "#f3f3f3", ec="k", lw=0.6))
    sig = signals if signals is not None else [s.position_m for s in line.signals
                                               if s.direction == d and lo <= s.position_m <= hi]
    if sig:
        ax.plot(np.asarray(sig) / 1000.0, np.full(len(sig), top * 0.07), "v", color="#37474f", ms=6,
                label="signal")
    bea = [b.position_m for b in line.beacons_for(d) if lo <= b.position_m <= hi]
    if bea:
        ax.plot(np.asarray(bea) / 1000.0, np.full(len(bea), top * 0.03), "|", color="#6a1b9a", ms=8, mew=1.5,
                label="ATS-P / TASC beacon")
    if eval_points:
        ep = np.asarray([p for p, _ in eval_points], float)
        ax.plot(ep / 1000.0, np.full(len(ep), top * 0.11), "D", color="#f2b705", mec="#8d6e00", ms=4.5,
                label="evaluation point")
    ax.set_ylabel("speed [km/h]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, frameon=False, borderaxespad=0.0)
    gx, gy = _steps(line.gradients, lo, hi, 0.0)
    ax2.fill_between(gx, 0.0, sign(d) * gy * 1000.0, step=None, color="#8d6e63", alpha=0.35, lw=0.8,
                     label="gradient in the running direction [‰] (+ rising)")
    ax2.axhline(0.0, color="0.4", lw=0.6)
    ax2.set_ylabel("gradient [‰]")
    for a, b, r in zip(line.curves.start_m, line.curves.end_m, line.curves.value):
        if b <= lo or a >= hi:
            continue
        a, b = max(a, lo), min(b, hi)
        ax2.axvspan(a / 1000.0, b / 1000.0, color="#5a7da8", alpha=0.18, lw=0)
        ax2.text(0.5 * (a + b) / 1000.0, 0.94, f"R{r:.0f}", ha="center", va="top", fontsize=7.5, color="#34507a",
                 transform=ax2.get_xaxis_transform())
    ax2.plot([], [], color="#5a7da8", alpha=0.4, lw=6, label="curve (radius [m])")
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, frameon=False, borderaxespad=0.0)
    ax2.set_xlabel("chainage [km]")
    ax2.grid(alpha=0.3)
    if d == "up":
        ax.invert_xaxis()
    fig.suptitle(f"{tt} {d} {o} → {de} ({(hi - lo) / 1000:.2f} km): scheduled {sched:.0f} s, minimum "
                 f"{float(row['min_running_time_s']):.1f} s, margin {fixed(float(row['margin_s']), 1, True)} s",
                 x=0.01, ha="left", fontsize=11, fontweight="bold")
    fig.subplots_adjust(left=0.055, right=0.75, top=0.93, bottom=0.09, hspace=0.06)
    return inline_svg(fig, close=False)


def chart_page(line, run, calls, trains, svg: str, back: str, *, nav=(), run_id: str | None = None,
               day: dict | None = None, run_date: str | None = None) -> str:
    """The chart page: the run's other pages (``nav``: (label, href)), its id and operating day (``day``: its
    record), title, what is drawn, the day's temporary restrictions on the leg, the trains that run the leg at
    this time (links back to their tables, ``back``)."""
    from planner.pages.margin_report import CSS
    from planner.pages.run_head import nav_html

    d, tt, o, de, sched = run.key[:5]
    e = html.escape
    links = ", ".join(f'<a href="{e(back)}#train-{e(t)}">{e(t)}</a>' for t in trains)
    title = f"{tt} {d} {o} → {de}, scheduled {sched:.0f} s"
    x = run.position_m
    temps = temporary_limits(line, d, tt, float(np.min(x)), float(np.max(x)))
    tsr = "; ".join(f"<b>{e(s.restriction_id)}</b> {kmh(s.limit_ms):.0f} km/h on km {s.start_m / 1000:.3f}–"
                    f"{s.end_m / 1000:.3f}" + ("" if s.has_beacon else " (no beacon: the on-board database feeds it)")
                    for s in temps)
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>{e(title)} — speed–distance</title>'
            f'<meta name="viewport" content="width=device-width, initial-scale=1"><style>{CSS}</style></head><body><main>'
            + nav_html(nav or [(f"running-time tables of line {line.line_id}", back)], run_id, day, run_date)
            + f"<h1>Speed–distance: {e(title)}</h1>"
            f'<p class="sub">Run at the on-time ratio {run.ratio:.0%} (the ratio the on-board logic picks when the '
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
