"""Sections of a line (planner.network.sections): each section's check gives what the whole line's gives.

The line here is two copies of the sample line joined end to end (``benchmarks/big_line.py``: no train runs
over the junction), so its trains fall into two groups that share no track. Every expected value comes from
the whole line's own check, computed here beside the sections'.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest

from planner.datasets.conflicts import conflict_report, renumbered
from planner.delay.predicted import predict_day
from planner.line.loader import load_line
from planner.network.check import check_timetable
from planner.network.routes import TrackGraph, plan_routes
from planner.network.sections import Section, line_sections, section_line, stream_of, train_span

ROOT = Path(__file__).resolve().parents[1]


def _big_line_module():
    spec = importlib.util.spec_from_file_location("big_line", ROOT / "benchmarks" / "big_line.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def joined(tmp_path_factory):
    """Two copies of the sample line, end to end."""
    return load_line(_big_line_module().build(2, tmp_path_factory.mktemp("joined")))


def _sections(line, connections=()):
    g = TrackGraph(line)
    return line_sections(line, g, plan_routes(line, g, unrouted={}), connections)


def test_joined_copies_are_two_sections_apart(joined):
    secs = _sections(joined)
    assert len(secs) == 2
    copy = [{t.train_id for t in joined.trains if t.train_id.endswith(s)} for s in ("-k00", "-k01")]
    assert [set(s.train_ids) for s in secs] == copy
    assert secs[0].hi_m < secs[1].lo_m  # apart along the line, not only on other tracks
    order = [t.train_id for t in joined.trains]
    for s in secs:  # the line's timetable order
        assert list(s.train_ids) == [t for t in order if t in set(s.train_ids)]


def test_a_train_span_covers_its_route_and_its_legs(joined):
    g = TrackGraph(joined)
    routes = plan_routes(joined, g, unrouted={})
    t = joined.trains[0]
    lo, hi = train_span(joined, g, routes[t.train_id], t)
    r = routes[t.train_id]
    assert lo <= g.pos_m[r.node_idx].min() and g.pos_m[r.node_idx].max() <= hi
    calls = t.stop_calls()
    a, b = joined.window_m(calls[0].station_id, calls[1].station_id, t.train_type)
    assert lo <= a and b <= hi


def test_the_sample_is_one_section_and_sees_the_whole_line(sample_line):
    secs = _sections(sample_line)
    assert len(secs) == 1 and len(secs[0].train_ids) == len(sample_line.trains)
    assert section_line(sample_line, secs[0]) is sample_line
    assert stream_of(secs[0], sample_line) == ()


def test_a_connection_joins_two_sections(joined):
    a = next(t.train_id for t in joined.trains if t.train_id.endswith("-k00"))
    b = next(t.train_id for t in joined.trains if t.train_id.endswith("-k01"))
    secs = _sections(joined, [(a, b, "X", 60.0)])
    assert len(secs) == 1


def test_the_sections_are_kept_over_a_speed_limit_edit_and_made_again_when_the_trains_change(joined, tmp_path):
    """The job keeps the line's sections in its work cache (planner.job.steps.line_sections_kept): a speed limit
    lowered (each day's restrictions, the usual edit) finds them; a train taken out, or a connection added, makes
    them again. Every answer is the sections planned afresh for the line as it is then."""
    import dataclasses

    from planner.job.cache import Cache
    from planner.job.steps import line_sections_kept

    cache = Cache(tmp_path / "cache")
    assert line_sections_kept(joined, [], cache) == _sections(joined) and (cache.hits, cache.misses) == (0, 1)
    lim = joined.speed_limits[0]
    slower = dataclasses.replace(joined, speed_limits=(dataclasses.replace(lim, limit_ms=lim.limit_ms * 0.5),)
                                 + joined.speed_limits[1:])
    assert line_sections_kept(slower, [], cache) == _sections(slower) and cache.hits == 1
    fewer = dataclasses.replace(joined, trains=joined.trains[1:])
    got = line_sections_kept(fewer, [], cache)
    assert cache.misses == 2 and got == _sections(fewer) and got != _sections(joined)
    a = next(t.train_id for t in joined.trains if t.train_id.endswith("-k00"))
    b = next(t.train_id for t in joined.trains if t.train_id.endswith("-k01"))
    joined_up = line_sections_kept(joined, [(a, b, "X", 60.0)], cache)
    assert cache.misses == 3 and len(joined_up) == 1


def test_each_section_checks_as_the_whole_line(joined):
    whole = check_timetable(joined)
    rep = conflict_report(whole)
    secs = _sections(joined)
    checks = [check_timetable(section_line(joined, s)) for s in secs]
    reps = [conflict_report(c) for c in checks]
    # the section's line is smaller: what a unit ships and digests is its stretch
    small = section_line(joined, secs[1])
    assert len(small.stations) < len(joined.stations) and len(small.network.nodes) < len(joined.network.nodes)
    occ = pd.concat([r.occupation for r in reps]).sort_values(["train_id", "seq"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(occ, rep.occupation.sort_values(["train_id", "seq"]).reset_index(drop=True))
    heads = pd.concat([r.headways for r in reps]).sort_values(
        ["from_m", "to_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
    pd.testing.assert_frame_equal(heads, rep.headways)
    # the conflicts numbered across the sections as the whole line numbers them (ids included)
    assert all(len(r.conflicts) for r in reps)  # both sections have conflicts: the numbering interleaves them
    pd.testing.assert_frame_equal(renumbered([r.conflicts for r in reps]), rep.conflicts)


def test_each_section_predicts_its_day_as_the_whole_line(joined):
    whole = predict_day(check_timetable(joined), min_dwell_s=20.0)
    delay = dict(zip(zip(np.asarray(whole.net.train_ids)[whole.net.ev_train], whole.net.ev_seq.tolist(),
                         whole.net.ev_kind.tolist()), whole.delay_s))
    n = 0
    for s in _sections(joined):
        day = predict_day(check_timetable(section_line(joined, s)), min_dwell_s=20.0)
        for key, d in zip(zip(np.asarray(day.net.train_ids)[day.net.ev_train], day.net.ev_seq.tolist(),
                              day.net.ev_kind.tolist()), day.delay_s):
            assert d == delay[key]
            n += 1
    assert n == whole.net.n_events and whole.delay_s.max() > 0  # some train is late: the day is not trivial


def test_streams_differ_per_section_and_do_not_move_with_the_others(joined):
    secs = _sections(joined)
    s0, s1 = (stream_of(s, joined) for s in secs)
    assert s0 != s1 and s0 and s1
    # the stream is the section's own: a section with the same first train draws the same
    assert stream_of(Section(secs[1].train_ids, 0.0, 1.0), joined) == s1


def test_merged_summary_weights_by_arrivals():
    from planner.job.robustness import merged_summary

    a = {"days": 10, "seed": 1, "trains": 2, "events": 8, "activities": 9, "dropped": 0, "day_conflicts": 1,
         "knock_on_conflicts": 1, "knock_on_places": ["B", "A"], "late_trains": 1, "max_delay_s": 30.0,
         "within_60s": 0.5}
    b = {**a, "trains": 3, "events": 12, "knock_on_places": ["C"], "max_delay_s": 90.0, "within_60s": 1.0}
    m = merged_summary([(a, 1), (b, 3)])
    assert m["trains"] == 5 and m["events"] == 20 and m["knock_on_places"] == ["A", "B", "C"]
    assert m["max_delay_s"] == 90.0 and m["within_60s"] == pytest.approx((0.5 * 1 + 1.0 * 3) / 4)
    assert m["days"] == 10 and merged_summary([(a, 1)]) is a


def test_section_line_keeps_every_track_piece_of_its_nodes(joined):
    sec = _sections(joined)[0]
    small = section_line(joined, sec)
    kept = {n.node_id for n in small.network.nodes}
    inside = {n.node_id for n in joined.network.nodes if sec.lo_m <= n.position_m <= sec.hi_m}
    assert inside <= kept
    for e in joined.network.edges:
        if e.from_node in inside or e.to_node in inside:
            assert e in small.network.edges


def _job(tmp: Path, line_dir: Path, out: Path):
    from planner.job.config import load_job

    text = (ROOT / "jobs" / "nightly.toml").read_text()
    text = text.replace('lines = ["lines/sample"]', f'lines = ["{line_dir}"]')
    text = text.replace('output_root = "outputs"', f'output_root = "{out}"')
    text = text.replace('feeds = ["feeds/sample"]', "feeds = []")
    text = text.replace("days = 1000 ", "days = 64 ")
    p = tmp / f"{out.name}.toml"
    p.write_text(text)
    return load_job(p)


def _rows(run: Path, dataset: str) -> pd.DataFrame:
    from planner.io.parquet import read_dataset

    t = read_dataset(run, dataset)
    return t.drop_columns([c for c in ("run_id", "run_date") if c in t.column_names]).to_pandas()


def test_an_edit_in_one_section_recomputes_that_section_and_publishes_what_a_cold_run_does(tmp_path):
    import pyarrow.parquet as pq

    from planner.job.pipeline import run_job

    folder = _big_line_module().build(2, tmp_path / "line")
    first = run_job(_job(tmp_path, folder, tmp_path / "out"), show_progress=False)
    assert first.computed["conflicts"] == 2
    # a part per section in each partition of the line's datasets
    assert {p.name for p in (first.run_dir / "occupation").rglob("*.parquet")} == {"part-0.parquet", "part-1.parquet"}
    assert {p.name for p in (first.run_dir / "delay_events").rglob("*.parquet")} == {"part-0.parquet",
                                                                                       "part-1.parquet"}
    # one speed limit of the second copy lowered
    line = load_line(folder)
    lo = _sections(line)[1].lo_m
    t = pq.read_table(folder / "speed_limits.parquet")
    lim = t.column("limit_kmh").to_numpy().copy()
    row = int(np.flatnonzero(t.column("start_m").to_numpy() > lo)[0])
    lim[row] *= 0.8
    i = t.column_names.index("limit_kmh")
    pq.write_table(t.set_column(i, t.schema.field(i), pa.array(lim)), folder / "speed_limits.parquet")
    edit = run_job(_job(tmp_path, folder, tmp_path / "out"), show_progress=False)
    assert (edit.computed["conflicts"], edit.reused["conflicts"]) == (1, 1)
    # the section the edit did not reach keeps the previous run's files (linked: the same inode), the other's are new
    from planner.io.parquet import without_run

    for name in ("occupation", "delay_events", "robustness_trains"):
        old, new = ({without_run(p.relative_to(r).as_posix()): p.stat().st_ino for p in (r / name).rglob("*.parquet")}
                    for r in (first.run_dir, edit.run_dir))
        assert old.keys() == new.keys() and len(new) >= 2, name
        assert all((new[k] == old[k]) == k.endswith("/part-0.parquet") for k in new), name
    assert (edit.computed["timetable"], edit.reused["timetable"]) == (1, 1)  # the tables of the edited section
    # the train graph: the edited section's trajectories and share of the page (2), the other's reused (2)
    assert (edit.computed["graph"], edit.reused["graph"]) == (2, 2)
    cold = run_job(_job(tmp_path, folder, tmp_path / "cold"), show_progress=False, use_cache=False)
    for name in ("conflicts", "headways", "occupation", "delay_events", "robustness_trains", "robustness_stations",
                 "train_timetable"):
        pd.testing.assert_frame_equal(_rows(edit.run_dir, name), _rows(cold.run_dir, name), obj=name)
    page = f"timetable/{line.line_id}_timetable.html"
    assert ((edit.run_dir / page).read_text().replace(edit.run_dir.name, "RUN")
            == (cold.run_dir / page).read_text().replace(cold.run_dir.name, "RUN"))
    assert edit.robustness == cold.robustness
    assert len(_rows(cold.run_dir, "conflicts"))  # the check is not empty
    graph = f"graph/{line.line_id}_graph.html"
    assert ((edit.run_dir / graph).read_text().replace(edit.run_dir.name, "RUN")
            == (cold.run_dir / graph).read_text().replace(cold.run_dir.name, "RUN"))
    # the page put together from the sections' shares is the page of the whole line's graph data at once
    _same_graph_page_as_the_whole_lines(load_line(folder), cold.run_dir)  # the edited line


def _same_graph_page_as_the_whole_lines(line, run: Path) -> None:
    import html
    import json

    from planner.job.views import _graph_unit, graph_links
    from planner.pages.train_graph import render_page
    from planner.report.graph_predicted import PREDICTED_COLUMNS
    from planner.report.published_run import read_line_dataset
    from planner.report.train_graph import WINDOW_COLUMNS, graph_data

    lid = line.line_id
    got = (run / "graph" / f"{lid}_graph.html").read_text()
    data = graph_data(line, paths=_graph_unit(line, True), check=False,
                      windows=read_line_dataset(run, "occupation", lid, columns=WINDOW_COLUMNS),
                      conflicts=read_line_dataset(run, "conflicts", lid),
                      margin_totals=read_line_dataset(run, "margin_totals", lid),
                      delay_events=read_line_dataset(run, "delay_events", lid, columns=PREDICTED_COLUMNS))
    payload = json.loads(got.split("id='graph-data'>")[1].split("</script>")[0])
    # both sections' trains are drawn with windows, conflicts and a predicted day: the merge has work to do
    assert {t["id"][-4:] for t in payload["trains"]} == {"-k00", "-k01"}
    assert {t[-4:] for t in payload["windows"]} == {"-k00", "-k01"} and payload["conflicts"]
    assert {t["id"][-4:] for t in payload["predicted"]["trains"]} == {"-k00", "-k01"}
    # the links to the legs' charts and the run's words are what the job gave the page (not made by the merge)
    legs = payload["charts"]["legs"]
    charts = {t: [tuple(legs[i]) for i in v] for t, v in payload["charts"]["by_train"].items()}
    label = html.unescape(got.split("<span id='run'>")[1].split("</span>")[0])
    expect = render_page(data, run_label=label, timetable_href=f"../timetable/{lid}_timetable.html", charts=charts,
                         links=graph_links(lid))
    assert got == expect


def test_each_section_draws_the_train_graph_as_the_whole_line(joined):
    from planner.job.views import _graph_unit

    whole = _graph_unit(joined, True)
    parts = [_graph_unit(section_line(joined, s), True) for s in _sections(joined)]
    order = {t.train_id: i for i, t in enumerate(joined.trains)}
    merged = sorted((p for part in parts for p in part), key=lambda p: order[p.train_id])
    assert [p.train_id for p in merged] == [p.train_id for p in whole]
    assert any(p.loop_stations for p in whole)  # a train stands in a loop: the routes are part of the answer
    for a, b in zip(merged, whole):
        assert a.calls == b.calls and a.loop_stations == b.loop_stations
        np.testing.assert_array_equal(a.t_s, b.t_s)
        np.testing.assert_array_equal(a.x_m, b.x_m)


def test_a_stored_unit_is_read_where_it_is_used_and_given_back_when_damaged(tmp_path):
    """A read on a worker takes the unit's key, not its inputs: an entry it trusts gives what the job keeps of it;
    a damaged one gives nothing but why (the job has the unit computed again and stored: test_cache_probes)."""
    from planner.job.cache import Cache
    from planner.job.units import _read_kept

    cache = Cache(tmp_path / "c")
    key = "ab" * 32
    cache.put("conflicts", key, {"x": np.arange(3.0)})
    assert cache.present("conflicts", key) and not cache.present("conflicts", "cd" * 32)
    kept, why = _read_kept(cache, "conflicts", key, len)
    assert (kept, why) == (1, None)
    path = cache.path("conflicts", key)
    data = bytearray(path.read_bytes())
    data[-1] ^= 0xFF  # one bit of the payload flipped
    path.write_bytes(bytes(data))
    kept, why = _read_kept(cache, "conflicts", key, len)
    assert kept is None and "digest" in why
    kept, why = _read_kept(cache, "conflicts", "cd" * 32, len)
    assert kept is None and why == "missing"
    assert Cache(tmp_path / "c", enabled=False).present("conflicts", key) is False  # --no-cache reads nothing


def test_the_tables_page_and_dataset_put_together_from_sections_are_the_whole_lines(joined, tmp_path):
    """The running-time tables are made a unit per section (planner.job.train_views) and put together on one page
    and one dataset: the same bytes as the page and dataset made from the whole line's rows at once."""
    from planner.io.parquet import read_dataset
    from planner.job.cache import Cache
    from planner.job.train_views import TimetablePart, timetable_units, timetable_written
    from planner.pages.timetable import render_page
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import leg_times, planned_legs, timetable_rows, write_timetable

    rows = compute_margins(joined, conflicts=False).rows
    runs = leg_times(joined, rows)  # recorded here, at once; the sections' units record their own legs'
    planned = planned_legs(joined, rows)
    types = sorted(set(rows["train_type"]))
    lid = joined.line_id
    page = dict(run_id="r0001-0123456789", day=None, run_date="2026-12-06")
    links = [("overview", "../index.html"), ("margin report", f"../report/{lid}_margins.html"),
             ("train graph", f"../graph/{lid}_graph.html")]
    whole = timetable_rows(joined, runs, set(types))
    expect = render_page(lid, joined.name, whole, links=links, graph_href=f"../graph/{lid}_graph.html", **page)
    write_timetable(joined, runs, tmp_path / "whole", set(types), whole)

    secs = _sections(joined)
    assert len(secs) == 2
    parts = [TimetablePart(section_line(joined, s), str(i), f"section {i}", None) for i, s in enumerate(secs)]
    units = timetable_units(joined, planned, {k: f"chart {k}" for k in planned}, types, tmp_path / "run", parts)
    cache = Cache(tmp_path / "cache")
    for u in units:
        assert 0 < len(u.args[1]) < len(planned)  # each section is given its own legs only
        cache.put("timetable", u.key, u.fn(*u.args))
    legs, files = timetable_written(str(cache.root), [u.key for u in units], tmp_path / "run", lid, joined.name, page)
    got = (tmp_path / "run" / "timetable" / f"{lid}_timetable.html").read_text()
    assert got == expect
    assert expect.count('<section class="tt"') == len({r["train_id"] for r in whole}) > 100
    assert len(files) == len(list((tmp_path / "whole").rglob("*.parquet")))
    a = read_dataset(tmp_path / "run", "train_timetable").to_pandas()
    b = read_dataset(tmp_path / "whole", "train_timetable").to_pandas()
    pd.testing.assert_frame_equal(a, b)
    for t in {r["train_id"] for r in whole}:
        ends = [(f"{r['leg_origin']}→{r['station_id']}", r["chart"]) for r in whole
                if r["train_id"] == t and r["chart"] and r["leg_flag"]]
        assert legs.get(t, []) == ends


def test_sections_conflicts_are_numbered_by_their_earliest_row_across_sections():
    """The numbering's definition, on sections whose conflicts span several rows (a conflict's earliest row places
    it: by the earlier of its two trains' window openings, then the pair, then the section and its number there),
    with ties in time and pair across sections."""
    rng = np.random.default_rng(7)
    parts = []
    for k in range(5):
        n = int(rng.integers(1, 30))
        ids = rng.integers(1, 8, n)
        parts.append(pd.DataFrame({
            "conflict_id": ids, "a_start_s": rng.choice([0.0, 30.0, 60.0, 90.0], n),
            "b_start_s": rng.choice([10.0, 30.0, 120.0], n), "train_a": rng.choice(["101", "103", "99"], n),
            "train_b": rng.choice(["102", "104"], n), "from_m": rng.choice([0.0, 500.0, 900.0], n),
            "resource_kind": rng.choice(["block", "route"], n), "resource_id": rng.choice(["x", "y", "z"], n),
            "row": [f"{k}/{i}" for i in range(n)]}))
    # the definition, one conflict at a time
    place = {}
    for k, c in enumerate(parts):
        for r in c.itertuples():
            key = (min(r.a_start_s, r.b_start_s), r.train_a, r.train_b)
            place[(k, r.conflict_id)] = min(place.get((k, r.conflict_id), key), key)
    number = {kc: n for n, kc in enumerate(sorted(place, key=lambda kc: (*place[kc], *kc)), start=1)}
    got = renumbered([c.copy() for c in parts])
    want = {r: number[(k, cid)] for k, c in enumerate(parts) for r, cid in zip(c["row"], c["conflict_id"])}
    assert dict(zip(got["row"], got["conflict_id"])) == want and len(got) == sum(map(len, parts))
    assert got["conflict_id"].dtype == np.int64 and sorted(set(got["conflict_id"])) == list(range(1, len(place) + 1))
    keys = list(zip(got["conflict_id"], got["from_m"], got["resource_kind"], got["resource_id"]))
    assert keys == sorted(keys)  # the rows in the order of their conflict, then place and resource
