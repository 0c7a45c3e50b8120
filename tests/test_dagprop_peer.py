"""planner's delay propagation against a peer engine, mc_dagprop, on the same networks and primary delays.

Deterministic cases equal to round-off; random cases agree per event within 3 standard errors over 10,000 days
(both engines seeded: the same numbers every run). mc_dagprop is a test dependency (`make test` installs it; a
failed build fails `make test`): its absence is an error here, not a skip.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dagprop_peer import dagprop_delays, exponential_slices, peer_primary
from planner.delay.montecarlo import simulate
from planner.delay.network import build_network, train_events
from planner.delay.predicted import predict_day
from planner.delay.primary import Rule
from planner.delay.propagate import propagate
from planner.network.windows import Windows

ROOT = Path(__file__).resolve().parents[1]
NAN = float("nan")


def _two(tid, dep, arr, run_min):
    return train_events(tid, "EMU", "down", [("A", 1, NAN, dep), ("B", 2, arr, NAN)], [(dep, dep), (arr, arr)],
                        [run_min])


def _net():
    t = [_two("T1", 100.0, 400.0, 280.0), _two("T2", 400.0, 700.0, 280.0), _two("T3", 300.0, 650.0, 330.0)]
    a = np.asarray([(0, 0, 70.0, 100.0, 350.0), (1, 0, 370.0, 400.0, 650.0), (2, 1, 270.0, 300.0, 500.0),
                    (1, 1, 505.0, 520.0, 640.0)], dtype=float)
    z = np.zeros(len(a))
    w = Windows(train=a[:, 0].astype(np.int64), kind=np.ones(len(a), dtype=np.int8), res=a[:, 1].astype(np.int64),
                item=np.arange(len(a)), from_m=z, to_m=z, entry_s=a[:, 3], exit_s=a[:, 4], clear_s=a[:, 4],
                start_s=a[:, 2], end_s=a[:, 4])
    return build_network(t, min_dwell_s=20.0, windows=w, resource_ids=["n0", "s0", "n1", "s1"])


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


def test_mc_dagprop_is_installed():
    import mc_dagprop

    assert mc_dagprop.__version__ == "0.9.1"


@pytest.mark.parametrize("delays", [(0.0, 0.0, 0.0), (30.0, 0.0, 0.0), (95.3, 12.5, 0.0), (0.0, 0.0, 41.0),
                                    (500.0, 3.0, 7.0)])
def test_fixed_primary_delays_give_the_same_delays(delays):
    net = _net()
    spec = [None] * net.n_events
    p = np.zeros((net.n_events, 1))
    for e, d in zip((0, 2, 4), delays):  # the three departures
        spec[e] = ("fixed", d)
        p[e, 0] = d
    ours = propagate(net, p)[:, 0]
    theirs = dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, spec, 1, 0)["mean"]
    np.testing.assert_allclose(theirs, ours, rtol=0, atol=1e-9)
    assert ours.max() > 0 or not any(delays)


def test_the_predicted_day_is_mc_dagprops_day_without_primary_delay(sample_day):
    day, _rules = sample_day
    net = day.net
    theirs = dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, [None] * net.n_events, 1, 0)["mean"]
    np.testing.assert_allclose(theirs, day.delay_s, rtol=0, atol=1e-6)
    assert day.delay_s.max() > 50.0  # a restricted day: the comparison sees real delays


def test_the_slices_of_an_exponential_have_its_mean():
    v, w = exponential_slices(0.3, 60.0)
    assert abs(np.dot(v, w) - 18.0) < 1e-9 and abs(sum(w) - 1.0) < 1e-12


def test_random_days_agree_per_event_within_three_standard_errors(sample_day):
    day, rules = sample_day
    net = day.net
    days = 10_000
    ours = simulate(net, rules, days, seed=1, n_jobs=1)
    theirs = dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, peer_primary(net, rules), days, 1)
    se = np.sqrt(ours.sem_s ** 2 + (theirs["std"] / np.sqrt(days)) ** 2)
    se = np.maximum(se, 1e-9)
    k = np.abs(ours.mean_s - theirs["mean"]) / se
    # one test per event (6,728): 3 standard errors are passed by chance by 0.27 % of them
    assert np.mean(k > 3.0) < 0.01, f"{np.mean(k > 3.0):.2%} of events beyond 3 standard errors"
    assert k.max() < 5.5
    assert abs(ours.mean_s.mean() - theirs["mean"].mean()) < 3 * np.sqrt(np.mean(se ** 2) / net.n_events) + 0.05
