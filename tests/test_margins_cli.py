"""``planner margins``: from scratch, reusing tables and closed-loop datasets, and bad input."""
from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from linedb import write_line_db
from planner import load_line
from planner.cli import app
from planner.io.parquet import read_dataset
from planner.report.margins import compute_margins

runner = CliRunner()


@pytest.fixture(scope="module")
def linedir(tmp_path_factory):
    return write_line_db(tmp_path_factory.mktemp("lines") / "tiny")


def _rows(out):
    return read_dataset(out, "margins").to_pandas().sort_values(
        ["direction", "train_type", "origin", "destination"]).reset_index(drop=True)


def test_from_scratch(linedir, tmp_path):
    out = tmp_path / "out"
    res = runner.invoke(app, ["margins", str(linedir), "--out", str(out), "--jobs", "1", "--no-conflicts"])
    assert res.exit_code == 0, res.output
    assert "tiny: 9 legs x train type (3 timetabled, 1 passing stations); tables 0 read, 9 computed" in res.output
    assert "flags:" in res.output and "wrote" in res.output
    rows = _rows(out)
    assert len(rows) == 9  # 2 types x 2 directions x 2 interstations + the EMU6 run passing B
    pas = rows[rows.passes.map(len) > 0]
    assert len(pas) == 1 and list(pas.iloc[0].passes) == ["B"] and pas.iloc[0].train_type == "EMU6"
    assert list(pas.iloc[0].train_ids) == ["202"]
    page = (out / "margins.html").read_text(encoding="utf-8")
    assert "<svg" in page and "Every leg" in page
    tot = read_dataset(out, "margin_totals").to_pandas()
    assert set(tot[tot.level == "train"].train_id) == {"101", "202"}


def test_reuses_tables_and_closed_loop(linedir, tmp_path):
    from planner.datasets.closed_loop import run_closed_loop, write_closed_loop
    from planner.tables.build import build_tables
    from planner.datasets.tables import write_tables

    line = load_line(linedir)
    tdir, cdir = tmp_path / "tables", tmp_path / "cl"
    write_tables(build_tables(line, train_types=["EMU6"], n_jobs=1), tdir)
    for sc in ("nominal", "perturbed"):
        write_closed_loop(run_closed_loop(line, tdir, train_types=["EMU6"], scenario_name=sc, n_jobs=1), cdir)
    scratch = compute_margins(line, train_types=["EMU6"], conflicts=False).rows
    reused = compute_margins(line, train_types=["EMU6"], tables_dir=tdir, closed_loop_dir=cdir,
                             conflicts=False).rows
    key = ["direction", "origin", "destination"]
    a = scratch.sort_values(key).reset_index(drop=True)
    b = reused.sort_values(key).reset_index(drop=True)
    assert list(b.tables_source) == ["dataset" if not len(p) else "computed" for p in b.passes]
    # the same tables, read back from Parquet: same minimum, slowest time, ratio, energy
    for c in ("min_running_time_s", "slowest_running_time_s", "ratio_on_time", "energy_at_ratio_kwh",
              "degraded_min_running_time_s"):
        np.testing.assert_allclose(b[c], a[c], rtol=0, atol=1e-9, err_msg=c)
    # closed-loop errors from the dataset: the same logic on a grid without the pattern-start nodes
    ok = b.scheduled_running_time_s.notna()
    np.testing.assert_allclose(b.arrival_error_s[ok], a.arrival_error_s[ok], atol=0.01)
    np.testing.assert_allclose(b.arrival_error_degraded_s[ok], a.arrival_error_degraded_s[ok], atol=0.01)


