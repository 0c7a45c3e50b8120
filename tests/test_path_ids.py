"""Ids that become file names or partition values: one rule (planner.io.paths.PATH_ID_RE), refused by
`validate` up front and checked again where paths are built; and a station beyond the line's end."""
from __future__ import annotations

import pyarrow as pa
import pytest

from planner.errors import BundleError, InputError, JobError, LineValidationError
from planner.line.loader import load_line

from linedb import default_tables, write_line_db

BAD_IDS = ["../../x", "a/b", "..", ".hidden", "x y", "a=b", "50%", "tab\tx", "é", "x" * 65, "-x"]
GOOD_IDS = ["Z", "E-6", "x" * 64, "0.9_a"]


def _load(tmp_path, **overrides):
    return load_line(write_line_db(tmp_path / "tiny", **overrides))


def _violations(tmp_path, **overrides):
    with pytest.raises(LineValidationError) as ei:
        _load(tmp_path, **overrides)
    return ei.value.violations


@pytest.mark.parametrize("bad", BAD_IDS)
def test_a_train_type_that_cannot_name_a_file_is_refused(tmp_path, bad):
    t = default_tables()
    for name in ("rolling_stock", "traction", "timetable"):
        df = t[name]
        df.loc[df["train_type"] == "EMU6", "train_type"] = bad
    sl = t["speed_limits"]
    sl.loc[sl["train_type"] == "EMU6", "train_type"] = bad
    found = _violations(tmp_path, **t)
    hits = [v for v in found if (v.file, v.row, v.column) == ("rolling_stock.parquet", 1, "train_type")]
    assert len(found) == 1 and hits, "\n".join(map(str, found))  # one message, on the defining row
    assert "cannot name a file or partition" in str(hits[0]) and "1-64 letters" in str(hits[0])


@pytest.mark.parametrize("bad", ["a b", "li%ne", "x" * 65])
def test_a_line_id_that_cannot_name_a_partition_is_refused(tmp_path, bad):
    folder = tmp_path / bad  # the folder has the same name: only the path rule is broken
    t = default_tables(bad)
    with pytest.raises(LineValidationError) as ei:
        load_line(write_line_db(folder, **t))
    found = ei.value.violations
    assert [str(v) for v in found] == [f"line.parquet row 0 (line_id={bad}) column line_id: {bad!r} cannot name "
                                       "a file or partition; use 1-64 letters, digits, '.', '_' or '-', starting "
                                       "with a letter or digit"]


@pytest.mark.parametrize("good", GOOD_IDS)
def test_ids_within_the_rule_load(tmp_path, good):
    t = default_tables()
    for name in ("rolling_stock", "traction", "timetable"):
        df = t[name]
        df.loc[df["train_type"] == "EMU6", "train_type"] = good
    sl = t["speed_limits"]
    sl.loc[sl["train_type"] == "EMU6", "train_type"] = good
    assert good in [tt.train_type for tt in _load(tmp_path, **t).train_types]


def test_writers_check_again_where_they_build_paths(tmp_path):
    from planner.bundle.manifest import bundle_name
    from planner.io.parquet import write_partitioned

    table = pa.table({"line": ["tiny"], "direction": ["down"], "train_type": ["../../x"], "v": [1.0]})
    with pytest.raises(InputError, match="cannot name a file or partition"):
        write_partitioned(table, tmp_path / "out", "table_a")
    assert not (tmp_path / "out").exists() and not (tmp_path / "x").exists()
    with pytest.raises(BundleError, match="cannot name a bundle"):
        bundle_name("tiny", "down", "a/b")


def test_a_scenario_name_that_cannot_name_a_partition_is_refused(tmp_path):
    from planner.job.config import load_job

    write_line_db(tmp_path / "lines" / "tiny")
    (tmp_path / "jobs").mkdir()
    p = tmp_path / "jobs" / "job.toml"
    p.write_text('[job]\nlines = ["lines/tiny"]\n[closed_loop]\nscenarios = [{name = "../evil"}]\n')
    with pytest.raises(JobError, match=r"scenarios\[0\]: name '../evil' cannot name a partition"):
        load_job(p)


@pytest.mark.parametrize("position", [5200.0, -10.0])
def test_a_station_outside_the_line_is_refused(tmp_path, position):
    t = default_tables()
    row = 2 if position > 0 else 0
    t["stations"].loc[row, "position_m"] = position
    found = _violations(tmp_path, stations=t["stations"])
    assert [str(v) for v in found] == [
        f"stations.parquet row {row} (station_id={'C' if row else 'A'}) column position_m: {position} is outside "
        "the line's chainage range [0.0, 5000.0] (line.parquet start_m/end_m)"]
