"""The running-time table per train (``train_timetable``) on the tiny line: times, supplements, dataset, page.

The computed times are checked against what other code computes independently: the minimum
run against the margin report's table (a) minimum, the on-time run against table (a) built by
:func:`planner.tables.build.interstation_tables` at that ratio, and the supplements of a leg
against its margin (they must add up to it, by their definition).
"""
from __future__ import annotations

import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def margins(tiny):
    from planner.report.margins import compute_margins

    return compute_margins(tiny, conflicts=False).rows


@pytest.fixture(scope="module")
def runs(tiny, margins):
    from planner.report.train_timetable import leg_runs

    return leg_runs(tiny, margins)


@pytest.fixture(scope="module")
def rows(tiny, runs):
    from planner.report.train_timetable import timetable_rows

    return timetable_rows(tiny, runs)


def test_clock_text():
    from planner.report.train_timetable import clock

    assert clock(0.0) == "00:00:00"
    assert clock(6 * 3600 + 5 * 60 + 7.4) == "06:05:07"
    assert clock(59.6) == "00:01:00"  # rounded to the second, carried into the minute
    assert clock(25 * 3600 + 61) == "25:01:01"  # past midnight, as timetables write it
    assert clock(math.nan) is None


def test_runs_are_table_a_runs(tiny, margins, runs):
    from planner.tables.build import interstation_tables

    has = margins[margins.scheduled_running_time_s.notna()]
    assert len(runs) == len(has) == 3  # 101: A-B and B-C; 202: C-A, passing B
    for run in runs.values():
        d, t, o, de, sched = run.key
        row = run.row
        assert run.t_s[1][-1] == pytest.approx(row["min_running_time_s"], abs=1e-6)
        it = interstation_tables(tiny, t, o, de, [1.0, run.ratio])
        assert run.t_s[0][-1] == pytest.approx(float(it.time_a_s[1]), abs=1e-6)
        assert np.all(np.diff(run.t_s, axis=1) >= 0)  # time never runs back along the leg


def test_rows_of_a_train_with_a_pass(rows, runs):
    r202 = [r for r in rows if r["train_id"] == "202"]
    assert [r["activity"] for r in r202] == ["departs", "passes", "arrives"]
    dep, pas, arr = r202
    assert dep["scheduled_departure"] == "06:06:40" and dep["computed_departure_s"] == 22000.0
    assert pas["scheduled_arrival"] == pas["scheduled_departure"] == "06:10:00"
    # the pass lies between the departure and the computed arrival, for both runs
    assert 22000.0 < pas["computed_arrival_s"] < arr["computed_arrival_s"]
    assert 22000.0 < pas["minimum_arrival_s"] < arr["minimum_arrival_s"] <= arr["computed_arrival_s"]
    assert pas["computed_departure_s"] == pas["computed_arrival_s"]
    # one leg C-A: its two sections' supplements add up to its margin (scheduled - minimum)
    assert pas["supplement_s"] + arr["supplement_s"] == pytest.approx(arr["leg_margin_s"], abs=1e-6)
    assert arr["leg_scheduled_running_time_s"] == 500.0
    assert pas["section_scheduled_s"] == 200.0 and arr["section_scheduled_s"] == 300.0
    assert arr["chart"] == pas["chart"] == "charts/tiny/up_EMU6_C-A_500s.html"
    assert pas["leg_flag"] is None and arr["leg_flag"] in ("ok", "tight", "infeasible", "unreachable")


def test_rows_of_a_stopping_train(rows):
    r101 = [r for r in rows if r["train_id"] == "101"]
    assert [r["activity"] for r in r101] == ["departs", "stops", "arrives"]
    b = r101[1]
    # a stop: computed departure is the scheduled one (an on-time departure), arrival from the leg's run
    assert b["computed_departure_s"] == b["scheduled_departure_s"] == 21830.0
    assert b["supplement_s"] == pytest.approx(b["leg_margin_s"], abs=1e-6)  # one section per leg
    assert b["computed_arrival"] == b["computed_arrival"] and len(b["computed_arrival"]) == 8