def test_closed_loop_in_hand_is_the_folder(linedir, tmp_path):
    """The nightly job gives the margins the closed loop's Arrow tables while the writer thread writes them:
    what the margins read from those tables is what they read from the written folder, a line's rows only."""
    import dataclasses

    import pyarrow as pa

    from planner.datasets.closed_loop import datasets, run_closed_loop, write_closed_loop
    from planner.datasets.tables import write_tables
    from planner.report.margin_datasets import closed_loop_index, closed_loop_worst
    from planner.report.margin_rule import MarginRule
    from planner.tables.build import build_tables

    line = load_line(linedir)
    tdir, cdir = tmp_path / "tables", tmp_path / "cl"
    write_tables(build_tables(line, train_types=["EMU6"], n_jobs=1), tdir)
    results = [r for sc in ("nominal", "perturbed")
               for r in run_closed_loop(line, tdir, train_types=["EMU6"], scenario_name=sc, n_jobs=1)]
    write_closed_loop(results, cdir)
    tables = datasets(results)
    # another line's rows beside them, with other errors (a run's tables hold one line; the filter must hold)
    other = datasets([dataclasses.replace(r, line_id="other", actual_s=r.actual_s + 100.0) for r in results])
    both = {k: pa.concat_tables([tables[k], other[k]]) for k in tables}
    rule = MarginRule()
    index = closed_loop_index(cdir, line.line_id, rule)
    assert len(index) > 0 and {k[4] for k in index} == {"nominal", "degraded"}
    assert closed_loop_index(None, line.line_id, rule, both) == index
    from planner.report.margin_datasets import _line_rows

    assert _line_rows(tables["closed_loop"], line.line_id) is tables["closed_loop"]  # one line's rows: not copied
    assert _line_rows(both["closed_loop"], line.line_id).equals(tables["closed_loop"])
    worst = closed_loop_worst(cdir, line.line_id)
    assert len(worst) > 0 and closed_loop_worst(None, line.line_id, both) == worst
    from_folder = compute_margins(line, train_types=["EMU6"], tables_dir=tdir, closed_loop_dir=cdir,
                                  conflicts=False).rows
    in_hand = compute_margins(line, train_types=["EMU6"], tables_dir=tdir, closed_loop=both, conflicts=False).rows
    assert from_folder.equals(in_hand)
    # the nightly job: what the margins read, made a direction at a time where the rows are (ClosedLoopFacts), at
    # the times the margins look up; nothing added from no legs
    from planner.report.margin_datasets import ClosedLoopFacts
    from planner.report.margin_legs import looked_up_by_leg

    scheduled = [t for v in looked_up_by_leg(line, ["EMU6"]).values() for t in v]
    times = scheduled + sorted({k[5] for k in index})[::7]  # some the sweep has
    facts = ClosedLoopFacts()
    for d in ("up", "down"):
        facts.add(datasets([r for r in results if r.direction == d]), line.line_id, rule, times)
    facts.add(datasets([]), line.line_id, rule, times)
    assert facts.index == closed_loop_index(cdir, line.line_id, rule, times=times) and len(facts.index) > 0
    assert facts.worst == worst
    made = compute_margins(line, train_types=["EMU6"], tables_dir=tdir, closed_loop=facts, conflicts=False).rows
    assert from_folder.equals(made)
    # each leg's own times (what the nightly job gives, a part of the line's legs at a time): a leg keeps its
    # errors at its own scheduled times only (another leg's times are not its), and the margins are the same
    sweep: dict = {}
    for k in index:
        sweep.setdefault(k[:4], set()).add(k[5])
    scheduled = looked_up_by_leg(line, ["EMU6"])
    assert scheduled and all(v == sorted(v) for v in scheduled.values())
    # each leg its scheduled times and some of its sweep's, every leg others
    by_leg = {leg: sorted(set(scheduled.get(leg, ())) | set(sorted(sweep[leg])[i % 7::7]))
              for i, leg in enumerate(sorted(sweep))}
    own = ClosedLoopFacts()
    for d in ("up", "down"):
        own.add(datasets([r for r in results if r.direction == d]), line.line_id, rule,
                {k: v for k, v in by_leg.items() if k[0] == d})
    union = closed_loop_index(cdir, line.line_id, rule, times=[t for v in by_leg.values() for t in v])
    assert own.index == {k: v for k, v in union.items() if k[5] in {round(t, 6) for t in by_leg[k[:4]]}}
    assert 0 < len(own.index) < len(union)  # a leg's entries at another leg's times are not its
    assert own.worst == worst
    assert from_folder.equals(compute_margins(line, train_types=["EMU6"], tables_dir=tdir, closed_loop=own,
                                              conflicts=False).rows)


