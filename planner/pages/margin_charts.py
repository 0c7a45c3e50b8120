"""The margin report's charts as page sections (:mod:`planner.pages.margin_report` puts them in the page).

:func:`chart_svgs` draws any of the four charts on its own (the nightly job draws
them on two workers while it writes the rest); :func:`chart_sections` wraps
them in their headings and captions.
"""
from __future__ import annotations

from html import escape

from planner.report.plots import adhesion_chart, curves_chart, margin_chart

__all__ = ["CHARTS", "chart_sections", "chart_svgs"]


def _esc(x) -> str:  # as the page's own escaping (planner.pages.margin_report)
    return escape(str(x), quote=True)


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
        "Where a leg has several scheduled times, the one with the least remaining margin is drawn.</p>")
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
            "<p class='caption'>The leg with the least remaining margin (or the one asked for with "
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