def test_dataset_has_the_declared_columns(tiny, runs, tmp_path):
    from planner.io.parquet import read_dataset
    from planner.report.train_timetable import TIMETABLE_SCHEMA, write_timetable

    files = write_timetable(tiny, runs, tmp_path)
    assert files
    t = read_dataset(tmp_path, "train_timetable")
    assert set(TIMETABLE_SCHEMA.names) <= set(t.column_names)
    assert t.num_rows == sum(len(tr.calls) for tr in tiny.trains)
    df = t.to_pandas()
    assert df.loc[df.train_id == "101", "scheduled_arrival"].tolist()[1:] == ["06:03:20", "06:08:20"]


def test_page_has_an_anchor_per_train_and_chart_links(tiny, rows):
    from planner.pages.timetable import render_page

    text = render_page("tiny", tiny.name, rows)
    for tr in tiny.trains:
        assert f'id="train-{tr.train_id}"' in text
    assert 'href="../charts/tiny/up_EMU6_C-A_500s.html"' in text
    assert "http" not in text.replace("http-equiv", "")  # self-contained: no link off the machine


def test_the_times_the_job_keeps_are_the_runs_times(tiny, margins, runs):
    """The job's process keeps each leg's ends and its times at the line's stations inside the run (leg_times),
    not the runs' node arrays: the timetable from those is the timetable from the runs, value for value (train
    202 passes B, a time between two grid nodes); a station outside the run has the time at its nearer end, as
    the run gives it; a chainage it did not keep is an error, not a guess."""
    from planner.report.train_timetable import leg_times, timetable_rows

    times = leg_times(tiny, margins)
    assert sorted(times) == sorted(runs)
    assert any(r["activity"] == "passes" for r in timetable_rows(tiny, runs))
    assert timetable_rows(tiny, times) == timetable_rows(tiny, runs)
    for k, t in times.items():
        r = runs[k]
        assert not hasattr(t, "t_s") and t.span_m == (float(r.position_m.min()), float(r.position_m.max()))
        lo, hi = t.span_m
        assert len(t.chainage_m) == 2 + sum(lo < s.position_m < hi for s in tiny.stations)  # not the whole line's
        for x in [s.position_m for s in tiny.stations] + [lo - 100.0, hi + 100.0]:
            assert t.time_at(x, 1) == r.time_at(x, 1) and t.time_at(x, 0) == r.time_at(x, 0)
        inside = lo + 0.37 * (hi - lo)
        assert inside not in t.chainage_m
        with pytest.raises(KeyError, match="no time kept"):
            t.time_at(inside, 0)


def test_a_legs_span_known_before_it_is_run_is_its_runs_span(tiny, margins, runs):
    """The job's process plans a leg without running it (planned_legs): the chainages it gives the leg's run
    (leg_span, read by the chart's page and key) are those of the recorded run, to the bit, both ways; and it
    plans the legs leg_runs runs, with their on-time ratios."""
    from planner.report.train_timetable import planned_legs

    planned = planned_legs(tiny, margins)
    assert sorted(planned) == sorted(runs) and {k[0] for k in planned} == {"down", "up"}
    for k, (leg, _win) in planned.items():
        r = runs[k]
        assert leg.span_m == r.span_m and leg.ratio == r.ratio and leg.key == k
        lo, hi = leg.span_m
        assert lo < hi


def test_a_leg_that_stalls_has_no_chart_no_page_and_no_computed_times(tiny, margins, runs, tmp_path, monkeypatch):
    """A leg whose run stalls at its on-time ratio (record_leg raises) is left out where it is run, on the
    workers, as leg_runs leaves it out: its chart unit stores an empty chart, no page is written for it, and the
    tables' times of its calls stay empty; the other legs are untouched."""
    import hashlib

    import planner.report.train_timetable as tt
    from planner.errors import InfeasibleError
    from planner.job.cache import Cache
    from planner.job.train_views import _chart_task, write_chart_pages

    planned = tt.planned_legs(tiny, margins)
    stalls, other = sorted(planned)[:2]
    real = tt.record_leg

    def record(win, key, row, ds_m):
        if key == stalls:
            raise InfeasibleError("the train stalls")
        return real(win, key, row, ds_m)

    monkeypatch.setattr(tt, "record_leg", record)
    times = tt.leg_times_of(planned, tt.station_chainages(tiny))
    assert sorted(times) == sorted(k for k in runs if k != stalls)
    kept = {k: r for k, r in runs.items() if k != stalls}
    assert tt.timetable_rows(tiny, times) == tt.timetable_rows(tiny, kept) != tt.timetable_rows(tiny, runs)

    cache = Cache(tmp_path / "cache")
    pages, keys = [], []
    for key in (stalls, other):
        leg, win = planned[key]
        d, _, o, de = key[:4]
        calls = [(o, True, tiny.station(o).stop_m(d)), (de, True, tiny.station(de).stop_m(d))]
        keys.append(hashlib.sha256(repr(key).encode()).hexdigest())
        cache.put("charts", keys[-1], _chart_task(win, key, leg.row, 1.0, calls, None, None, None))
        pages.append((tmp_path / "run" / f"{len(pages)}.html", win, leg, calls, []))
    page = dict(back="t.html", nav=[], run_id="r0001-0123456789", day=None, run_date="2026-12-06")
    assert write_chart_pages(pages, str(cache.root), keys, page) == 1
    assert not pages[0][0].exists() and "<svg" in pages[1][0].read_text()


