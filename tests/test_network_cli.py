"""`planner conflicts LINE --out DIR`: summary, datasets, one-line errors (tiny line on disk, real simulator)."""
from __future__ import annotations

import pandas as pd
import pyarrow.dataset as ds
from typer.testing import CliRunner

from planner.cli import app

from linedb import default_tables, write_line_db

runner = CliRunner()
N = None

# Single track "1" with a stop node at each direction's stop marker and two switches.
NODES = pd.DataFrame(
    [("END-0", "end", 0.0, "IXL1", N, "1"),
     ("A-up", "stop", 140.0, "IXL1", "A", "1"), ("A-dn", "stop", 260.0, "IXL1", "A", "1"),
     ("W1", "switch", 1000.0, "IXL1", N, "1"),
     ("B-up", "stop", 2440.0, "IXL1", "B", "1"), ("B-dn", "stop", 2560.0, "IXL1", "B", "1"),
     ("BND", "boundary", 3000.0, "IXL1", N, "1"),
     ("W2", "switch", 3500.0, "IXL2", N, "1"),
     ("C-up", "stop", 4740.0, "IXL2", "C", "1"), ("C-dn", "stop", 4860.0, "IXL2", "C", "1"),
     ("END-1", "end", 5000.0, "IXL2", N, "1")],
    columns=["node_id", "kind", "position_m", "interlocking", "station_id", "track"])
ORDER = list(NODES["node_id"])
POS = dict(zip(NODES["node_id"], NODES["position_m"]))
EDGES = pd.DataFrame(
    [(f"E{i}", a, b, POS[b] - POS[a], "1") for i, (a, b) in enumerate(zip(ORDER[:-1], ORDER[1:]))],
    columns=["edge_id", "from_node", "to_node", "length_m", "track"])


def timetable(up_dep):
    tt = default_tables()["timetable"]
    up = tt["train_id"] == "202"
    tt.loc[up, ["arrival_s", "departure_s"]] = tt.loc[up, ["arrival_s", "departure_s"]] - 22000.0 + up_dep
    return tt


def test_cli_reports_the_single_track_deadlock_and_writes_datasets(tmp_path):
    # 101 (down) runs B→C 21830–22100 (W2 at 3500 m about 21942). 202 (up) leaves C at 21900, so it claims
    # the section C–W2 (21870) before 101 claims W2 and that section (~21912): 101 then stops holding W2 and
    # the sections behind it, which 202 needs next — a deadlock on the single track.
    line = write_line_db(tmp_path / "tiny", nodes=NODES, edges=EDGES, timetable=timetable(21900.0))
    out = tmp_path / "out"
    r = runner.invoke(app, ["conflicts", str(line), "--out", str(out), "--release-s", "7"])
    assert r.exit_code == 0, r.output
    assert "2 trains routed" in r.stdout and "deadlocks avoided: 1" in r.stdout
    c = ds.dataset(out / "conflicts", partitioning="hive").to_table().to_pandas()
    assert c["deadlock"].all() and c["conflict_id"].nunique() == 1
    # the printed counts are the dataset's: conflicts, train pairs and distinct resources (not rows)
    n_res = c["resource_id"].nunique()
    on = "1 resource" if n_res == 1 else f"{n_res} resources"
    assert f"conflicts: 1 conflict between 1 train pair on {on};" in r.stdout
    assert list(c["conflict_id"].unique()) == [1] and "#1: 101 before 202 at " in r.stdout
    assert all(c["station_id"].isin(["A", "B", "C"])) and "km " in r.stdout
    # 101 leaves the stretch first (arrives C 22100 < 202 leaving it near A); 202 waits at C.
    assert set(c["train_a"]) == {"101"} and set(c["train_b"]) == {"202"}
    occ = ds.dataset(out / "occupation", partitioning="hive").to_table().to_pandas()
    assert set(occ["train_id"]) == {"101", "202"}
    assert (occ["release_s"] == 7.0).all()
    assert (occ["end_s"] - occ["clear_s"]).round(9).eq(7.0).all()
    assert sorted(p.parent.name for p in (out / "occupation").rglob("*.parquet")) == [
        "train_type=EMU10", "train_type=EMU6"]


def test_cli_opposing_train_that_finds_the_track_taken_just_waits(tmp_path):
    # 202 leaving C at 22000 finds 101 already holding every resource up to C: it waits, no deadlock.
    line = write_line_db(tmp_path / "tiny", nodes=NODES, edges=EDGES, timetable=timetable(22000.0))
    r = runner.invoke(app, ["conflicts", str(line), "--out", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    assert "deadlocks avoided: 0" in r.stdout and "leaves-first: 1" in r.stdout


def test_cli_bad_parameter_is_one_line(tmp_path):
    line = write_line_db(tmp_path / "tiny", nodes=NODES, edges=EDGES)
    r = runner.invoke(app, ["conflicts", str(line), "--out", str(tmp_path / "o"), "--setting-s", "-3"])
    assert r.exit_code != 0
    assert "--setting-s" in str(r.exception) or "--setting-s" in r.output


def test_cli_line_without_network_is_a_clear_error(tmp_path):
    line = write_line_db(tmp_path / "tiny", nodes=None, edges=None)
    r = runner.invoke(app, ["conflicts", str(line), "--out", str(tmp_path / "o")])
    assert r.exit_code != 0
    assert "nodes.parquet" in str(r.exception) or "nodes.parquet" in r.output
