"""The command line as a new user meets it (issue 17, "The command line"): each point runs the command
and checks the exit code and the message. Everything here is fast: the checks happen before computing."""
from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

import planner
from planner.cli import app

SAMPLE = Path(__file__).resolve().parents[1] / "lines" / "sample"
runner = CliRunner()


def run(*args, **kw):
    return runner.invoke(app, [str(a) for a in args], **kw)


def one_line_error(r, *needles, code=1):
    """Exit ``code``, exactly one stderr line starting with 'error:', no traceback, holding every needle."""
    assert r.exit_code == code, (r.exit_code, r.output)
    err = r.stderr.strip()
    assert err.startswith("error:") and "\n" not in err and "Traceback" not in r.output, r.output
    for n in needles:
        assert n in err, (n, err)
    return err


def _forbid(monkeypatch, module, name):
    """Make a computation fail loudly if it is reached: proves the check came first."""
    def boom(*a, **k):
        raise AssertionError(f"{name} ran before the output path was checked")
    monkeypatch.setattr(module, name, boom)


# --- output paths checked before computing, one-line errors -----------------------------------
def test_stops_out_an_existing_file_fails_before_computing(tmp_path, monkeypatch):
    import planner.stopping.sweep

    _forbid(monkeypatch, planner.stopping.sweep, "stop_sweep")
    f = tmp_path / "file"
    f.write_text("x")
    one_line_error(run("stops", SAMPLE, "--out", f), "--out", "not a folder")
    assert f.read_text() == "x"


@pytest.mark.parametrize("cmd", [
    ["tables", SAMPLE, "--out", "{f}/sub"],
    ["margins", SAMPLE, "--out", "{f}"],
    ["conflicts", SAMPLE, "--out", "{f}"],
    ["simulate", SAMPLE, "--tables", "{d}", "--out", "{f}"],
    ["bundle", "build", SAMPLE, "--out", "{f}", "--key", "{f}"],
])
def test_every_out_folder_is_checked(tmp_path, cmd):
    f = tmp_path / "file"
    f.write_text("x")
    args = [str(a).format(f=f, d=tmp_path) for a in cmd]
    one_line_error(run(*args), "--out", str(f))


@pytest.mark.parametrize("where", ["{f}/sub", "/proc/x"])  # below a regular file; a pseudo file system
@pytest.mark.parametrize("cmd", [
    ["graph", SAMPLE, "--out", "{out}"],
    ["export", "csv", SAMPLE, "--out", "{out}"],
    ["import", "csv", "{d}", "--out", "{out}"],
    ["import", "csv", "--template", "{out}"],
    ["import", "railjson", "{d}/infra.json", "--path", "A,B", "--rolling-stock", "{d}/rs.json", "--out", "{out}"],
    ["import", "railml", "{d}/line.xml", "--line", "L1", "--rolling-stock", "{d}/rs.json", "--out", "{out}"],
    ["diff", "{d}", "{d}", "--out", "{out}"],
    ["schema", "--write", "{out}/line-database.md"],
    ["datasets", "--write", "{out}/README.md"],
])
def test_every_other_output_path_is_checked_before_anything_runs(tmp_path, cmd, where, monkeypatch):
    import planner.report.changes
    import planner.report.train_graph

    _forbid(monkeypatch, planner.report.train_graph, "graph_data")
    _forbid(monkeypatch, planner.report.changes, "compare_runs")
    f = tmp_path / "file"
    f.write_text("x")
    out = where.format(f=f)
    args = [str(a).format(out=out, d=tmp_path) for a in cmd]
    err = one_line_error(run(*args), out)
    assert "not a folder" in err or "cannot write" in err
    assert f.read_text() == "x"


def test_runtime_plot_in_proc_fails_before_computing(monkeypatch):
    import planner.api

    _forbid(monkeypatch, planner.api, "running_time")
    one_line_error(run("runtime", SAMPLE, "--train-type", "E10", "--from", "TKD", "--to", "OHS",
                       "--plot", "/proc/x/a.png"), "--plot /proc/x/a.png", "cannot write")


def test_keys_generate_in_proc_and_below_a_file(tmp_path):
    one_line_error(run("keys", "generate", "/proc/x"), "/proc/x", "cannot write")
    f = tmp_path / "file"
    f.write_text("x")
    one_line_error(run("keys", "generate", f / "k"), "is a file, not a folder")


def test_datasets_write_into_a_folder_is_refused(tmp_path):
    one_line_error(run("datasets", "--write", tmp_path), "--write", "is a folder")


