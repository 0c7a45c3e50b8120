"""One train the track network cannot carry is a flag on that train, never the end of the night.

A third train (303, down, A → D) is added to the tiny single-track line of ``test_network_cli.py`` with
station D's only stop node on a track piece joined to nothing: no route reaches it. The night publishes,
names the train and why in the ``unrouted`` dataset, the flags and the notes, and every other train's
rows in every dataset are those of the same night without train 303.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import pandas as pd
import pyarrow.dataset as ds
import pytest

from linedb import default_tables, write_line_db
from test_network_cli import EDGES, NODES, timetable

CUT = "303"
STAMP = {"run_id", "run_date"}


def _project(root: Path, with_cut: bool) -> Path:
    tt = timetable(21900.0)
    st = default_tables()["stations"]
    st = pd.concat([st, pd.DataFrame([("D", "Dai", 3800.0, 3860.0, 3740.0, 200.0)], columns=st.columns)])
    nodes = pd.concat([NODES, pd.DataFrame([("D-x", "stop", 3860.0, "IXL2", "D", "9")], columns=NODES.columns)])
    if with_cut:
        nan = float("nan")
        tt = pd.concat([tt, pd.DataFrame([(CUT, "EMU6", "down", 0, "A", nan, 23000.0, True),
                                          (CUT, "EMU6", "down", 1, "D", 23400.0, nan, True)], columns=tt.columns)],
                       ignore_index=True)
    write_line_db(root / "lines" / "tiny", nodes=nodes, edges=EDGES, timetable=tt,
                  stations=st.sort_values("position_m"))
    job = root / "job.toml"
    job.write_text(textwrap.dedent("""
        [job]
        lines = ["lines/tiny"]
        output_root = "out"
        run_date = "2026-12-01"
        [stops]
        adhesion_kmh_s = "3.0:3.0:0.5"
        [closed_loop]
        modes = ["nearest"]
        horizon_s = 4.0
        step_s = 2.0
        [bundles]
        allow_development_key = true
        [parallel]
        n_jobs = 2
    """))
    return job


def _run(job: Path):
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    return run_job(load_job(job), show_progress=False)


def _rows(run: Path, name: str) -> pd.DataFrame:
    t = ds.dataset(run / name, format="parquet", partitioning="hive").to_table().to_pandas()
    t = t.drop(columns=[c for c in t.columns if c in STAMP])
    for c in t.columns:
        if isinstance(t[c].dtype, pd.CategoricalDtype):
            t[c] = t[c].astype(str)
    return t


@pytest.fixture(scope="module")
def nights(tmp_path_factory):
    cut = _run(_project(tmp_path_factory.mktemp("with"), True))
    alone = _run(_project(tmp_path_factory.mktemp("without"), False))
    return cut, alone


def test_the_night_publishes_and_names_the_train_and_why(nights):
    cut, _ = nights
    assert cut.run_dir is not None and cut.run_dir.is_dir()
    assert cut.flags["unrouted"] == 1
    u = _rows(cut.run_dir, "unrouted")
    assert list(u["train_id"]) == [CUT] and list(u["direction"]) == ["down"]
    assert "stop of station D (stop nodes D-x at 3860.0 m)" in u["reason"][0]
    assert any(n.startswith("not routed, left out of the conflict check: train 303 (down)") for n in cut.notes)
    page = (cut.run_dir / "index.html").read_text()
    assert "trains the track network cannot carry" in page


def test_every_other_train_is_as_on_a_night_without_it(nights):
    cut, alone = nights
    assert alone.flags["unrouted"] == 0 and len(_rows(alone.run_dir, "unrouted")) == 0
    names = sorted(p.name for p in cut.run_dir.iterdir() if p.is_dir() and any(p.rglob("*.parquet")))
    assert {"conflicts", "occupation", "headways", "margins"} <= set(names)
    compared = 0
    for name in names:
        if name in ("unrouted", "changes", "inputs"):  # what the run read (the timetable differs), what changed
            continue
        a, b = _rows(cut.run_dir, name), _rows(alone.run_dir, name)
        if "level" in a.columns:  # totals over a train type or the line count train 303 too, as they should
            a, b = a[a["level"] == "train"], b[b["level"] == "train"]
        trains = [c for c in ("train_id", "train_a", "train_b") if c in a.columns]
        for c in trains:
            a = a[a[c] != CUT]
        if "train_ids" in a.columns:  # a leg run by train 303 alone (no other train shares one of its legs)
            a = a[[list(ids) != [CUT] for ids in a["train_ids"]]]
        a = a.reset_index(drop=True)
        pd.testing.assert_frame_equal(a, b.reset_index(drop=True), check_dtype=False, obj=name)
        compared += 1
    assert compared >= 10
