"""Acceptance (issue 4) on the sample line: closed-loop arrival errors of the on-board modes.

The whole line is measured by ``benchmarks/bench_closed_loop.py`` (66 interstation tasks, a few
minutes); this test runs a representative subset in well under a minute: for every train type,
two interstations per direction —

* TKD→OHS and OHS→TKD, the 7.0 km runs (longest, most evaluation points, OHS→TKD has the
  deliberately tight margin of the timetable);
* HGO→MDR down, where the sawtooth E6 had its largest error in the adaptive mode (the coasting
  band's phase at the home-signal beacon 325 m before the stop, until table (d));
* KWB→SKM up, where the E6 adaptive mode once chose the lowest ratio 325 m before the stop
  (5 s late, perturbed) from a coasting-band spike of table (c): a regression case (table (d)
  now predicts there from the train's own state; table (c) is no longer smoothed).

Tables are built as the nightly job builds them (load 0, nominal traction, default ratio grid);
the perturbed scenario runs a heavier, weaker train against those same tables. Bounds are the
issue's, over feasible runs (designated time the scenario's train can meet at all):
nearest rule max ≤ 2 s nominal, ≤ 3 s perturbed; better mode (``adaptive``) median ≤ 0.3 s and
max ≤ 1 s in both. Cases the method does not meet are strict xfails with the reason, so an
improvement that meets them turns into a failure asking to remove the mark.
"""
from __future__ import annotations


import numpy as np
import pytest

from planner.tables.closed_loop import closed_loop_interstation
from planner.tables.ratios import ratio_grid
from planner.tables.build import interstation_tables

SUBSET = (("TKD", "OHS"), ("HGO", "MDR"), ("OHS", "TKD"), ("KWB", "SKM"))
TYPES = ("E10", "E8", "E6")
SCENARIOS = ("nominal", "perturbed")
NEAREST_MAX_S = {"nominal": 2.0, "perturbed": 3.0}     # issue 4
BETTER_MEDIAN_S, BETTER_MAX_S = 0.3, 1.0                # issue 4, both scenarios

NEAREST_REASON = (
    "published nearest rule, default grid: the 10 % steps above 70 % leave gaps of 5-8 s between "
    "neighbouring table-(b) entries at the last evaluation point with authority (the block signal "
    "~1 km before the stop); the home-signal beacon 325-450 m before the stop can barely change "
    "the arrival any more (the train is about to brake, its row spans < 1 s at ratios >= 0.7), so "
    "half that gap, 2.5-4 s, remains (measured max 3.7 s nominal, 5.3 s perturbed on the line). "
    "Issue 22: no setting with bundles under 2x today's meets it on the whole line either: best "
    "measured 2.5 % steps, points every 500 m (bundle 1.59x): 1.55 s nominal, 3.43 s perturbed; 2.5 % "
    "beacons only (1.35x): 1.67 s / 3.74 s; 5 % steps, points every 200 m (1.18x): 2.83 s / 4.04 s "
    "(bench_eval_interval.py). The perturbed worst (E6 TKD->OHS) is already "
    "late at the last points with authority (1167 m and 335 m before the stop: the remaining time "
    "wanted is below the row's fastest entry), because the nominal tables overrate the heavy train; "
    "the nominal worst comes from table (b) indexing the state by the ratio run before, which no "
    "longer holds after ratio changes (E6 sawtooth)"
)


@pytest.fixture(scope="module")
def results(sample_line):
    line = sample_line
    grid = ratio_grid(None, line_max_speed_ms=line.max_speed_ms)
    out = {}
    for tt in TYPES:
        for o, d in SUBSET:
            tabs = interstation_tables(line, tt, o, d, grid).onboard()
            for mode in ("nearest", "adaptive"):
                for sc in SCENARIOS:
                    out.setdefault((tt, mode, sc), []).append(
                        closed_loop_interstation(line, tt, tabs, scenario=sc, mode=mode))
    return out


def _errors(res) -> np.ndarray:
    """|arrival error| of the feasible runs [s]."""
    return np.abs(np.concatenate([r.error_s[r.feasible] for r in res]))


def test_subset_is_representative(results):
    """Every type, both directions, both 7 km runs; enough feasible runs in each case."""
    for (tt, mode, sc), res in results.items():
        assert {(r.origin, r.destination) for r in res} == set(SUBSET)
        assert {r.direction for r in res} == {"down", "up"}
        n = sum(int(r.feasible.sum()) for r in res)
        assert n >= 0.8 * sum(r.designated_s.size for r in res), (tt, mode, sc, n)


@pytest.mark.parametrize("sc", SCENARIOS)
@pytest.mark.parametrize("tt", TYPES)
def test_adaptive_meets_the_issue_bounds(results, tt, sc):
    e = _errors(results[(tt, "adaptive", sc)])
    assert np.median(e) <= BETTER_MEDIAN_S and e.max() <= BETTER_MAX_S, (np.median(e), e.max())


def test_adaptive_is_not_tuned_to_the_perturbed_train(sample_line):
    """The reference train of tables (c)/(d) is the perturbed scenario's train (full load,
    traction x 0.9), so the perturbed figures could flatter the mode: a train between the two
    (load 0.5, traction x 0.95) on the sawtooth E6's worst interstation of the plain adaptive
    mode still arrives within the median bound, and within 1.5 s at worst (the whole line:
    `make bench`, scenario 'half')."""
    from planner.tables.closed_loop import Scenario

    line = sample_line
    grid = ratio_grid(None, line_max_speed_ms=line.max_speed_ms)
    half = Scenario("half", 0.5, 0.95)
    for tt, (o, d) in (("E6", ("HGO", "MDR")), ("E10", ("TKD", "OHS"))):
        tabs = interstation_tables(line, tt, o, d, grid).onboard()
        r = closed_loop_interstation(line, tt, tabs, scenario=half, mode="adaptive")
        e = np.abs(r.error_s[r.feasible])
        assert np.median(e) <= BETTER_MEDIAN_S and e.max() <= 1.5, (tt, np.median(e), e.max())


@pytest.mark.parametrize("sc", SCENARIOS)
def test_adaptive_beats_the_nearest_rule(results, sc):
    """The better mode is better on every type: smaller median and maximum error."""
    for tt in TYPES:
        a, n = _errors(results[(tt, "adaptive", sc)]), _errors(results[(tt, "nearest", sc)])
        assert np.median(a) < np.median(n) and a.max() < n.max(), (tt, sc)


@pytest.mark.xfail(strict=True, reason=NEAREST_REASON)
@pytest.mark.parametrize("sc", SCENARIOS)
def test_nearest_rule_meets_the_issue_bounds(results, sc):
    e = np.concatenate([_errors(results[(tt, "nearest", sc)]) for tt in TYPES])
    assert e.max() <= NEAREST_MAX_S[sc], e.max()
