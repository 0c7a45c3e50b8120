"""The train graph's data: thinning, locals/rapids, trajectories from the network module, page payload, charts."""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from planner.errors import InputError
from planner.report.train_graph import (
    TOL_T_S,
    TOL_X_M,
    graph_data,
    parse_hhmm,
    service_of,
    simplify,
)
from planner.report.train_graph import train_graph_chart as draw_chart
from planner.pages.train_graph import page_payload, render_page


@pytest.fixture(scope="module")
def data(tiny):
    return graph_data(tiny)


def _chord_error(t, x, keep, tol_t, tol_x):
    """Largest scaled distance of a dropped point from its kept chord (must be ≤ 1)."""
    worst = 0.0
    for a, b in zip(keep[:-1], keep[1:]):
        for i in range(a + 1, b):
            dt, dx = (t[b] - t[a]) / tol_t, (x[b] - x[a]) / tol_x
            pt, px = (t[i] - t[a]) / tol_t, (x[i] - x[a]) / tol_x
            worst = max(worst, abs(pt * dx - px * dt) / math.hypot(dt, dx))
    return worst


def test_simplify_keeps_every_point_within_tolerance_and_the_steps():
    # a stop (flat step) between two smooth runs, densely sampled
    t = np.concatenate([np.linspace(0, 100, 501), np.linspace(100, 130, 31)[1:], np.linspace(130, 230, 501)[1:]])
    x = np.concatenate([1000 * (1 - np.cos(np.linspace(0, np.pi, 501))) / 2, np.full(30, 1000.0),
                        1000 + 1000 * (1 - np.cos(np.linspace(0, np.pi, 501)[1:])) / 2])
    keep = simplify(t, x)
    assert keep[0] == 0 and keep[-1] == len(t) - 1 and len(keep) < len(t) / 10
    assert _chord_error(t, x, keep, TOL_T_S, TOL_X_M) <= 1.0
    # both ends of the stop survive: the step stays flat
    assert 500 in keep and 530 in keep
    # a straight line needs its two ends only
    assert simplify(np.arange(100.0), 3 * np.arange(100.0)).tolist() == [0, 99]


def _textbook_rdp(t, x, tol_t, tol_x):
    """Ramer–Douglas–Peucker as the 1973 paper recurses it, one chord at a time (with simplify's fixed
    points: the ends and both ends of every stand): the reference simplify must equal."""
    t, x = np.asarray(t, float) / tol_t, np.asarray(x, float) / tol_x
    keep = {0, len(t) - 1}
    for i in range(len(t) - 1):
        if x[i + 1] == x[i] and t[i + 1] > t[i]:
            keep |= {i, i + 1}

    def split(a, b):
        if b - a < 2:
            return
        dt, dx = t[b] - t[a], x[b] - x[a]
        seg = math.hypot(dt, dx)
        d = [math.hypot(t[i] - t[a], x[i] - x[a]) if seg == 0.0
             else abs((t[i] - t[a]) * dx - (x[i] - x[a]) * dt) / seg for i in range(a + 1, b)]
        k = max(range(len(d)), key=d.__getitem__)  # the first of equal maxima
        if d[k] > 1.0:
            keep.add(a + 1 + k)
            split(a, a + 1 + k)
            split(a + 1 + k, b)

    fixed = sorted(keep)
    for a, b in zip(fixed[:-1], fixed[1:]):
        split(a, b)
    return sorted(keep)


@pytest.mark.parametrize("kind", ["smooth", "grid", "stands", "crowded"])
def test_simplify_keeps_the_points_the_textbook_recursion_keeps(kind):
    """simplify splits every chord of one depth at once; the kept points must be the recursion's exactly,
    ties (the first farthest point), closed chords (a train back where it was) and stands included."""
    rng = np.random.default_rng(7)
    for _ in range(150):
        n = int(rng.integers(0, 200))
        if kind == "smooth":
            t, x = np.cumsum(rng.uniform(0, 3, n)), np.cumsum(rng.normal(0, 10, n))
        elif kind == "grid":  # many equal distances
            t, x = np.cumsum(rng.integers(0, 3, n)) * 1.0, np.cumsum(rng.integers(-2, 3, n)) * 5.0
        elif kind == "stands":
            t, x = np.round(np.cumsum(rng.uniform(0, 2, n))), np.round(np.cumsum(rng.uniform(0, 30, n)), -1)
        else:  # few distinct points: closed chords everywhere
            t, x = rng.integers(0, 5, n) * 1.0, rng.integers(0, 5, n) * 5.0
        assert simplify(t, x, 1.0, 5.0).tolist() == (_textbook_rdp(t, x, 1.0, 5.0) if n > 2 else list(range(n)))


