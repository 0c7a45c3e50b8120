"""The margin report's charts, drawn as SVG by :mod:`planner.pages.svg_plot`, and their page sections.

:func:`chart_svgs` draws any of the four charts on its own (tens of milliseconds all four);
:func:`chart_sections` wraps them in their headings and captions
(:mod:`planner.pages.margin_report` puts them in the page). Each chart is an inline ``<svg>`` with its
legend, if any, in HTML under it, so the page stays self-contained and the browser lays the legend out:

* :func:`margin_chart`, per direction: a panel per train type (legs passing stations in their own):
  per leg a light bar of the margin (scheduled − minimum), a narrow bar of what remains on a bad day in
  the colour of the leg's worst flag, with its number, and a black line at the supplement the rule asks
  for; the station codes over every panel, a grey line at each stop marker;
* :func:`curves_chart`: the chosen leg's minimum, as-scheduled and bad-day runs with the stopping pattern,
  and under them how far each run is behind the minimum run;
* :func:`adhesion_chart`: stopping time against adhesion for every approach of the chosen train type,
  a panel per direction, and the sentence naming the hardest approach.

Chainage runs left to right in the running direction (``up`` mirrored). Drawing the four costs ~30 ms
of CPU on the sample (with matplotlib it was ~1.2 s, and importing it ~0.3 s in every worker that drew
them), ~100 kB against ~300 kB. The same report gives the same bytes.
"""
from __future__ import annotations

import math
from collections import namedtuple
from html import escape

import numpy as np

from planner.line.units import KMH_S, fixed, percent
from planner.pages.svg_plot import Figure, legend_html, padded, swatch
from planner.report.leg_flags import FLAG, FLAGS, FLAGS_SHOWN, flag_of

__all__ = ["CHARTS", "chart_sections", "chart_svgs", "margin_chart", "curves_chart", "adhesion_chart",
           "FLAG_COLOURS", "MARGIN_COLOUR"]


def _esc(x) -> str:  # as the page's own escaping (planner.pages.margin_report)
    return escape(str(x), quote=True)


FLAG_COLOURS = {f.name: f.colour for f in FLAGS_SHOWN} | {"ok": "#2e7d32"}
"""Colour of a leg by its worst flag (the badges' colours)."""
MARGIN_COLOUR = "#b0c4de"
"""Bar colour of the nominal margin (its edge: ``MARGIN_EDGE``)."""
MARGIN_EDGE = "#7d93ad"
RED, BLUE, GREEN, GREY = "#c62828", "#1f5fa8", "#2e7d32", "#8c8c8c"
W = 1200.0
"""Width of every chart in user units (its ``viewBox``; drawn at the width of the page)."""


CHARTS = ("margin:down", "margin:up", "curves", "adhesion")
"""The report's charts, by name: what :func:`chart_svgs` draws."""


def chart_svgs(report, markers: dict[str, dict[str, float]], names=CHARTS) -> dict:
    """The charts ``names`` (of :data:`CHARTS`) of a report as inline SVG: ``margin:<direction>`` the
    margin per leg ("" when the direction has none), ``curves`` the run curves of the chosen leg,
    ``adhesion`` (SVG, the sentence naming the hardest leg). Each is drawn on its own, so they
    can be drawn on several workers; a chart a report has no data for is left out."""
    out: dict = {}
    for name in names:
        kind, _, d = name.partition(":")
        if kind == "margin" and d in markers:
            out[name] = margin_chart(report, d, markers[d])
        elif kind == "curves" and report.chosen:
            out[name] = curves_chart(report)
        elif kind == "adhesion" and report.chosen:
            out[name] = adhesion_chart(report)
    return out


