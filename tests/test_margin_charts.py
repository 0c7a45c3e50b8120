"""The margin report's charts, written as SVG by :mod:`planner.pages.margin_charts` (with :mod:`planner.pages.svg_plot`).

Checked from the outside, on the SVG a browser gets, on the closed-form line of ``tests/test_margins.py`` (margins,
minimum running times and flags known by hand): each chart parses as XML with its legend; a leg's bars stand where
the chart's own axes put them (the y scale read from the tick marks and their labels, the x from the station ticks
over the panel), as high as the closed-form margin; each narrow bar has its flag's colour; the run curves mirror
the ``up`` direction and put the leg's ends where the x ticks say; the adhesion chart marks the approach that loses
most; labels are escaped; the same report gives the same bytes whatever was drawn before; and drawing the page
never imports matplotlib (nor does a worker's warm-up).
"""
from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from planner.pages.margin_charts import CHARTS, FLAG_COLOURS, MARGIN_COLOUR, chart_svgs
from planner.pages.margin_report import stop_markers
from planner.report.leg_flags import FLAG
from test_margins import EXPECTED, t_run
from test_report import line, report  # noqa: F401 - the closed-form line and its report, the page tests' fixtures

SVG = "{http://www.w3.org/2000/svg}"
NUM = r"(-?\d+(?:\.\d+)?)"


@pytest.fixture(scope="module")
def svgs(report, line):
    return chart_svgs(report, stop_markers(line))


def parse(fragment: str):
    """(svg root, [(legend head, [labels])]) of a chart; every part must be well-formed XML."""
    root = ET.fromstring(f"<div>{fragment}</div>")
    svg = root.find(f"{SVG}svg")
    legends = [((lg.findtext("b") or ""), [("".join(s.itertext())).strip() for s in lg.findall("span")])
               for lg in root.findall("div")]
    return svg, legends


def frames(svg) -> list[dict]:
    """Each panel as drawn: its frame box, its tick marks with their labels (x along the bottom, y on the left,
    labelled ticks on the top), read from the frame's elements in document order."""
    out, kids = [], list(svg)
    for i, el in enumerate(kids):
        if el.tag == f"{SVG}rect" and el.get("fill") == "none" and el.get("stroke") == "#222":
            box = [float(el.get(k)) for k in ("x", "y", "width", "height")]
            marks = kids[i + 1].get("d")
            xt = [float(x) for x, _ in re.findall(rf"M{NUM},{NUM}v4", marks)]
            yt = [float(y) for _, y in re.findall(rf"M{NUM},{NUM}h-4", marks)]
            labels = [(t.get("text-anchor"), float(t.get("x")), float(t.get("y")), "".join(t.itertext()))
                      for t in kids[i + 2].iter(f"{SVG}text")]
            out.append(dict(box=box, xt=xt, yt=yt, labels=labels))
    return out


def y_axis(frame):
    """value → user units, from the y tick marks and their labels (right-aligned, left of the frame)."""
    vals = [float(s.replace("−", "-")) for a, x, y, s in frame["labels"] if a == "end"]
    marks = sorted(frame["yt"], reverse=True)  # labels go bottom to top: largest y first
    assert len(vals) == len(marks) >= 2
    k = (marks[-1] - marks[0]) / (vals[-1] - vals[0])
    return lambda v: marks[0] + (v - vals[0]) * k


def x_axis(frame):
    """value → user units, from the x tick marks and their labels under the frame."""
    bottom = frame["box"][1] + frame["box"][3]
    labels = [(x, float(s)) for a, x, y, s in frame["labels"] if a == "middle" and bottom < y < bottom + 20]
    assert len(labels) >= 2
    (x0, v0), (x1, v1) = labels[0], labels[-1]
    return lambda v: x0 + (v - v0) * (x1 - x0) / (v1 - v0)