def test_the_closed_loop_index_keeps_the_times_looked_up(tmp_path, monkeypatch):
    """The margins keep only the closed loop's designated times that the timetable's scheduled times look up
    (6 places, as they are looked up): the same entries as the whole sweep has for them, and the same margin rows
    as with the whole sweep in memory."""
    import pandas as pd

    from linedb import default_tables
    from planner.datasets.closed_loop import run_closed_loop, write_closed_loop
    from planner.datasets.tables import write_tables
    import planner.report.margins as margins
    from planner.report.margin_datasets import closed_loop_index
    from planner.report.margin_rule import MarginRule
    from planner.tables.build import build_tables

    tt = default_tables("tiny")["timetable"]  # train 101 scheduled inside the sweep: 150 s and 160 s
    tt = pd.concat([tt[tt.train_id == "101"].assign(
        arrival_s=[np.nan, 21750.0, 21940.0], departure_s=[21600.0, 21780.0, np.nan]), tt[tt.train_id != "101"]])
    line = load_line(write_line_db(tmp_path / "tiny", timetable=tt))
    tdir, cdir = tmp_path / "tables", tmp_path / "cl"
    write_tables(build_tables(line, train_types=["EMU10"], n_jobs=1), tdir)
    write_closed_loop([r for sc in ("nominal", "perturbed")
                       for r in run_closed_loop(line, tdir, train_types=["EMU10"], scenario_name=sc, n_jobs=1)], cdir)
    rule = MarginRule()
    whole = closed_loop_index(cdir, line.line_id, rule)
    sweep = sorted({k[5] for k in whole})
    assert 150.0 in sweep and 160.0 in sweep
    times = [sweep[0] + 3e-7, sweep[len(sweep) // 2] - 4e-7, sweep[-1], sweep[0] + 0.5, -1.0]  # the last two: none
    kept = closed_loop_index(cdir, line.line_id, rule, times=times)
    want = {round(t, 6) for t in times}
    assert kept == {k: v for k, v in whole.items() if k[5] in want}
    assert {k[5] for k in kept} == {sweep[0], sweep[len(sweep) // 2], sweep[-1]}
    assert closed_loop_index(cdir, line.line_id, rule, times=[]) == {}
    kw = dict(train_types=["EMU10"], tables_dir=tdir, closed_loop_dir=cdir, conflicts=False, n_jobs=1)
    import planner.report.leg_margin as leg_margin

    given, scheduled_runs = {}, leg_margin._scheduled_runs
    monkeypatch.setattr(leg_margin, "_scheduled_runs", lambda out, *a: given.setdefault(
        (out.origin, out.destination), a[-2]) is not None and scheduled_runs(out, *a))
    filtered = compute_margins(line, **kw)
    monkeypatch.undo()
    for o, d in (("A", "B"), ("B", "C")):  # each leg's entries at the line's scheduled times (150 s, 160 s)
        assert given[(o, d)] == {k[4:]: v for k, v in whole.items()
                                 if k[:4] == ("down", "EMU10", o, d) and k[5] in (150.0, 160.0)}
    assert {("nominal", 150.0), ("degraded", 150.0)} <= set(given[("A", "B")])  # what it looks up
    monkeypatch.setattr(margins, "closed_loop_index", lambda *a: closed_loop_index(*a[:4]))  # the whole sweep
    unfiltered = compute_margins(line, **kw)
    assert filtered.sources["closed_loop_dataset"] and filtered.rows.equals(unfiltered.rows)
    assert {round(x, 6) for x in filtered.rows["scheduled_running_time_s"].dropna()} >= {150.0, 160.0}


@pytest.mark.parametrize("args,msg", [
    (["--tables", "nowhere"], "--tables nowhere: no such folder"),
    (["--curves", "EMU10"], "--curves 'EMU10': give TYPE:ORIGIN-DESTINATION"),
    (["--adhesion", "3.5:2.5:0.1"], "--adhesion"),
    (["--jobs", "0"], "--jobs must be"),
])
def test_bad_input_is_one_line(linedir, tmp_path, args, msg):
    res = runner.invoke(app, ["margins", str(linedir), "--out", str(tmp_path / "o"), "--no-conflicts",
                              "--train-type", "EMU10", *args])
    assert res.exit_code == 1
    assert msg in res.output
    assert "Traceback" not in res.output
    assert not (tmp_path / "o" / "margins.html").exists()
