"""`planner timekeeping` and the function `planner simulate --mode timekeeping` dispatches to."""
from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from planner.line import testing
from planner.cli import app
from planner.cli.timekeeping import parse_change, simulate_timekeeping_cli
from planner.errors import InputError

runner = CliRunner()


def test_parse_change():
    assert parse_change("40:130") == (40.0, 130.0)
    assert parse_change("40.5:99.25") == (40.5, 99.25)
    for bad in ("40", "40-130", "a:b", "1:2:3"):
        with pytest.raises(InputError, match="--change"):
            parse_change(bad)


def test_function_on_an_in_memory_line(capsys):
    line = testing.line(length_m=1000.0, limits=[(400.0, 600.0, 60.0)])
    res = simulate_timekeeping_cli(line, "T", "S0", "S1", 90.0, ["40:100"], 0.0, 1.0, True)
    out = json.loads(capsys.readouterr().out)
    assert out["scheduled_arrival_s"] == 100.0
    assert abs(out["arrival_error_s"]) <= 0.2 and abs(out["stop_error_m"]) <= 0.2
    assert out["feasible"] and res.feasible
    assert [c["arrival_s"] for c in out["changes"]] == [90.0, 100.0]
    assert {s["advice"] for s in out["advice"]} <= {"power", "hold", "coast", "brake"}


def test_cli_text_json_and_plot(tmp_path, sample_dir):
    png = tmp_path / "tk.png"
    r = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "E10", "--from", "MNT", "--to", "SKM",
                            "--arrival", "140", "--change", "40:170", "--plot", str(png)])
    assert r.exit_code == 0, r.output
    assert "arrival error" in r.output and "advice:" in r.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    r1 = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "E10", "--from", "MNT", "--to", "SKM",
                             "--arrival", "140", "--change", "40:170", "--json"])
    r2 = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "E10", "--from", "MNT", "--to", "SKM",
                             "--arrival", "140", "--change", "40:170", "--json"])
    assert r1.exit_code == 0 and r1.stdout == r2.stdout  # deterministic
    assert abs(json.loads(r1.stdout)["arrival_error_s"]) <= 0.2


def test_cli_fails_on_shortfall(sample_dir):
    """An arrival that cannot be met prints the run, then one error line, and exits 1 (issue 17)."""
    r = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "E10", "--from", "MNT", "--to", "SKM",
                            "--arrival", "140", "--change", "40:60", "--json"])
    assert r.exit_code == 1
    assert r.stderr.startswith("error: scheduled arrival") and "shortfall" in r.stderr
    out = json.loads(r.stdout)
    assert not out["feasible"] and out["shortfall_s"] > 0
    assert out["arrival_error_s"] == pytest.approx(out["shortfall_s"], abs=0.2)


def test_cli_bad_input_is_one_line(sample_dir):
    r = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "E10", "--from", "MNT", "--to", "SKM",
                            "--arrival", "140", "--change", "40-60"])
    assert r.exit_code != 0
    assert r.stderr.strip().startswith("error: --change") and "Traceback" not in r.output
    r = runner.invoke(app, ["timekeeping", str(sample_dir), "--train-type", "NOPE", "--from", "MNT", "--to", "SKM",
                            "--arrival", "140"])
    assert r.exit_code != 0 and "unknown train type" in r.stderr


def test_planner_simulate_mode_timekeeping(tmp_path, sample_dir):
    """`planner simulate --mode timekeeping` sweeps designated times like the table modes and writes
    the same closed_loop rows, with the plant's stop error (issue 14)."""
    import pyarrow.dataset as ds

    from linedb import write_line_db

    line_dir = write_line_db(tmp_path / "tiny")
    tabs, sim = tmp_path / "tables", tmp_path / "sim"
    r = runner.invoke(app, ["tables", str(line_dir), "--out", str(tabs), "--train-type", "EMU10",
                            "--ratios", "1.0:0.6:0.1", "--jobs", "1"])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["simulate", str(line_dir), "--tables", str(tabs), "--out", str(sim), "--train-type",
                            "EMU10", "--mode", "timekeeping", "--extra", "6",
                            "--jobs", "1"])
    assert r.exit_code == 0, r.output
    assert "stop error" not in r.output  # 0 by construction: the simulated train stands on the marker
    rows = ds.dataset(sim / "closed_loop", partitioning="hive").to_table().to_pandas()
    assert set(rows["mode"]) == {"timekeeping"} and set(rows["scenario"]) == {"nominal"}
    assert len(rows) == 4 * 7  # 4 interstation x direction, designated minimum … minimum + 6 s
    feas = rows[rows.feasible]
    assert len(feas) >= 4 * 6
    assert feas.error_s.abs().max() <= 0.5
    assert "stop_error_m" not in rows.columns
    no_tables = runner.invoke(app, ["simulate", str(sample_dir), "--mode", "timekeeping"])
    assert no_tables.exit_code == 1 and "--tables" in no_tables.output
