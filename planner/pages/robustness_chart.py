"""The robustness page's chart: punctuality along the line, one panel per direction (inline SVG, legend in HTML).

x is the station's chainage [km], the same way round in every panel (so a station sits at the same place
in both), each station named over the panel's top edge (rotated, a grid line down to its values); y the share of the arrivals
there at most 1, 3 and 5 min late over the simulated days, three lines told apart by colour and dash, the
1-minute share written under its marker. Each station carries a tooltip with its figures. Drawn with
:mod:`planner.pages.svg_plot`; deterministic (ids fixed, coordinates rounded).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from planner.line.units import fixed
from planner.pages.svg_plot import Figure, esc, legend_html, num, padded, swatch, text_width

W = 1000.0
LEFT, RIGHT = 78.0, 26.0
PANEL_H = 230.0
HEAD = 40.0
NAME_SIZE = 12.0
ANGLE = 40.0
MINUTES = ((60, "within 1 min", "#c62828", None), (180, "within 3 min", "#1f5fa8", (7, 4)),
           (300, "within 5 min", "#2e7d32", (2, 3)))
"""(seconds, label, colour, dash) of the three lines."""


def direction_order(values) -> list[str]:
    """Directions in the order the pages list them: ``down``, ``up``, then any other alphabetically."""
    seen = {str(v) for v in values}
    return [d for d in ("down", "up") if d in seen] + sorted(seen - {"down", "up"})


def _tip(r, direction: str) -> str:
    return (f"{r.station_name} ({r.station_id}), {direction}: {int(r.arrivals)} arrivals a day; within 1 / 3 / 5 min "
            f"{fixed(100 * r.within_60s, 1)} / {fixed(100 * r.within_180s, 1)} / {fixed(100 * r.within_300s, 1)} %; "
            f"mean delay {fixed(r.mean_delay_s, 1)} s, of it knock-on {fixed(r.knock_on_s, 1)} s")


def punctuality_chart(stations: pd.DataFrame, travel: dict[str, str] | None = None) -> str:
    """The chart (``<div class='fig'>`` with the SVG and its legend), "" without a station row.

    ``stations``: rows of ``robustness_stations``; ``travel``: direction → words on which way its trains run
    (``Minato → Senzan, left to right``), put in the panel's title."""
    st = stations[np.isfinite(stations["position_m"].astype(float))]
    if st.empty:
        return ""
    travel = travel or {}
    km_all = st["position_m"].astype(float).to_numpy() / 1000.0
    xlim = padded(float(km_all.min()), float(km_all.max()), 0.035)
    low = float(np.nanmin(st["within_60s"].astype(float))) * 100.0
    ylo = min(90.0, 5.0 * math.floor((low - 8.0) / 5.0)) if math.isfinite(low) else 0.0
    ylim = (max(0.0, ylo), 101.0)
    dirs = direction_order(st["direction"])
    cos, sin = math.cos(math.radians(ANGLE)), math.sin(math.radians(ANGLE))
    widths = {str(n): text_width(str(n), NAME_SIZE) for n in st["station_name"]}
    name_h = max(widths.values()) * sin + 16
    plot_w = W - LEFT - RIGHT
    reach = max(widths[str(r.station_name)] * cos - (xlim[1] - r.position_m / 1000.0) / (xlim[1] - xlim[0]) * plot_w
                for r in st.itertuples())  # how far the last names reach past the frame's right edge
    right = max(RIGHT, reach + 8)
    block = HEAD + name_h + PANEL_H + 46
    fig = Figure(W, 4 + block * len(dirs), ident="punct")
    for i, d in enumerate(dirs):
        sub = st[st.direction == d].sort_values(["position_m", "station_id"], kind="stable")
        top = 4 + HEAD + name_h + i * block
        p = fig.panel((LEFT, top, W - LEFT - right, PANEL_H), xlim, ylim, grid="y", font=12,
                      xlabel="chainage [km]" if i == len(dirs) - 1 else "", ylabel="arrivals late at most … [%]")
        words = travel.get(d, "")
        p.title(f"{d}" + (f": {words}" if words else "") + f" · {int(sub.arrivals.sum()):,} arrivals a day",
                size=14, pad=name_h + 8)
        km = sub["position_m"].astype(float).to_numpy() / 1000.0
        for x in km:
            p.vline(x, color="#e2e2e2", width=0.8)
        for m, _, colour, dash in MINUTES:
            y = sub[f"within_{m}s"].astype(float).to_numpy() * 100.0
            p.polyline(km, y, color=colour, width=2.2, dash=dash)
            p.markers(km, y, "o", size=6.5, fill=colour, stroke="#fff", width=0.8)
        for x, y in zip(km, sub["within_60s"].astype(float).to_numpy() * 100.0):
            p.text(x, y, fixed(y, 0), size=11, va="top", dy=5, color="#8e1b1b")
        half = 0.012 * (xlim[1] - xlim[0])
        p.rects(km - half, km + half, ylim[0], ylim[1], fill="#000", opacity=0,
                tips=[_tip(r, d) for r in sub.itertuples()])
        names = []
        for x, r in zip(p.x(km).tolist(), sub.itertuples()):
            y0 = top - 9
            names.append(f'<path d="M{num(x)},{num(top)}v-5" stroke="#222" stroke-width="0.8"/>'
                         f'<text x="{num(x)}" y="{num(y0)}" transform="rotate(-{ANGLE:g} {num(x)} {num(y0)})">'
                         f'{esc(r.station_name)}</text>')
        p.labels.append(f'<g font-size="{NAME_SIZE:g}" fill="#222">{"".join(names)}</g>')
    legend = [(swatch("line", color=c, width=2.2, dash=dash), f"arrivals {lbl} late") for _, lbl, c, dash in MINUTES]
    svg = fig.svg(label="punctuality along the line: share of arrivals within 1, 3 and 5 min, per direction")
    return (f"<div class='fig'>{svg}{legend_html(legend)}<div class='caption'>Every direction is drawn with chainage "
            f"growing to the right, its stations named over its panel. The number under "
            f"each red marker is its 1-minute share [%]. Hover a station "
            f"for its figures; the table below has them all.</div></div>")


__all__ = ["punctuality_chart", "direction_order"]
