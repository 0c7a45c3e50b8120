"""The planner's charts drawn with matplotlib (the one module that imports it); the speed–distance chart of
each leg, drawn thousands of times a night on a network, is written as SVG directly
(:mod:`planner.pages.svg_plot`, :mod:`planner.pages.speed_chart`).

Takes computed results (a margin report, train-graph data, a station-approach
sweep, one run or one time-keeping run, the evaluation-interval study) and gives
charts: inline SVG strings for the self-contained HTML pages, or PNG/SVG files
written atomically (temp file, then rename). Every chart is deterministic: the
same result gives the same bytes (fixed SVG hash salt, no date or software
metadata). Units appear only here, at the edge: the results are SI, the axes
km/h, km/h/s and km (:mod:`planner.line.units`).

Charts
------
* margin report (:mod:`planner.pages.margin_report`): :func:`margin_chart`,
  :func:`curves_chart`, :func:`adhesion_chart`;
* train graph (``planner graph``): :func:`planner.report.train_graph.train_graph_chart`;
* station approach (``planner stops --plot``): :func:`approach_chart`;
* one run (``planner runtime --plot``): :func:`run_curve_chart`;
* time-keeping run (``planner timekeeping --plot``): :func:`timekeeping_chart`;
* evaluation-interval study: :func:`interval_study_chart`.

Position axes: one per kind of chart, labelled with its unit. A chart of a run along the line
(the margin report's, ``runtime --plot``, ``timekeeping --plot``) is against the chainage [km],
running left to right in the running direction; a chart of a stop (``stops --plot``) against the
distance to the stop marker [m], the way a braking curve is read.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from planner.errors import InputError
from planner.line.units import KMH, KMH_S, KMH_S2, fixed, kmh
from planner.report.leg_flags import FLAGS_SHOWN, flag_of

FLAG_COLOURS = {f.name: f.colour for f in FLAGS_SHOWN} | {"ok": "#2e7d32"}
"""Colour of a leg by its worst flag (the badges' colours)."""
MARGIN_COLOUR = "#b0c4de"
"""Bar colour of the nominal margin."""
SVG_SALT = "planner-margins"
"""Fixed ``svg.hashsalt``: matplotlib's SVG ids become deterministic."""


# --- drawing and saving ---------------------------------------------------------------

def pyplot():
    """matplotlib's pyplot on the Agg backend, with the HTML pages' style (fixed SVG hash salt)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"svg.hashsalt": SVG_SALT, "svg.fonttype": "none", "font.size": 9,
                         "axes.titlesize": 10, "figure.dpi": 72})
    return plt


def _agg():
    """matplotlib's pyplot on the Agg backend, rcParams untouched (the file charts set their own)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def inline_svg(fig) -> str:
    """A matplotlib figure as an inline <svg> element (deterministic); closes the figure."""
    import matplotlib.pyplot as plt

    buf = io.StringIO()
    fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": "planner"})
    plt.close(fig)
    s = buf.getvalue()
    return s[s.index("<svg"):]


def save_png(fig, path: str | os.PathLike, *, dpi: float | None = None) -> Path:
    """Save a matplotlib figure as a PNG atomically and close it.

    No software/time metadata is written, so the same figure gives the same bytes.
    """
    import matplotlib.pyplot as plt

    from planner.io.atomic import atomic_path

    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format="png", dpi=dpi, metadata={"Software": None})
    finally:
        plt.close(fig)
    return Path(path)


# --- the margin report ------------------------------------------------------------------