def test_job_whose_output_root_is_a_file(tmp_path, monkeypatch):
    import planner.job.pipeline

    _forbid(monkeypatch, planner.job.pipeline, "run_job")
    (tmp_path / "lines" / "x").mkdir(parents=True)
    (tmp_path / "outputs").write_text("x")
    (tmp_path / "jobs").mkdir()
    job = tmp_path / "jobs" / "j.toml"
    job.write_text('[job]\nlines = ["lines/x"]\noutput_root = "outputs"\n')
    one_line_error(run("run", job), "[job] output_root", "is a file, not a folder")


# --- version, completion, --jobs ---------------------------------------------------------------
def test_version():
    r = run("--version")
    assert r.exit_code == 0 and r.stdout.strip() == f"planner {planner.__version__}"


def test_shell_completion_is_on():
    r = run("--help")
    assert r.exit_code == 0 and "--install-completion" in r.stdout and "--show-completion" in r.stdout
    r = runner.invoke(app, [], env={"_PLANNER_COMPLETE": "complete_bash", "COMP_WORDS": "planner ru",
                                    "COMP_CWORD": "1"}, prog_name="planner")
    assert r.exit_code == 0 and r.stdout.split() == ["runtime", "run"]


def _all_options():
    import typer.main

    cli = typer.main.get_command(app)

    def walk(cmd, path):
        for p in getattr(cmd, "params", []):
            yield path, p
        for name, sub in getattr(cmd, "commands", {}).items():
            yield from walk(sub, path + [name])
    return list(walk(cli, []))


def test_one_spelling_jobs():
    names = {o for _, p in _all_options() for o in getattr(p, "opts", [])}
    assert "--n-jobs" not in names and "--jobs" in names
    with_jobs = {" ".join(path) for path, p in _all_options() if "--jobs" in getattr(p, "opts", [])}
    assert {"conflicts", "tables", "simulate", "stops", "margins"} <= with_jobs
    r = run("conflicts", SAMPLE, "--out", "/tmp/x", "--n-jobs", "2")
    assert r.exit_code == 2 and "No such option" in r.output
    one_line_error(run("conflicts", SAMPLE, "--out", "/tmp/x", "--jobs", "0"), "--jobs")


# --- codes: case-insensitive, "did you mean" ----------------------------------------------------
def test_codes_are_case_insensitive():
    r = run("runtime", SAMPLE, "--train-type", "e10", "--from", "tkd", "--to", "Ohs", "--json")
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert (d["train_type"], d["origin"], d["destination"]) == ("E10", "TKD", "OHS")


def test_unknown_codes_get_a_suggestion():
    one_line_error(run("runtime", SAMPLE, "--train-type", "E10", "--from", "TKX", "--to", "OHS"),
                   "--from TKX", "did you mean TKD?")
    one_line_error(run("runtime", SAMPLE, "--train-type", "E1O", "--from", "TKD", "--to", "OHS"),
                   "--train-type E1O", "did you mean E10?")
    one_line_error(run("timekeeping", SAMPLE, "--train-type", "E10", "--from", "MNT", "--to", "skx",
                       "--arrival", "140"), "--to skx", "did you mean SKM?")


# --- --load outside 0…1 -------------------------------------------------------------------------
@pytest.mark.parametrize("load", ["1.5", "-0.1"])
def test_load_outside_0_1_is_refused(load):
    base = ["--train-type", "E10", "--from", "MNT", "--to", "SKM"]
    one_line_error(run("runtime", SAMPLE, *base, "--load", load), "--load", "between 0 and 1")
    one_line_error(run("timekeeping", SAMPLE, *base, "--arrival", "140", "--load", load), "--load")


# --- an impossible time-keeping arrival exits non-zero --------------------------------------------
def test_impossible_timekeeping_arrival_exits_1():
    r = run("timekeeping", SAMPLE, "--train-type", "E10", "--from", "MNT", "--to", "SKM", "--arrival", "60")
    err = one_line_error(r, "cannot be met", "shortfall")
    assert "arrived" in r.stdout  # what the train did at the limit is still printed
    assert err


# --- the job file reports all its errors at once ----------------------------------------------
def test_job_file_reports_every_problem(tmp_path):
    (tmp_path / "lines" / "x").mkdir(parents=True)
    (tmp_path / "jobs").mkdir()
    job = tmp_path / "jobs" / "j.toml"
    job.write_text(textwrap.dedent("""
        [job]
        lines = ["lines/x"]
        keep_runs = 0
        [tables]
        ds_m = -1
        colour = "red"
        [margins]
        degraded_load = 1.5
        [tabels]
    """))
    r = run("run", job)
    assert r.exit_code == 1 and "Traceback" not in r.output
    err = r.stderr.strip().splitlines()
    assert err[0] == f"error: {job}: 5 problems"
    body = "\n".join(err[1:])
    for needle in ("[job] keep_runs", "[tables] ds_m", "[tables] colour: unknown key", "[margins] degraded_load",
                   "unknown section [tabels]"):
        assert needle in body, needle
    assert len(err) == 6


