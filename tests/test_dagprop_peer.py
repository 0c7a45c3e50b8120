"""mc_dagprop, the peer engine of delay propagation (tests/dagprop_peer.py), against closed forms worked by hand.

Deterministic cases (fixed delays, none) equal the closed form to the round-off of the times' additions; random
ones (10,000 seeded days, the same numbers every run) agree within 3 standard errors computed from the
distribution itself. mc_dagprop is a test dependency (`make test` builds it; a failed build fails `make test`):
its absence is an error here, not a skip. planner's own engine against it on the sample's day:
test_dagprop_peer_sample.py.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from dagprop_peer import build, dagprop_delays, day_seeds
from planner.delay.network import build_network, train_events
from planner.delay.propagate import propagate
from planner.network.windows import Windows

T0 = 36_000.0  # 10:00, so that times carry round-off like a real day's
DAYS = 10_000
NAN = float("nan")


def tol(*times) -> float:
    """A few units in the last place of the largest time: the round-off of an addition or two."""
    return 4 * float(np.spacing(max(abs(t) for t in times)))


def run(sched, acts, primary, days=1, seed=0, **kw):
    src, dst, mins = (np.asarray(c) for c in zip(*acts))
    return dagprop_delays(np.asarray(sched, dtype=float), src, dst, mins, primary, days, seed, **kw)


def within_3se(sample: np.ndarray, mean: float, sd: float) -> None:
    se = sd / math.sqrt(len(sample))
    assert abs(sample.mean() - mean) < 3 * se, f"mean {sample.mean():.3f}, expected {mean:.3f} ± 3 × {se:.3f}"


def test_mc_dagprop_is_installed():
    import mc_dagprop

    assert mc_dagprop.__version__ == "0.9.1"
    assert mc_dagprop.MonteCarloPropagator is not None  # the compiled core imports


# -- deterministic: fixed delays -----------------------------------------------------------------------------------

CHAIN = [T0, T0 + 120.0, T0 + 300.0]  # runs of 100 s and 150 s: slacks 20 s and 30 s
CHAIN_ACTS = [(0, 1, 100.0), (1, 2, 150.0)]


@pytest.mark.parametrize("d", [0.0, 10.0, 20.0, 35.5, 50.0, 95.3, 600.0])
def test_a_fixed_delay_down_a_chain_loses_each_slack(d):
    z = run(CHAIN, CHAIN_ACTS, [("fixed", d), None, None])
    want = [d, max(0.0, d - 20.0), max(0.0, d - 50.0)]
    np.testing.assert_allclose(z["mean"], want, rtol=0, atol=tol(*CHAIN, CHAIN[-1] + d))
    assert (z["std"] == 0).all()


@pytest.mark.parametrize("d0, d1", [(0.0, 7.0), (15.0, 7.0), (45.0, 7.0), (45.0, 0.0), (200.5, 33.25)])
def test_an_events_own_delay_comes_after_the_maximum(d0, d1):
    # the second event's own delay is added to whatever it inherits, never absorbed by its incoming slack
    z = run(CHAIN, CHAIN_ACTS, [("fixed", d0), ("fixed", d1), None])["mean"]
    z1 = max(0.0, d0 - 20.0) + d1
    np.testing.assert_allclose(z, [d0, z1, max(0.0, z1 - 30.0)], rtol=0, atol=tol(CHAIN[-1] + d0 + d1))


@pytest.mark.parametrize("d", [0.0, 30.0, 60.0, 61.5, 150.0, 420.0])
def test_a_headway_passes_the_first_trains_delay_less_its_buffer(d):
    # train 1 departs A at T0 (event 0), arrives B at T0 + 300 (event 1), runs 280 s; train 2 departs A at
    # T0 + 180 (event 2), arrives B at T0 + 480 (event 3), runs 290 s; a 120 s departure headway 0 → 2 leaves
    # train 2 a 60 s buffer, a 120 s arrival headway 1 → 3 one of 60 s as well
    sched = [T0, T0 + 300.0, T0 + 180.0, T0 + 480.0]
    acts = [(0, 1, 280.0), (2, 3, 290.0), (0, 2, 120.0), (1, 3, 120.0)]
    z = run(sched, acts, [("fixed", d), None, None, None])["mean"]
    z1, z2 = max(0.0, d - 20.0), max(0.0, d - 60.0)
    want = [d, z1, z2, max(0.0, z2 - 10.0, z1 - 60.0)]
    np.testing.assert_allclose(z, want, rtol=0, atol=tol(T0 + 480.0 + d))
    assert z[2] == pytest.approx(max(0.0, d - 60.0), abs=tol(T0 + 180 + d))


@pytest.mark.parametrize("d, p2", [(100.0, 0.0), (100.0, 30.0), (0.0, 30.0), (30.0, 0.0), (5.0, 3.0),
                                   (41.0, 4.5)])
def test_a_diamond_takes_the_later_of_its_two_paths(d, p2):
    # 0 → 1 → 3 with slacks 10 s and 30 s, 0 → 2 → 3 with 40 s and 5 s; a fixed delay d at 0 and p2 at 2
    sched = [T0, T0 + 70.0, T0 + 100.0, T0 + 160.0]
    acts = [(0, 1, 60.0), (0, 2, 60.0), (1, 3, 60.0), (2, 3, 55.0)]
    z = run(sched, acts, [("fixed", d), None, ("fixed", p2), None])["mean"]
    z1, z2 = max(0.0, d - 10.0), max(0.0, d - 40.0) + p2
    want = [d, z1, z2, max(0.0, z1 - 30.0, z2 - 5.0)]
    np.testing.assert_allclose(z, want, rtol=0, atol=tol(T0 + 160.0 + d + p2))


def test_events_without_activities_and_two_activities_between_the_same_events():
    # event 0 has nothing; 1 → 2 twice (100 s and 130 s against 120 s scheduled: the longer leaves −10 s);
    # event 3 has no incoming activity and no delay, event 4 none either but a fixed 12 s of its own
    sched = [T0, T0 + 50.0, T0 + 170.0, T0 + 9.0, T0 + 11.0]
    acts = [(1, 2, 100.0), (1, 2, 130.0)]
    z = run(sched, acts, [None, None, None, None, ("fixed", 12.0)])["mean"]
    np.testing.assert_allclose(z, [0.0, 0.0, 10.0, 0.0, 12.0], rtol=0, atol=tol(T0 + 180.0))
    # the same pair of activities into an event with a delay of its own: into its pre-event, the longer binds
    z = run(sched, acts, [None, ("fixed", 5.0), ("fixed", 1.0), None, None])["mean"]
    np.testing.assert_allclose(z, [0.0, 5.0, 16.0, 0.0, 0.0], rtol=0, atol=tol(T0 + 180.0))


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


@pytest.mark.parametrize("delays", [(0.0, 0.0, 0.0), (30.0, 0.0, 0.0), (95.3, 12.5, 0.0), (0.0, 0.0, 41.0),
                                    (500.0, 3.0, 7.0)])
def test_fixed_primary_delays_give_planners_delays(delays):
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


# -- random: exponential and empirical -----------------------------------------------------------------------------

M = 60.0  # the exponential's mean [s]


@pytest.mark.parametrize("q", [1.0, 0.3])
def test_an_exponential_delay_with_a_probability(q):
    # event 1 of the chain has the delay, nothing else does: z1 = B·X, B ~ Bernoulli(q), X ~ Exp(M); event 2 (30 s
    # slack) gets max(0, z1 − 30): mean q·M·e^{−30/M} (memorylessness), late on a share q·e^{−30/M} of days
    r = run(CHAIN, CHAIN_ACTS, [None, ("exponential", q, M), None], days=DAYS, seed=7, keep=True)
    z = r["all"]
    assert z.shape == (DAYS, 3) and (z[:, 0] == 0).all() and (z >= 0).all()
    within_3se(z[:, 1], q * M, math.sqrt(2 * q * M * M - (q * M) ** 2))
    assert r["mean"][1] == pytest.approx(z[:, 1].mean()) and r["std"][1] == pytest.approx(z[:, 1].std(ddof=1))
    late = z[:, 1] > 0
    within_3se(late.astype(float), q, math.sqrt(q * (1 - q)) or 1e-12)
    if q == 1.0:
        assert late.all()
    within_3se(z[late, 1], M, M)  # late: exponential of mean M, not some other split of the same mean
    within_3se(z[late, 1] ** 2, 2 * M * M, math.sqrt(24 - 4) * M * M)  # E X² = 2M², Var X² = 20 M⁴
    p = q * math.exp(-30.0 / M)
    within_3se(z[:, 2], M * p, math.sqrt(2 * M * M * p - (M * p) ** 2))
    within_3se((z[:, 2] > 0).astype(float), p, math.sqrt(p * (1 - p)))


def test_an_empirical_delay_draws_each_value_with_equal_weight():
    values = np.array([0.0, 60.0, 120.0])
    z = run(CHAIN, CHAIN_ACTS, [("empirical", values), None, None], days=DAYS, seed=3, keep=True)["all"]
    within_3se(z[:, 0], 60.0, math.sqrt(2400.0))  # Var = (60² + 0 + 60²) / 3
    assert set(np.unique(z[:, 0])) == {0.0, 60.0, 120.0}
    for v in values:
        within_3se((z[:, 0] == v).astype(float), 1 / 3, math.sqrt(2 / 9))
    # downstream: max(0, z0 − 20) is 0, 40 or 100, each a third of the days
    assert set(np.unique(np.round(z[:, 1], 9))) == {0.0, 40.0, 100.0}


def test_independent_delays_on_two_events_add_up_when_nothing_absorbs():
    # two exponentials in a chain with no slack: z2 = X1 + X2 (events 0 and 1 late, event 1's run exactly
    # scheduled): mean 2M, variance 2M²
    sched = [T0, T0 + 100.0, T0 + 200.0]
    spec = [("exponential", 1.0, M), ("exponential", 1.0, M), None]
    z = run(sched, [(0, 1, 100.0), (1, 2, 100.0)], spec, days=DAYS, seed=11, keep=True)["all"]
    within_3se(z[:, 2], 2 * M, math.sqrt(2) * M)
    assert abs(np.corrcoef(z[:, 0], z[:, 1] - z[:, 0])[0, 1]) < 3 / math.sqrt(DAYS)  # the draws are independent


# -- the adapter's plumbing ----------------------------------------------------------------------------------------

def test_seeded_days_repeat_and_batches_do_not_change_them():
    spec = [("exponential", 0.5, M), ("empirical", np.array([0.0, 90.0])), None]
    a = run(CHAIN, CHAIN_ACTS, spec, days=300, seed=5, keep=True)
    b = run(CHAIN, CHAIN_ACTS, spec, days=300, seed=5, keep=True, batch=7)
    c = run(CHAIN, CHAIN_ACTS, spec, days=300, seed=6, keep=True)
    assert np.array_equal(a["all"], b["all"]) and not np.array_equal(a["all"], c["all"])
    np.testing.assert_allclose(a["mean"], b["mean"], rtol=1e-12)
    np.testing.assert_allclose(a["std"], b["std"], rtol=1e-12)
    s = day_seeds(2 ** 40 + 1, 1000)
    assert len(set(s.tolist())) == 1000 and s.min() >= 0 and s.max() < 2 ** 31


def test_the_mapped_dag():
    # a fixed and an empirical delay: a pre-event each; the exponential: a pre-event and a helper
    spec = [("fixed", 3.0), ("empirical", np.array([1.0, 2.0])), ("exponential", 0.5, 10.0)]
    ctx, _gen = build(CHAIN, [0, 1], [1, 2], [100.0, 150.0], spec)
    assert [e.event_id for e in ctx.events] == ["0", "1", "2", "0'", "1'", "2'", "2^"]
    acts = {k: (a.minimal_duration, a.activity_type) for k, a in ctx.activities.items()}
    assert acts[(0, 4)] == (100.0, -1) and acts[(1, 5)] == (150.0, -1)  # into the pre-events
    assert acts[(3, 0)] == (3.0, -1) and acts[(4, 1)] == (0.0, 0)
    assert acts[(5, 6)] == (1.0, 1) and acts[(5, 2)] == (0.0, -1)
    assert acts[(6, 2)][0] == pytest.approx(-(1.0 + 10.0 * math.log(2.0)))


@pytest.mark.parametrize("bad", [("fixed", -1.0), ("exponential", 1.5, 60.0), ("exponential", 0.5, -1.0),
                                 ("empirical", np.array([])), ("empirical", np.array([5.0, -1.0])), ("gamma", 2.0)])
def test_malformed_primary_delays_are_refused(bad):
    with pytest.raises(ValueError):
        run(CHAIN, CHAIN_ACTS, [bad, None, None])


def test_a_cycle_is_refused_by_mc_dagprop():
    with pytest.raises(RuntimeError, match="cycle"):
        run(CHAIN, CHAIN_ACTS + [(2, 0, 1.0)], [None, None, None])