def margin_chart(report, direction: str, stations: dict[str, float]) -> str:
    """Bar chart of the margin per leg along the line for one direction (inline SVG).

    One row of axes per train type (legs passing stations in their own row);
    bars span the leg from stop marker to stop marker, running left to right.
    """
    plt = pyplot()
    rows = report.rows[(report.rows.direction == direction) & report.rows.scheduled_running_time_s.notna()]
    if rows.empty:
        return ""
    groups = []
    for t in sorted(rows.train_type.unique()):
        sub = rows[rows.train_type == t]
        plain, passing = sub[sub.passes.map(len) == 0], sub[sub.passes.map(len) > 0]
        if len(plain):
            groups.append((f"{t}: stop to next station", plain))
        if len(passing):
            groups.append((f"{t}: legs passing stations", passing))
    fig, axes = plt.subplots(len(groups), 1, figsize=(13.5, 2.6 * len(groups) + 1.7), sharex=True,
                             squeeze=False)
    lo = min(min(stations.values()), 0.0) / 1000.0
    hi = max(stations.values()) / 1000.0
    ymax = max(float(np.nanmax(rows.margin_s)), float(np.nanmax(rows.supplement_required_s))) + 4
    ymin = min(0.0, float(np.nanmin(rows.remaining_margin_s)))
    ymin -= max(3.0, 0.12 * (ymax - ymin))  # room for the label under the lowest bar
    for ax, (title, sub) in zip(axes[:, 0], groups):
        # several scheduled times on one leg: draw the one with the least remaining margin
        sub = sub.sort_values("remaining_margin_s", kind="stable").drop_duplicates(["origin", "destination"])
        for r in sub.itertuples(index=False):
            a = stations[r.origin] / 1000.0
            b = stations[r.destination] / 1000.0
            x0, x1 = min(a, b), max(a, b)
            pad = 0.04 * (x1 - x0)
            w = x1 - x0 - 2 * pad
            ax.bar(x0 + pad, r.margin_s, width=w, align="edge", color=MARGIN_COLOUR, edgecolor="#7d93ad", lw=0.6)
            col = FLAG_COLOURS[flag_of(r)]
            ax.bar(x0 + pad + 0.25 * w, r.remaining_margin_s, width=0.5 * w, align="edge", color=col, alpha=0.9)
            ax.plot([x0 + pad, x0 + pad + w], [r.supplement_required_s] * 2, color="k", lw=1.4)
            y = r.remaining_margin_s
            ax.text(x0 + pad + 0.5 * w, y + (0.6 if y >= 0 else -0.6), fixed(y, 1, True), ha="center",
                    va="bottom" if y >= 0 else "top", fontsize=7.5, fontweight="bold",
                    color="#8e1b1b" if y < 0 else "#1d2327")
        ax.axhline(0, color="k", lw=0.8)
        ax.set_ylim(ymin, ymax)
        ax.set_ylabel("seconds")
        ax.set_title(title, loc="left", fontsize=9.5, fontweight="bold", pad=16)
        ax.grid(axis="y", alpha=0.3)
        for sid, x in stations.items():
            ax.axvline(x / 1000.0, color="0.85", lw=0.6, zorder=0)
    order = sorted(stations.items(), key=lambda kv: kv[1])
    for ax in axes[:, 0]:  # station codes above every panel, not only the first
        top = ax.secondary_xaxis("top")
        top.set_xticks([x / 1000.0 for _, x in order], [s for s, _ in order], fontsize=8)
    axes[-1, 0].set_xlabel("chainage [km] (stop markers of this direction)")
    axes[-1, 0].set_xlim(lo - 0.3, hi + 0.3)
    if direction == "up":
        axes[-1, 0].invert_xaxis()  # run left to right
    from matplotlib.patches import Patch
    from matplotlib.lines import Line2D

    handles = [Patch(color=MARGIN_COLOUR, label="margin = scheduled − minimum"),
               Patch(color=FLAG_COLOURS["ok"], label="remaining on a bad day (≥ tight threshold)"),
               Patch(color=FLAG_COLOURS["tight"], label="remaining < tight threshold"),
               Patch(color=FLAG_COLOURS["short_bad_day"], label="negative: short on a bad day"),
               Patch(color=FLAG_COLOURS["impossible"], label="impossible: margin < 0"),
               Line2D([], [], color="k", lw=1.4, label="supplement the rule asks for")]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8.5, frameon=False)  # 6 in a row are too wide
    first, last = order[0][0], order[-1][0]
    if direction == "up":
        first, last = last, first
    fig.suptitle(f"{direction}: {first} → {last}, running left to right", x=0.01, y=1 - 0.12 / fig.get_figheight(),
                 ha="left", va="top", fontsize=11, fontweight="bold")
    h = fig.get_figheight()  # fixed margins in inches: tight_layout costs seconds per chart
    fig.subplots_adjust(left=0.06, right=0.99, top=1 - 1.05 / h, bottom=1.25 / h, hspace=0.62)
    return inline_svg(fig)