def chart_sections(report, markers: dict[str, dict[str, float]], svgs: dict | None = None) -> list[str]:
    """Margin per interstation, the run curves of the chosen leg and stopping time against adhesion:
    the page's chart sections (HTML with inline SVG), the slow part of :func:`render_html`.
    ``svgs``: the charts drawn beforehand (:func:`chart_svgs`); else they are drawn here."""
    if svgs is None:
        svgs = chart_svgs(report, markers)
    rule = report.rule
    parts = []
    parts.append("<h2>Margin per interstation along the line</h2>")
    parts.append(
        "<p class='caption'>Each bar spans one leg from stop marker to stop marker. Light bar: margin the timetable "
        "grants over the minimum running time. Narrow coloured bar and its number: what remains on a bad day "
        f"(scheduled − bad-day minimum); below zero the leg is short on a bad day (dark red where the margin "
        "itself is below zero: impossible). Black line: the supplement the rule asks "
        f"for ({rule.supplement_percent:g} % of the minimum + {rule.supplement_min_per_100km:g} min/100 km). "
        "Where a leg has several scheduled times, the one with the least bad-day margin is drawn. Hover a bar "
        "for the leg's times.</p>")
    for d in ("down", "up"):
        if d in markers:
            svg = svgs[f"margin:{d}"]
            if svg:
                parts.append(f"<div class='fig'>{svg}</div>")

    if report.chosen:
        k = report.chosen
        parts.append(f"<h2>Run curves: {_esc(k['train_type'])} {_esc(k['direction'])} {_esc(k['origin'])} → "
                     f"{_esc(k['destination'])}</h2>")
        parts.append(
            "<p class='caption'>The leg with the least bad-day margin (or the one asked for with "
            "<code>--curves</code>). Top: speed against chainage for the minimum run, the run the on-board logic "
            "makes for the scheduled time (it re-chooses the ratio at every evaluation point), and the bad-day "
            "run, which hands over to the stopping pattern at the pattern start. Bottom: how far each run is "
            "behind the minimum run at each point; the dashed blue line is the margin the timetable grants, so "
            "a red curve that ends above it cannot be kept.</p>")
        parts.append(f"<div class='fig'>{svgs['curves']}</div>")
        svg, hardest = svgs["adhesion"]
        if svg:
            parts.append("<h2>Stopping time against adhesion</h2>")
            parts.append(
                f"<p class='caption'>Minimum-time jerk-limited stopping pattern from the pattern start at the "
                f"speed of the minimum run, for every adhesion level of the sweep, relative to the best level. "
                f"Worse adhesion to the right; where a curve is flat the comfort limit, not adhesion, bounds the "
                f"braking. {_esc(hardest)}</p>")
            parts.append(f"<div class='fig'>{svg}</div>")

    return parts


# --- margin per leg -----------------------------------------------------------------------------------------------
M_LEFT, M_TOP, M_PANEL, M_HEAD, M_GAP, M_FOOT = 64.0, 34.0, 150.0, 36.0, 18.0, 46.0
"""Margin chart: frame left edge, room for the title, a panel's height, the room over it (its title and
the station codes), between panels, under the last (tick labels, axis label)."""


BAR_COLUMNS = ("direction", "train_type", "origin", "destination", "scheduled_running_time_s", "min_running_time_s",
               "margin_s", "degraded_min_running_time_s", "remaining_margin_s", "supplement_required_s", *FLAGS)
"""The columns of a margin row that a bar shows (its tooltip and colour)."""


Leg = namedtuple("Leg", BAR_COLUMNS)


def _margin_groups(rows) -> list:
    """(title, legs) per panel: per train type its stop-to-stop legs, then its legs passing stations; a leg
    with several scheduled times once, with the least remaining margin (legs as :data:`Leg`, in plain Python:
    the frame's row access costs more than the drawing)."""
    legs = [Leg(*v) for v in zip(*(rows[c].tolist() for c in BAR_COLUMNS))]
    passing = (rows.passes.map(len) > 0).tolist()
    order = sorted(range(len(legs)), key=lambda i: (math.isnan(legs[i].remaining_margin_s),
                                                   legs[i].remaining_margin_s))  # NaN last, ties as given
    panels: dict = {}
    for i in order:
        r = legs[i]
        seen, part = panels.setdefault((r.train_type, passing[i]), (set(), []))
        if (r.origin, r.destination) not in seen:
            seen.add((r.origin, r.destination))
            part.append(r)
    return [(f"{t}: legs passing stations" if p else f"{t}: stop to next station", part)
            for (t, p), (_, part) in sorted(panels.items())]


