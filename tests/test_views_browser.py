"""The run's pages in a real headless browser: train graph, overview, changes section.

Each page is opened in Debian's ``chromium`` (driven over the DevTools pipe by
``tests/browser.py``); a page passes when it loads without console errors,
uncaught exceptions or any network request, and shows what it should: the
train paths, a tooltip naming the train under a real mouse pointer, the
stairway of a clicked train, the zoom to an hour; the overview's datasets,
pages and bundle verify status (a tampered bundle shows FAILED).

``.ci/run`` installs chromium when it is missing, so in CI this runs; on a
machine without it the tests are skipped with the reason.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from browser import Browser, find_chromium

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="needs chromium (apt-get install chromium)")


@pytest.fixture(scope="module")
def browser():
    with Browser(1200, 800) as b:
        yield b


def _clean(page) -> None:
    assert page.errors == [], page.errors
    assert page.failed == [] and page.requests == [page.url], page.requests  # self-contained: no request but the page


def test_graph_page_draws_hovers_selects_and_zooms(browser, tiny, tmp_path):
    from planner.report.train_graph import graph_data
    from planner.pages.train_graph import write_page

    data = graph_data(tiny)
    path = write_page(data, tmp_path / "g.html", train="202")
    page = browser.open(path)
    _clean(page)
    assert page.eval("document.body.dataset.ready") == "1"
    ids = page.eval("[...document.querySelectorAll('#trains path')].map(p => p.dataset.train)")
    assert sorted(ids) == sorted(t.train_id for t in tiny.trains)
    # the train given on the command line opens selected (no network here: no windows to draw)
    assert page.eval("document.getElementById('selinfo').textContent").startswith("202")
    # a real pointer over train 101 mid-run: the tooltip names it, its type and its times
    t = (data.train("101").start_s + data.train("101").end_s) / 2
    x, y = page.eval(f"(() => {{ const tr = byId.get('101'); const r = svg.getBoundingClientRect();"
                     f" return [r.left + sx({t}), r.top + sy(xAt(tr, {t}))]; }})()")
    page.mouse(x, y)
    tip = page.eval("document.getElementById('tip').innerText")
    assert "101" in tip and "EMU10" in tip and "A 06:00 → C 06:08" in tip
    page.mouse(x, y, "click")
    assert page.eval("document.getElementById('selinfo').textContent").startswith("101")
    # zoom to the 06:00 hour with its button
    page.eval("document.querySelector('button.hour[data-t0=\"21600\"]').click()")
    assert page.eval("document.getElementById('range').textContent") == "06:00 – 07:00"
    assert page.errors == []


def test_graph_page_draws_the_days_restrictions_train_numbers_and_a_km_axis(browser, tiny, tmp_path):
    """A restriction in force 05:30-06:30 on 1000-1400 m is a block at those times and chainages; each train's
    number is written at its departure in a view of three hours or less; the right axis is in km."""
    from planner.report.train_graph import graph_data
    from planner.pages.train_graph import write_page

    data = graph_data(tiny)
    data.restrictions = [("TSR-1", 1000.0, 1400.0, 19800.0, 23400.0, 40.0, "down")]
    page = browser.open(write_page(data, tmp_path / "g.html"))
    _clean(page)
    page.eval("document.querySelector('button.hour[data-t0=\"21600\"]').click()")  # 06:00-07:00
    block = page.eval("(() => { const r = document.querySelector('#restrictions rect.tsr');"
                      " return [+r.getAttribute('x'), +r.getAttribute('y'), +r.getAttribute('width'),"
                      " +r.getAttribute('height'), sx(21600), sx(23400), sy(1000), sy(1400),"
                      " r.querySelector('title').textContent]; })()")
    x, y, w, h, x_view, x_end, y_a, y_b, title = block
    assert (x, y) == pytest.approx((x_view, y_a)) and x + w == pytest.approx(x_end) and y + h == pytest.approx(y_b)
    assert title == "TSR-1: 40 km/h down, km 1.000–1.400, 05:30–06:30"
    labels = page.eval("[...document.querySelectorAll('text.train-label')].map(t => t.textContent)")
    assert sorted(labels) == sorted(t.train_id for t in tiny.trains if 21600 <= t.calls[0].departure_s < 25200)
    km = page.eval("[...document.querySelectorAll('#axis text.tick')].map(t => t.textContent).filter(s => /km/.test(s))")
    assert km and km[0].endswith(" km")
    page.eval("document.querySelector('button.hour[data-t0=\"3600\"]')?.click()")
    assert page.errors == []


def _fake_run(tmp_path: Path, line) -> Path:
    """A run folder with what the overview reads: manifest, inputs copy, one dataset, signed bundles, pages."""
    from planner.bundle.container import build_line
    from planner.bundle.signing import generate_keypair, load_private_key
    from planner.job.views import copy_inputs

    run = tmp_path / "r0002-0123456789"
    copy_inputs(line, run)
    generate_keypair(tmp_path / "keys")
    key = load_private_key(tmp_path / "keys" / "signing_key.pem")
    from test_bundle_support import release

    build_line(line, run / "bundles", key, release=release())
    shutil.copy(tmp_path / "keys" / "signing_key.pub.pem", run / "bundles" / "signing_key.pub.pem")
    (run / "report").mkdir()
    (run / "report" / "tiny_margins.html").write_text("<!DOCTYPE html><title>r</title>")
    (run / "table_a").mkdir()
    return run


def test_overview_page_lists_inputs_datasets_and_bundle_status(browser, tiny, tmp_path):
    from planner.pages.overview import write_overview

    run = _fake_run(tmp_path, tiny)
    bundles = sorted(p.name for p in (run / "bundles").glob("*.pdb"))
    # tamper with one bundle: the page must say it fails verification
    bad = run / "bundles" / bundles[0]
    data = bytearray(bad.read_bytes())
    data[600] ^= 1
    bad.write_bytes(bytes(data))
    manifest = {"run_id": run.name, "job": "nightly", "inputs_digest": "ab" * 32, "code_digest": "cd" * 32,
                "software": {"planner": "0.1.0"}, "lines": [{"line_id": "tiny", "path": "lines/tiny",
                                                              "source_digest": tiny.source_digest}],
                "parameters": {"tables": {"ds_m": 1.0}}, "timings_s": {"tables": 12.5, "graph": 0.4},
                "units_computed": {"tables": 2}, "units_reused": {"tables": 6}, "rows": {"table_a": 112},
                "flags": {"infeasible": 1, "tight": 0}, "changes": {"base_run": "r0001-9999999999",
                                                                   "lines": {"tiny": {"line_table": 1, "leg": 3}}}}
    page = browser.open(write_overview(run, manifest))
    _clean(page)
    text = page.eval("document.body.innerText")
    assert f"Run {run.name}" in text and tiny.source_digest in text
    assert "1 line table, 3 leg" in text  # what changed, per line
    status = page.eval("Object.fromEntries([...document.querySelectorAll('#bundles + table tbody tr')]"
                       ".map(r => [r.cells[0].innerText, r.cells[1].innerText]))")
    assert sorted(status) == bundles
    assert status[bundles[0]].startswith("FAILED") and all(v.startswith("verified") for k, v in status.items()
                                                           if k != bundles[0])
    rows = page.eval("Object.fromEntries([...document.querySelectorAll('#datasets + table tbody tr')]"
                     ".map(r => [r.cells[0].innerText, r.cells[1].innerText]))")
    assert rows["table_a"] == "112" and rows["changes"] == "not written"
    links = page.eval("[...document.querySelectorAll('a')].map(a => a.getAttribute('href'))")
    assert "report/tiny_margins.html" in links and "#ds-changes" in links
    assert "graph/tiny_graph.html" not in links  # only pages that exist are linked
    steps = page.eval("[...document.querySelectorAll('#steps + table tbody tr')].map(r => r.innerText)")
    assert any(s.startswith("tables\t12.5\t2\t6\tpartly reused") for s in steps), steps
    # each flag card opens where its legs are listed; a dataset opens its columns, not a folder listing
    cards = page.eval("Object.fromEntries([...document.querySelectorAll('#flags + .cards a.card')]"
                      ".map(a => [a.querySelector('.l').innerText.split(' ')[1], a.getAttribute('href')]))")
    assert cards["infeasible"] == "report/tiny_margins.html#flagged", cards
    assert cards["tight:"] == "report/tiny_margins.html#flagged", cards
    hrefs = page.eval("[...document.querySelectorAll('#datasets + table tbody tr')].map(r => r.cells[0]"
                      ".querySelector('a').getAttribute('href'))")
    assert hrefs and all(h.startswith("#ds-") for h in hrefs), hrefs


def test_changes_section_renders_in_the_report_page(browser, tmp_path):
    from planner.report.changes import LineChanges
    from planner.pages.changes import changes_html

    ch = LineChanges("tiny", "r0001-aaaaaaaaaa", "r0002-bbbbbbbbbb")
    cid = ch.add("line_table", "speed_limits", "speed restriction 4000–4200 m up civil: limit_kmh 70 → 65",
                 field_="limit_kmh", before=70.0, after=65.0, delta=-5.0)
    ch.add("leg", "EMU6 up C→B (scheduled 200 s)", "x", field_="min_running_time_s", before=129.8, after=133.1,
           delta=3.3, caused_by=[cid])
    page = browser.open(_page(tmp_path, changes_html(ch)))
    _clean(page)
    text = page.eval("document.getElementById('changes').innerText")
    assert "limit_kmh 70 → 65 — affects 1 leg" in text and "minimum 129.8 → 133.1 s (+3.3 s)" in text
    assert json.loads(page.eval("JSON.stringify(getComputedStyle(document.querySelector('#changes .up')).color)")) \
        == "rgb(198, 40, 40)"  # slower is red


def _page(tmp_path: Path, body: str) -> Path:
    p = tmp_path / "c.html"
    p.write_text("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>c</title></head><body>"
                 + body + "</body></html>")
    return p


def test_graph_page_conflict_box_is_visible_and_a_click_shows_both_stairways_and_the_overlap(browser, tmp_path):
    from planner.report.train_graph import CONFLICT_COLOUR, COLOURS, graph_data
    from planner.pages.train_graph import write_page
    from test_conflict_places import three_trains
    from test_network import P, const_curves

    line = three_trains()  # T1/T2 conflict on J and J–c (#1), T2/T3 on J–c (#2)
    data = graph_data(line, params=P, curves=const_curves(line))
    page = browser.open(write_page(data, tmp_path / "g.html"))
    _clean(page)
    assert CONFLICT_COLOUR not in COLOURS.values()
    boxes = page.eval("[...document.querySelectorAll('rect.conflict')].map(r => { const b = r.getBoundingClientRect();"
                      " return [+r.dataset.cid, b.width, b.height, b.left + b.width / 2, b.top + b.height / 2]; })")
    assert sorted(b[0] for b in boxes) == [1, 1, 2]
    assert all(w >= 11.5 and h >= 11.5 for _, w, h, _, _ in boxes)  # at least 12 px a side, whatever the zoom
    # a real pointer over conflict #2's box: the tooltip is the conflict's, with where it is
    _, _, _, x, y = next(b for b in boxes if b[0] == 2)
    page.mouse(x, y)
    tip = page.eval("document.getElementById('tip').innerText")
    assert "#2: T2 before T3 at J-c" in tip and "Station 2 (S2) track M, km 0.500–2.000" in tip
    page.mouse(x, y, "click")
    assert page.eval("document.getElementById('selinfo').textContent").startswith("#2: T2 before T3 at J-c")
    # both stairways: every window of T2 (first) and of T3 (waits), and the overlap on J–c
    stairs = page.eval("[...document.querySelectorAll('#stair rect.window')].map(r => r.dataset.train + ' ' + r.getAttribute('class'))")
    n = data.windows.groupby("train_id").size()
    assert stairs.count("T2 window a") == n["T2"] and stairs.count("T3 window b") == n["T3"] and len(stairs) == n["T2"] + n["T3"]
    ov = page.eval("[...document.querySelectorAll('#stair rect.overlap')].map(r => [+r.dataset.t0, +r.dataset.t1, +r.dataset.x0, +r.dataset.x1])")
    assert ov == [[110, 120, 500, 2000]]  # T3 opens J–c at 110 s, T2 closes it at 120 s (module doc of test_conflict_places)
    assert page.eval("location.hash") == "#conflict=2"
    assert page.eval("[...document.querySelectorAll('#highlight path')].map(p => p.getAttribute('class')).sort()") == ["sel", "sel2"]
    # a click on a train afterwards shows that train's stairway alone again
    page.eval("select('T1')")
    assert page.eval("document.querySelectorAll('#stair rect.b, #stair rect.overlap').length") == 0
    # the page opened at #conflict=1 selects it
    page = browser.open(f"{(tmp_path / 'g.html').resolve().as_uri()}#conflict=1")
    assert page.eval("document.getElementById('selinfo').textContent").startswith("#1: T1 before T2 at J and 1 more")
    assert page.errors == []
    # opened on a view that does not hold the conflict (the first minute; #2 overlaps from 110 to 120 s): it moves there
    far = write_page(data, tmp_path / "g2.html", t0=0.0, t1=60.0)
    page = browser.open(f"{far.resolve().as_uri()}#conflict=2")
    t0, t1 = page.eval("[st.t0, st.t1]")
    assert t0 <= 110 and t1 >= 120 and page.errors == []


def test_graph_links_to_the_train_table_and_its_chart(browser, tiny, tmp_path):
    """A run's pages hang together: click a train in the graph → its running-time table → a leg's chart."""
    from types import SimpleNamespace

    from planner.job.config import Job
    from planner.job.train_views import timetable_href, train_views
    from planner.job.views import graph_links
    from planner.report.margins import compute_margins
    from planner.report.train_graph import graph_data
    from planner.pages.train_graph import write_page

    run = tmp_path / "r0003-0123456789"
    import dataclasses

    job = Job(str(tmp_path / "job.toml"), str(tmp_path))
    job = dataclasses.replace(job, parallel=dataclasses.replace(job.parallel, n_jobs=1))
    summary = SimpleNamespace(rows={})
    from planner.job.cache import Cache
    from planner.job.units import Progress, Runner

    runner = Runner(job, Cache(tmp_path / "cache"), Progress(enabled=False))  # the job's units, cached
    legs = train_views(job, tiny, run, compute_margins(tiny, conflicts=False), runner, summary)
    assert legs == {"101": [("A→B", "charts/tiny/down_EMU10_A-B_200s.html"),
                            ("B→C", "charts/tiny/down_EMU10_B-C_270s.html")],
                    "202": [("C→A", "charts/tiny/up_EMU6_C-A_500s.html")]}  # the timetable's legs (tests/linedb.py)
    assert summary.rows == {"train_timetable": 6}
    data = graph_data(tiny)
    (run / "graph").mkdir()
    graph = write_page(data, run / "graph" / "tiny_graph.html", timetable_href="../" + timetable_href("tiny"),
                       charts={t: [(lbl, "../" + h) for lbl, h in v] for t, v in legs.items()},
                       links=graph_links("tiny"))
    page = browser.open(graph)
    _clean(page)
    # the top links: overview, margin report and tables of the same run (line_views writes them: index.html and
    # report/ are the run_views' pages, not made here)
    assert page.eval("[...document.querySelectorAll('#top a')].map(a => [a.innerText, a.href])") == [
        ["overview", (run / "index.html").as_uri()], ["margin report", (run / "report" / "tiny_margins.html").as_uri()],
        ["running-time tables", (run / "timetable" / "tiny_timetable.html").as_uri()]]
    assert page.eval("getComputedStyle(document.getElementById('tt-link')).display") == "none"  # nothing selected
    t = (data.train("202").start_s + data.train("202").end_s) / 2
    x, y = page.eval(f"(() => {{ const tr = byId.get('202'); const r = svg.getBoundingClientRect();"
                     f" return [r.left + sx({t}), r.top + sy(xAt(tr, {t}))]; }})()")
    page.mouse(x, y)
    page.mouse(x, y, "click")
    href = page.eval("document.getElementById('tt-link').href")
    assert href == (run / "timetable" / "tiny_timetable.html").as_uri() + "#train-202"
    from_graph = page.eval("[...document.querySelectorAll('#chart-links a')].map(a => [a.innerText, a.href])")
    assert from_graph == [["C→A", (run / "charts" / "tiny" / "up_EMU6_C-A_500s.html").as_uri()]]
    table = browser.open(href)
    assert table.errors == [] and table.failed == [] and table.requests == [href.split("#")[0]]  # no network
    assert table.eval("document.querySelector(':target').id") == "train-202"
    assert table.eval("window.scrollY > 0 || document.body.scrollHeight <= innerHeight")
    calls = table.eval("[...document.querySelectorAll('#train-202 tr')].slice(1).map(r => r.cells[1].innerText)")
    assert calls == ["departs", "passes", "arrives"]
    charts = table.eval("[...document.querySelectorAll('#train-202 a')].filter(a => a.innerText === 'chart')"
                        ".map(a => a.href)")
    assert charts == [(run / "charts" / "tiny" / "up_EMU6_C-A_500s.html").as_uri()]  # one leg, on the stop ending it
    chart = browser.open(charts[0])
    _clean(chart)
    assert chart.eval("document.querySelectorAll('.fig > svg').length") == 1
    assert "202" in chart.eval("[...document.querySelectorAll('a')].map(a => a.innerText)")
    back = chart.eval("[...document.querySelectorAll('a')].find(a => a.innerText === '202').href")
    assert back == href
    # and back from the table to the graph, on that train's run
    to_graph = table.eval("document.querySelector('#train-202 a[href*=\"_graph.html\"]').href")
    assert to_graph == graph.as_uri() + "#train=202"
    again = browser.open(to_graph)
    assert again.errors == [] and again.eval("st.sel.id") == "202"
    tr = data.train("202")
    # its run with ten minutes either side, moved to start at 06:00, where the day starts (202 leaves at 06:05)
    assert tr.start_s - 600 < 21600 and again.eval("[st.t0, st.t1]") == [21600, 21600 + tr.end_s - tr.start_s + 1200]


def _view(page) -> list:
    return page.eval("[st.t0, st.t1]")


def test_graph_opens_on_the_peak_fills_the_window_and_zooms_to_a_train_named_in_any_case(browser, tmp_path):
    """The day of tests/test_graph.py's day_graph: the page opens on 07:00-09:00 (worked by hand there), the whole
    day one click away; #train=ID (any case) selects that train and shows its run, as the search box does; the
    plot reaches the bottom of the window at any window height."""
    from test_graph import day_graph

    from planner.pages.train_graph import write_page

    path = write_page(day_graph(), tmp_path / "two_graph.html")
    page = browser.open(path)
    _clean(page)
    h = 3600
    assert _view(page) == [7 * h, 9 * h] and page.eval("document.getElementById('range').textContent") == "07:00 – 09:00"
    assert page.eval("document.querySelector('#hours button.on').textContent") == "morning peak 07:00–09:00"
    page.eval("document.querySelector('#hours button.day').click()")
    assert _view(page) == [5 * h, 23 * h]  # the whole day, one click
    # the plot fills the window below the bars: its bottom within the last 20 px of the viewport, at 800 and 1100 px
    bottom = "document.getElementById('wrap').getBoundingClientRect().bottom"
    assert 800 - 20 <= page.eval(bottom) <= 800
    browser.send("Emulation.setDeviceMetricsOverride", {"width": 1200, "height": 1100, "deviceScaleFactor": 1,
                                                         "mobile": False}, session=page.session)
    page.eval("new Promise(r => requestAnimationFrame(() => setTimeout(r, 0)))")
    assert 1100 - 20 <= page.eval(bottom) <= 1100 and page.eval("innerHeight") == 1100
    # #train=m4 opens on train M4 (08:30-09:00) with ten minutes either side, highlighted
    page = browser.open(f"{path.resolve().as_uri()}#train=m4")
    assert page.errors == [] and page.requests == [path.resolve().as_uri()]
    assert page.eval("document.getElementById('selinfo').textContent").startswith("M4")
    assert _view(page) == [8 * h + 1200, 9 * h + 600]
    assert page.eval("document.querySelector('#highlight path.sel').dataset.train") == "M4"
    # a link within the page (the hash changes): that train, its run
    page.eval("location.hash = '#train=E1'; new Promise(r => setTimeout(r, 50))")
    assert page.eval("st.sel.id") == "E1" and _view(page) == [5 * h, 5 * h + 3000]  # 05:00 is the day's start
    # the search box: any case too; an unknown id is marked, the selection stays
    page.eval("const f = document.getElementById('find'); f.value = ' M1 '; f.dispatchEvent(new Event('change'))")
    assert page.eval("st.sel.id") == "m1" and _view(page) == [7 * h - 300, 7 * h + 2700]
    page.eval("const g = document.getElementById('find'); g.value = 'zz'; g.dispatchEvent(new Event('change'))")
    assert page.eval("st.sel.id") == "m1" and page.eval("document.getElementById('find').style.background") != ""
    page = browser.open(f"{path.resolve().as_uri()}#train=nope")
    assert page.eval("document.getElementById('selinfo').textContent") == "no train nope on this line"
    assert _view(page) == [7 * h, 9 * h] and page.errors == []
