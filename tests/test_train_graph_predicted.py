"""The train graph shows the predicted day beside the lines: each late train's events from ``delay_events``.

A synthetic ``delay_events`` frame on the tiny line (tests/linedb.py: 101 down A→B→C stopping at B, 202 up C→B→A
passing B): 101 is 30 s late at B and 12 s at C, 202 only 0.3 s (rounding, not late). The graph keeps exactly
101, a point per event at its predicted time and the station's stop marker for its direction; the page embeds
it with a toggle, escapes what the data says, and is the page it was when there is no predicted day.
"""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pandas as pd
import pytest

from planner.pages.train_graph import page_payload, predicted_summary, render_page, write_page
from planner.report.graph_predicted import LATE_S, PREDICTED_COLUMNS, largest_delay, predicted_paths
from planner.report.train_graph import graph_data, train_paths

HOSTILE = "</script><script>alert(1)</script><!--<script> & 'x' \"y\""
LATE = {("101", 1, "arrival"): 30.0, ("101", 1, "departure"): 30.0, ("101", 2, "arrival"): 12.0,
        ("202", 2, "arrival"): 0.3}
CAUSES = {("101", 1, "arrival"): "its run from A needs 230.0 s, 200.0 s scheduled",
          ("101", 2, "arrival"): HOSTILE}


@pytest.fixture(scope="module")
def paths(tiny):
    return train_paths(tiny)


def delay_events(line, late=LATE, causes=CAUSES) -> pd.DataFrame:
    """Every event of the line's trains as the ``delay_events`` dataset has it, ``late`` (train, seq, event) →
    delay [s], rows shuffled (the graph puts them in running order)."""
    rows = []
    for t in line.trains:
        for c in t.calls:
            for ev, s in (("arrival", c.arrival_s), ("departure", c.departure_s)):
                if math.isnan(s):
                    continue
                d = late.get((t.train_id, c.seq, ev), 0.0)
                cause = causes.get((t.train_id, c.seq, ev), "")
                rows.append(dict(train_id=t.train_id, train_type=t.train_type, direction=t.direction, seq=c.seq,
                                 station_id=c.station_id, event=ev, scheduled_s=s, computed_s=s, predicted_s=s + d,
                                 delay_s=d, own_delay_s=d, knock_on_s=0.0, cause_kind="run" if cause else "",
                                 cause_train="", cause=cause))
    rows.append(dict(rows[0], train_id="999", delay_s=60.0, predicted_s=rows[0]["scheduled_s"] + 60))  # not drawn
    return pd.DataFrame(rows).sample(frac=1.0, random_state=3).reset_index(drop=True)


def _payload(page: str) -> dict:
    return json.loads(page.split("id='graph-data'>")[1].split("</script>")[0])


def test_exactly_the_late_trains_with_a_point_per_event(tiny, paths):
    data = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny))
    assert list(data.predicted) == ["101"]  # 202's 0.3 s is below LATE_S; 999 is not on the graph
    p = data.predicted["101"]
    assert p.direction == "down" and p.station_ids == ("A", "B", "B", "C")
    assert p.events == ("departure", "arrival", "departure", "arrival")
    np.testing.assert_allclose(p.scheduled_s, [21600.0, 21800.0, 21830.0, 22100.0])
    np.testing.assert_allclose(p.t_s, [21600.0, 21830.0, 21860.0, 22112.0])
    np.testing.assert_allclose(p.x_m, [260.0, 2560.0, 2560.0, 4860.0])  # the stop markers down: where 101 stands
    np.testing.assert_allclose(p.delay_s, [0.0, 30.0, 30.0, 12.0])
    assert p.late.tolist() == [1, 2, 3] and p.max_delay_s == 30.0
    assert p.causes == ("", CAUSES[("101", 1, "arrival")], "", HOSTILE)
    # the drawn run of 101 stands at B's stop marker: the points sit on its line's flat step
    tp = next(t for t in paths if t.train_id == "101")
    assert 2560.0 in set(tp.x_m.tolist())
    # an up train's points stand at the up stop markers
    up = predicted_paths(tiny, delay_events(tiny, late={("202", 1, "arrival"): 5.0}), paths)
    assert list(up) == ["202"] and up["202"].x_m.tolist() == [4740.0, 2440.0, 2440.0, 140.0]
    best, i = largest_delay(data.predicted)
    assert (best.train_id, i) == ("101", 1)
    assert predicted_summary(data) == ("1 train late on the predicted day, the largest 30 s (101 at B, arrival "
                                       "06:03:50)")
    # no late train: known, and said; no frame: not known
    none = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny, late={}))
    assert none.predicted == {} and predicted_summary(none) == "no train late on the predicted day"
    assert graph_data(tiny, paths=paths, check=False).predicted is None
    assert predicted_paths(tiny, delay_events(tiny).iloc[:0], paths) == {}
    assert LATE_S == 0.5 and set(PREDICTED_COLUMNS) <= set(delay_events(tiny).columns)