# --- help texts -------------------------------------------------------------------------------------
def test_conflicts_help_shows_the_section_literally():
    r = run("conflicts", "--help")
    assert r.exit_code == 0 and "[conflicts]" in r.stdout and "\\[" not in r.stdout


def test_tables_help_names_all_four_tables():
    r = run("tables", "--help")
    text = " ".join(r.stdout.split())
    assert r.exit_code == 0 and "(a), (b), (c) and (d)" in text and "table_d/" in text


def test_mode_help_and_error_list_the_same_modes():
    import re

    text = " ".join(run("simulate", "--help").stdout.split())
    in_help = re.search(r"On-board mode, one of ([a-z, ]+):", text).group(1).split(", ")
    err = one_line_error(run("simulate", SAMPLE, "--mode", "fastest"), "--mode 'fastest'")
    in_error = err.split("use one of ")[1].split(", ")
    assert in_help == in_error and "timekeeping" in in_help and "adaptive" in in_help


# --- conflict listings: in order, no "(+0 more)" ----------------------------------------------
def test_conflict_listing_in_time_order_without_plus_zero():
    from planner.datasets.conflicts import _summary

    rows = []
    for cid, (t0, delay, n) in enumerate([(100.0, 5.0, 1), (200.0, 30.0, 3), (300.0, 1.0, 1), (400.0, 20.0, 2),
                                          (500.0, 2.0, 1), (600.0, 9.0, 1), (700.0, 0.5, 1)]):
        for k in range(n):
            rows.append(dict(conflict_id=cid, train_a=f"A{cid}", train_b=f"B{cid}", rule="follow", delay_s=delay,
                             deadlock=False, overlap_s=1.0, resource_id=f"R{cid}-{k}", overlap_start_s=t0 + k,
                             overlap_end_s=t0 + k + 1.0, decision="", resource_kind="section", interlocking="IXL",
                             track="D1", station_id="S", station_name="Sta", station_distance_m=0.0,
                             from_m=100.0 * k, to_m=100.0 * k + 50.0, headway_s=1.0, min_headway_s=2.0))
    s = _summary([], [], [], pd.DataFrame(rows))
    ids = [int(x.split(":")[0].lstrip("#")) for x in s["worst"]]
    assert ids == sorted(ids) == [0, 1, 3, 4, 5]  # the five largest delays, in time order
    assert not any("+0 more" in x for x in s["worst"])
    assert "and 2 more resources" in s["worst"][1] and "and 1 more resource " in s["worst"][2]


def test_conflicts_command_output_has_no_plus_zero(tmp_path):
    from test_network_cli import EDGES, NODES, timetable
    from linedb import write_line_db

    line = write_line_db(tmp_path / "tiny", nodes=NODES, edges=EDGES, timetable=timetable(21900.0))
    r = run("conflicts", line, "--out", tmp_path / "out")
    assert r.exit_code == 0, r.output
    assert "#1: 101 before 202" in r.stdout and "(+" not in r.stdout


def test_an_os_error_while_writing_is_one_line(tmp_path, monkeypatch):
    """A fault no up-front check can see (the disk fills while writing) is one line, not a traceback."""
    import errno

    import planner.io.atomic

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x.md"))

    monkeypatch.setattr(planner.io.atomic, "write_bytes_atomic", full)
    one_line_error(run("schema", "--write", tmp_path / "x.md"), "No space left on device", str(tmp_path / "x.md"))


def test_output_starts_with_its_first_line_and_says_how_many_more(tmp_path):
    """No blank first line (a progress bar that stops on a stdout that is no terminal printed one), and a
    listing cut to its first lines says how many it left out: the tiny line has 3 stations, so 2
    interstations x 2 directions x 2 train types = 8 tables, 3 shown."""
    from linedb import write_line_db

    line = write_line_db(tmp_path / "tiny")
    r = run("tables", line, "--out", tmp_path / "t", "--jobs", "1")
    assert r.exit_code == 0, r.output
    lines = r.stdout.splitlines()
    assert lines[0].startswith("tiny: tables for 8 interstation"), lines[:2]
    assert sum("->" in x and "minimum" in x for x in lines) == 3
    assert f"  … 5 more (every one in {tmp_path / 't' / 'table_a'})" in lines
