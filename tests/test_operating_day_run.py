"""`planner run` plans one operating day: the day and what is in force go into the manifest and the
inputs digest; another day is another run that recomputes only the units what is in force reaches;
a bad feed fails the run before anything is published.
"""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest
from typer.testing import CliRunner

from linedb import write_line_db
from planner.cli import app
from planner.errors import BundleError, LineValidationError
from planner.job.config import load_job
from planner.job.day import with_day
from planner.job.publish import latest_run, list_runs
from test_daily_feed import OK, calendar_rows, write_feed


@pytest.fixture
def project(tmp_path):
    write_line_db(tmp_path / "lines" / "tiny", nodes=None, edges=None)
    write_feed(tmp_path / "feeds" / "tiny", restrictions=[OK], **calendar_rows())
    (tmp_path / "jobs").mkdir()
    (tmp_path / "jobs" / "job.toml").write_text(textwrap.dedent("""
        [job]
        lines = ["lines/tiny"]
        output_root = "out"
        [stops]
        adhesion_kmh_s = "2.5:3.5:0.5"
        [closed_loop]
        modes = ["nearest"]
        horizon_s = 3.0
        step_s = 3.0
        [bundles]
        allow_development_key = true
        [parallel]
        n_jobs = 1
        [day]
        day = "2026-11-30"
        time_zone = "Asia/Tokyo"
        feeds = ["feeds/tiny"]
    """))
    return tmp_path


def _manifest(root: Path) -> dict:
    return json.loads((root / "out" / latest_run(root / "out") / "manifest.json").read_text())


def test_the_day_is_in_the_manifest_and_another_day_recomputes_what_its_restrictions_reach(project):
    from planner.job.pipeline import run_job

    job = load_job(project / "jobs" / "job.toml")
    first = run_job(job, show_progress=False)
    day = _manifest(project)["operating_day"]
    assert (day["day"], day["start"], day["end"]) == ("2026-11-30", "2026-11-30T03:00:00+09:00",
                                                      "2026-12-01T03:00:00+09:00")
    (line,) = day["lines"]
    # R1: 01:00 on the 30th (before the day's 03:00 start) to 05:00 on 2 December (after its end)
    assert [r["restriction_id"] for r in line["restrictions"]] == ["R1"] and line["restrictions"][0]["whole_day"]
    assert line["trains_running"] == 2 and line["trains_not_running"] == []
    # the run's bundles are that day's: verify refuses one the day after (the day ends 2026-11-30T18:00Z)
    from planner.bundle.verify import verify_bundle

    b = project / "out" / "latest" / "bundles"
    pub = b / "signing_key.pub.pem"
    info = verify_bundle(b / "tiny_down_EMU10.pdb", pub, at="2026-11-30T17:59:59Z", allow_dev=True)
    assert info.operating_day["day"] == "2026-11-30" and info.operating_day["restrictions"] == ["R1"]
    with pytest.raises(BundleError, match="outside its window"):
        verify_bundle(b / "tiny_down_EMU10.pdb", pub, at="2026-11-30T18:00:00Z", allow_dev=True)
    # the page a planner reads first, linked from the overview
    run = project / "out" / "latest"
    page = (run / "report" / "tiny_restrictions.html").read_text()
    page = page.split("<h2 id='changes'>")[0]  # what is in force (the changes since Sunday list the trains' legs)
    assert "<b>R1</b>" in page and "EMU10 A→B" in page and "EMU6 B→A" in page and "B→C" not in page
    assert "href='report/tiny_restrictions.html'" in (run / "index.html").read_text()
    # the overview verifies the day's bundles when vehicles load them (the day's start), not today: a run for a
    # later day must not read as refused; and it names them without this machine's paths
    overview = (run / "index.html").read_text()
    assert "FAILED" not in overview and "checked at the start of operating day 2026-11-30" in overview
    assert str(project) not in overview

    holiday = run_job(with_day(job, "2026-11-23"), show_progress=False)  # weekday service removed
    assert holiday.run_id != first.run_id and not holiday.up_to_date
    # R1 (1000-1400 m, both directions, every type) is not in force on the 23rd: it lies between A (200 m)
    # and B (2500 m) only, so 2 directions x 2 types of the 8 interstation units change (tables, stops,
    # closed loop each), and the line-level units (the trains that run changed too); B-C is reused
    # (the train graph's two: the trajectories and the page's share of the line's one section); no train runs, so
    # there is no leg to chart (and the running-time tables are empty, not a crash)
    # the margin report's leg groups: 8 that day (202 runs EMU6's only C-A); computed again the 4 whose stretch
    # holds 1000-1400 m (A-B and B-A of both types) and EMU10's B-C, whose scheduled times lost 101's; the 3
    # others between B and C are read back
    assert holiday.computed == {"tables": 4, "stops": 4, "closed_loop": 4, "margins": 1, "margin_leg": 5,
                                "graph": 2, "charts": 0, "timetable": 1}
    assert holiday.reused == {"tables": 4, "stops": 4, "closed_loop": 4, "margins": 0, "margin_leg": 3, "graph": 0,
                              "charts": 0, "timetable": 0}
    assert any("no train runs on 2026-11-23 (Monday)" in n for n in holiday.notes)
    assert _manifest(project)["operating_day"]["lines"][0]["trains_not_running"] == ["101", "202"]
    again = run_job(with_day(job, "2026-11-23"), show_progress=False)
    assert again.up_to_date and again.run_id == holiday.run_id


def test_a_bad_feed_fails_before_anything_is_published(project):
    from planner.job.pipeline import run_job

    write_feed(project / "feeds" / "tiny", restrictions=[{**OK, "end_m": 9000.0}])
    with pytest.raises(LineValidationError, match="restrictions.parquet row 0 .* column end_m"):
        run_job(load_job(project / "jobs" / "job.toml"), show_progress=False)
    assert list_runs(project / "out") == []
    r = CliRunner().invoke(app, ["run", str(project / "jobs" / "job.toml"), "--no-progress", "--day", "2026-11-31"])
    assert r.exit_code == 1 and r.output == "error: --day: expected a date YYYY-MM-DD, found '2026-11-31'\n"
