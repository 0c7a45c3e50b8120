"""Delay propagation against closed forms: hand-built networks whose every delay is known without the code."""
from __future__ import annotations

import numpy as np
from planner.delay.montecarlo import Stats, simulate
from planner.delay.network import HEADWAY, build_network, train_events
from planner.delay.primary import Rule, sample
from planner.delay.propagate import propagate
from planner.network.windows import Windows

NAN = float("nan")


def windows(rows):
    """Windows from (train, resource, start, entry, end) rows (times exact in binary)."""
    a = np.asarray(rows, dtype=float)
    n = len(a)
    z = np.zeros(n)
    return Windows(train=a[:, 0].astype(np.int64), kind=np.ones(n, dtype=np.int8), res=a[:, 1].astype(np.int64),
                   item=np.arange(n), from_m=z, to_m=z, entry_s=a[:, 3], exit_s=a[:, 4], clear_s=a[:, 4],
                   start_s=a[:, 2], end_s=a[:, 4])


def two_stop_train(tid, dep, arr, run_min, *, plan=None):
    """A train from A (departs ``dep``) to B (arrives ``arr``), minimum running time ``run_min``."""
    stops = [("A", 1, NAN, dep), ("B", 2, arr, NAN)]
    return train_events(tid, "EMU", "down", stops, plan or [(dep, dep), (arr, arr)], [run_min])


def test_a_feasible_day_without_primary_delay_has_no_delay():
    t1 = two_stop_train("T1", 100.0, 400.0, 280.0)
    t2 = two_stop_train("T2", 500.0, 800.0, 300.0)
    w = windows([(0, 0, 70.0, 100.0, 450.0), (1, 0, 470.0, 500.0, 850.0)])  # buffer 20 s
    net = build_network([t1, t2], min_dwell_s=20.0, windows=w, resource_ids=["s0", "s1"])
    z = propagate(net)
    assert (net.act_kind == HEADWAY).sum() == 1
    assert np.all(z == 0.0)


def test_the_follower_is_delayed_by_the_excess_over_the_buffer_to_the_bit():
    t1 = two_stop_train("T1", 100.0, 400.0, 280.0)
    t2 = two_stop_train("T2", 400.0, 700.0, 280.0)
    # T1 holds a section from 70 s to 350 s after departing at 100 s (it clears it before arriving, so the
    # window moves with its departure); T2's window opens at 370 s, 30 s before it departs: buffer 20 s
    w = windows([(0, 0, 70.0, 100.0, 350.0), (1, 0, 370.0, 400.0, 650.0)])
    net = build_network([t1, t2], min_dwell_s=20.0, windows=w, resource_ids=["s0", "s1"])
    buffer = 370.0 - 350.0
    for d in (0.0, 7.5, 20.0, 20.125, 95.3, 1234.5678, 1e-7):
        p = np.zeros((net.n_events, 1))
        p[0, 0] = d  # T1 departs late by d
        z = propagate(net, p)[:, 0]
        assert z[0] == d
        # T1's arrival: its margin (20 s) absorbs the first 20 s of the delay
        assert z[1] == max(0.0, d - 20.0)
        # T2's departure waits for the section: exactly the excess over the buffer
        assert z[2] == max(0.0, d - buffer)


def test_a_margin_larger_than_the_primary_delay_gives_an_on_time_arrival():
    m = 37.25
    t = two_stop_train("T1", 100.0, 400.0, 300.0 - m)
    net = build_network([t], min_dwell_s=20.0)
    for d in (0.0, 1.0, 20.0, 37.0, m):
        p = np.zeros((net.n_events, 1))
        p[0, 0] = d
        assert propagate(net, p)[1, 0] == 0.0
    p[0, 0] = m + 4.0
    assert propagate(net, p)[1, 0] == 4.0


def test_a_late_arrival_departs_after_the_minimum_dwell_and_never_before_its_schedule():
    stops = [("A", 1, NAN, 0.0), ("B", 2, 100.0, 160.0), ("C", 3, 300.0, NAN)]
    t = train_events("T", "EMU", "down", stops, [(0, 0), (100, 160), (300, 300)], [130.0, 130.0])
    net = build_network([t], min_dwell_s=25.0)
    z = propagate(net)[:, 0]
    # arrives 30 s late at B (130 s run, 100 s scheduled); dwell 60 s scheduled, 25 s minimum: departs 160 → 160
    assert z.tolist() == [0.0, 30.0, 0.0, 0.0]
    p = np.zeros((net.n_events, 1))
    p[1, 0] = 40.0  # 70 s late at B: departs at 170 + 25 = 195 (35 s late), arrives 195 + 130 = 325 (25 s late)
    assert propagate(net, p)[:, 0].tolist() == [0.0, 70.0, 35.0, 25.0]