def curves_chart(report) -> str:
    """Run curves of the chosen leg and where along it the time goes (inline SVG)."""
    c, k = report.curves, report.chosen
    if not c or not k:
        return ""
    plt = pyplot()
    row = report.rows[(report.rows.direction == k["direction"]) & (report.rows.train_type == k["train_type"])
                      & (report.rows.origin == k["origin"]) & (report.rows.destination == k["destination"])]
    row = row.iloc[0]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(15.5, 7.4), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    km = c["position_m"] / 1000.0
    ax.step(km, c["vmax_kmh"], where="mid", color="0.55", lw=1.1, label="on-board maximum (limit − margin)")
    ax.plot(km, c["min_speed_kmh"], color="#1f5fa8", lw=1.8,
            label=f"minimum: ratio 100 %, nominal — {row.min_running_time_s:.1f} s")
    if "sched_speed_kmh" in c:
        ax.plot(km, c["sched_speed_kmh"], color="#2e7d32", lw=1.5,
                label=f"as scheduled: on-board logic, departs at ratio {row.ratio_on_time:.0%}\n  "
                      f"{row.scheduled_running_time_s:.0f} s scheduled, arrives {fixed(row.arrival_error_s, 1, True)} s")
    dkm = c["degraded_position_m"] / 1000.0
    ax.plot(dkm, c["degraded_speed_kmh"], color="#c62828", lw=1.5,
            label=f"bad day: load {report.rule.bad_load:.0%}, traction ×{report.rule.bad_traction:g},\n  "
                  f"ratio 100 % — {row.degraded_min_running_time_s:.1f} s")
    if "pattern_position_m" in c:
        ax.plot(c["pattern_position_m"] / 1000.0, c["pattern_speed_kmh"], color="#c62828", lw=1.5, ls="--",
                label=f"stopping pattern at adhesion {row.adhesion_min_ms2 / KMH_S:g} km/h/s\n  — {row.stop_time_degraded_s:.1f} s")
    ps = c["pattern_start_m"] / 1000.0
    ax.axvline(ps, color="#c62828", lw=0.8, ls=":")
    ax.text(ps, 3, " pattern start", color="#c62828", fontsize=8, ha="left", va="bottom")
    ax.set_ylabel("speed [km/h]")
    ax.set_ylim(0, float(np.nanmax(c["vmax_kmh"])) * 1.12)
    ax.grid(alpha=0.3)
    # legends beside the axes, never over the curves
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, ncol=1, frameon=False,
              borderaxespad=0.0)
    for x, name in ((km[0], row.origin), (km[-1], row.destination)):
        ax.axvline(x, color="k", lw=1.0)
        ax.text(x, ax.get_ylim()[1] * 0.985, f" {name} ", ha="center", va="top", fontsize=9,
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="k", lw=0.6))
    # where the time goes: time behind the minimum run at each point
    tmin = c["min_time_s"]
    if "sched_time_s" in c:
        ax2.plot(km, c["sched_time_s"] - tmin, color="#2e7d32", lw=1.5, label="as scheduled − minimum")
    dt = c["degraded_time_s"] - tmin[: len(c["degraded_time_s"])]
    ax2.plot(dkm, dt, color="#c62828", lw=1.5, label="degraded − minimum")
    if "pattern_position_m" in c:
        x_p = c["pattern_position_m"]
        order = np.argsort(c["position_m"])
        tm_p = np.interp(x_p, c["position_m"][order], tmin[order])
        ax2.plot(x_p / 1000.0, c["pattern_time_s"] - tm_p, color="#c62828", lw=1.5, ls="--")
    ax2.axhline(row.margin_s, color="#1f5fa8", lw=1.0, ls="--")
    ax2.text(km[0], row.margin_s, f"  scheduled margin {row.margin_s:.1f} s", color="#1f5fa8", fontsize=8,
             va="bottom", ha="left")
    ax2.axvline(ps, color="#c62828", lw=0.8, ls=":")
    ax2.set_ylabel("time behind the\nminimum run [s]")
    ax2.set_xlabel("chainage [km]")
    ax2.grid(alpha=0.3)
    ax2.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8.2, frameon=False, borderaxespad=0.0)
    if k["direction"] == "up":
        ax.invert_xaxis()
    fig.suptitle(f"{k['train_type']} {k['direction']} {row.origin} → {row.destination} "
                 f"({row.length_m / 1000:.2f} km): scheduled {row.scheduled_running_time_s:.0f} s, "
                 f"remaining margin on a bad day {fixed(row.remaining_margin_s, 1, True)} s",
                 x=0.01, ha="left", fontsize=11, fontweight="bold")
    fig.subplots_adjust(left=0.055, right=0.71, top=0.93, bottom=0.08, hspace=0.08)
    return inline_svg(fig)