def test_the_page_written_in_pieces_is_the_page(tiny, rows, tmp_path, monkeypatch):
    """The job writes the tables page a train's section at a time (page_parts, never the whole text held):
    the file has exactly render_page's bytes, also when the pieces are gathered into several writes."""
    import planner.io.atomic as atomic
    from planner.pages.timetable import page_parts, render_page, write_page

    kw = dict(links=[("overview", "../index.html")], run_id="r0001-abc", graph_href="../graph/tiny_graph.html")
    whole = render_page("tiny", tiny.name, rows, **kw)
    parts = list(page_parts("tiny", tiny.name, rows, **kw))
    assert len(parts) == len(tiny.trains) + 2  # the head, a section per train, the end
    monkeypatch.setattr(atomic, "_CHUNK", 300)  # several gathered writes
    got = write_page(tmp_path / "t" / "tt.html", page_parts("tiny", tiny.name, rows, **kw)).read_bytes()
    assert got == whole.encode("utf-8") and got.count(b"<html") == 1 and got.endswith(b"</html>\n")


def test_a_page_whose_pieces_fail_leaves_no_file(tmp_path):
    """A piece that cannot be made (an error part way) leaves neither the page nor a temporary file."""
    from planner.pages.timetable import write_page

    def pieces():
        yield "<html>"
        raise RuntimeError("a train's section failed")

    with pytest.raises(RuntimeError):
        write_page(tmp_path / "tt.html", pieces())
    assert list(tmp_path.iterdir()) == []


def test_a_chart_is_named_safely_whatever_the_station_ids():
    """Station ids may be any text (validation allows unicode, '/', '<'); a chart's file name may not: such a
    leg is named by a digest of its ids, distinct per leg, and an ordinary leg keeps its readable name."""
    from planner.io.paths import is_path_id
    from planner.report.train_timetable import chart_name

    plain = chart_name("L", ("down", "E10", "TKD", "OHS", 130.0))
    assert plain == "charts/L/down_E10_TKD-OHS_130s.html"
    odd = [chart_name("L", ("down", "E10", o, d, 130.0)) for o, d in (("A", "駅"), ("A", "../x"), ("../x", "A"),
                                                                      ("A", "<b>x</b>"))]
    assert len(set(odd)) == 4
    for p in odd:
        folder, name = p.rsplit("/", 1)
        assert folder == "charts/L" and is_path_id(name.removesuffix(".html")) and name.startswith("down_E10_leg-")


def test_the_tables_read_no_field_of_a_margins_row_but_those_their_key_digests(tiny, runs):
    """A section's tables unit digests each leg's run by its chart's key and the row's fields in row_fields: rows
    cut down to those fields give the same tables, so no field the key leaves out can change them."""
    import dataclasses

    from planner.report.train_timetable import row_fields, timetable_rows

    cut = {k: dataclasses.replace(r, row={f: r.row.get(f) for f in row_fields()}) for k, r in runs.items()}
    assert any(len(r.row) > len(row_fields()) for r in runs.values())
    assert timetable_rows(tiny, cut) == timetable_rows(tiny, runs)
    less = {k: dataclasses.replace(r, row={f: v for f, v in r.row.items() if f != "remaining_margin_s"})
            for k, r in runs.items()}
    assert timetable_rows(tiny, less) != timetable_rows(tiny, runs)  # a field the tables do read
