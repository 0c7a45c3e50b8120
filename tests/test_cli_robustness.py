"""``planner robustness`` and the job's ``[robustness]``: what a user types, what they get, what they are told."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from planner.cli import app

ROOT = Path(__file__).resolve().parents[1]


def job_file(tmp: Path, robustness: str = "") -> Path:
    text = (ROOT / "jobs" / "nightly.toml").read_text()
    text = text.replace('lines = ["lines/sample"]', f'lines = ["{ROOT / "lines" / "sample"}"]')
    text = text.replace('output_root = "outputs"', f'output_root = "{tmp / "out"}"')
    text = text.replace('feeds = ["feeds/sample"]', f'feeds = ["{ROOT / "feeds" / "sample"}"]')
    if robustness:
        text = text[:text.index("[robustness]")] + robustness
    p = tmp / "job.toml"
    p.write_text(text)
    return p


def test_the_command_writes_the_datasets_and_the_page_and_says_the_day(tmp_path):
    job = job_file(tmp_path)
    r = CliRunner().invoke(app, ["robustness", str(job), "--days", "300", "--seed", "7", "--jobs", "1",
                                 "--out", str(tmp_path / "rob")])
    assert r.exit_code == 0, r.output
    assert "predicted day:" in r.output and "300 days (seed 7)" in r.output
    assert "arrivals within 1 / 3 / 5 min" in r.output
    for name in ("delay_events", "delay_activities", "delay_conflicts", "robustness_trains",
                 "robustness_stations", "robustness_activities"):
        assert (tmp_path / "rob" / name / "line=sample" / "part-0.parquet").is_file(), name
    assert (tmp_path / "rob" / "report" / "sample_robustness.html").is_file()
    # the same seed gives the same bytes
    first = (tmp_path / "rob" / "robustness_trains" / "line=sample" / "part-0.parquet").read_bytes()
    r = CliRunner().invoke(app, ["robustness", str(job), "--days", "300", "--seed", "7", "--jobs", "2",
                                 "--out", str(tmp_path / "rob2")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "rob2" / "robustness_trains" / "line=sample" / "part-0.parquet").read_bytes() == first


def test_days_zero_computes_the_predicted_day_only(tmp_path):
    r = CliRunner().invoke(app, ["robustness", str(job_file(tmp_path)), "--days", "0", "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    assert "no days simulated" in r.output
    assert (tmp_path / "o" / "delay_events" / "line=sample" / "part-0.parquet").is_file()
    assert not (tmp_path / "o" / "robustness_trains").exists()


@pytest.mark.parametrize("section, message", [
    ('[robustness]\ndelays = [{ kind = "late", distribution = "exponential", mean_s = 60.0 }]\n',
     "kind: one of origin, dwell, running"),
    ('[robustness]\ndelays = [{ kind = "origin", distribution = "gamma" }]\n', "distribution: one of none"),
    ('[robustness]\ndelays = [{ kind = "origin", distribution = "exponential", probability = 1.5, mean_s = 6.0 }]\n',
     "probability: expected a number in [0, 1]"),
    ('[robustness]\ndelays = [{ kind = "origin", distribution = "empirical" }]\n', "needs the Parquet file"),
    ('[robustness]\nmin_dwell = [{ station_id = "HGO", wait = 3 }]\n', "unknown key 'wait'"),
    ("[robustness]\ndays = -3\n", "[robustness] days"),
])
def test_a_bad_robustness_table_is_one_line_naming_the_key(tmp_path, section, message):
    r = CliRunner().invoke(app, ["robustness", str(job_file(tmp_path, section)), "--days", "0"])
    assert r.exit_code != 0
    assert message in r.output
    assert "Traceback" not in r.output


def test_observed_delays_are_read_from_their_file_and_refused_when_wrong(tmp_path):
    good = tmp_path / "observed.parquet"
    pq.write_table(pa.table({"delay_s": [0.0, 0.0, 30.0, 90.0], "kind": ["origin"] * 4}), good)
    section = (f'[robustness]\ndays = 250\ndelays = [{{ kind = "origin", distribution = "empirical", '
               f'file = "{good}" }}]\n')
    r = CliRunner().invoke(app, ["robustness", str(job_file(tmp_path, section)), "--jobs", "1",
                                 "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    assert "drawn from 4 observed delays" in r.output
    tr = pq.read_table(tmp_path / "o" / "robustness_trains" / "line=sample" / "part-0.parquet").to_pandas()
    origin = tr.groupby("train_id").head(1)  # each train's first event: its departure from the origin
    # a quarter of the days on time... of the draws 0, 0, 30, 90: mean 30 s at the origin, within 3 standard errors
    se = np.std([0.0, 0.0, 30.0, 90.0]) / np.sqrt(250)
    assert abs(origin["primary_s"].mean() - 30.0) < 3 * se
    bad = tmp_path / "bad.parquet"
    pq.write_table(pa.table({"delay_s": [10.0, -4.0]}), bad)
    section = f'[robustness]\ndays = 10\ndelays = [{{ kind = "dwell", distribution = "empirical", file = "{bad}" }}]\n'
    r = CliRunner().invoke(app, ["robustness", str(job_file(tmp_path, section)), "--out", str(tmp_path / "o2")])
    assert r.exit_code != 0
    assert f"{bad} row 1 column delay_s" in r.output and "Traceback" not in r.output


def test_a_late_train_holds_the_next_and_that_one_the_train_after_it(tmp_path):
    """One E6 up train slowed to 30 km/h over 5 km (07:00-10:00): it is ~10 min late; the train behind it waits
    for it (a conflict the timetable as planned has, with the restriction) and then holds the train after it at
    four places: knock-on conflicts, each named."""
    import shutil

    shutil.copytree(ROOT / "feeds" / "sample", tmp_path / "feed")
    (tmp_path / "r.csv").write_text(
        "restriction_id,start_m,end_m,limit_kmh,direction,train_type,valid_from,valid_until,reason,has_beacon\n"
        "KNOCK-1,12000.0,17000.0,30.0,up,E6,2026-12-02T07:00,2026-12-02T10:00,test,false\n")
    r = CliRunner().invoke(app, ["restrictions", "import", str(tmp_path / "r.csv"), "--line",
                                 str(ROOT / "lines" / "sample"), "--feed", str(tmp_path / "feed"),
                                 "--time-zone", "Asia/Tokyo"])
    assert r.exit_code == 0, r.output
    job = job_file(tmp_path)
    job.write_text(job.read_text().replace(f'feeds = ["{ROOT / "feeds" / "sample"}"]', f'feeds = ["{tmp_path / "feed"}"]')
                   .replace('day = "2026-11-30"', 'day = "2026-12-02"'))
    r = CliRunner().invoke(app, ["robustness", str(job), "--days", "0", "--out", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    held = pq.read_table(tmp_path / "o" / "delay_conflicts" / "line=sample" / "part-0.parquet").to_pandas()
    first = held[held["train_b"] == "1078U"]
    assert set(first["train_a"]) == {"1076U"} and not first["knock_on"].any()
    cascade = held[held["knock_on"]]
    assert set(zip(cascade["train_a"], cascade["train_b"])) == {("1078U", "2020U")}
    assert len(cascade) >= 2 and (cascade["hold_s"] > 0).all()
    ev = pq.read_table(tmp_path / "o" / "delay_events" / "line=sample" / "part-0.parquet").to_pandas()
    late = ev[ev["train_id"] == "2020U"]
    assert late["cause"].str.contains("held by 1078U").any()
    assert "1 knock-on" in r.output