def adhesion_chart(report) -> tuple[str, str]:
    """Stopping-pattern time against adhesion for every approach of the chosen leg's train type.

    Returns the SVG and the hardest approach's description.
    """
    k = report.chosen
    sw = report.sweep
    if sw is None or len(sw) == 0 or not k:
        return "", ""
    plt = pyplot()
    tt = k["train_type"]
    rows = report.rows
    plain = rows[(rows.train_type == tt) & (rows.passes.map(len) == 0)][
        ["direction", "origin", "destination"]].drop_duplicates()
    sw = sw.merge(plain, on=["direction", "origin", "destination"])
    sw = sw[sw.train_type == tt]
    fig, axes = plt.subplots(1, 2, figsize=(13.5, 4.4), sharey=True)
    hardest = ""
    worst = (-1.0, None)
    for ax, d in zip(axes, ("down", "up")):
        sub = sw[sw.direction == d]
        losses = []
        for (o, de), g in sub.groupby(["origin", "destination"], sort=True):
            g = g.sort_values("adhesion_kmh_s")
            a = g.adhesion_kmh_s.to_numpy()
            t = g.stop_time_s.to_numpy()
            if not np.isfinite(t[-1]):
                continue
            losses.append((float(np.nanmax(t - t[-1])), o, de, a, t))
        losses.sort(key=lambda x: -x[0])
        for i, (loss, o, de, a, t) in enumerate(losses):
            is_chosen = (d, o, de) == (k["direction"], k["origin"], k["destination"])
            hard = i == 0
            col = "#c62828" if hard else ("#1f5fa8" if is_chosen else "0.7")
            lw = 2.0 if (hard or is_chosen) else 1.0
            ax.plot(a, t - t[-1], color=col, lw=lw, marker="o" if (hard or is_chosen) else None, ms=3,
                    zorder=3 if (hard or is_chosen) else 2)
            if hard or is_chosen:
                # described in a corner (the flat, good-adhesion side), not at the crowded line ends
                ax.text(0.02, 0.95 - 0.07 * (0 if hard else 1), f"{o} → {de}: {t[-1]:.1f} s at {a[-1]:g}, "
                        f"{t[0]:.1f} s at {a[0]:g} km/h/s", transform=ax.transAxes, fontsize=8.5, color=col,
                        va="top", ha="left", fontweight="bold")
            if loss > worst[0]:
                worst = (loss, (d, o, de, t[0], t[-1], a[0], a[-1]))
        ax.set_title(f"{tt} {d}: every approach (grey), hardest (red), the leg above (blue)", fontsize=9.5)
        ax.set_xlabel("adhesion-limited deceleration [km/h/s]")
        ax.grid(alpha=0.3)
        ax.invert_xaxis()  # worse adhesion to the right
    axes[0].set_ylabel("stopping time lost against\nthe best adhesion [s]")
    fig.tight_layout()
    if worst[1] is not None:
        d, o, de, t0, t1, a0, a1 = worst[1]
        hardest = (f"The hardest approach for {tt} is {d} {o} → {de}: the stopping pattern takes {t1:.1f} s "
                   f"at {a1:g} km/h/s and {t0:.1f} s at {a0:g} km/h/s (+{t0 - t1:.1f} s).")
    return inline_svg(fig), hardest


