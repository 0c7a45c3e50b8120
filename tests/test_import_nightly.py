"""Imported lines through the nightly job: a railjson line with switches (conflicts checked) and a railML
line with its own <timetable> (margins computed), its track network removed (the overview says its
conflicts were not checked)."""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from importsrc import EXTRA_TOML, write_railml
from linedb import quick_job
from test_import_network import write_loop_line
from test_import_timetable import railml_with_timetable

from planner.job.config import load_job
from planner.line.importers.railml import import_railml


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    from planner.job.pipeline import run_job

    root = tmp_path_factory.mktemp("night")
    loop = write_loop_line(root / "src-loop")
    f, r, x = write_railml(root / "src-railml", railml_with_timetable())
    x.write_text(EXTRA_TOML.replace('at = "D1"\n', "").split("[[timetable]]")[0])
    import_railml(f, "L1", [r], root / "lines" / "l1", extra=x)
    assert (root / "lines" / "l1" / "nodes.parquet").exists()  # railML gives a network: taken away here, so
    for name in ("nodes", "edges"):                            # L1 stands for a line without one (hand-made, CSV)
        (root / "lines" / "l1" / f"{name}.parquet").unlink()
    (root / "jobs").mkdir()
    job = root / "jobs" / "job.toml"
    job.write_text(quick_job(["lines/l1", loop], "out"))
    run_job(load_job(job), show_progress=False)
    return root / "out" / "latest"


def _dataset(run: Path, name: str, line: str) -> pd.DataFrame:
    files = sorted((run / name).glob(f"run_id=*/run_date=*/line={line}/**/*.parquet"))
    return pd.concat([pd.read_parquet(p) for p in files]) if files else pd.DataFrame()


def test_railml_timetable_trains_get_margins(run_dir):
    totals = _dataset(run_dir, "margin_totals", "L1")
    trains = set(totals.loc[totals["level"] == "train", "train_id"])
    assert trains == {"101", "102"}
    legs = _dataset(run_dir, "margins", "L1")
    run = legs[legs["train_ids"].map(len) > 0]
    got = {(o, d): t for o, d, t in zip(run["origin"], run["destination"], run["scheduled_running_time_s"])}
    # by hand from the railML times: 06:00:00→06:04:00, 06:04:30→06:08:00, 23:56:00→00:03:30 (passing M)
    assert got == {("W", "M"): 240.0, ("M", "E"): 210.0, ("E", "W"): 450.0}
    assert run["margin_s"].notna().all() and (run["margin_s"] > 0).all()


def test_railjson_loop_line_conflicts_dataset(run_dir):
    con = _dataset(run_dir, "conflicts", "loop")
    assert len(con) and set(con["train_a"]) | set(con["train_b"]) == {"D1", "U1"}
    row = con[(con["from_m"] == 500.0) & (con["to_m"] == 1800.0)]
    assert list(row["overlap_s"].round(6)) == [55.0]   # the hand calculation of test_import_network


def test_overview_says_which_line_was_not_checked(run_dir):
    manifest = json.loads((run_dir / "manifest.json").read_text())
    assert {x["line_id"]: x["conflicts"] for x in manifest["lines"]} == {"L1": "no track network", "loop": "checked"}
    page = (run_dir / "index.html").read_text()
    assert "conflicts not checked: no track network (nodes.parquet, edges.parquet) (L1)" in page
    assert "conflicts not checked: no track network (nodes.parquet, edges.parquet) (loop)" not in page
    graph = (run_dir / "graph" / "L1_graph.html").read_text()
    assert "conflicts not checked" in graph and "0 conflicts" not in graph
