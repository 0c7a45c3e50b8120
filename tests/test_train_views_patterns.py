"""The stopping patterns a leg's chart draws (``train_views._patterns``): per arrival stop, the samples of the
lowest and the highest adhesion level of the run's ``stop_samples``, in the dataset's order, whatever the
levels between them and however the partition's rows are split over files."""
from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from planner.job.train_views import _patterns
from planner.line.units import KMH_S


def _write(stage, line, direction, tt, name, rows):
    """A ``stop_samples`` file: rows of (station, adhesion [km/h/s], position, speed)."""
    d = stage / "stop_samples" / f"line={line}" / f"direction={direction}" / f"train_type={tt}"
    d.mkdir(parents=True, exist_ok=True)
    st, a, x, v = zip(*rows)
    pq.write_table(pa.table({"station_id": list(st), "adhesion_ms2": [k * KMH_S for k in a],
                             "position_m": list(map(float, x)), "speed_kmh": list(map(float, v))}), d / name)


def test_lowest_and_highest_level_per_stop_in_dataset_order(tmp_path):
    # stop B: three levels, the middle one left out; its lowest level's samples interleaved with others
    _write(tmp_path, "L", "down", "E1", "part-0.parquet", [
        ("B", 3.0, 10, 30), ("A", 2.5, 1, 5), ("B", 2.5, 11, 31), ("B", 3.5, 12, 32), ("B", 2.5, 13, 33),
        ("A", 2.5, 2, 6),
    ])
    # the same partition in a second file: stop B again, a new lowest level that replaces 2.5
    _write(tmp_path, "L", "down", "E1", "part-1.parquet", [("B", 2.0, 20, 40), ("B", 2.0, 21, 41)])
    _write(tmp_path, "L", "up", "E1", "part-0.parquet", [("A", 3.0, 7, 8)])
    _write(tmp_path, "M", "down", "E1", "part-0.parquet", [("Z", 1.0, 0, 0)])  # another line: not read
    pats = _patterns(tmp_path, "L")
    assert set(pats) == {("down", "E1", "A"), ("down", "E1", "B"), ("up", "E1", "A")}
    b = pats[("down", "E1", "B")]
    assert list(b) == [2.0, 3.5]  # lowest first; 2.5 and 3.0 are between
    assert b[2.0][0].tolist() == [20.0, 21.0] and b[2.0][1].tolist() == [40.0, 41.0]
    assert b[3.5][0].tolist() == [12.0] and b[3.5][1].tolist() == [32.0]
    a = pats[("down", "E1", "A")]  # one level: lowest and highest are the same
    assert list(a) == [2.5] and a[2.5][0].tolist() == [1.0, 2.0] and a[2.5][1].tolist() == [5.0, 6.0]
    assert pats[("up", "E1", "A")][3.0][0].dtype == np.float64


def test_no_samples(tmp_path):
    assert _patterns(tmp_path, "L") == {}


def test_a_file_read_a_row_group_at_a_time_gives_what_the_whole_file_gives(tmp_path):
    """_patterns reads a file a row group at a time (twice: the levels, then their samples): a stop whose lowest
    and highest levels are in different row groups, each row group with its own dictionary of stations, gives
    the patterns of the same rows written as one row group."""
    rows = [("B", 3.0, 10, 30), ("A", 2.5, 1, 5), ("B", 2.5, 11, 31), ("C", 1.0, 3, 3), ("B", 3.5, 12, 32),
            ("B", 2.5, 13, 33), ("A", 2.5, 2, 6), ("B", 3.5, 14, 34), ("C", 4.0, 5, 5)]
    _write(tmp_path / "one", "L", "down", "E1", "part-0.parquet", rows)
    d = tmp_path / "split" / "stop_samples" / "line=L" / "direction=down" / "train_type=E1"
    d.mkdir(parents=True)
    st, a, x, v = zip(*rows)
    pq.write_table(pa.table({"station_id": list(st), "adhesion_ms2": [k * KMH_S for k in a],
                             "position_m": list(map(float, x)), "speed_kmh": list(map(float, v))}),
                   d / "part-0.parquet", row_group_size=2)
    assert pq.ParquetFile(d / "part-0.parquet").metadata.num_row_groups == 5
    one, split = _patterns(tmp_path / "one", "L"), _patterns(tmp_path / "split", "L")
    assert set(one) == set(split) == {("down", "E1", s) for s in "ABC"}
    for k in one:
        assert list(one[k]) == list(split[k])
        for level in one[k]:
            assert all(np.array_equal(p, q) for p, q in zip(one[k][level], split[k][level]))
    assert split[("down", "E1", "B")][3.5][0].tolist() == [12.0, 14.0]  # two row groups, in the file's order
    assert list(split[("down", "E1", "C")]) == [1.0, 4.0]
