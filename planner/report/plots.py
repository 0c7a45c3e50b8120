"""The planner's charts drawn with matplotlib (the one module that imports it, with the train graph's file
chart): the file charts of the CLI and the evaluation-interval study. The charts of the pages the nightly
job writes are SVG written directly (:mod:`planner.pages.svg_plot`: the speed–distance chart of each leg
and the margin report's, :mod:`planner.pages.margin_charts`), so the nightly job never imports matplotlib.

Takes computed results (a station-approach sweep, one run or one time-keeping run, the
evaluation-interval study) and gives charts: PNG files written atomically (temp file,
then rename), or inline SVG for the study's page. Every chart is deterministic: the
same result gives the same bytes (fixed SVG hash salt, no date or software
metadata). Units appear only here, at the edge: the results are SI, the axes
km/h, km/h/s and km (:mod:`planner.line.units`).

Charts
------
* train graph (``planner graph``): :func:`planner.report.train_graph.train_graph_chart`;
* station approach (``planner stops --plot``): :func:`approach_chart`;
* one run (``planner runtime --plot``): :func:`run_curve_chart`;
* time-keeping run (``planner timekeeping --plot``): :func:`timekeeping_chart`;
* evaluation-interval study (:mod:`planner.pages.eval_study`): :func:`interval_study_chart`.

Position axes: one per kind of chart, labelled with its unit. A chart of a run along the line
(``runtime --plot``, ``timekeeping --plot``, like the margin report's) is against the chainage [km],
running left to right in the running direction; a chart of a stop (``stops --plot``) against the
distance to the stop marker [m], the way a braking curve is read.
"""
from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from planner.errors import InputError
from planner.line.units import KMH, KMH_S, KMH_S2, kmh

SVG_SALT = "planner-margins"
"""Fixed ``svg.hashsalt``: matplotlib's SVG ids become deterministic."""


# --- drawing and saving ---------------------------------------------------------------

def pyplot():
    """matplotlib's pyplot on the Agg backend, with the study page's style (fixed SVG hash salt)."""
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