def _leg_tip(r) -> str:
    return (f"{r.train_type} {r.direction} {r.origin} → {r.destination}: scheduled "
            f"{r.scheduled_running_time_s:.0f} s, minimum {r.min_running_time_s:.1f} s, margin "
            f"{fixed(r.margin_s, 1, True)} s; bad-day minimum {fixed(r.degraded_min_running_time_s, 1)} s, "
            f"remaining {fixed(r.remaining_margin_s, 1, True)} s; supplement asked {fixed(r.supplement_required_s, 1)} s")


def margin_chart(report, direction: str, stations: dict[str, float]) -> str:
    """The margin per leg along the line for one direction (inline SVG and its legend), "" when the direction
    has no timetabled leg.

    A panel per train type (legs passing stations in their own), sharing the chainage axis; bars span
    the leg from stop marker to stop marker (``stations``: station → stop marker [m]), running left to
    right; the y axis is the same on every panel.
    """
    rows = report.rows[(report.rows.direction == direction) & report.rows.scheduled_running_time_s.notna()]
    if rows.empty:
        return ""
    groups = _margin_groups(rows)
    xlim = (min(min(stations.values()), 0.0) / 1000.0 - 0.3, max(stations.values()) / 1000.0 + 0.3)
    ymax = max(float(np.nanmax(rows.margin_s)), float(np.nanmax(rows.supplement_required_s))) + 4
    ymin = min(0.0, float(np.nanmin(rows.remaining_margin_s)))
    ymin -= max(3.0, 0.12 * (ymax - ymin))  # room for the label under the lowest bar
    order = sorted(stations.items(), key=lambda kv: kv[1])
    n = len(groups)
    fig = Figure(W, M_TOP + n * (M_HEAD + M_PANEL) + (n - 1) * M_GAP + M_FOOT, ident=f"m{direction}")
    drawn = set()
    for i, (title, sub) in enumerate(groups):
        top = M_TOP + M_HEAD + i * (M_HEAD + M_PANEL + M_GAP)
        last = i == n - 1
        p = fig.panel((M_LEFT, top, W - M_LEFT - 16, M_PANEL), xlim, (ymin, ymax), x_inverted=direction == "up",
                      ylabel="seconds", xticks=last, grid="y",
                      xlabel="chainage [km] (stop markers of this direction)" if last else "")
        p.title(title, size=11, pad=24)
        p.top_ticks([x / 1000.0 for _, x in order], [sid for sid, _ in order])
        for _, x in order:
            p.vline(x / 1000.0, color="#d9d9d9", width=0.6)
        for r in sub:
            a, b = sorted((stations[r.origin] / 1000.0, stations[r.destination] / 1000.0))
            pad = 0.04 * (b - a)
            x0, w = a + pad, b - a - 2 * pad
            tip = [_leg_tip(r)]
            flag = flag_of(r)
            drawn.add(flag)
            p.rects(x0, x0 + w, 0.0, r.margin_s, fill=MARGIN_COLOUR, stroke=MARGIN_EDGE, width=0.6, tips=tip)
            p.rects(x0 + 0.25 * w, x0 + 0.75 * w, 0.0, r.remaining_margin_s, fill=FLAG_COLOURS[flag], opacity=0.9,
                    tips=tip)
            p.polyline([x0, x0 + w], [r.supplement_required_s] * 2, color="#000", width=1.4)
            y = r.remaining_margin_s
            if np.isfinite(y):
                p.text(x0 + 0.5 * w, y, fixed(y, 1, True), size=9, bold=True, va="bottom" if y >= 0 else "top",
                       dy=-2.0 if y >= 0 else 2.0, color="#8e1b1b" if y < 0 else "#1d2327")
        p.hline(0.0, color="#000", width=0.8)
    first, last_sid = order[0][0], order[-1][0]
    if direction == "up":
        first, last_sid = last_sid, first
    title = f"{direction}: {first} → {last_sid}, running left to right"
    fig.title(8, 20, title)
    legend = [(swatch("patch", color=MARGIN_COLOUR), "margin = scheduled − minimum"),
              (swatch("patch", color=FLAG_COLOURS["ok"]), "bad-day margin (≥ tight threshold)"),
              (swatch("patch", color=FLAG_COLOURS["tight"]), "bad-day margin < tight threshold"),
              (swatch("patch", color=FLAG_COLOURS["short_bad_day"]), "negative: short on a bad day"),
              (swatch("patch", color=FLAG_COLOURS["impossible"]), "impossible: margin < 0")]
    legend += [(swatch("patch", color=FLAG_COLOURS[f]), f"{FLAG[f].badge} (its bar in this colour)")
               for f in ("unassessed", "unreachable", "inaccurate") if f in drawn]
    legend.append((swatch("line", color="#000", width=1.4), "supplement the rule asks for"))
    return fig.svg(label=f"margin per leg, {title}") + legend_html(legend)


