"""A restriction that leaves a station without a stopping pattern is one verdict on every page and in the bundle.

The sample line on 2026-12-01 with one restriction of our own (up, 9,000–9,300 m, 40 km/h, 09:00–15:00):
no pattern stops the up trains at Midorigaoka (MDR) from Takadai at any adhesion level (the 650 m approach
from the TASC beacon is too short once the 40 km/h limit lies in it). The run found it (24 infeasible
patterns) and said nothing else: the overview showed 0 legs without a stopping pattern, the margin report
gave the legs a bad-day figure, the bundles verified complete. Here every place says the same three legs.
"""
from __future__ import annotations

import re

import json
import shutil
from pathlib import Path

import pyarrow.dataset as ds
import pytest
from typer.testing import CliRunner

from planner.cli import app

ROOT = Path(__file__).resolve().parents[1]
OURS = ("restriction_id,start_m,end_m,limit_kmh,direction,train_type,valid_from,valid_until,reason,has_beacon\n"
        "OURS-1,9000.0,9300.0,40.0,up,,2026-12-01T09:00,2026-12-01T15:00,test,false\n")
LEGS = {("E10", "up", "TKD", "MDR"), ("E6", "up", "TKD", "MDR"), ("E8", "up", "TKD", "MDR")}


@pytest.fixture(scope="module")
def night(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("nostop")
    shutil.copytree(ROOT / "feeds" / "sample", tmp / "feed")
    (tmp / "r.csv").write_text(OURS)
    runner = CliRunner()
    r = runner.invoke(app, ["restrictions", "import", str(tmp / "r.csv"), "--line", str(ROOT / "lines" / "sample"),
                            "--feed", str(tmp / "feed"), "--time-zone", "Asia/Tokyo"])
    assert r.exit_code == 0, r.output
    job = (ROOT / "jobs" / "nightly.toml").read_text()
    job = job.replace('lines = ["lines/sample"]', f'lines = ["{ROOT / "lines" / "sample"}"]')
    job = job.replace('output_root = "outputs"', f'output_root = "{tmp / "out"}"')
    job = job.replace('feeds = ["feeds/sample"]', f'feeds = ["{tmp / "feed"}"]')
    job = job.replace('day = "2026-11-30"', 'day = "2026-12-01"').replace('run_date = ""', 'run_date = "2026-12-01"')
    (tmp / "job.toml").write_text(job)
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    return run_job(load_job(tmp / "job.toml"), show_progress=False)


def _legs(frame) -> set:
    return {tuple(r) for r in frame[["train_type", "direction", "origin", "destination"]].itertuples(index=False)}


def test_every_dataset_and_count_names_the_same_legs(night):
    run = night.run_dir
    stops = ds.dataset(run / "stop_summary", partitioning="hive").to_table().to_pandas()
    stuck = stops[~stops["feasible"]].rename(columns={"station_id": "destination"})
    assert _legs(stuck) == LEGS
    m = ds.dataset(run / "margins", partitioning="hive").to_table().to_pandas()
    flagged = m[m["unassessed_cause"] == "no_stop"]
    assert _legs(flagged) == LEGS and flagged["remaining_margin_s"].isna().all()  # no bad-day figure
    assert flagged["unassessed"].all() and flagged["short_bad_day"].isna().all()
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["flags"]["no_stop"] == len(LEGS) and night.flags["no_stop"] == len(LEGS)
    assert manifest["flags"]["infeasible_stops"] == int((~stops["feasible"]).sum())
    notes = [n for n in night.notes if "no stopping pattern at MDR" in n]
    assert len(notes) == len(LEGS)


def test_the_pages_say_it_and_none_calls_those_legs_fine(night):
    run = night.run_dir
    page = (run / "report" / "sample_restrictions.html").read_text()
    assert "Stops without a stopping pattern" in page
    for tt, d, o, de in LEGS:
        assert f"<b>{tt} {d} {o}→{de}</b>, the restriction(s) on the leg: OURS-1" in page
        # its row in the legs' table gives no bad-day margin or arrival error: there is no pattern to give one of
        row = re.search(rf"<tr><td[^>]*>{tt} {o}→{de}</td>.*?</tr>", page, flags=re.S).group(0)
        assert row.count("no stopping pattern stops the train: no figure") == 3, row
    margins = (run / "report" / "sample_margins.html").read_text()  # said on the first screen, not only in the table
    assert ("6 of 78 legs are <b>unassessed</b>: no bad-day minimum (<a href='#legs'>every leg</a> says why); among "
            "them, no stopping pattern stops the train on E10 up TKD → MDR, E6 up TKD → MDR, E8 up TKD → MDR") in margins
    overview = (run / "index.html").read_text()
    assert "legs where no stopping pattern stops the train" in overview
    assert "<div class='n'>3</div><div class='l'>legs where no stopping pattern" in overview
    assert "partial: no stopping pattern at MDR from TKD" in overview


def test_the_up_bundles_name_the_stop_and_require_complete_refuses_them(night):
    b = night.run_dir / "bundles"
    base = ["bundle", "verify", "--public-key", str(b / "signing_key.pub.pem"), "--allow-dev",
            "--at", "2026-12-01T12:00+09:00", "--require-complete"]
    for tt in ("E10", "E6", "E8"):
        up = CliRunner().invoke(app, base[:2] + [str(b / f"sample_up_{tt}.pdb")] + base[2:] + ["--expect",
                                                                                             f"sample/up/{tt}"])
        assert up.exit_code == 1 and "incomplete, no stopping pattern at MDR from TKD at 2.5…" in up.output
        down = CliRunner().invoke(app, base[:2] + [str(b / f"sample_down_{tt}.pdb")] + base[2:] + ["--expect",
                                                                                                 f"sample/down/{tt}"])
        assert down.exit_code == 0, down.output
