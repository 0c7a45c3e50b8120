"""The speed–distance chart drawn on the reused figure is the same bytes as one drawn on a new figure.

:func:`planner.pages.speed_chart.reused_subplots` empties one figure per process for every chart; whatever
the previous chart left (another direction, so an inverted x axis, other limits, a stopping pattern
and evaluation points or none, so other legends and data limits) must not reach the next one.
"""
from __future__ import annotations

import numpy as np
import pytest

from linedb import write_line_db


@pytest.fixture(scope="module")
def charts(tmp_path_factory):
    """Every leg's chart inputs of the tiny line, half with a stopping pattern and evaluation points."""
    from planner import load_line
    from planner.report.margins import compute_margins
    from planner.report.train_timetable import leg_runs

    folder = tmp_path_factory.mktemp("line") / "tiny"
    write_line_db(folder, nodes=None, edges=None)
    line = load_line(folder)
    runs = leg_runs(line, compute_margins(line, conflicts=False).rows)
    out = []
    for i, (key, run) in enumerate(sorted(runs.items())):
        d, _, o, de, _ = key
        calls = [(o, True, line.station(o).stop_m(d)), (de, True, line.station(de).stop_m(d))]
        x, v = run.position_m, run.v_ms[1] * 3.6
        extra = ({1.0: (x[-50:], v[-50:]), 2.0: (x[-30:], v[-30:])}, [(float(x[len(x) // 2]), "E1")]) \
            if i % 2 else (None, None)
        out.append((line, run, calls, *extra))
    return out


def _fresh(args) -> str:
    """The chart on a new figure: the reused one closed first (it is made again)."""
    from planner.pages.speed_chart import chart_svg, reused_subplots
    from planner.report.plots import pyplot

    fig, _ = reused_subplots("speed_chart")
    pyplot().close(fig)
    return chart_svg(*args)


def test_the_tiny_line_has_legs_both_ways(charts):
    assert {c[1].key[0] for c in charts} == {"down", "up"}


def test_charts_drawn_in_turn_match_charts_on_new_figures(charts):
    from planner.pages.speed_chart import chart_svg

    fresh = [_fresh(c) for c in charts]
    assert len(set(fresh)) == len(fresh)  # different charts: a figure left unchanged would be noticed
    order = list(range(len(charts)))[::-1] + list(range(len(charts))) + list(np.random.default_rng(1).permutation(
        len(charts)))
    for i in order:
        assert chart_svg(*charts[i]) == fresh[i], f"chart {charts[i][1].key} differs after another chart"
