"""The speed–distance chart of a leg, written as SVG by :mod:`planner.pages.svg_plot`.

Checked from the outside, on the SVG a browser gets: it parses as XML, a run's points land at the pixels the
axis limits predict (the leg's ends sit 1/22 of the frame in from its sides: matplotlib's 5 % margins),
the ``up`` direction mirrors x, every drawn thing is in the legend, the day's restriction is drawn with its id,
ids are escaped, and the same inputs give the same bytes whatever was drawn before.
"""
from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from linedb import write_line_db

SVG = "{http://www.w3.org/2000/svg}"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    from planner import load_line
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import leg_runs

    folder = tmp_path_factory.mktemp("line") / "tiny"
    write_line_db(folder, nodes=None, edges=None)
    line = load_line(folder)
    return line, leg_runs(line, compute_margins(line, conflicts=False).rows)


@pytest.fixture(scope="module")
def charts(tiny):
    """Every leg's chart inputs of the tiny line, half with a stopping pattern and evaluation points."""
    line, runs = tiny
    out = []
    for i, (key, run) in enumerate(sorted(runs.items())):
        d, _, o, de, _ = key
        calls = [(o, True, line.station(o).stop_m(d)), (de, True, line.station(de).stop_m(d))]
        x, v = run.position_m, run.v_ms[1] * 3.6
        extra = ({1.0: (x[-50:], v[-50:]), 2.0: (x[-30:], v[-30:])}, [(float(x[len(x) // 2]), "E1")]) \
            if i % 2 else (None, None)
        out.append((line, run, calls, *extra))
    return out


def _parse(fragment: str):
    """(svg root, legend labels) of a chart; both parts must be well-formed XML."""
    root = ET.fromstring(f"<div>{fragment}</div>")
    svg = root.find(f"{SVG}svg")
    legend = [("".join(s.itertext())).strip() for s in root.find("div").findall("span")]
    return svg, legend


def _polyline(svg, colour: str, box=None) -> np.ndarray:
    """The points (user units) of the one polyline drawn in ``colour`` (inside the panel ``box``, if given:
    the speed and the time panel draw a run in the same colour)."""
    from planner.pages.speed_chart import SPEED_BOX

    top, h = (box or SPEED_BOX)[1], (box or SPEED_BOX)[3]
    pts = [np.array([[float(v) for v in pt.split(",")] for pt in p.get("points").split()])
           for p in svg.iter(f"{SVG}polyline") if p.get("stroke") == colour]
    got = [q for q in pts if np.all((q[:, 1] >= top - 1e-6) & (q[:, 1] <= top + h + 1e-6))]
    assert len(got) == 1, f"{len(got)} polylines in {colour}"
    return got[0]


def _texts(svg) -> list[str]:
    return ["".join(t.itertext()) for t in svg.iter(f"{SVG}text")] + \
        [t.text for t in svg.iter(f"{SVG}tspan")]


def _down_ab(charts):
    return next(c for c in charts if c[1].key[:4] == ("down", "EMU10", "A", "B"))


def test_the_tiny_line_has_legs_both_ways(charts):
    assert {c[1].key[0] for c in charts} == {"down", "up"}


def test_the_minimum_run_lands_where_the_axes_put_it(charts):
    from planner.pages.speed_chart import SPEED_BOX, chart_svg

    line, run, calls, *_ = _down_ab(charts)
    svg, _ = _parse(chart_svg(line, run, calls))
    left, top, w, h = SPEED_BOX
    pts = _polyline(svg, "#9dbde6")  # the minimum run
    # departure at the stop marker at 0 km/h: 1/22 of the width in from the left (5 % margins of the leg), bottom
    assert pts[0] == pytest.approx([left + w / 22, top + h], abs=0.06)
    assert pts[-1] == pytest.approx([left + w * 21 / 22, top + h], abs=0.06)
    # the y axis runs from 0 to 1.14 × the line's 100 km/h (no restriction on the leg): the highest point
    v_top = 114.0
    peak = float(np.max(run.v_ms[1])) * 3.6
    assert float(np.min(pts[:, 1])) == pytest.approx(top + h * (1 - peak / v_top), abs=0.2 / v_top * h + 0.06)
    # x of every point within the leg, linear in chainage: the fastest node's chainage lands at its pixel
    k = int(np.argmax(run.v_ms[1]))
    lo, hi = run.position_m.min(), run.position_m.max()
    px = left + w * (1 / 22 + 20 / 22 * (run.position_m[k] - lo) / (hi - lo))
    near = pts[np.argmin(pts[:, 1])]
    assert abs(near[0] - px) < w * 20 / 22 * 50.0 / (hi - lo)  # within 50 m: a flat top spans several nodes


def test_up_mirrors_x(charts):
    from planner.pages.speed_chart import SPEED_BOX, chart_svg

    line, run, calls, *_ = _down_ab(charts)
    up = dataclasses.replace(run, key=("up",) + tuple(run.key[1:]))
    a = _polyline(_parse(chart_svg(line, run, calls))[0], "#9dbde6")
    b = _polyline(_parse(chart_svg(line, up, calls))[0], "#9dbde6")
    left, _, w, _ = SPEED_BOX
    assert len(a) == len(b)
    assert np.allclose(a[:, 0] + b[:, 0], 2 * left + w, atol=0.11)
    assert b[0, 0] == pytest.approx(left + w * 21 / 22, abs=0.06)  # the departure on the right: x runs leftwards


def test_every_drawn_thing_is_in_the_legend(charts):
    from planner.pages.speed_chart import chart_svg

    line, run, calls, *_ = _down_ab(charts)
    x, v = run.position_m, run.v_ms[1] * 3.6
    _, legend = _parse(chart_svg(line, run, calls, {1.0: (x[-50:], v[-50:]), 2.5: (x[-30:], v[-30:])},
                                 [(1500.0, "E1")]))
    t_m, t_r = float(run.t_s[1][-1]), float(run.t_s[0][-1])
    want = ["permanent speed limit", "on-board maximum (limit − margin)", f"minimum run: ratio 100 % — {t_m:.1f} s",
            f"on-time departure: ratio {round(run.ratio * 100)} % — {t_r:.1f} s (scheduled {run.key[4]:.0f} s)",
            "stopping pattern, lowest adhesion 1 km/h/s", "stopping pattern, highest adhesion 2.5 km/h/s",
            "signal", "ATS-P / TASC beacon", "evaluation point",  # SG1 at 1000 m, B1/B2 at 900/1000 m (down)
            "scheduled running time",
            "gradient in the running direction [‰] (+ rising)", "curve (radius [m])"]  # R600 at 1200–1600 m
    assert legend == want
    # and what the legend names is drawn: one signal (triangle), two beacons (ticks), one evaluation point
    svg, _ = _parse(chart_svg(line, run, calls, None, [(1500.0, "E1")]))
    paths = {p.get("fill") if p.get("fill") != "none" else p.get("stroke"): p.get("d") for p in svg.iter(f"{SVG}path")}
    assert paths["#37474f"].count("M") == 1 and paths["#6a1b9a"].count("M") == 2 and paths["#f2b705"].count("M") == 1
    assert "R600" in _texts(svg)


def test_the_days_restriction_is_hatched_and_named(charts):
    from planner.line.daily import TemporaryRestriction
    from planner.line.units import KMH
    from planner.pages.speed_chart import SPEED_BOX, chart_svg

    line, run, calls, *_ = _down_ab(charts)
    tsr = TemporaryRestriction("TSR-T1", 600.0, 900.0, 40.0 * KMH, "down", None, "2026-11-29T14:20",
                               "2026-12-02T16:00", 0, 1, "rail defect", False)
    line = dataclasses.replace(line, speed_limits=line.speed_limits + (tsr.as_speed_limit(),))
    svg, legend = _parse(chart_svg(line, run, calls))
    assert "TSR-T1" in _texts(svg) and "40 km/h" in _texts(svg)
    assert any(s.startswith("temporary speed restriction") for s in legend)
    band = [r for r in svg.iter(f"{SVG}rect") if (r.get("fill") or "").startswith("url(#")]
    assert len(band) == 1
    assert svg.find(f".//{SVG}pattern[@id='{band[0].get('fill')[5:-1]}']") is not None  # the hatch is defined
    left, top, w, h = SPEED_BOX
    lo, hi = run.position_m.min(), run.position_m.max()
    px = [left + w * (1 / 22 + 20 / 22 * (c - lo) / (hi - lo)) for c in (600.0, 900.0)]
    assert float(band[0].get("x")) == pytest.approx(px[0], abs=0.06)
    assert float(band[0].get("width")) == pytest.approx(px[1] - px[0], abs=0.11)
    # the band reaches 0.8 of the axis, which now runs to 1.3 × 100 km/h (room for the id)
    assert float(band[0].get("y")) == pytest.approx(top + 0.2 * h, abs=0.06)
    lim = _polyline(svg, "#e65100")
    assert sorted(set(np.round(lim[:, 1], 1)))[-1] == pytest.approx(top + h * (1 - 40 / 130), abs=0.06)


def test_ids_are_escaped(charts):
    from planner.pages.speed_chart import chart_svg

    line, run, calls, *_ = _down_ab(charts)
    odd = '<&"A\'>'
    out = chart_svg(line, run, [(odd, True, calls[0][2])] + calls[1:])
    assert odd not in out
    svg, _ = _parse(out)  # parses: nothing unescaped
    assert odd in _texts(svg)  # the station's label reads as given


def test_a_worker_draws_the_chart_of_the_run_the_job_recorded(tiny):
    """The job's process keeps only a leg's times; the chart's worker records the run again from the leg's
    window: the same chart, byte for byte, as drawn from the job's own run of the leg."""
    from planner.job.train_views import _chart_task
    from planner.pages.speed_chart import chart_svg
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import leg_window, legs

    line, runs = tiny
    seen = 0
    for key, row in legs(line, compute_margins(line, conflicts=False).rows):
        win = leg_window(line, key)
        d, _, o, de = key[:4]
        calls = [(o, True, line.station(o).stop_m(d)), (de, True, line.station(de).stop_m(d))]
        assert _chart_task(win, key, row, 1.0, calls, None, None, None) == chart_svg(win, runs[key], calls)
        seen += 1
    assert seen == len(runs) > 1


def test_a_charts_key_follows_what_the_run_depends_on(tiny):
    """A chart's cache key names the run by what it is computed from (the leg's window, the ratio, the step),
    not by its arrays: another step, ratio or speed limit on the leg is another key; the same inputs, the same."""
    from planner.job.train_views import _chart_key
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import planned_legs

    line, _ = tiny
    rows = compute_margins(line, conflicts=False).rows
    key, (t, _w) = sorted(planned_legs(line, rows).items())[0]
    rest = ([], None, [], [])
    k0 = _chart_key(line, t, 1.0, rest)
    assert _chart_key(line, t, 1.0, rest) == k0
    assert _chart_key(line, t, 0.5, rest) != k0
    assert _chart_key(line, dataclasses.replace(t, ratio=t.ratio - 0.1), 1.0, rest) != k0
    d, tt, o, de = key[:4]
    (lim, *_) = [s for s in line.limits_for(d, tt) if s.end_m > line.window(o, de, tt).run_between(o, de).start_m]
    slower = dataclasses.replace(line, speed_limits=tuple(
        dataclasses.replace(s, limit_ms=s.limit_ms - 1.0) if s is lim else s for s in line.speed_limits))
    assert _chart_key(slower, t, 1.0, rest) != k0
    # the arrival's patterns read on the worker from the stops unit: the key names that unit (what they are made of)
    from planner.job.units import Stored

    by = [_chart_key(line, t, 1.0, ([], Stored("/c", "stops", k * 64), [], [])) for k in "ab"]
    assert by[0] != by[1] and k0 not in by and by[0] == _chart_key(line, t, 1.0, ([], Stored("/d", "stops", "a" * 64),
                                                                                   [], []))


def test_same_inputs_same_bytes_whatever_was_drawn_before(charts):
    from planner.pages.speed_chart import chart_svg

    first = [chart_svg(*c) for c in charts]
    assert len(set(first)) == len(first)  # different charts
    order = list(range(len(charts)))[::-1] + list(np.random.default_rng(1).permutation(len(charts)))
    for i in order:
        assert chart_svg(*charts[i]) == first[i], f"chart {charts[i][1].key} differs after another chart"
    for c in first:
        _parse(c)
        assert not re.search(r'id="[^"]*[0-9a-f]{8,}', c)  # no hashed or random ids


@pytest.mark.parametrize("lo,hi,target,ticks", [
    (0.0, 128.0, 7, [0, 20, 40, 60, 80, 100, 120]),
    (0.0, 128.0, 6, [0, 25, 50, 75, 100, 125]),
    (-0.35, 7.65, 10, [0, 1, 2, 3, 4, 5, 6, 7]),
    (26.02, 27.68, 10, [26.2, 26.4, 26.6, 26.8, 27.0, 27.2, 27.4, 27.6]),
    (0.0, 0.9, 4, [0.0, 0.25, 0.5, 0.75]),
    (-0.2, 0.9, 4, [0.0, 0.5])])
def test_nice_ticks(lo, hi, target, ticks):
    from planner.pages.svg_plot import nice_ticks

    got, dec = nice_ticks(lo, hi, target)
    assert got == pytest.approx(ticks)
    assert dec == {0.2: 1, 0.25: 2, 0.5: 1}.get(round(ticks[1] - ticks[0], 6), 0)


def test_a_points_list_writes_each_value_as_num_does():
    """The points list is made without a call per point; each value must still read as :func:`num` writes it:
    whole numbers without ``.0``, one decimal otherwise, never ``-0``, and values past 1e15 (where ``repr`` would
    switch to an exponent) too."""
    from planner.pages.svg_plot import _pairs, num

    rng = np.random.default_rng(7)
    x = np.r_[np.arange(-3000, 3000) / 10 + 0.01, rng.normal(0, 1e4, 20000), rng.normal(0, 1e9, 2000),
              -0.04, 0.04, -0.05, 0.05, 0.15, 0.25, -0.25, 2.5, -2.5, 1e14 + 0.05, 0.0, -0.0]
    y = rng.normal(0, 300, x.size)
    by_num = lambda px, py: " ".join(f"{num(a)},{num(b)}" for a, b in zip(px, py))  # noqa: E731
    got = _pairs(x, y)
    rx, ry = np.round(x, 1) + 0.0, np.round(y, 1) + 0.0
    keep = np.r_[True, (rx[1:] != rx[:-1]) | (ry[1:] != ry[:-1])]
    assert got == by_num(rx[keep].tolist(), ry[keep].tolist())
    assert "-0," not in got and not re.search(r"\.0(,| |$)", got)
    big = np.array([3e15, -7.25e17, 12.0])
    assert _pairs(big, np.array([1.0, 2.0, 3.0])) == by_num(big.tolist(), [1.0, 2.0, 3.0])
    assert "e+" not in _pairs(big, np.array([1.0, 2.0, 3.0]))
    assert _pairs(np.array([]), np.array([])) == ""


def test_mid_steps_change_halfway_between_points():
    from planner.pages.svg_plot import Figure

    fig = Figure(100, 100)
    p = fig.panel((0, 0, 100, 100), (0, 10), (0, 10))
    p.steps_mid([0, 2, 4, 6, 10], [5, 5, 7, 7, 7], color="#000")
    pts = _polyline(ET.fromstring(fig.svg()), "#000", (0, 0, 100, 100))
    # (0, 5) … (3, 5) | (3, 7) … (10, 7) in data; y up from the bottom
    assert pts.tolist() == [[0, 50], [30, 50], [30, 30], [100, 30]]


def test_the_time_panel_shows_both_runs_and_a_late_arrival_is_called_late(charts):
    """Time since departure along the leg: each run ends at its running time on the time axis; a leg whose
    on-time departure arrives after the scheduled time says by how much (title, label and legend), and the
    minimum run, drawn as a band under the on-time run, stays visible where the two coincide."""
    from planner.pages.speed_chart import TIME_BOX, chart_svg

    line, run, calls, *_ = _down_ab(charts)
    t_r, t_m = float(run.t_s[0][-1]), float(run.t_s[1][-1])
    svg, legend = _parse(chart_svg(line, run, calls))
    left, top, w, h = TIME_BOX
    y_top = max(float(run.key[4]), t_r, t_m) * 1.08
    on_time, minimum = _polyline(svg, "#2e7d32", TIME_BOX), _polyline(svg, "#9dbde6", TIME_BOX)
    assert on_time[-1, 1] == pytest.approx(top + h * (1 - t_r / y_top), abs=0.06)
    assert minimum[-1, 1] == pytest.approx(top + h * (1 - t_m / y_top), abs=0.06)
    assert "late" not in " ".join(_texts(svg)) and not any("late" in x for x in legend)
    # the on-time ratio's run over the scheduled time, the leg not late (its minimum within it): said, not red
    sched = round(t_r) - 1.0
    over = dataclasses.replace(run, key=run.key[:4] + (sched,) + tuple(run.key[5:]))
    svg, legend = _parse(chart_svg(line, over, calls))
    words = " ".join(_texts(svg))
    assert f"the run takes {t_r:.1f} s, {t_r - sched:.1f} s more than scheduled" in words and "late" not in words
    _polyline(svg, "#2e7d32", TIME_BOX)
    # a late leg: scheduled 10 s below the minimum run (its margin -10 s), the on-time run red and its lateness
    sched = t_m - 10.0
    late = dataclasses.replace(run, key=run.key[:4] + (sched,) + tuple(run.key[5:]),
                               row={**run.row, "margin_s": -10.0})
    svg, legend = _parse(chart_svg(line, late, calls))
    words = " ".join(_texts(svg))
    assert "late: the minimum run itself takes 10.0 s more than scheduled" in words
    assert f"{t_r - sched:.1f} s late" in words and "on-time departure on a late leg (time panel)" in legend
    _polyline(svg, "#c62828", TIME_BOX)


def test_every_text_of_the_chart_is_at_least_11_px_in_a_1000_px_window(charts):
    """The chart is drawn at the page's width: about 940 px of a 1000 px window (page margins), so its text must
    be at least 11 / 0.78 user units of its 1200-unit view box; it was 8.5-10 (7 px)."""
    from planner.pages.speed_chart import W, chart_svg

    line, run, calls, pattern, points = next(c for c in charts if c[3] is not None)
    svg, _ = _parse(chart_svg(line, run, calls, pattern, points))
    sizes = [float(e.get("font-size")) for e in svg.iter() if e.get("font-size")]
    assert sizes and min(sizes) * 940.0 / W >= 11.0, sorted(set(sizes))


def test_the_bad_day_run_is_the_margin_reports_bad_day_minimum_and_is_drawn(tiny):
    """The chart's bad-day run is made by the functions that make the margin report's bad-day minimum (the
    degraded run to the row's pattern start, then the pattern at the row's adhesion): it ends at the row's
    degraded_min_running_time_s, on every leg, and the chart draws it in both panels and says how it ends."""
    from planner.job.train_views import _chart_task
    from planner.report.leg_margin import bad_day_run
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import leg_window, legs

    line, _runs = tiny
    seen = 0
    for key, row in legs(line, compute_margins(line, conflicts=False).rows):
        win = leg_window(line, key)
        d, tt, o, de = key[:4]
        got = bad_day_run(win, tt, o, de, row, 1.0, 0.9, True, 1.0)
        assert got is not None
        x, v, t = got
        assert t[-1] == pytest.approx(float(row["degraded_min_running_time_s"]), abs=1e-6)
        assert v[0] == 0.0 and abs(v[-1]) < 1e-6  # from the departure to a stand at the marker
        assert x[-1] == pytest.approx(line.station(de).stop_m(d), abs=1e-6)
        calls = [(o, True, line.station(o).stop_m(d)), (de, True, line.station(de).stop_m(d))]
        svg, legend = _parse(_chart_task(win, key, row, 1.0, calls, None, None, None, (1.0, 0.9, True)))
        from planner.pages.speed_chart import COLOURS, TIME_BOX

        _polyline(svg, COLOURS["bad_day"])  # the speed panel
        _polyline(svg, COLOURS["bad_day"], TIME_BOX)  # the time panel
        assert any(lbl.startswith("bad-day minimum run") and f"{t[-1]:.1f} s" in lbl for lbl in legend)
        assert any("on a bad day" in s for s in _texts(svg))
        seen += 1
    assert seen > 1
