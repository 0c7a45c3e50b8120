"""The stopping patterns a leg's chart draws (``datasets.stops.extreme_patterns``): per arrival, the samples of the
lowest and the highest adhesion level, as the run's ``stop_samples`` dataset holds them (its rows of those levels, in
the dataset's order). Made on the chart's worker from the stops step's stored unit; checked here against the
dataset written from the same results and read back with pandas."""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest

from linedb import write_line_db
from planner.datasets.stops import extreme_patterns, write_stops
from planner.line.units import KMH_S


@pytest.fixture(scope="module")
def approaches(tmp_path_factory):
    """Every arrival's patterns of the tiny line (both directions, both train types), at four levels."""
    from planner import load_line
    from planner.stopping.sweep import approach_patterns

    line = load_line(write_line_db(tmp_path_factory.mktemp("line") / "tiny", nodes=None, edges=None))
    levels = [k * KMH_S for k in (2.0, 2.5, 3.0, 3.5)]
    return [approach_patterns(line, t.train_type, a.station_id, b.station_id, levels)
            for t in line.train_types for d in ("down", "up") for a, b in line.interstations(d)]


def _from_dataset(folder) -> dict:
    """{(direction, train type, station): {level: (positions, speeds)}} of the lowest and highest level, from the
    ``stop_samples`` files (their rows in file order)."""
    from planner.io.parquet import read_dataset

    df = read_dataset(folder, "stop_samples").to_pandas()
    df["level"] = np.round(df["adhesion_ms2"].to_numpy() / KMH_S, 6)
    out = {}
    for (d, t, s), g in df.groupby(["direction", "train_type", "station_id"], sort=False):
        out[(d, t, s)] = {lv: (g.loc[g["level"] == lv, "position_m"].to_numpy(float),
                               g.loc[g["level"] == lv, "speed_kmh"].to_numpy(float))
                          for lv in (g["level"].min(), g["level"].max())}
    return out


def test_the_extreme_levels_of_an_arrival_are_its_rows_of_the_dataset(approaches, tmp_path):
    write_stops(approaches, tmp_path)
    expect = _from_dataset(tmp_path)
    got = {(r.direction, r.train_type, r.station_id): extreme_patterns(r) for r in approaches}
    assert len(got) == 8 and {k for k, v in got.items() if v is not None} == set(expect)
    got = {k: v for k, v in got.items() if v is not None}  # no feasible pattern: no rows, nothing drawn
    assert len(got) >= 6
    for k, pats in got.items():
        assert list(pats) == sorted(expect[k]) and len(pats) == 2  # lowest first
        for level, (x, v) in pats.items():
            ex, ev = expect[k][level]
            assert x.dtype == v.dtype == np.float64 and len(x) > 10
            assert np.array_equal(x, ex) and np.array_equal(v, ev)


def test_only_feasible_patterns_count_and_none_without_one(approaches):
    r = approaches[0]
    low = min(range(len(r.patterns)), key=lambda i: r.adhesion_ms2[i])
    gone = dataclasses.replace(r, patterns=tuple(dataclasses.replace(p, feasible=False) if i == low else p
                                                 for i, p in enumerate(r.patterns)))
    assert min(extreme_patterns(gone)) == round(sorted(r.adhesion_ms2)[1] / KMH_S, 6)
    none = dataclasses.replace(r, patterns=tuple(dataclasses.replace(p, feasible=False) for p in r.patterns))
    assert extreme_patterns(none) is None


def test_the_dataset_reader_of_the_test_sees_the_levels_apart(approaches, tmp_path):
    """The reference above is not the function under test in disguise, and it has levels to leave out: every
    arrival's samples in the files are of three levels or more."""
    write_stops(approaches, tmp_path)
    df = pd.concat([pd.read_parquet(f) for f in sorted(tmp_path.rglob("*.parquet")) if "stop_samples" in str(f)])
    levels = df.assign(level=np.round(df["adhesion_ms2"] / KMH_S, 6)).groupby("station_id")["level"].nunique()
    assert len(levels) >= 2 and (levels >= 3).all()
