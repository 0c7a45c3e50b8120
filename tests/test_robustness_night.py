"""The nightly job's day as it will run, on the sample's restricted day 2026-11-30, read from what it publishes."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.dataset as ds
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("night")
    job = (ROOT / "jobs" / "nightly.toml").read_text()
    job = job.replace('lines = ["lines/sample"]', f'lines = ["{ROOT / "lines" / "sample"}"]')
    job = job.replace('output_root = "outputs"', f'output_root = "{tmp / "out"}"')
    job = job.replace('feeds = ["feeds/sample"]', f'feeds = ["{ROOT / "feeds" / "sample"}"]')
    job = job.replace("days = 1000 ", "days = 300 ")
    (tmp / "job.toml").write_text(job)
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    return run_job(load_job(tmp / "job.toml"), show_progress=False).run_dir


def _read(run_dir: Path, name: str):
    return ds.dataset(run_dir / name, partitioning="hive").to_table().to_pandas()


def test_the_timetable_never_departs_before_arrival_plus_the_minimum_dwell(run):
    tt = _read(run, "train_timetable")
    stops = tt[tt["predicted_arrival_s"].notna() & tt["predicted_departure_s"].notna()]
    assert len(stops) > 1000
    assert (stops["predicted_departure_s"] >= stops["predicted_arrival_s"] + 20.0 - 1e-9).all()
    assert (stops["predicted_departure_s"] >= stops["scheduled_departure_s"] - 1e-9).all()
    # the computed times of the conflict check alone let a late train leave at its arrival: the 1013D
    row = tt[(tt["train_id"] == "1013D") & (tt["station_id"] == "HGO")].iloc[0]
    assert row["predicted_arrival_s"] - row["scheduled_arrival_s"] > 50.0
    assert row["predicted_departure_s"] == pytest.approx(row["predicted_arrival_s"] + 20.0)
    assert "its run from KWB" in row["delay_cause"]
    assert row["predicted_departure"] > row["predicted_arrival"]  # HH:MM:SS, same day


def test_the_events_carry_every_delay_and_say_why(run):
    ev = _read(run, "delay_events")
    assert (ev["delay_s"] >= 0).all()
    np.testing.assert_allclose(ev["predicted_s"] - ev["scheduled_s"], ev["delay_s"], atol=1e-6)
    grown = ev[ev["cause"] != ""]
    assert set(grown["cause_kind"]) <= {"run", "dwell", "headway", "connection"}
    # every train late somewhere is late for a reason named at or before its first late event
    for tid, g in ev[ev["delay_s"] > 1e-6].groupby("train_id"):
        first = g.sort_values("scheduled_s").iloc[0]
        assert first["cause"], tid
    acts = _read(run, "delay_activities")
    assert set(acts["activity"]) >= {"run", "dwell", "headway"}
    # an activity sets each event that is later than the one before it (and those that carry a delay on)
    assert acts["binding"].sum() >= (ev["cause_kind"] != "").sum() > 0


def test_punctuality_shares_are_ordered_and_the_page_is_linked(run):
    st = _read(run, "robustness_stations")
    assert len(st) > 0
    assert ((0 <= st["within_60s"]) & (st["within_60s"] <= st["within_180s"])
            & (st["within_180s"] <= st["within_300s"]) & (st["within_300s"] <= 1)).all()
    tr = _read(run, "robustness_trains")
    assert (tr["p50_s"] <= tr["p90_s"]).all() and (tr["p90_s"] <= tr["p99_s"]).all()
    assert (tr["knock_on_s"] >= -1e-9).all()
    page = run / "report" / "sample_robustness.html"
    assert page.is_file()
    assert "sample_robustness.html" in (run / "index.html").read_text()
    occ = _read(run, "occupation")
    assert {"predicted_start_s", "predicted_end_s"} <= set(occ.columns)
    assert (occ["predicted_start_s"] >= occ["start_s"] - 1e-6).all()