# --- a station approach, one run, a time-keeping run ------------------------------------

def approach_chart(result, path: str | Path) -> Path:
    """Speed, acceleration and jerk against distance to the stop marker, one curve per adhesion level.

    Three stacked axes sharing the distance to the marker (decreasing to the
    right, as the train runs). Drawn limits: the on-board maximum speed
    (black steps), the deceleration limit of each adhesion level (dashed, in
    the level's colour) and ±jerk limit (grey dashed). Brake starts are marked
    on the speed axis. Infeasible levels are listed in the title. The PNG is
    written atomically (temp file, rename).

    Returns
    -------
    Path
        The file written.
    """
    import matplotlib
    from matplotlib import cm, colors

    plt = _agg()
    path = Path(path)
    X = result.approach_length_m
    levels = [a / KMH_S for a in result.adhesion_ms2]  # km/h/s, as the job spells them
    norm = colors.Normalize(vmin=min(levels), vmax=max(levels) if max(levels) > min(levels) else min(levels) + 1)
    cmap = matplotlib.colormaps["viridis"]
    fig, (ax_v, ax_a, ax_j) = plt.subplots(3, 1, sharex=True, figsize=(10, 8.5), layout="constrained",
                                           gridspec_kw={"height_ratios": [3, 2, 1.4]})

    def steps(pairs, scale):
        """Step function over [0, X] as distance-to-go arrays for plotting."""
        xs = [p[0] for p in pairs] + [X]
        d, y = [], []
        for k, (x, val) in enumerate(pairs):
            d += [X - xs[k], X - xs[k + 1]]
            y += [val * scale, val * scale]
        return np.array(d), np.array(y)

    if result.speed_limits:
        d, y = steps(result.speed_limits, 1.0 / KMH)
        ax_v.plot(d, y, color="black", lw=1.4, label="on-board maximum speed")
    J = result.jerk_max_ms3 / KMH_S2
    for sgn in (1, -1):
        ax_j.axhline(sgn * J, color="0.45", ls="--", lw=1.0, label="jerk limit" if sgn > 0 else None)
    infeasible = []
    for a, p, dl in zip(levels, result.patterns, result.decel_limits):
        col = cmap(norm(a))
        if dl:
            d, y = steps(dl, -1.0 / KMH_S)
            ax_a.plot(d, y, color=col, ls="--", lw=0.9, alpha=0.9)
        if not p.feasible:
            infeasible.append(f"{a:g}")
            continue
        s = p.sample(max(p.duration_s / 2000.0, 1e-3))
        dist = X - s.x_m
        ax_v.plot(dist, kmh(s.v_ms), color=col, lw=1.2)
        ax_a.plot(dist, s.a_ms2 / KMH_S, color=col, lw=1.2)
        # jerk is piecewise constant: draw it from the breakpoints, not from samples
        jd, jy = [], []
        for k, j in enumerate(p.j_ms3):
            jd += [X - p.x_m[k], X - p.x_m[k + 1]]
            jy += [j / KMH_S2, j / KMH_S2]
        ax_j.plot(jd, jy, color=col, lw=1.1, alpha=0.8)
        ax_v.plot([X - p.brake_start_m], [kmh(p.v_start_ms)], marker="o", ms=4, color=col)
    ax_v.set_ylabel("speed [km/h]")
    ax_a.set_ylabel("acceleration [km/h/s]")
    ax_j.set_ylabel("jerk [km/h/s²]")
    ax_j.set_xlabel("distance to the stop marker [m]")
    ax_v.set_ylim(bottom=0.0)
    ax_a.plot([], [], color="0.3", ls="--", lw=0.9, label="deceleration limit (per adhesion)")
    ax_a.plot([], [], color="0.3", lw=1.2, label="pattern (colour: adhesion)")
    ax_v.plot([], [], color="0.3", marker="o", ls="none", ms=4, label="brake start")
    for ax in (ax_v, ax_a, ax_j):
        ax.grid(True, lw=0.4, alpha=0.6)
        ax.legend(loc="center left" if ax is ax_a else "lower left", fontsize=8, framealpha=0.85)
    ax_j.set_ylim(-1.6 * J, 1.6 * J)
    lo, _ = ax_a.get_ylim()
    ax_a.set_ylim(lo, -0.18 * lo)  # headroom above a = 0 for the gradient labels
    # the gradient (over the train, safe-side steps) explains the steps of the deceleration limits
    gx = [g[0] for g in result.gradients_permil] + [X]
    for k, (x, g) in enumerate(result.gradients_permil):
        mid = X - 0.5 * (x + gx[k + 1])
        ax_a.text(mid, 0.97, f"{g:+g} ‰" if g else "level", transform=ax_a.get_xaxis_transform(),
                  ha="center", va="top", fontsize=8, color="0.3")
        if k:
            ax_a.axvline(X - x, color="0.6", lw=0.6, ls=":")
    ax_j.set_xlim(X, 0.0)  # the train runs left to right, towards the marker at 0
    start = f"TASC beacon {result.tasc_beacon_id}" if result.tasc_beacon_id else "fixed approach start"
    title = (f"{result.line_id}: stop at {result.station_id} ({result.direction}, {result.train_type}, from "
             f"{result.origin}) — {start} {X:.0f} m before the marker, "
             f"v_start {kmh(result.v_start_ms):.1f} km/h")
    if infeasible:
        title += f"\nno pattern at adhesion {', '.join(infeasible)} km/h/s"
    fig.suptitle(title, fontsize=10)
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=[ax_v, ax_a, ax_j], label="adhesion limit [km/h/s]", shrink=0.6, pad=0.02)
    return save_png(fig, path, dpi=110)