def test_the_page_has_the_toggle_and_the_late_trains_data(tiny, paths):
    data = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny))
    page = render_page(data)
    assert "<input type='checkbox' id='show-predicted' checked> predicted</label>" in page
    assert "dashed: predicted (delays carried forward)" in page
    assert "1 train late on the predicted day, the largest 30 s (101 at B, arrival 06:03:50)" in page
    pr = _payload(page)["predicted"]
    assert pr == page_payload(data)["predicted"]
    names = [s[0] for s in _payload(page)["stations"]]
    (t,) = pr["trains"]
    assert t["id"] == "101" and [names[i] for i in t["st"]] == ["A", "B", "B", "C"] and t["e"] == "dada"
    assert np.cumsum(t["t"]).tolist() == [216000, 218300, 218600, 221120]  # 0.1 s, delta-coded as the trains
    assert t["o"] == [0, 300, 300, 120] and t["late"] == [1, 2, 3]  # predicted − scheduled [0.1 s]
    assert [pr["causes"][k] for _, k in t["c"]] == [CAUSES[("101", 1, "arrival")], HOSTILE]
    assert [i for i, _ in t["c"]] == [1, 3] and pr["causes"][0] == ""
    assert [pr["stops"]["down"][names.index(s)] for s in "ABC"] == [260, 2560, 4860]
    # deterministic: the same bytes again, and from the rows in another order
    again = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny).iloc[::-1])
    assert render_page(again) == page == render_page(data)


def test_a_hostile_cause_and_train_id_are_escaped(tiny, paths):
    data = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny))
    page = render_page(data)
    body = page.split("id='graph-data'>")[1]
    script = body.split("</script>")[0]
    assert "<" not in script  # neither "</script" nor "<!--" can come out of the data
    assert HOSTILE in json.loads(script)["predicted"]["causes"]  # the same string to the script
    assert page.count("</script>") == 2 and "<!--" not in page and "alert(1)</script>" not in page
    # a train id is data too: escaped in the header's words
    evil = "<b>x</b>&"
    ren = [dataclasses.replace(t, train_id=evil) if t.train_id == "101" else t for t in paths]
    ev = delay_events(tiny)
    ev.loc[ev.train_id == "101", "train_id"] = evil
    page = render_page(graph_data(tiny, paths=ren, check=False, delay_events=ev))
    assert "<b>x</b>&" not in page.split("<script")[0] and "&lt;b&gt;x&lt;/b&gt;&amp; at B" in page
    assert _payload(page)["predicted"]["trains"][0]["id"] == evil


def test_without_a_predicted_day_the_page_is_as_it_was(tiny, paths):
    before = render_page(graph_data(tiny, paths=paths, check=False))
    assert render_page(graph_data(tiny, paths=paths, check=False, delay_events=None)) == before
    html = before.split("<script")[0]  # the page's own elements (the script knows of a predicted day, unused)
    assert "show-predicted" not in html and "dashed: predicted" not in html and "predicted day" not in html
    assert "each line is the train front's predicted run" in html
    assert "predicted" not in _payload(before)
    # a predicted day without a late train: said in the header, nothing drawn
    page = render_page(graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny, late={})))
    assert "no train late on the predicted day" in page and "show-predicted" not in page.split("<script")[0]
    assert "predicted" not in _payload(page)