# --- run curves of the chosen leg ---------------------------------------------------------------------------------
C_LEFT, C_SPEED, C_BEHIND = 78.0, (34.0, 330.0), (376.0, 200.0)
"""Run-curves chart: frame left edge (a two-line axis label), (top, height) of the speed panel and of the
time-behind panel under it."""


TOL_V_KMH, TOL_T_S, TOL_X_M = 0.05, 0.01, 0.5
"""How far a drawn run may stray from the computed one: 0.05 km/h, 0.01 s or 0.5 m, a quarter of a pixel
or less on a wide screen, so the curves look as smooth as every computed point (~100 points a run of
3,000 instead of 3,000: a few kB)."""


def _thin(x_m, y, tol_y: float):
    """(x [km], y) thinned for drawing (:func:`planner.report.train_graph.simplify`, as the speed chart, within
    ``tol_y`` or :data:`TOL_X_M`)."""
    from planner.report.train_graph import simplify

    x_m, y = np.asarray(x_m, float), np.asarray(y, float)
    if not (np.isfinite(x_m).all() and np.isfinite(y).all()):
        return x_m / 1000.0, y
    k = simplify(y, x_m, tol_y, TOL_X_M)
    return x_m[k] / 1000.0, y[k]


def curves_chart(report) -> str:
    """Run curves of the chosen leg and where along it the time goes (inline SVG and its legends)."""
    c, k = report.curves, report.chosen
    if not c or not k:
        return ""
    rows = report.rows
    row = rows[(rows.direction == k["direction"]) & (rows.train_type == k["train_type"])
               & (rows.origin == k["origin"]) & (rows.destination == k["destination"])].iloc[0]
    x, dx = c["position_m"], c["degraded_position_m"]
    km = x / 1000.0
    has_sched, has_pattern = "sched_speed_kmh" in c, "pattern_position_m" in c
    xs = [x, dx] + ([c["pattern_position_m"]] if has_pattern else [])
    xlim = padded(min(float(np.min(v)) for v in xs) / 1000.0, max(float(np.max(v)) for v in xs) / 1000.0)
    inv = k["direction"] == "up"
    top_v = float(np.nanmax(c["vmax_kmh"])) * 1.12
    width = W - C_LEFT - 16
    sp = Figure(W, C_BEHIND[0] + C_BEHIND[1] + 46, ident="rc")
    p = sp.panel((C_LEFT, C_SPEED[0], width, C_SPEED[1]), xlim, (0.0, top_v), x_inverted=inv, xticks=False,
                 ylabel="speed [km/h]", ytarget=7)
    top_items, low_items = [], []
    p.steps_mid(km, c["vmax_kmh"], color=GREY, width=1.1)
    top_items.append((swatch("line", color=GREY, width=1.1), "on-board maximum (limit − margin)"))
    p.polyline(*_thin(x, c["min_speed_kmh"], TOL_V_KMH), color=BLUE, width=1.8)
    top_items.append((swatch("line", color=BLUE, width=1.8),
                      f"minimum: ratio 100 %, nominal — {row.min_running_time_s:.1f} s"))
    if has_sched:
        p.polyline(*_thin(x, c["sched_speed_kmh"], TOL_V_KMH), color=GREEN, width=1.5)
        top_items.append((swatch("line", color=GREEN, width=1.5),
                          f"as scheduled: on-board logic, departs at ratio {percent(row.ratio_on_time)} — "
                          f"{row.scheduled_running_time_s:.0f} s scheduled, arrives "
                          f"{fixed(row.arrival_error_s, 1, True)} s"))
    p.polyline(*_thin(dx, c["degraded_speed_kmh"], TOL_V_KMH), color=RED, width=1.5)
    top_items.append((swatch("line", color=RED, width=1.5),
                      f"bad day: load {report.rule.bad_load:.0%}, traction ×{report.rule.bad_traction:g}, ratio "
                      f"100 % — {row.degraded_min_running_time_s:.1f} s"))
    if has_pattern:
        p.polyline(*_thin(c["pattern_position_m"], c["pattern_speed_kmh"], TOL_V_KMH), color=RED, width=1.5,
                   dash=(5.5, 2.4))
        top_items.append((swatch("line", color=RED, width=1.5, dash=(5.5, 2.4)),
                          f"stopping pattern at adhesion {row.adhesion_min_ms2 / KMH_S:g} km/h/s — "
                          f"{row.stop_time_degraded_s:.1f} s"))
    ps = c["pattern_start_m"] / 1000.0
    p.vline(ps, color=RED, width=0.8, dash=(1.0, 1.65))
    p.text(ps, 3.0, "pattern start", size=9, color=RED, anchor="start", va="bottom", dx=4.0)
    for xk, name in ((km[0], row.origin), (km[-1], row.destination)):
        p.vline(xk, color="#000", width=1.0)
        p.text(xk, top_v * 0.985, name, size=10, box=("white", "#000"))
    # where the time goes: time behind the minimum run at each point
    tmin = c["min_time_s"]
    behind = []
    if has_sched:
        behind.append((x, c["sched_time_s"] - tmin, GREEN, None))
        low_items.append((swatch("line", color=GREEN, width=1.5), "as scheduled − minimum"))
    behind.append((dx, c["degraded_time_s"] - tmin[: len(c["degraded_time_s"])], RED, None))
    low_items.append((swatch("line", color=RED, width=1.5), "bad day − minimum"))
    if has_pattern:
        order = np.argsort(x)
        tm_p = np.interp(c["pattern_position_m"], x[order], tmin[order])
        behind.append((c["pattern_position_m"], c["pattern_time_s"] - tm_p, RED, (5.5, 2.4)))
        low_items.append((swatch("line", color=RED, width=1.5, dash=(5.5, 2.4)), "stopping pattern − minimum"))
    ys = np.concatenate([b[1] for b in behind] + [[row.margin_s]])
    q = sp.panel((C_LEFT, C_BEHIND[0], width, C_BEHIND[1]), xlim, padded(np.nanmin(ys), np.nanmax(ys)),
                 x_inverted=inv, ylabel="time behind the\nminimum run [s]", xlabel="chainage [km]", ytarget=5)
    for bx, by, col, dash in behind:
        q.polyline(*_thin(bx, by, TOL_T_S), color=col, width=1.5, dash=dash)
    q.hline(row.margin_s, color=BLUE, width=1.0, dash=(3.7, 1.6))
    q.text(km[0], row.margin_s, f"scheduled margin {row.margin_s:.1f} s", size=9, color=BLUE, anchor="start",
           va="bottom", dx=6.0, dy=-1.0)
    q.vline(ps, color=RED, width=0.8, dash=(1.0, 1.65))
    title = (f"{k['train_type']} {k['direction']} {row.origin} → {row.destination} ({row.length_m / 1000:.2f} km): "
             f"scheduled {row.scheduled_running_time_s:.0f} s, bad-day margin "
             f"{fixed(row.remaining_margin_s, 1, True)} s")
    sp.title(8, 20, title)
    return (sp.svg(label=f"run curves: {title}") + legend_html(top_items, head="Top:")
            + legend_html(low_items, head="Bottom:"))