def test_locals_and_rapids(tiny):
    services = {t.train_id: service_of(t) for t in tiny.trains}
    assert services == {"101": "local", "202": "rapid"}  # 202 passes B


def test_paths_follow_the_predicted_trajectory(tiny, data):
    from planner.network.arrivals import SimulatorCurves, build_trajectory

    src = SimulatorCurves(tiny)
    for tp, train in zip(data.trains, tiny.trains):
        traj = build_trajectory(tiny, train, src)
        x = (1 if train.direction == "down" else -1) * traj.u_m
        # the drawn path is within the thinning tolerance of the network module's trajectory
        xi = np.interp(traj.t_s, tp.t_s, tp.x_m)
        step = np.r_[True, np.diff(traj.t_s) > 0]  # skip the instant of a stop (same time, two chainages)
        assert np.all(np.abs(xi - x)[step] <= TOL_X_M + 60.0 * TOL_T_S)
        assert tp.t_s[0] == pytest.approx(train.calls[0].departure_s)
    # 101 stands at B from 21800 to 21830 s: a flat step at B's down stop marker
    p = data.train("101")
    at_b = (p.t_s >= 21800) & (p.t_s <= 21830)
    assert np.ptp(p.x_m[at_b]) < 1.0 and p.x_m[at_b][0] == pytest.approx(2560.0, abs=1.0)


def test_page_payload_decodes_to_the_paths(data):
    pl = page_payload(data)
    for tr, tp in zip(pl["trains"], data.trains):
        assert np.allclose(np.cumsum(tr["t"]) / 10.0, tp.t_s, atol=0.051)
        assert np.allclose(np.cumsum(tr["x"]), tp.x_m, atol=0.51)
    page = render_page(data)
    assert "http://" not in page.replace("http://www.w3.org/2000/svg", "") and "https://" not in page
    assert render_page(data) == page  # deterministic
    js = page.split("id='graph-data'>")[1].split("</script>")[0]
    assert json.loads(js)["view"] == [21600, 25200]


def test_charts_and_bad_input(data, tmp_path):
    svg = draw_chart(data, tmp_path / "g.svg", direction="down", train="101")
    assert svg.read_text().count("<svg") == 1
    assert draw_chart(data, tmp_path / "g.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(InputError, match="--train 999"):
        draw_chart(data, tmp_path / "x.svg", train="999")
    with pytest.raises(InputError, match=r"\.svg or \.png"):
        draw_chart(data, tmp_path / "x.pdf")
    assert parse_hhmm("07:30", "--from") == 27000 and parse_hhmm("24:15", "--to") == 87300
    for bad in ("7.30", "07:60", "x"):
        with pytest.raises(InputError, match="HH:MM"):
            parse_hhmm(bad, "--from")
    assert not (tmp_path / "x.svg").exists()


def test_cli_graph_one_line_errors(tiny, tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "planner.cli", "graph", tiny.source_path, "--out", str(tmp_path / "o"),
                        "--train", "nope"], capture_output=True, text=True)
    assert r.returncode != 0 and r.stderr.startswith("error: --train nope") and "Traceback" not in r.stderr
    assert not (tmp_path / "o").exists()


def test_page_payload_windows_decode(data):
    import dataclasses

    import pandas as pd

    w = pd.DataFrame({"train_id": ["101"] * 3, "resource_id": ["E1", "N3", "E3"],
                      "start_s": [21570.04, 21590.0, 21620.3], "end_s": [21640.0, 21655.5, 21900.0],
                      "from_m": [260.0, 1000.0, 1000.0], "to_m": [1000.0, 1000.0, 4860.0]})
    pl = page_payload(dataclasses.replace(data, windows=w))
    start, dur, lo, length, res = pl["windows"]["101"]
    assert np.allclose(np.cumsum(start) / 10, w.start_s, atol=0.051)
    assert np.allclose(np.cumsum(start) / 10 + np.array(dur) / 10, w.end_s, atol=0.11)
    assert np.cumsum(lo).tolist() == [260, 1000, 1000] and length == [740, 0, 3860]
    assert [pl["resources"][k] for k in res] == ["E1", "N3", "E3"]


