"""The margin report's leg groups as units of their own (planner.job.leg_memo): an unchanged line reads every
group back and gives the same report; an edit recomputes exactly the groups whose slice of the line it
touches, and the report is the one a cold computation of the edited line gives."""
from __future__ import annotations

import dataclasses

import pandas as pd
import pytest

from planner.job.leg_memo import LegMemo
from planner.report.margins import compute_margins

TYPES = ["E6"]


def _report(line, memo, **options):
    return compute_margins(line, conflicts=False, memo=memo, n_jobs=1, train_types=TYPES, **options)


def _same(a, b) -> None:
    pd.testing.assert_frame_equal(a.rows, b.rows)
    pd.testing.assert_frame_equal(a.totals, b.totals)
    pd.testing.assert_frame_equal(a.sweep, b.sweep)


def test_an_unchanged_line_reads_every_group_back(tmp_path, sample_line):
    cold = LegMemo(tmp_path)
    first = _report(sample_line, cold)
    assert cold.hits == 0 and cold.computed == len(first.rows.groupby(["direction", "origin", "destination"]))
    warm = LegMemo(tmp_path)
    _same(first, _report(sample_line, warm))
    assert (warm.hits, warm.computed) == (cold.computed, 0)
    other = LegMemo(tmp_path)      # the options a leg is computed with are part of its key
    _report(sample_line, other, adhesion_kmh_s=[2.0, 3.0])
    assert other.hits == 0


def test_an_edit_recomputes_the_groups_it_touches_and_gives_the_cold_report(tmp_path, sample_line):
    # lower the civil limit at 5,000-5,150 m (row 4 of the sample) from 85 to 60 km/h
    i = next(k for k, s in enumerate(sample_line.speed_limits) if s.kind == "civil" and s.start_m == 5000.0)
    limits = list(sample_line.speed_limits)
    limits[i] = dataclasses.replace(limits[i], limit_ms=60 / 3.6)
    edited = dataclasses.replace(sample_line, speed_limits=tuple(limits))
    memo = LegMemo(tmp_path)
    _report(sample_line, memo)
    n = memo.computed
    memo = LegMemo(tmp_path)
    after = _report(edited, memo)
    # the groups whose run can see 5,000-5,150 m: their stretch between the stop markers, widened by a train
    stretch = {}
    for r in after.rows.itertuples():
        a, b = sorted((sample_line.station(r.origin).position_m, sample_line.station(r.destination).position_m))
        stretch[(r.direction, r.origin, r.destination)] = (a - 300.0, b + 300.0)
    touched = sum(a < 5150.0 and b > 5000.0 for a, b in stretch.values())
    assert 0 < memo.computed == touched < n
    assert memo.hits == n - touched
    _same(after, _report(edited, None))