def test_a_headway_that_would_close_a_cycle_is_left_out_and_counted():
    t1 = two_stop_train("T1", 100.0, 400.0, 280.0)
    t2 = two_stop_train("T2", 100.0, 400.0, 280.0)
    # two resources ordered opposite ways: T1 before T2 on one, T2 before T1 on the other, both anchored at
    # the departures → T1.dep → T2.dep and T2.dep → T1.dep
    w = windows([(0, 0, 70.0, 100.0, 90.0), (1, 0, 95.0, 100.0, 200.0),
                 (1, 1, 70.0, 100.0, 90.0), (0, 1, 95.0, 100.0, 200.0)])
    net = build_network([t1, t2], min_dwell_s=20.0, windows=w, resource_ids=["r0", "r1", "r2", "r3"])
    assert net.dropped == 1
    assert len(net.order) == net.n_events


def test_no_primary_delay_simulated_days_are_the_predicted_day():
    t1 = two_stop_train("T1", 100.0, 400.0, 330.0)  # 30 s late by its own leg
    t2 = two_stop_train("T2", 440.0, 800.0, 300.0)
    w = windows([(0, 0, 70.0, 100.0, 450.0), (1, 0, 455.0, 470.0, 850.0)])  # anchored: T1's arrival, T2's departure
    net = build_network([t1, t2], min_dwell_s=20.0, windows=w, resource_ids=["s0", "s1"])
    pred = propagate(net)[:, 0]
    assert pred.tolist() == [0.0, 30.0, 25.0, 0.0]  # T2 departs 30 − 5 s buffer late; 60 s margin absorbs it
    st = simulate(net, [Rule("origin", "none")], 7, seed=3)
    assert st.days == 7
    np.testing.assert_array_equal(st.sum_s, 7 * pred)
    np.testing.assert_array_equal(st.knock_on_s, pred - propagate(net.without((HEADWAY,)))[:, 0])


def test_primary_delays_are_reproducible_and_independent_of_the_workers():
    t = [two_stop_train(f"T{k}", 100.0 + 400 * k, 400.0 + 400 * k, 280.0) for k in range(5)]
    net = build_network(t, min_dwell_s=20.0)
    rules = [Rule("origin", "exponential", probability=0.5, mean_s=60.0),
             Rule("running", "empirical", values=(0.0, 10.0, 30.0))]
    a = simulate(net, rules, 600, seed=11, n_jobs=1, chunk=250)
    b = simulate(net, rules, 600, seed=11, n_jobs=2, chunk=250)
    for f in ("sum_s", "sumsq_s", "hist", "push_s", "absorbed_s"):
        assert getattr(a, f).tobytes() == getattr(b, f).tobytes()
    c = simulate(net, rules, 600, seed=12, n_jobs=1, chunk=250)
    assert a.sum_s.tobytes() != c.sum_s.tobytes()


def test_exponential_primary_delays_have_their_mean():
    t = two_stop_train("T", 100.0, 400.0, 300.0)
    net = build_network([t], min_dwell_s=20.0)
    p = sample(net, [Rule("origin", "exponential", probability=0.3, mean_s=60.0)], 20000, seed=5, chunk=0)
    assert p[1].max() == 0.0  # the arrival is not an origin departure
    se = np.sqrt(0.3 * 2 * 60.0 ** 2 - (0.3 * 60.0) ** 2) / np.sqrt(20000)
    assert abs(p[0].mean() - 0.3 * 60.0) < 3 * se
    assert abs(np.mean(p[0] > 0) - 0.3) < 3 * np.sqrt(0.3 * 0.7 / 20000)


def test_punctuality_shares_and_quantiles_from_the_bins():
    t = two_stop_train("T", 100.0, 400.0, 300.0)
    net = build_network([t], min_dwell_s=20.0)
    vals = (0.0, 45.0, 61.0, 200.0)  # within 1 min: 2 of 4; within 3: 3; within 5: 4
    st = simulate(net, [Rule("origin", "empirical", values=vals)], 4000, seed=2)
    share = np.mean(np.asarray(vals) <= 60.0)
    assert abs(st.within(60.0)[0] - share) < 3 * np.sqrt(share * (1 - share) / 4000)
    assert st.within(300.0)[0] == 1.0
    assert st.quantile_s(0.99)[0] == 200.0  # 200 s falls in (190, 200]
    assert isinstance(st, Stats)


def test_the_compiled_histogram_is_searchsorted_on_the_edges():
    from planner.delay.montecarlo import EDGES_S, bins
    from planner.delay.propagate import histogram

    rng = np.random.default_rng(0)
    edges_near = np.concatenate([EDGES_S, np.nextafter(EDGES_S, np.inf), np.nextafter(EDGES_S, -np.inf)])
    z = np.concatenate([edges_near, rng.exponential(300.0, 5000), [0.0, -0.0, 1e9, 3600.0, 3600.0001]])
    z = z.reshape(1, -1)
    got = histogram(z, EDGES_S)[0]
    want = np.bincount(bins(z[0]), minlength=len(EDGES_S) + 1)
    np.testing.assert_array_equal(got, want)