def test_the_runs_page_reads_delay_events(tiny, paths, tmp_path):
    """The job's page reads the run's delay_events (as the line's conflicts step writes them, a part per section)
    and draws the late train; a run without the dataset gives the page without a predicted day."""
    from planner.datasets.delays import DELAY_EVENTS_SCHEMA, _write
    from planner.job.cache import Cache
    from planner.job.units import Stored
    from planner.job.views import _page_unit, graph_head, graph_written

    cache = Cache(tmp_path / "cache")
    cache.put("graph", "ab" * 32, paths)  # the section's trajectories, as its graph unit stores them

    def page(stage):
        share = _page_unit(tiny, Stored(str(cache.root), "graph", "ab" * 32), str(stage), "0", True)
        cache.put("graph", "cd" * 32, share)
        graph_written(str(cache.root), ["cd" * 32], stage, graph_head(tiny), {}, "", False)
        return (stage / "graph" / "tiny_graph.html").read_text()

    assert "predicted" not in _payload(page(tmp_path / "none"))
    _write(delay_events(tiny), DELAY_EVENTS_SCHEMA, tmp_path / "run", "delay_events", "tiny")
    got = page(tmp_path / "run")
    assert [t["id"] for t in _payload(got)["predicted"]["trains"]] == ["101"] and "id='show-predicted'" in got
    # the same page as the whole line's graph data gives (one section here)
    data = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny))
    assert _payload(got)["predicted"] == page_payload(data)["predicted"]


def test_the_page_in_a_browser_draws_the_late_trains_dashed(tiny, paths, tmp_path):
    from browser import Browser, find_chromium

    if find_chromium() is None:
        pytest.skip("needs chromium (apt-get install chromium)")
    data = graph_data(tiny, paths=paths, check=False, delay_events=delay_events(tiny))
    path = write_page(data, tmp_path / "g.html", train="101")
    with Browser(1200, 800) as b:
        page = b.open(path)
        assert page.errors == [], page.errors
        assert page.requests == [page.url] and page.eval("document.body.dataset.ready") == "1"
        segs = page.eval("[...document.querySelectorAll('#predicted path.pred')].map(p => [p.dataset.train,"
                         " p.getAttribute('stroke-dasharray'), p.getAttribute('stroke'), p.querySelector('title').textContent])")
        # 101's late stretch: A→B (arrives late), the dwell at B, B→C; in its colour, dashed
        assert [s[0] for s in segs] == ["101"] * 3 and {s[1] for s in segs} == {"5 3"}
        colour = page.eval("byId.get('101').path.getAttribute('stroke')")
        assert {s[2] for s in segs} == {colour}
        assert segs[0][3] == ("101 arrival at Bashi (B): scheduled 06:03:20 → predicted 06:03:50, 30 s late · "
                              "its run from A needs 230.0 s, 200.0 s scheduled")
        assert segs[2][3] == f"101 arrival at Chuo (C): scheduled 06:08:20 → predicted 06:08:32, 12 s late · {HOSTILE}"
        assert page.eval("document.querySelectorAll('#predicted path.pred-dot').length") == 3
        assert page.eval("document.querySelectorAll('script').length") == 2  # the cause made no element
        # the run follows 101's drawn line from A to B, 30 s later where it arrives
        d = page.eval("document.querySelector('#predicted path.pred').getAttribute('d')")
        pts = [tuple(map(float, q.split())) for q in d[1:].split("L")]
        assert pts[0] == (21600.0, 260.0) and pts[-1] == (21830.0, 2560.0) and len(pts) > 2
        # the selected train's predicted run is drawn over its highlight; the toggle hides it all
        assert page.eval("document.querySelectorAll('#highlight .sel.pred').length") == 6
        page.eval("document.getElementById('show-predicted').click()")
        assert page.eval("getComputedStyle(document.getElementById('predicted')).display") == "none"
        assert page.eval("document.querySelectorAll('#highlight .pred').length") == 0
        assert page.errors == []