def station_ticks(svg) -> list[dict[str, float]]:
    """Per panel, station code → x of its tick on the top edge."""
    out = []
    for el in svg:
        if el.tag == f"{SVG}path" and re.fullmatch(rf"(M{NUM},{NUM}v-4)+", el.get("d") or ""):
            xs = [float(x) for x, _ in re.findall(rf"M{NUM},{NUM}v-4", el.get("d"))]
            out.append(xs)
    groups = [g for g in svg if g.tag == f"{SVG}g" and g.get("font-size") == "9"]
    return [dict(zip(["".join(t.itertext()) for t in g], xs)) for g, xs in zip(groups, out)]


def bars(svg, leg: str) -> list[ET.Element]:
    """The rects whose tooltip names ``leg`` (``down S0 → S1``), in drawing order."""
    return [r for r in svg.iter(f"{SVG}rect") if leg in (r.findtext(f"{SVG}title") or "")]


def test_every_chart_parses_with_its_legend(svgs):
    assert set(svgs) == set(CHARTS)
    for name in CHARTS:
        svg, legends = parse(svgs[name][0] if name == "adhesion" else svgs[name])
        assert svg is not None and svg.get("viewBox"), name


@pytest.mark.parametrize("direction, o, d", [("down", "S0", "S1"), ("down", "S1", "S2"), ("up", "S2", "S1"),
                                             ("up", "S1", "S0")])
def test_a_margin_bar_stands_where_the_axes_put_it(svgs, direction, o, d):
    """The light bar spans the leg between its stations' ticks (4 % in from each), from 0 up to the margin the
    timetable grants over the closed-form minimum, T(L, 1) = L/V + V."""
    svg, _ = parse(svgs[f"margin:{direction}"])
    length, sched, _ = EXPECTED[(direction, o, d)]
    margin_s = sched - t_run(length, 1.0)
    light, narrow = bars(svg, f"{direction} {o} → {d}")
    assert light.get("fill") == MARGIN_COLOUR
    panel = next(f for f in frames(svg) if f["box"][1] <= float(light.get("y")) <= f["box"][1] + f["box"][3])
    ticks = next(t for t in station_ticks(svg) if o in t)
    a, b = sorted((ticks[o], ticks[d]))
    x, w = float(light.get("x")), float(light.get("width"))
    assert x == pytest.approx(a + 0.04 * (b - a), abs=0.15)
    assert x + w == pytest.approx(b - 0.04 * (b - a), abs=0.15)
    y = y_axis(panel)
    top, h = float(light.get("y")), float(light.get("height"))
    lo, hi = sorted((y(0.0), y(margin_s)))
    assert top == pytest.approx(lo, abs=0.3) and top + h == pytest.approx(hi, abs=0.3)
    # the narrow bar is the middle half of the light one
    assert float(narrow.get("x")) == pytest.approx(x + 0.25 * w, abs=0.15)
    assert float(narrow.get("width")) == pytest.approx(0.5 * w, abs=0.15)


def test_up_runs_left_to_right(svgs):
    down, _ = parse(svgs["margin:down"])
    up, _ = parse(svgs["margin:up"])
    t = station_ticks(down)[0]
    assert t["S0"] < t["S1"] < t["S2"]
    t = station_ticks(up)[0]
    assert t["S2"] < t["S1"] < t["S0"]
    assert "down: S0 → S2, running left to right" in "".join(down.itertext())
    assert "up: S2 → S0, running left to right" in "".join(up.itertext())


def test_each_leg_has_its_flags_colour(svgs):
    """The narrow bar is in the colour of the leg's worst flag (the badge's), green without one."""
    worst = {"tight": "tight", "infeasible": "short_bad_day", "unreachable": "unreachable"}  # 140 > 135.8, 82 > 81.8
    for (direction, o, d), (_, _, flags) in EXPECTED.items():
        svg, _ = parse(svgs[f"margin:{direction}"])
        _, narrow = bars(svg, f"{direction} {o} → {d}")
        want = FLAG[worst[next(iter(flags))]].colour if flags else "#2e7d32"
        assert narrow.get("fill") == want == FLAG_COLOURS[worst[next(iter(flags))] if flags else "ok"]


