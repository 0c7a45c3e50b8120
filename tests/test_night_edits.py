"""A night that never blocks: ordinary edits of the inputs between two runs, and a comparison that fails.

Every test starts from one published run of the tiny line (tests/linedb.py) on an output root that
holds its cache, copied per test, so the run after an edit is the incremental run a production
night makes. The comparison with the previous run (the ``changes`` step) must name the edit and
must never stop the run from publishing.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.dataset as ds
import pytest

from linedb import default_tables, quick_job, write_line_db
from planner.job.config import load_job
from planner.job.publish import latest_run, list_runs

JOB = quick_job(["lines/tiny"], "out", keep_runs=3)


def write_tiny(folder: Path, tables: dict | None = None) -> None:
    """The tiny line without its network (its network lacks a stop node at B), tables replaced by ``tables``."""
    write_line_db(folder, **({"nodes": None, "edges": None} | (tables or {})))


def run(project: Path):
    from planner.job.pipeline import run_job

    return run_job(load_job(project / "jobs" / "job.toml"), show_progress=False)


@pytest.fixture(scope="module")
def published(tmp_path_factory) -> Path:
    """A project folder (line, job, output root with cache) after one published run."""
    p = tmp_path_factory.mktemp("published")
    write_tiny(p / "lines" / "tiny")
    (p / "jobs").mkdir()
    (p / "jobs" / "job.toml").write_text(JOB)
    run(p)
    return p


@pytest.fixture
def project(published, tmp_path) -> Path:
    dst = tmp_path / "project"
    shutil.copytree(published, dst, symlinks=True)
    return dst


def changes_of(run_dir: Path):
    return ds.dataset(run_dir / "changes", format="parquet", partitioning="hive").to_table().to_pandas()


def test_timetable_edit_publishes_and_the_changes_name_it(project):
    tt = default_tables()["timetable"]
    tt.loc[tt.train_id == "101", ["arrival_s", "departure_s"]] += 60.0  # train 101 a minute later
    write_tiny(project / "lines" / "tiny", {"timetable": tt})
    s = run(project)
    assert latest_run(project / "out") == s.run_id and len(list_runs(project / "out")) == 2
    ch = changes_of(s.run_dir)
    edits = ch[ch.category == "line_table"]
    # train 101's four times, each 60 s later, named by train and stop
    assert sorted(edits.field) == ["arrival_s", "arrival_s", "departure_s", "departure_s"]
    assert set(edits.delta) == {60.0} and all(d.startswith("timetable 101 ") for d in edits.detail)
    assert json.loads((s.run_dir / "manifest.json").read_text())["changes"]["status"] == "compared"
    # the bundles are compared by content although a development key signs them: 101 runs down as EMU10
    bundles = ch[ch.category == "bundle"]
    assert not bundles.detail.str.contains("could not be compared").any()
    assert bundles[bundles.subject == "tiny_down_EMU10.pdb"].detail.str.contains("timetable").all()
    assert not bundles.detail.str.contains(str(project)).any()  # no absolute paths in a dataset


def test_station_rename_publishes_and_the_changes_name_it(project):
    t = default_tables()
    t["stations"].loc[t["stations"].station_id == "B", "station_id"] = "X"
    t["timetable"].loc[t["timetable"].station_id == "B", "station_id"] = "X"
    write_tiny(project / "lines" / "tiny", {"stations": t["stations"], "timetable": t["timetable"]})
    s = run(project)
    assert latest_run(project / "out") == s.run_id
    ch = changes_of(s.run_dir)
    renamed = ch[(ch.category == "line_table") & (ch.subject == "stations")]
    assert sorted(renamed.detail.str.contains("row added")) == [False, True]  # B removed, X added
    legs = ch[ch.category == "leg"]
    # the legs into and out of B disappear, those into and out of X appear (101 stops at both)
    assert any("A→X" in d and "appeared" in d for d in legs.detail)
    assert any("A→B" in d and "disappeared" in d for d in legs.detail)


@pytest.mark.parametrize("module, name", [("planner.report.changes", "compare_runs"),
                                          ("planner.report.bundle_changes", "bundle_changes")])
def test_a_broken_comparison_still_publishes_and_says_so(project, monkeypatch, module, name):
    """The legs' comparison or the bundles' (made on the worker that built them) failing fails the comparison, not
    the run."""
    import importlib

    def broken(*a, **k):
        raise RuntimeError("comparison exploded on purpose")

    monkeypatch.setattr(importlib.import_module(module), name, broken)
    write_tiny(project / "lines" / "tiny", {"gradients": default_tables()["gradients"].iloc[:2]})
    s = run(project)
    assert latest_run(project / "out") == s.run_id  # published
    m = json.loads((s.run_dir / "manifest.json").read_text())
    assert m["changes"]["status"] == "failed" and "exploded on purpose" in m["changes"]["error"]
    assert not (s.run_dir / "changes").exists()  # no list rather than a wrong one
    assert [w for w in s.warnings if w.startswith("changes: comparing with run r0001")] and \
        all("\n" not in w for w in s.warnings)
    for page in ("index.html", "report/tiny_margins.html"):
        assert "exploded on purpose" in (s.run_dir / page).read_text()
    assert (s.run_dir / "bundles").is_dir() and (s.run_dir / "margins").is_dir()  # the run's own outputs
    assert m["bundles"] == sorted(p.name for p in (s.run_dir / "bundles").glob("*.pdb")) and m["bundles"]


def test_a_changes_write_that_fails_half_way_leaves_no_part_file(project, monkeypatch):
    import planner.report.changes as changes

    real = changes.write_changes

    def half(ch, out_dir):
        real(ch, out_dir)  # the file is there ...
        raise OSError(28, "No space left on device (simulated after the write)")  # ... then the write fails

    monkeypatch.setattr(changes, "write_changes", half)
    write_tiny(project / "lines" / "tiny", {"gradients": default_tables()["gradients"].iloc[:2]})
    s = run(project)
    assert latest_run(project / "out") == s.run_id
    assert not list((s.run_dir).glob("changes/**/*.parquet"))
    assert json.loads((s.run_dir / "manifest.json").read_text())["changes"]["status"] == "failed"


def test_an_internal_error_is_one_line_with_the_traceback_in_a_file(monkeypatch, capsys):
    import planner.cli as cli

    def bug(*a, **k):
        raise ValueError("The truth value of an array\nwith more than one element is ambiguous")

    monkeypatch.setattr(cli, "app", bug)
    with pytest.raises(SystemExit) as e:
        cli.main()
    assert e.value.code == 70
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: internal error in planner (ValueError: The truth value")
    saved = Path(err.rsplit(" ", 1)[1].strip())
    try:
        assert "Traceback" in saved.read_text() and "ambiguous" in saved.read_text()
    finally:
        saved.unlink()


def test_two_runs_of_identical_inputs_differ_in_nothing(project):
    """A re-run of the same inputs re-issues every bundle (new version, build time and expiry in the signed
    manifest), but holds the same content: the comparison lists no change at all."""
    from planner.job.pipeline import run_job
    from planner.report.changes import compare_runs

    before = latest_run(project / "out")
    s = run_job(load_job(project / "jobs" / "job.toml"), show_progress=False, use_cache=False)
    assert s.run_id != before
    old, new = (sorted((project / "out" / r / "bundles").glob("*.pdb")) for r in (before, s.run_id))
    assert [p.name for p in old] == [p.name for p in new]
    assert all(p.read_bytes() != q.read_bytes() for p, q in zip(old, new))  # re-issued: other bytes ...
    (ch,) = compare_runs(project / "out" / before, s.run_dir)
    assert ch.rows == [] and len(changes_of(s.run_dir)) == 0  # ... and no change


def test_the_night_lists_what_planner_diff_finds(project):
    """The night compares a line's margins, conflicts and inputs as soon as its margins are written, and its
    bundles where they were built, then puts the two together: the same rows, numbered the same, as comparing the
    two published runs in one go (``planner diff``)."""
    from planner.report.changes import compare_runs

    t = default_tables()
    t["timetable"].loc[t["timetable"].train_id == "101", ["arrival_s", "departure_s"]] += 60.0
    t["speed_limits"].loc[0, "limit_kmh"] -= 10.0  # a limit lowered: the legs and the bundles move too
    write_tiny(project / "lines" / "tiny", {"timetable": t["timetable"], "speed_limits": t["speed_limits"]})
    before = latest_run(project / "out")
    s = run(project)
    (ch,) = compare_runs(project / "out" / before, s.run_dir)
    assert {"line_table", "leg", "bundle"} <= {r["category"] for r in ch.rows}
    night = changes_of(s.run_dir).drop(columns=["line", "run_id", "run_date"], errors="ignore")
    diff = ch.table().drop_columns(["line"]).to_pandas()
    assert list(night.change_id) == list(range(len(diff)))
    for col in ("category", "subject", "field", "before", "after", "detail", "base_run"):
        assert list(night[col]) == list(diff[col]), col
    assert [list(c) for c in night.caused_by] == [list(c) for c in diff.caused_by]
    # the margin report page, drawn before the comparison was in, shows it at its top, where the first run's note was
    from planner.job.views import CHANGES_HERE

    page = (s.run_dir / "report" / "tiny_margins.html").read_text()
    first = (project / "out" / before / "report" / "tiny_margins.html").read_text()
    assert CHANGES_HERE not in page and "nothing to compare with" in first and "nothing to compare with" not in page
    assert page.index("tiny_down_EMU10.pdb") < page.index("<svg")
