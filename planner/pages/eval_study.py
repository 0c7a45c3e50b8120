"""The evaluation-interval study as a page: one self-contained HTML file (inline CSS and SVG, no scripts).

The study itself (settings, runs, worst cases, checks' bounds) is :mod:`planner.report.eval_study`;
``benchmarks/bench_eval_interval.py`` writes this page with ``--html``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from planner.report.eval_study import (
    ADAPTIVE_MAX_S,
    BUNDLE_FACTOR,
    GRIDS,
    INTERVALS,
    NEAREST_BOUNDS_S,
    Setting,
    SettingResult,
    Worst,
    best_nearest,
    bundle_sizes,
    default_settings,
    format_table,
    format_worst,
    replay,
    run_setting,
    run_study,
    study_rows,
)


def _checks_html(results: Sequence[SettingResult], base_bytes: int | None) -> list[str]:
    """The issue's two checks as page sections: the nearest rule's best setting under the bundle
    bound (met, or the closest figures and why: the worst runs' last point with authority and
    the gap between neighbouring table entries there) and the adaptive mode at every setting."""
    from planner.pages.margin_report import _e

    out = []
    base = base_bytes if base_bytes is not None else (results[0].bundle_max_bytes if results else 0)
    if any(("nearest", sc) in r.stats for r in results for sc in NEAREST_BOUNDS_S):
        out.append(f"<h2>Nearest rule: best setting with bundles under {BUNDLE_FACTOR:g}× today's</h2>")
        best = best_nearest(results, base, BUNDLE_FACTOR, NEAREST_BOUNDS_S) if base else None
        if best is None:
            out.append("<p>No setting with measured bundle bytes under the bound (a part of the line only "
                       "has no bundle bytes).</p>")
        else:
            figs = {sc: best.stats[("nearest", sc)]["max_abs_error_s"] for sc in NEAREST_BOUNDS_S
                    if ("nearest", sc) in best.stats}
            ok = all(figs[sc] <= b for sc, b in NEAREST_BOUNDS_S.items() if sc in figs)
            out.append(f"<p><b>{_e(best.setting.label)}</b>: bundle {best.bundle_max_bytes / 1024:.0f} kB "
                       f"({best.bundle_max_bytes / base:.2f}× today's); max |arrival error| "
                       + ", ".join(f"{_e(sc)} {v:.2f} s (bound {NEAREST_BOUNDS_S[sc]:g} s)" for sc, v in figs.items())
                       + f": <b>{'met' if ok else 'not met'}</b>."
                       + ("" if ok else " No setting under the bundle bound reaches the bounds; these are the "
                          "closest figures. Why, in the worst run of each scenario: the last evaluation point "
                          "that still had authority (its row of table (b) spans more than the final error) and "
                          "the gap between the neighbouring table entries around the remaining time wanted "
                          "there (the nearest rule is off by up to half of it), or that the train was already "
                          "late there (wanted below the row's fastest entry).") + "</p><ul>")
            for sc in NEAREST_BOUNDS_S:
                w = best.worst.get(("nearest", sc))
                if w is not None:
                    out.append(f"<li><b>{_e(sc)}</b>: {_e(format_worst(w))}</li>")
            out.append("</ul>")
    cases = [(r, sc) for r in results for sc in ("nominal", "perturbed") if ("adaptive", sc) in r.stats]
    if cases:
        bad = [(r, sc) for r, sc in cases if r.stats[("adaptive", sc)]["max_abs_error_s"] > ADAPTIVE_MAX_S]
        worst = max(r.stats[("adaptive", sc)]["max_abs_error_s"] for r, sc in cases)
        out.append(f"<h2>Adaptive mode: max ≤ {ADAPTIVE_MAX_S:g} s at every setting</h2>"
                   f"<p>Worst over {len(results)} settings, both scenarios: {worst:.2f} s: "
                   f"<b>{'met' if not bad else 'not met'}</b>"
                   + ("." if not bad else " at " + "; ".join(
                       f"{_e(r.setting.label)} {_e(sc)} {r.stats[('adaptive', sc)]['max_abs_error_s']:.2f} s"
                       for r, sc in bad) + ".") + "</p>")
        if bad:
            out.append("<ul>" + "".join(f"<li><b>{_e(r.setting.label)}, {_e(sc)}</b>: "
                                        f"{_e(format_worst(r.worst[('adaptive', sc)]))}</li>"
                                        for r, sc in bad if ("adaptive", sc) in r.worst) + "</ul>")
    return out


def render_html(results: Sequence[SettingResult], *, line_name: str, base_bytes: int | None = None,
                note: str = "") -> str:
    """The study as one self-contained HTML page (inline CSS and SVG, no scripts), deterministic."""
    from planner.pages.margin_report import CSS, _e
    from planner.report.plots import interval_study_chart

    rows = study_rows(results, base_bytes)
    cases = list(dict.fromkeys(k.rsplit("/", 1)[0] for k in rows[0] if "/" in k)) if rows else []
    parts = ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             "<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>Evaluation interval study — {_e(line_name)}</title><style>{CSS}</style></head><body><main>",
             f"<h1>Evaluation points and ratio grid — {_e(line_name)}</h1>",
             "<p class='sub'>Arrival error |actual − designated| over feasible closed-loop runs (designated times "
             "minimum … minimum + 60 s in 1 s steps, every interstation, direction and train type) against the "
             "interval of the odometer evaluation points (beside the departure, the point 200 m after it and the "
             "flagged beacons) and the ratio grid. Tables for the empty train at nominal traction; "
             "<b>perturbed</b> = load 100 %, traction × 0.9 against the same tables. The odometer is taken as "
             "exact (no position error modelled). Bundle = the largest signed on-board bundle of the line; "
             "× = relative to today's (default grid, beacons only). CPU = table build, summed over tasks.</p>"]
    if note:
        parts.append(f"<p class='note'>{_e(note)}</p>")
    # chart: max error against interval, one panel per case, a line per grid
    if rows:
        bounds = {f"{m}/{sc}": b for m, per in (("nearest", NEAREST_BOUNDS_S),
                                                 ("adaptive", dict.fromkeys(NEAREST_BOUNDS_S, ADAPTIVE_MAX_S)))
                  for sc, b in per.items()}
        svg = interval_study_chart(rows, cases, bounds)
        parts.append(f"<div class='fig'>{svg}<div class='caption'>Maximum |arrival error| against the "
                     "evaluation interval, per ratio grid; dashed: the issue's bound (the nearest rule's at its "
                     "best setting under the bundle bound, the adaptive mode's at every setting).</div></div>")
    head = ("<tr><th class='l' rowspan=2>grid</th><th class='l' rowspan=2>interval</th><th rowspan=2>ratios</th>"
            "<th rowspan=2>points</th><th rowspan=2>table (b) rows</th><th rowspan=2>all table rows</th>"
            "<th rowspan=2>bundle [kB]</th><th rowspan=2>×</th><th rowspan=2>CPU [s]</th>"
            + "".join(f"<th colspan=3>{_e(c)}</th>" for c in cases) + "</tr><tr>"
            + "".join("<th>median</th><th>p95</th><th>max</th>" for _ in cases) + "</tr>")
    body = []
    for w in rows:
        cells = "".join(f"<td>{w[c + '/med']:.2f}</td><td>{w[c + '/p95']:.2f}</td><td>{w[c + '/max']:.2f}</td>"
                        for c in cases)
        body.append(f"<tr><td class='l'>{_e(w['grid'])}</td><td class='l'>{_e(w['interval'])}</td>"
                    f"<td>{w['ratios']}</td><td>{w['points']}</td><td>{w['table_b_rows']}</td><td>{w['table_rows']}</td>"
                    + (f"<td>{w['bundle_kb']:.0f}</td>" if w["bundle_kb"] else "<td>—</td>")  # not measured
                    + (f"<td>{w['bundle_x']:.2f}</td>" if w["bundle_x"] == w["bundle_x"] else "<td>—</td>")
                    + f"<td>{w['cpu_s']:.1f}</td>{cells}</tr>")
    parts.append("<h2>The study</h2><div class='tw'><table>" + head + "".join(body) + "</table></div>")
    parts.extend(_checks_html(results, base_bytes))
    worst = [(r.setting.label, k, w) for r in results for k, w in r.worst.items() if k[0] == "nearest"]
    if worst:
        parts.append("<h2>Worst runs of the nearest rule</h2><ul>")
        for label, (m, sc), w in worst:
            parts.append(f"<li><b>{_e(label)}, {_e(sc)}</b>: {_e(format_worst(w))}</li>")
        parts.append("</ul>")
    parts.append("</main></body></html>\n")
    return "\n".join(parts)


def write_html(results: Sequence[SettingResult], path: str | Path, **kw) -> Path:
    """Write :func:`render_html` to ``path`` atomically."""
    from planner.io.atomic import write_bytes_atomic

    write_bytes_atomic(path, render_html(results, **kw).encode("utf-8"))
    return Path(path)


__all__ = ["ADAPTIVE_MAX_S", "BUNDLE_FACTOR", "GRIDS", "INTERVALS", "NEAREST_BOUNDS_S", "Setting", "SettingResult",
           "Worst", "best_nearest", "bundle_sizes", "default_settings", "format_table", "format_worst", "render_html", "replay", "run_setting", "run_study",
           "study_rows", "write_html"]