def test_margin_legend_names_each_colour(svgs):
    _, [(_, down)] = parse(svgs["margin:down"])
    _, [(_, up)] = parse(svgs["margin:up"])
    for labels in (down, up):
        assert labels[0] == "margin = scheduled − minimum" and labels[-1] == "supplement the rule asks for"
        assert "negative: short on a bad day" in labels and "impossible: margin < 0" in labels
    # a colour drawn beyond the four is named where it is drawn: the unreachable leg runs up
    assert any(s.startswith("unreachable") for s in up) and not any(s.startswith("unreachable") for s in down)


def test_run_curves_mirror_up_and_name_the_runs(svgs, report, line):
    """The chosen leg (least remaining margin: up S2 → S1) has its ends where the x ticks put its stop markers,
    S2 on the left; the legends name each run with its closed-form time."""
    assert report.chosen["direction"] == "up" and report.chosen["origin"] == "S2"
    svg, legends = parse(svgs["curves"])
    upper, lower = frames(svg)
    x = x_axis(lower)
    ends = sorted(float(el.get("x1")) for el in svg.iter(f"{SVG}line") if el.get("stroke") == "#000")
    marks = stop_markers(line)["up"]
    want = sorted(x(marks[s] / 1000.0) for s in ("S2", "S1"))
    assert ends[0] == pytest.approx(want[0], abs=0.15) and ends[-1] == pytest.approx(want[-1], abs=0.15)
    assert x(marks["S2"] / 1000.0) < x(marks["S1"] / 1000.0)
    heads = [h for h, _ in legends]
    assert heads == ["Top:", "Bottom:"]
    top = legends[0][1]
    assert f"minimum: ratio 100 %, nominal — {t_run(1500.0, 1.0):.1f} s" in top
    assert any(s.startswith("bad day: load 100%") for s in top)
    assert legends[1][1][:2] == ["as scheduled − minimum", "bad day − minimum"]


def test_adhesion_marks_the_approach_that_loses_most(svgs, report):
    """Red: the approach of the chosen train type losing the most time from the best to the worst adhesion,
    worked out here from the sweep; worse adhesion to the right."""
    svg, _ = parse(svgs["adhesion"][0])
    sw = report.sweep
    loss = {}
    for (d, o, de), g in sw.groupby(["direction", "origin", "destination"]):
        t = g.sort_values("adhesion_kmh_s").stop_time_s.to_numpy()
        loss[(d, o, de)] = float(np.nanmax(t - t[-1]))
    plain = {(d, o, de) for (d, o, de), (_, _, _) in EXPECTED.items() if (d, o, de) != ("down", "S0", "S2")}
    d, o, de = max((k for k in loss if k in plain), key=loss.get)
    assert f"{d} {o} → {de}" in svgs["adhesion"][1]
    red = [t for t in svg.iter(f"{SVG}text") if t.get("fill") == "#c62828"]
    assert any("".join(t.itertext()).startswith(f"{o} → {de}:") for t in red)
    for f in frames(svg):
        bottom = f["box"][1] + f["box"][3]
        ticks = [(x, float(s)) for a, x, y, s in f["labels"] if a == "middle" and bottom < y < bottom + 20]
        assert len(ticks) > 1
        ticks.sort()  # left to right
        assert ticks[0][1] > ticks[-1][1]  # best adhesion on the left


def test_labels_are_escaped(report, line):
    """Station and train-type codes with markup characters come out as text."""
    odd = 'S<1>&"'
    ren = {"S1": odd}
    rows = report.rows.copy()
    for c in ("origin", "destination"):
        rows[c] = rows[c].map(lambda s: ren.get(s, s))
    rows["train_type"] = "T&<x>"
    sweep = report.sweep.copy()
    sweep["train_type"] = "T&<x>"
    for c in ("origin", "destination"):
        sweep[c] = sweep[c].map(lambda s: ren.get(s, s))
    chosen = {k: ren.get(v, v) for k, v in report.chosen.items()} | {"train_type": "T&<x>"}
    rep = dataclasses.replace(report, rows=rows, sweep=sweep, chosen=chosen)
    markers = {d: {ren.get(s, s): x for s, x in m.items()} for d, m in stop_markers(line).items()}
    out = chart_svgs(rep, markers)
    for name in CHARTS:
        svg, _ = parse(out[name][0] if name == "adhesion" else out[name])
        text = "".join(svg.itertext())
        assert "T&<x>" in text, name
        if name != "adhesion" or odd in out["adhesion"][1]:
            assert odd in text, name