def test_the_pages_data_made_a_train_at_a_time_is_the_payloads_json(data):
    """The page writes its data a train at a time (page_json), never the whole payload as Python lists: the same
    text as json.dumps of page_payload with the page's own keys after it, windows, resources and conflicts
    included, and it parses back to that payload."""
    import dataclasses
    import json

    import pandas as pd

    from planner.pages.train_graph import page_json

    w = pd.DataFrame({"train_id": ["101", "101", "102"], "resource_id": ["E1", "N3", "E1"],
                      "start_s": [21570.0, 21590.0, 21700.0], "end_s": [21640.0, 21655.5, 21760.0],
                      "from_m": [260.0, 1000.0, 260.0], "to_m": [1000.0, 1000.0, 900.0]})
    for d in (data, dataclasses.replace(data, windows=w)):
        extra = {"view": [0, 3600], "select": None, "tt": "../timetable/x.html"}
        want = json.dumps(page_payload(d) | extra, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
        got = page_json(d, extra)
        assert got == want and json.loads(got) == json.loads(want)
        assert len(json.loads(got)["trains"]) == len(d.trains)
    assert json.loads(page_json(dataclasses.replace(data, windows=w), {}))["resources"] == ["E1", "N3"]


# --- a synthetic day: the window the page opens on, ids in any case, titles and the legend --------------------
def _train(train_id: str, direction: str, t0: float, t1: float):
    from planner.report.train_graph import TrainPath

    a, b = ("A", "B") if direction == "down" else ("B", "A")
    x = [0.0, 5000.0] if direction == "down" else [5000.0, 0.0]
    return TrainPath(train_id, "EMU", direction, "local", np.array([t0, t1]), np.array(x),
                     ((a, math.nan, t0, True), (b, t1, math.nan, True)))


def day_graph(name: str = "Two Stations (two)"):
    """A day from 05:10 to 22:40: one train 05-06, three from 07:05 to 08:10, one 08:30-09:00, six after noon, one
    late; by hand the two whole hours before noon holding the most trains are 07:00-09:00 (4: m1, m2, m3, M4),
    against 06:00-08:00 (3) and 08:00-10:00 (2: m3 still running at 08:00, M4); 13:00-15:00 holds 6 but is after noon."""
    from planner.report.train_graph import GraphData

    h = 3600.0
    trains = [_train("E1", "down", 5 * h + 600, 5 * h + 2400),
              _train("m1", "down", 7 * h + 300, 7 * h + 2100), _train("m2", "up", 7 * h + 1200, 7 * h + 3000),
              _train("m3", "down", 7 * h + 2400, 8 * h + 600), _train("M4", "up", 8 * h + 1800, 9 * h)]
    trains += [_train(f"P{i}", "down", 13 * h + 600 * i, 13 * h + 600 * i + 1800) for i in range(6)]
    trains.append(_train("L1", "up", 22 * h, 22 * h + 2400))
    return GraphData("two", name, 0.0, 5000.0, [("A", "Alpha", 0.0), ("B", "Beta", 5000.0)], trains)


def test_the_page_opens_on_the_morning_peak_not_the_whole_day():
    from planner.report.train_graph import start_window, time_window

    g = day_graph()
    assert time_window(g, None, None) == (5 * 3600.0, 23 * 3600.0)  # the whole day: one click away
    assert start_window(g) == (7 * 3600.0, 9 * 3600.0)
    assert start_window(g, hours=1.0) == (7 * 3600.0, 8 * 3600.0)  # 07-08: m1, m2, m3 (3) against 08-09: m3, M4
    late = dataclasses.replace(g, trains=g.trains[5:])  # no train before noon: the busiest window of the afternoon
    assert start_window(late) == (13 * 3600.0, 15 * 3600.0)
    short = dataclasses.replace(g, trains=g.trains[1:4])  # 07:05-08:10: two whole hours, shown whole
    assert start_window(short) == (7 * 3600.0, 9 * 3600.0) == time_window(short, None, None)
    pl = json.loads(render_page(g).split("id='graph-data'>")[1].split("</script>")[0])
    assert pl["view"] == [7 * 3600.0, 9 * 3600.0] and pl["day"] == [5 * 3600, 23 * 3600]
    # a train given: its run with ten minutes either side; a window given: that window
    pl = json.loads(render_page(g, train="m4").split("id='graph-data'>")[1].split("</script>")[0])
    assert pl["view"] == [8 * 3600.0 + 1200, 9 * 3600.0 + 600] and pl["select"] == "M4"
    pl = json.loads(render_page(g, t0=6 * 3600.0, t1=10 * 3600.0).split("id='graph-data'>")[1].split("</script>")[0])
    assert pl["view"] == [6 * 3600.0, 10 * 3600.0]


def test_train_ids_match_in_any_case_when_only_one_train_fits():
    from planner.report.train_graph import match_train

    ids = ["1001D", "ab", "AB", "m1"]
    assert match_train(ids, "1001d") == "1001D" and match_train(ids, " M1 ") == "m1"
    assert match_train(ids, "ab") == "ab" and match_train(ids, "AB") == "AB"  # the exact one first
    assert match_train(ids, "Ab") is None and match_train(ids, "1001") is None  # two fit / none fits
    assert day_graph().train("e1").train_id == "E1"
    with pytest.raises(InputError, match="--train Ab"):
        dataclasses.replace(day_graph(), trains=[_train("ab", "down", 0, 60), _train("AB", "up", 0, 60)]).train("Ab")


def test_titles_name_the_line_once_and_the_run(tmp_path):
    from planner.pages.run_head import run_words

    label = run_words("r0007-0123456789", {"day": "2026-11-30", "time_zone": "Asia/Tokyo",
                                           "start": "2026-11-30T03:00:00+09:00",
                                           "end": "2026-12-01T03:00:00+09:00"}, "2026-11-27")
    assert label == ("run r0007-0123456789 of 2026-11-27 · operating day Monday 2026-11-30, 03:00 to 03:00 the next "
                     "day (Asia/Tokyo)")
    assert run_words(None, None) == "" and run_words("r1", None) == "run r1"
    g = day_graph("Minato Line (two)")  # a name that already ends with the id: said once
    page = render_page(g, run_label=label, links=[("overview", "../index.html")])
    assert "<h1>Train graph — Minato Line (two)</h1>" in page and "(two) (two)" not in page
    assert "operating day Monday 2026-11-30" in page and "<a href='../index.html'>overview</a>" in page
    assert "Train graph — Two Stations (two)</h1>" in render_page(day_graph("Two Stations"))
    svg = draw_chart(g, tmp_path / "g.svg", run_label=label).read_text()
    assert "Minato Line (two) — train graph" in svg and "(two) (two)" not in svg and "operating day Monday" in svg


def test_the_chart_legend_stands_outside_the_plot(tmp_path):
    """No train is under the legend: its box starts right of the axes' box (matplotlib's SVG: the axes background
    is the axes' first patch, the legend frame the legend group's first)."""
    import re

    svg = draw_chart(day_graph(), tmp_path / "g.svg", t0=7 * 3600.0, t1=9 * 3600.0).read_text()

    def xs(group: str) -> list[float]:
        body = svg[svg.index(f'<g id="{group}">'):]
        d = re.search(r'<path d="([^"]*)"', body).group(1)
        return [float(a) for a, _ in re.findall(r"(-?[\d.]+) (-?[\d.]+)", d)]

    axes = xs("axes_1")
    legend = xs("legend_1")
    assert min(legend) > max(axes)


def test_the_page_of_a_run_reads_only_the_windows_columns_it_draws(tmp_path):
    """The train graph of a run reads WINDOW_COLUMNS of its occupation dataset (a fourth of the columns): the same
    page data as from the whole conflict report it was written from."""
    from planner import load_line
    from planner.datasets.conflicts import check_conflicts, write_conflicts
    from planner.report.published_run import read_line_dataset
    from planner.report.train_graph import WINDOW_COLUMNS

    line = load_line(Path(__file__).resolve().parents[1] / "lines" / "sample")
    rep = check_conflicts(line, {})
    assert len(rep.occupation) and len(rep.occupation.columns) > 3 * len(WINDOW_COLUMNS)
    write_conflicts(rep, tmp_path / "run")
    occ = read_line_dataset(tmp_path / "run", "occupation", line.line_id, columns=WINDOW_COLUMNS)
    assert list(occ.columns) == list(WINDOW_COLUMNS) and len(occ) == len(rep.occupation)
    assert read_line_dataset(tmp_path / "run", "occupation", "other", columns=WINDOW_COLUMNS).empty
    whole = graph_data(line, windows=rep.occupation, conflicts=rep.conflicts)
    narrow = graph_data(line, windows=occ, conflicts=rep.conflicts)
    assert page_payload(narrow) == page_payload(whole) and page_payload(whole)["windows"]