def test_the_built_kernels_give_the_just_in_time_bytes():
    from planner.delay import kernel
    from planner.delay.propagate import SOURCES
    from planner.io import compiled

    built = compiled.load("delay", SOURCES)
    assert built is not None, "make install builds the delay kernels (planner kernels build)"
    t = [two_stop_train(f"T{k}", 100.0 + 200 * k, 400.0 + 200 * k, 280.0) for k in range(6)]
    w = windows([(k, 0, 70.0 + 200 * k, 100.0 + 200 * k, 330.0 + 200 * k) for k in range(6)])
    net = build_network(t, min_dwell_s=20.0, windows=w, resource_ids=["n0", "s0"])
    p = sample(net, [Rule("origin", "exponential", probability=0.6, mean_s=90.0)], 300, seed=4, chunk=0)
    out = []
    for k in (kernel, built):
        z = np.empty_like(p)
        push, binds, absorbed = np.zeros(net.n_activities), np.zeros(net.n_activities, dtype=np.int64), \
            np.zeros(net.n_activities)
        k.propagate(net.order, net.in_ptr, net.in_act, net.act_src, net.slack_s, p, z, push, binds, absorbed)
        hist = np.zeros((net.n_events, 5), dtype=np.int64)
        k.histogram(z, np.array([0.0, 10.0, 60.0, 600.0]), hist)
        out.append(b"".join(a.tobytes() for a in (z, push, binds, absorbed, hist)))
    assert out[0] == out[1]
    assert (net.act_kind == HEADWAY).sum() == 5


def test_window_anchors_are_each_trains_last_event_at_or_before():
    """The anchors by their definition (module doc of planner.delay.network), event by event, against
    window_anchors on windows of many trains in no order."""
    from planner.delay.network import TOL_S, window_anchors

    rng = np.random.default_rng(4)
    sizes = rng.integers(2, 9, size=40)
    plan = np.concatenate([np.sort(rng.uniform(0, 5000, n)) for n in sizes])
    first = np.r_[0, np.cumsum(sizes)]
    n = 600
    train = rng.integers(0, len(sizes), n)
    entry = rng.uniform(-100, 5100, n)
    end = entry + rng.uniform(0, 300, n)
    w = windows(np.column_stack([train, np.zeros(n), entry - 10, entry, end]))
    a_start, a_end = window_anchors(w, sizes.tolist(), plan)

    def last_at_or_before(k, t):
        evs = [e for e in range(first[k], first[k + 1]) if plan[e] <= t + TOL_S]
        return evs[-1] if evs else first[k]

    assert a_start.tolist() == [last_at_or_before(k, t) for k, t in zip(train, entry)]
    assert a_end.tolist() == [last_at_or_before(k, t) for k, t in zip(train, end)]
    none = windows(np.zeros((0, 5)))  # a day without windows (no train routed)
    assert [a.tolist() for a in window_anchors(none, sizes.tolist(), plan)] == [[], []]


def test_chunks_keep_their_delays_in_bounds_and_sum_as_they_arrive():
    """Days per chunk: the sample's 250, a network so large that 250 days pass CHUNK_BYTES fewer, never fewer than
    MIN_CHUNK_DAYS; and a run's statistics are its chunks' statistics summed in order."""
    from planner.delay.montecarlo import CHUNK_BYTES, CHUNK_DAYS, MIN_CHUNK_DAYS, chunk_days, chunk_stats

    assert chunk_days(6_728) == CHUNK_DAYS
    for n in (67_280, 672_800, 6_728_000):
        d = chunk_days(n)
        assert MIN_CHUNK_DAYS <= d < CHUNK_DAYS
        assert d == MIN_CHUNK_DAYS or (d * n * 8 <= CHUNK_BYTES < (d + 1) * n * 8)
    t = [two_stop_train(f"T{k}", 100.0 + 300 * k, 400.0 + 300 * k, 280.0) for k in range(4)]
    net = build_network(t, min_dwell_s=20.0)
    rules = [Rule("origin", "exponential", probability=0.5, mean_s=60.0)]
    whole = simulate(net, rules, 25, seed=3, chunk=10)
    alone = net.without((HEADWAY,))
    parts = [chunk_stats(net, alone, rules, d, 3, i) for i, d in enumerate((10, 10, 5))]
    by_hand = parts[0] + parts[1] + parts[2]
    assert whole.days == by_hand.days == 25
    for f in ("sum_s", "sumsq_s", "alone_sum_s", "primary_sum_s", "hist", "push_s", "binds", "absorbed_s"):
        assert getattr(whole, f).tobytes() == getattr(by_hand, f).tobytes(), f