def test_same_report_same_bytes(report, line, svgs):
    """No ids or state from a previous chart: drawn again, one at a time and in reverse order, the same bytes."""
    markers = stop_markers(line)
    again = {}
    for name in reversed(CHARTS):
        again |= chart_svgs(report, markers, (name,))
    assert again == svgs
    ids = re.findall(r'id="([^"]+)"', "".join(v[0] if isinstance(v, tuple) else v for v in svgs.values()))
    assert len(ids) == len(set(ids))  # the four on one page keep apart


def test_svg_plot_padding_and_gaps():
    """The generic parts the charts need: matplotlib's 5 % autoscale margins, a line broken at NaN, no box
    for a missing value."""
    from planner.pages.svg_plot import Figure, padded

    assert padded(0.0, 10.0) == (-0.5, 10.5)
    assert padded(2.0, 2.0) == (1.5, 2.5)
    assert padded(float("nan"), 1.0) == (0.0, 1.0)
    fig = Figure(100, 100)
    p = fig.panel((0, 0, 100, 100), (0, 10), (0, 10))
    p.polyline([0, 1, 2, 3, 4], [1, 2, float("nan"), 4, 5], color="#123456")
    p.rects([0, 2], [1, 3], [0, 0], [5, float("nan")], fill="#abcdef", tips=["a<b", "c"])
    root = ET.fromstring(fig.svg())
    lines = [e.get("points") for e in root.iter(f"{SVG}polyline")]
    assert lines == ["0,90 10,80", "30,60 40,50"]
    rects = [e for e in root.iter(f"{SVG}rect") if e.get("fill") == "#abcdef"]
    assert len(rects) == 1 and rects[0].findtext(f"{SVG}title") == "a<b"
    assert (rects[0].get("x"), rects[0].get("y"), rects[0].get("width"), rects[0].get("height")) == ("0", "50", "10", "50")


def test_svg_plot_draws_nothing_at_a_missing_value():
    """A line or label at a missing value (a leg without a scheduled margin) is left out, as matplotlib left
    it out, instead of failing the page (the nightly job's margin report stopped on one)."""
    from planner.pages.svg_plot import Figure

    fig = Figure(100, 100)
    p = fig.panel((0, 0, 100, 100), (0, 10), (0, 10))
    p.hline(float("nan"), color="#111111")
    p.vline(float("nan"), color="#222222")
    p.text(1.0, float("nan"), "margin nan s")
    p.hline(5.0, color="#333333")
    root = ET.fromstring(fig.svg())
    strokes = [e.get("stroke") for e in root.iter(f"{SVG}line")]
    assert "#111111" not in strokes and "#222222" not in strokes and "#333333" in strokes
    assert "nan" not in fig.svg()


def test_the_page_and_a_workers_warm_up_never_import_matplotlib():
    """matplotlib stays for the CLI's file charts: drawing the margin page (and warming a nightly worker)
    does without it."""
    tests = Path(__file__).resolve().parent
    code = ("import sys\n"
            f"sys.path.insert(0, {str(tests)!r})\n"
            "from planner.job.pipeline import warm_worker\n"
            "warm_worker()\n"
            "from planner.pages.margin_report import render_html, stop_markers\n"
            "from planner.report.margins import compute_margins\n"
            "from test_margins import APPROACH, closed_form_line\n"
            "line = closed_form_line()\n"
            "rep = compute_margins(line, adhesion_kmh_s='3.0:3.5:0.5', approach_m=APPROACH, conflicts=False)\n"
            "page = render_html(rep, stop_markers(line))\n"
            "print(page.count(\"<div class='fig'><svg\"), 'matplotlib' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["4", "False"]
