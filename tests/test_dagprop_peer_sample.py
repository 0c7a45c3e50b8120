"""planner's delay propagation against the peer engine, mc_dagprop (tests/dagprop_peer.py), on the sample's day.

The predicted day (no primary delay) equals mc_dagprop's to round-off; 10,000 random days of the job's rules
agree per event within 3 standard errors (both engines seeded: the same numbers every run). Closed forms on
small networks: test_dagprop_peer.py. mc_dagprop is a test dependency (`make test` builds it): its absence is an
error here, not a skip.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dagprop_peer import dagprop_delays, peer_primary
from planner.delay.montecarlo import simulate
from planner.delay.predicted import predict_day

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def sample_day():
    from planner.job.config import load_job
    from planner.job.day import line_on_day
    from planner.job.robustness import rules
    from planner.line.loader import load_line
    from planner.network.arrivals import train_curves
    from planner.network.check import check_timetable

    job = load_job(ROOT / "jobs" / "nightly.toml")
    on, _said, lifted = line_on_day(job, load_line(ROOT / "lines" / "sample"))
    day = predict_day(check_timetable(on, {}, curves=train_curves(on, lifted)), min_dwell_s=20.0)
    return day, rules(job)


def test_the_predicted_day_is_mc_dagprops_day_without_primary_delay(sample_day):
    day, _rules = sample_day
    net = day.net
    theirs = dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, [None] * net.n_events, 1, 0)["mean"]
    np.testing.assert_allclose(theirs, day.delay_s, rtol=0, atol=1e-6)
    assert day.delay_s.max() > 50.0  # a restricted day: the comparison sees real delays


def test_random_days_agree_per_event_within_three_standard_errors(sample_day):
    day, rules = sample_day
    net = day.net
    days = 10_000
    prim = peer_primary(net, rules)
    assert {p[0] for p in prim if p is not None} >= {"exponential"}
    ours = simulate(net, rules, days, seed=1, n_jobs=1)
    theirs = dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, prim, days, 1)
    se = np.sqrt(ours.sem_s ** 2 + (theirs["std"] / np.sqrt(days)) ** 2)
    se = np.maximum(se, 1e-9)
    k = np.abs(ours.mean_s - theirs["mean"]) / se
    # one test per event (6,728): 3 standard errors are passed by chance by 0.27 % of them
    assert np.mean(k > 3.0) < 0.01, f"{np.mean(k > 3.0):.2%} of events beyond 3 standard errors"
    assert k.max() < 5.5
    assert abs(ours.mean_s.mean() - theirs["mean"].mean()) < 3 * np.sqrt(np.mean(se ** 2) / net.n_events) + 0.05