# --- stopping time against adhesion -------------------------------------------------------------------------------
A_LEFT, A_TOP, A_HEIGHT, A_GAP = 78.0, 30.0, 330.0, 24.0
"""Adhesion chart: frame left edge, top and height of the two panels, the gap between them."""


def _approach_losses(sw) -> dict:
    """Per direction, (time lost at worst, origin, destination, adhesion levels, stop times) of every approach
    that stops at the best level, the largest loss first (ties: by origin, destination)."""
    sw = sw.sort_values(["direction", "origin", "destination", "adhesion_kmh_s"], kind="stable")
    keys = list(zip(sw.direction.tolist(), sw.origin.tolist(), sw.destination.tolist()))
    a_all, t_all = sw.adhesion_kmh_s.to_numpy(float), sw.stop_time_s.to_numpy(float)
    starts = [i for i in range(len(keys)) if i == 0 or keys[i] != keys[i - 1]] + [len(keys)]
    losses: dict = {"down": [], "up": []}
    for i, j in zip(starts[:-1], starts[1:]):
        (d, o, de), a, t = keys[i], a_all[i:j], t_all[i:j]
        if d in losses and np.isfinite(t[-1]):
            losses[d].append((float(np.nanmax(t - t[-1])), o, de, a, t))
    for v in losses.values():
        v.sort(key=lambda w: -w[0])
    return losses


