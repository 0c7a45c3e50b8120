"""`planner validate LINE_DIR`: summary and exit 0, or one line per violation on stderr and exit 1."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from planner.cli import app
from planner.line.schema import RADIUS

from linedb import default_tables, write_line_db

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "lines" / "sample"
PLANNER = Path(sys.executable).with_name("planner")  # the venv's console script

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, ["validate", *map(str, args)])


def test_valid_line_prints_summary(tmp_path):
    r = invoke(write_line_db(tmp_path / "tiny"))
    assert r.exit_code == 0, r.output
    out = r.stdout
    assert "line tiny (Tiny test line): valid, schema v2" in out
    assert "5.000 km" in out
    assert "stations:           3 (2 interstations per direction)" in out
    assert "speed restrictions: 3 (1 without ATS-P beacon)" in out
    assert "beacons:            4 (2 evaluation points)" in out
    assert "signals:            2" in out
    assert "train types:        2 (EMU10, EMU6)" in out
    assert "trains:             2 with 6 calls" in out
    assert "network:            4 nodes, 3 edges" in out
    assert r.stderr == ""


def test_summary_without_network(tmp_path):
    r = invoke(write_line_db(tmp_path / "tiny", nodes=None, edges=None))
    assert r.exit_code == 0
    assert "network" not in r.stdout


def test_violations_one_line_each_on_stderr(tmp_path):
    t = default_tables()
    t["curves"].loc[0, "radius_m"] = -1.0
    t["timetable"]["station_id"] = t["timetable"]["station_id"].astype(object)
    t["timetable"].loc[1, "station_id"] = "Z"
    r = invoke(write_line_db(tmp_path / "tiny", curves=t["curves"], timetable=t["timetable"]))
    assert r.exit_code == 1
    assert r.stdout == ""
    lines = r.stderr.splitlines()
    assert lines == [
        f"curves.parquet row 0 (start_m=1200.0) column radius_m: must be >= 10, found -1.0 "
        f"(accepted [10, 1000000]: {RADIUS.why})",
        "timetable.parquet row 1 (train_id=101 seq=1) column station_id: unknown station 'Z' "
        "(not in stations.parquet)",
        f"{tmp_path / 'tiny'}: 2 problem(s); the line database is invalid"
        " (the rules: docs/line-database.md, or `planner schema`)",
    ]


def test_many_violations_are_capped(tmp_path):
    g = pd.DataFrame({"start_m": np.arange(70) * 10.0, "end_m": np.arange(70) * 10.0 + 5.0,
                      "gradient_permil": np.full(70, -45.0)})
    r = invoke(write_line_db(tmp_path / "tiny", gradients=g))
    assert r.exit_code == 1
    lines = r.stderr.splitlines()
    assert len(lines) == 52  # 50 violations, "… and 20 more", the total
    assert lines[50] == "… and 20 more"
    assert lines[51].endswith("70 problem(s); the line database is invalid"
                              " (the rules: docs/line-database.md, or `planner schema`)")


def test_missing_folder_is_one_line(tmp_path):
    r = invoke(tmp_path / "nowhere")
    assert r.exit_code == 1
    assert len(r.stderr.splitlines()) == 1
    assert "does not exist" in r.stderr
    assert r.exception is None or isinstance(r.exception, SystemExit)


def test_not_parquet(tmp_path):
    path = write_line_db(tmp_path / "tiny")
    (path / "stations.parquet").write_bytes(b"not parquet at all")
    r = invoke(path)
    assert r.exit_code == 1
    assert r.stderr.splitlines()[0].startswith("stations.parquet: is not a readable Parquet file")


@pytest.fixture(scope="module")
def broken_and_valid(tmp_path_factory):
    base = tmp_path_factory.mktemp("cli")
    good = write_line_db(base / "good" / "tiny")
    bad = write_line_db(base / "bad" / "tiny", beacons=None)
    (bad / "curves.parquet").write_text("start_m,end_m\n")
    return good, bad


def _run(path):
    return subprocess.run([str(PLANNER), "validate", str(path)], capture_output=True, text=True,
                          timeout=120, cwd=ROOT)


@pytest.mark.skipif(not PLANNER.exists(), reason="console script not installed next to this python")
def test_console_script_exit_codes_and_no_traceback(broken_and_valid, tmp_path):
    good, bad = broken_and_valid
    ok = _run(good)
    assert ok.returncode == 0, ok.stderr
    assert "valid, schema v2" in ok.stdout
    fail = _run(bad)
    assert fail.returncode == 1
    assert "Traceback" not in fail.stderr
    lines = fail.stderr.splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("curves.parquet: is not a readable Parquet file (")
    assert str(bad) not in lines[0]  # no absolute paths in the per-file message
    assert lines[1] == ("beacons.parquet: file is missing; every line database needs it, even if it has no rows "
                        "(see docs/line-database.md or `planner schema`)")
    assert lines[2] == (f"{bad}: 2 problem(s); the line database is invalid"
                        " (the rules: docs/line-database.md, or `planner schema`)")
    gone = _run(tmp_path / "nowhere")
    assert gone.returncode == 1
    assert "Traceback" not in gone.stderr
    assert len(gone.stderr.splitlines()) == 1


def _sample_ready() -> bool:
    return (SAMPLE / "line.parquet").exists()


@pytest.mark.skipif(not _sample_ready(), reason="lines/sample/*.parquet not built yet (run `make sample`)")
def test_sample_line_is_valid():
    r = invoke(SAMPLE)
    assert r.exit_code == 0, r.stderr
    assert "line sample" in r.stdout
