"""`--job JOB.toml [--day D]` on the one-off commands: their answers are the published night's (issue 50).

`planner runtime … --from TKD --to OHS` said 313.8 s while the published day's minimum was 355.7 s (a
restriction in force), and `planner conflicts` found 16 conflicts where the run found 0.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.dataset as ds
import pytest
from typer.testing import CliRunner

from planner.cli import app

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def night(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("day")
    for name in ("lines", "feeds", "jobs"):
        shutil.copytree(ROOT / name, tmp / name)
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    s = run_job(load_job(tmp / "jobs" / "nightly.toml"), show_progress=False)
    return tmp, s.run_dir


def test_runtime_with_the_job_is_the_published_days_minimum(night):
    tmp, run = night
    m = ds.dataset(run / "margins", partitioning="hive").to_table().to_pandas()
    row = m[(m.train_type == "E10") & (m.origin == "TKD") & (m.destination == "OHS")
            & m.restrictions.map(lambda r: "TSR-2026-101" in list(r))].iloc[0]
    args = ["runtime", str(tmp / "lines" / "sample"), "--train-type", "E10", "--from", "TKD", "--to", "OHS", "--json"]
    with_job = CliRunner().invoke(app, args + ["--job", str(tmp / "jobs" / "nightly.toml")])
    assert with_job.exit_code == 0, with_job.output
    assert json.loads(with_job.stdout)["running_time_s"] == pytest.approx(float(row.min_running_time_s), abs=1e-3)
    assert with_job.stderr.startswith("note: operating day 2026-11-30 of the job: temporary restrictions in force "
                                      "(TSR-2026-101, TSR-2026-104, TSR-2026-102)")
    alone = CliRunner().invoke(app, args)
    assert json.loads(alone.stdout)["running_time_s"] < float(row.min_running_time_s) - 30.0  # 313.8 s
    assert "no operating day's temporary restrictions" in alone.stderr
    wrong = CliRunner().invoke(app, args + ["--day", "2026-12-01"])
    assert wrong.exit_code == 1 and wrong.output == ("error: --day needs --job JOB.toml: the job names the line's "
                                                     "daily feed and time zone\n")


def test_conflicts_with_the_job_finds_what_the_run_found(night):
    tmp, run = night
    manifest = json.loads((run / "manifest.json").read_text())
    r = CliRunner().invoke(app, ["conflicts", str(tmp / "lines" / "sample"), "--out", str(tmp / "cf"), "--jobs", "2",
                                 "--job", str(tmp / "jobs" / "nightly.toml")])
    assert r.exit_code == 0, r.output
    n = manifest["flags"]["conflicts"]
    assert f"conflicts: {n} conflict" in r.stdout
    c = ds.dataset(tmp / "cf" / "conflicts", partitioning="hive").to_table()
    assert len(set(c.column("conflict_id").to_pylist())) == n