def adhesion_chart(report) -> tuple[str, str]:
    """Stopping-pattern time against adhesion for every approach of the chosen leg's train type, a panel per
    direction sharing the time axis, worse adhesion to the right.

    Returns the SVG and the hardest approach's description.
    """
    k, sw = report.chosen, report.sweep
    if sw is None or len(sw) == 0 or not k:
        return "", ""
    tt, rows = k["train_type"], report.rows
    plain = rows[(rows.train_type == tt) & (rows.passes.map(len) == 0)][
        ["direction", "origin", "destination"]].drop_duplicates()
    sw = sw.merge(plain, on=["direction", "origin", "destination"])
    sw = sw[sw.train_type == tt]
    losses = _approach_losses(sw)
    ys = [t - t[-1] for d in losses for *_, t in losses[d]]
    ylim = padded(min((float(np.nanmin(v)) for v in ys), default=np.nan),
                  max((float(np.nanmax(v)) for v in ys), default=np.nan))
    width = (W - A_LEFT - 16 - A_GAP) / 2
    fig = Figure(W, A_TOP + A_HEIGHT + 46, ident="ad")
    worst = (-1.0, None)
    for i, d in enumerate(("down", "up")):
        levels = [a for *_, a, _ in losses[d]]
        xlim = padded(min((float(a.min()) for a in levels), default=np.nan),
                      max((float(a.max()) for a in levels), default=np.nan))
        p = fig.panel((A_LEFT + i * (width + A_GAP), A_TOP, width, A_HEIGHT), xlim, ylim, x_inverted=True,
                      yticks=i == 0, ylabel="" if i else "stopping time lost against\nthe best adhesion [s]",
                      xlabel="adhesion-limited deceleration [km/h/s]", xtarget=7, ytarget=7)
        p.title(f"{tt} {d}: every approach (grey), hardest (red), the leg above (blue)", loc="center", size=11.5,
                bold=False)
        marked = []
        for j, (loss, o, de, a, t) in enumerate(losses[d]):
            hard, chosen = j == 0, (d, o, de) == (k["direction"], k["origin"], k["destination"])
            if hard or chosen:
                marked.append((hard, o, de, a, t))
            else:
                p.polyline(a, t - t[-1], color="#b3b3b3", width=1.0)
            if loss > worst[0]:
                worst = (loss, (d, o, de, t[0], t[-1], a[0], a[-1]))
        for hard, o, de, a, t in sorted(marked, key=lambda m: m[0]):  # the hardest on top
            col = RED if hard else BLUE
            p.polyline(a, t - t[-1], color=col, width=2.0)
            p.markers(a, t - t[-1], "o", size=4.5, fill=col)
            # described in a corner (the flat, good-adhesion side), not at the crowded line ends
            p.text(0.02, 0.95 if hard else 0.88, f"{o} → {de}: {t[-1]:.1f} s at {a[-1]:g}, {t[0]:.1f} s at "
                   f"{a[0]:g} km/h/s", size=10.5, color=col, bold=True, anchor="start", x_frac=True, y_frac=True)
    hardest = ""
    if worst[1] is not None:
        d, o, de, t0, t1, a0, a1 = worst[1]
        hardest = (f"The hardest approach for {tt} is {d} {o} → {de}: the stopping pattern takes {t1:.1f} s "
                   f"at {a1:g} km/h/s and {t0:.1f} s at {a0:g} km/h/s (+{t0 - t1:.1f} s).")
    return fig.svg(label=f"stopping time against adhesion, {tt}"), hardest