def run_curve_chart(result, path: Path) -> Path:
    """Draw a railway run-curve chart of ``result`` (a RunResult) to a PNG, atomically.

    Speed, on-board maximum and target (km/h) against chainage (km), running
    left to right in the running direction; elapsed time on a second axis; the
    two stations marked.
    """
    plt = _agg()
    c = result.curve
    km = c["position_m"].to_numpy() / 1000.0
    fig, ax = plt.subplots(figsize=(10, 5.2), dpi=110)
    ax.step(km, c["vmax_kmh"], where="mid", color="0.55", lw=1.2, label="on-board maximum")
    ax.step(km, c["target_kmh"], where="mid", color="tab:orange", lw=1.0, ls="--", label="target (ratio × max)")
    ax.plot(km, c["speed_kmh"], color="tab:blue", lw=1.8, label="speed")
    ax.set_xlabel("chainage [km]")
    ax.set_ylabel("speed [km/h]")
    ax.set_ylim(0, max(float(c["vmax_kmh"].max()), float(c["speed_kmh"].max())) * 1.15)
    if result.direction == "up":
        ax.invert_xaxis()  # run left to right
    ax.grid(True, alpha=0.3)
    top = ax.get_ylim()[1]
    for x, name in ((km[0], result.origin), (km[-1], result.destination)):
        ax.axvline(x, color="k", lw=1.0)
        ax.text(x, top * 0.97, f" {name} ", ha="center", va="top", fontsize=9,
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="k", lw=0.6))
    ax2 = ax.twinx()
    ax2.plot(km, c["time_s"], color="tab:green", lw=1.0, ls=":", label="time")
    ax2.set_ylabel("time since departure [s]", color="tab:green")
    ax2.set_ylim(0, result.time_s * 1.15)
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    # below the axes, never over the curves
    ax.legend(h1 + h2, l1 + l2, loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize=8, ncol=4,
              frameon=False)
    ax.set_title(
        f"{result.line_id} {result.direction}: {result.origin} → {result.destination}, type {result.train_type}, "
        f"ratio {result.ratio:.0%}, load {result.load:.0%}, traction ×{result.traction_factor:g}\n"
        f"running time {result.time_s:.1f} s, traction energy {result.energy_kwh:.1f} kWh", fontsize=10)
    fig.subplots_adjust(left=0.08, right=0.91, top=0.88, bottom=0.22)
    return save_png(fig, path)


