"""Numbers as the pages write them (planner.line.units): whole percent with the space, as ``ratio 100 %``
is written on every page, and the no-value dash."""
from __future__ import annotations

import math

from planner.line.units import percent


def test_percent_is_whole_percent_with_a_space():
    assert percent(0.7) == "70 %"
    assert percent(1.0) == "100 %"
    assert percent(0.655) == "66 %" and percent(0.645) == "64 %"  # halves round to even, as Python formats
    assert percent(0.0) == "0 %" and percent(-0.001) == "0 %"  # never "-0 %"


def test_percent_of_no_value_is_the_dash():
    assert percent(math.nan) == "–" and percent(None) == "–" and percent(math.inf) == "–"
