"""The pandas, pyarrow and DuckDB examples of outputs/README.md, run as written against two small
published runs, and what each returns checked against the datasets read another way.

The examples are taken from the generated README itself (not copied here), so an example that
stops working, or starts returning something else than its text says, fails this test.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

from linedb import quick_job, write_line_db

README = Path(__file__).resolve().parents[1] / "outputs" / "README.md"


def _blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def _value(code: str, cwd: Path, monkeypatch) -> dict:
    """Run one example in ``cwd``; a last ``….show()`` gives its relation as a DataFrame in ``_shown``."""
    tree = ast.parse(code)
    last = tree.body[-1]
    if (isinstance(last, ast.Expr) and isinstance(last.value, ast.Call)
            and isinstance(last.value.func, ast.Attribute) and last.value.func.attr == "show"):
        rel = last.value.func.value
        tree.body[-1] = ast.parse("_shown = None").body[0]
        tree.body[-1].value = ast.Call(ast.Attribute(rel, "df", ast.Load()), [], [])
        ast.fix_missing_locations(tree)
    monkeypatch.chdir(cwd)
    ns: dict = {}
    exec(compile(tree, "outputs/README.md", "exec"), ns)  # noqa: S102 - the documentation's own examples
    return ns


def _margins(run: Path) -> pd.DataFrame:
    rows = []
    for f in sorted((run / "margins").rglob("*.parquet")):
        parts = dict(p.split("=", 1) for p in f.relative_to(run / "margins").parts[:-1])
        rows.append(pq.read_table(f).to_pandas().assign(**parts))
    return pd.concat(rows, ignore_index=True)


@pytest.fixture(scope="module")
def published(tmp_path_factory):
    """Two runs of a tiny line on two run dates (the second reuses every cached result) under
    ``outputs/``, as the README's paths expect."""
    from planner.job.config import load_job
    from planner.job.pipeline import run_job

    root = tmp_path_factory.mktemp("proj")
    write_line_db(root / "lines" / "tiny", nodes=None, edges=None)
    (root / "jobs").mkdir()
    job = root / "jobs" / "job.toml"
    runs = []
    for day in ("2026-01-01", "2026-01-02"):
        job.write_text(quick_job(["lines/tiny"], "outputs", run_date=day))
        runs.append(run_job(load_job(job), show_progress=False).run_id)
    return root, runs


def test_readme_has_the_four_examples():
    code = _blocks()
    assert len(code) == 4 and sum("duckdb" in c for c in code) == 2


def test_side_by_side_gives_one_row_per_leg_with_both_runs(published, monkeypatch):
    root, (r1, r2) = published
    code = next(c for c in _blocks() if "outputs/r*/margins" in c)
    got = _value(code, root, monkeypatch)["_shown"]
    want = _margins(root / "outputs" / r2)
    want = want[want.scheduled_running_time_s.notna()]
    assert list(got.columns) == ["direction", "train_type", "origin", "destination", "scheduled_running_time_s",
                                 "restrictions", "before_s", "after_s", "change_s"]
    # side by side: one row per timetabled leg, not one per leg and run stacked
    assert len(got) == len(want) > 0
    keys = ["direction", "train_type", "origin", "destination", "scheduled_running_time_s"]
    m = got.merge(want[keys + ["remaining_margin_s"]], on=keys, validate="one_to_one")
    assert (m.after_s == m.remaining_margin_s).all()
    # the two runs planned the same line (only the date differs): the same margins, no change
    assert (m.before_s == m.after_s).all() and (m.change_s == 0.0).all()


def test_pandas_example_reads_the_down_rows_of_table_a(published, monkeypatch):
    root, (_, r2) = published
    code = next(c for c in _blocks() if "pd.read_parquet" in c)
    a = _value(code, root, monkeypatch)["a"]
    files = sorted((root / "outputs" / r2 / "table_a").rglob("direction=down/**/*.parquet"))
    assert files and len(a) == sum(pq.read_metadata(f).num_rows for f in files)
    assert set(a.direction) == {"down"} and set(a.run_id) == {r2}
    # the tiny line: 2 down interstations per train type, each with every ratio of the grid
    assert a.groupby(["train_type", "origin"]).ratio.nunique().nunique() == 1


def test_pyarrow_example_reads_the_perturbed_summary(published, monkeypatch):
    root, (_, r2) = published
    code = next(c for c in _blocks() if "pyarrow.dataset" in c)
    worst = _value(code, root, monkeypatch)["worst"]
    # 2 interstations x 2 directions x 2 train types, one mode, the perturbed scenario only
    assert len(worst) == 8 and set(worst.scenario) == {"perturbed"} and set(worst["mode"]) == {"nearest"}


def test_duckdb_flag_example_lists_the_flagged_legs_unassessed_first(published, monkeypatch):
    root, (_, r2) = published
    code = next(c for c in _blocks() if "outputs/latest/margins" in c)
    got = _value(code, root, monkeypatch)["_shown"]
    m = _margins(root / "outputs" / r2)
    flagged = m[m.unassessed.fillna(False) | m.infeasible.fillna(False) | m.tight.fillna(False)]
    assert len(got) == len(flagged)
    assert sorted(got.remaining_margin_s.dropna()) == list(got.remaining_margin_s.dropna())


def test_the_2_5_level_filters_without_arithmetic(published):
    """adhesion in km/h/s beside the SI column: `= 2.5` finds the job's lowest level (2.5:3.5:0.5)."""
    import duckdb

    root, (_, r2) = published
    run = root / "outputs" / r2
    n = duckdb.sql(f"select count(*) from read_parquet('{run}/stop_summary/**/*.parquet', hive_partitioning = true)"
                   " where adhesion_kmh_s = 2.5").fetchall()[0][0]
    s = pd.concat(pq.read_table(f).to_pandas() for f in sorted((run / "stop_summary").rglob("*.parquet")))
    assert n == int((abs(s.adhesion_ms2 - 2.5 / 3.6) < 1e-12).sum()) > 0
    m = _margins(run)
    assert set(m.adhesion_min_kmh_s) == {2.5}  # the bad day's stop at the sweep's lowest level