def timekeeping_chart(result, segments: list[dict], path: Path, title: str) -> Path:
    """Speed, target and advice against chainage (km, running left to right, as every chart of a run), as a
    PNG written atomically.

    ``segments``: the runs of one driver advice, ``[{"from_m", "to_m", "advice"}]`` (running distance).
    """
    plt = _agg()
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise InputError(f"--plot {path}: the plot is a PNG; give a file name ending in .png")
    c = result.curve
    colours = {"power": "tab:red", "hold": "tab:green", "coast": "tab:blue", "brake": "tab:orange"}
    fig, ax = plt.subplots(figsize=(9, 4.5), dpi=100)
    dist, pos = c["distance_m"].to_numpy(float), c["position_m"].to_numpy(float)
    km = pos / 1000.0
    ax.plot(km, c["target_kmh"], color="0.6", lw=1.0, ls="--", label="target")
    ax.plot(km, c["speed_kmh"], color="k", lw=1.3, label="speed")
    for seg in segments:  # running distance -> chainage
        a, b = np.interp([seg["from_m"], seg["to_m"]], dist, pos) / 1000.0
        ax.axvspan(min(a, b), max(a, b), ymin=0, ymax=0.04, color=colours[seg["advice"]], lw=0)
    for name, col in colours.items():
        ax.plot([], [], color=col, lw=6, label=name)
    ax.set_xlabel("chainage [km]")
    if len(km) > 1 and km[-1] < km[0]:
        ax.invert_xaxis()  # run left to right
    ax.set_ylabel("speed [km/h]")
    ax.set_title(title)
    # below the axes, never over the curves
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.14), fontsize=8, ncol=6, frameon=False)
    ax.grid(True, alpha=0.3)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.92, bottom=0.24)
    return save_png(fig, path)


def interval_study_chart(rows: list[dict], cases: list[str], bounds: dict[str, float] | None = None) -> str:
    """Maximum |arrival error| against the evaluation interval, a panel per case, a line per ratio grid (SVG);
    ``bounds`` (case → s) draws the issue's bound of a case as a dashed line."""
    plt = pyplot()
    fig, axes = plt.subplots(1, len(cases), figsize=(3.2 * len(cases), 2.8), squeeze=False)
    labels = list(dict.fromkeys(w["interval"] for w in rows))
    for ax, c in zip(axes[0], cases):
        for g in dict.fromkeys(w["grid"] for w in rows):
            pts = [(labels.index(w["interval"]), w[c + "/max"]) for w in rows if w["grid"] == g]
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=g)
        if bounds and c in bounds:
            ax.axhline(bounds[c], color="#8e1b1b", ls="--", lw=1.0, label="bound")
        ax.set_xticks(range(len(labels)), labels, fontsize=8)
        ax.set_title(c)
        ax.set_ylabel("max |error| [s]")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8, title="grid", title_fontsize=8)
    fig.tight_layout()
    return inline_svg(fig)
