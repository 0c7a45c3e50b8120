"""mc_dagprop, the peer engine of delay propagation (tests/dagprop_peer.py), on a random DAG of 25,000 events and
60,000 activities: the wall time of 10,000 simulated days through the adapter (building mc_dagprop's DAG,
the runs, the mean and standard deviation of every event's delay), with no primary delay and with one on two
thirds of the events (a third exponential, q = 0.3 and mean 60 s: a pre-event and a helper each; a third
empirical, 0, 30 or 120 s: a pre-event each), at the adapter's batch of 1,000 runs per call and at 10 (each run's
result holds its own copy of every time and duration: smaller batches stay in cache). A timing only: the random
DAG's delays mean nothing.

    .venv/bin/python benchmarks/bench_dagprop_peer.py [--days 10000] [--events 25000] [--activities 60000]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def random_dag(n: int, na: int, seed: int = 0):
    """Events in time order over a day; ``na`` distinct activities from an event to one a few later (geometric
    gap, mean 20), each with a minimum a random slack (exponential, mean 120 s) short of the schedules' gap."""
    rng = np.random.default_rng(seed)
    sched = np.sort(rng.uniform(0.0, 86_400.0, n))
    pairs = np.zeros((0, 2), dtype=np.int64)
    while len(pairs) < na:
        s = rng.integers(0, n - 1, 2 * na)
        d = np.minimum(s + rng.geometric(0.05, 2 * na), n - 1)
        pairs = np.unique(np.concatenate([pairs, np.c_[s, d]]), axis=0)
    pairs = pairs[rng.permutation(len(pairs))[:na]]
    src, dst = pairs[:, 0], pairs[:, 1]
    min_s = np.maximum(sched[dst] - sched[src] - rng.exponential(120.0, na), 0.0)
    return sched, src, dst, min_s


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=10_000)
    ap.add_argument("--events", type=int, default=25_000)
    ap.add_argument("--activities", type=int, default=60_000)
    args = ap.parse_args()
    try:
        from dagprop_peer import build, dagprop_delays
        from mc_dagprop import MonteCarloPropagator
    except ImportError as e:
        print(f"mc_dagprop: not available ({e}); `make test` installs it")
        return 0
    n = args.events
    sched, src, dst, min_s = random_dag(n, args.activities)
    mixed = [(("exponential", 0.3, 60.0), ("empirical", np.array([0.0, 30.0, 120.0])), None)[e % 3]
             for e in range(n)]
    print(f"random DAG: {n} events, {len(src)} activities, {args.days} days")
    for name, prim in (("no primary delay", [None] * n), ("a primary delay on two thirds of the events", mixed)):
        t0 = time.perf_counter()
        ctx, gen = build(sched, src, dst, min_s, prim)
        MonteCarloPropagator(ctx, gen)
        print(f"  {name}: mc_dagprop's DAG of {len(ctx.events)} events and {len(ctx.activities)} activities "
              f"built in {time.perf_counter() - t0:.2f} s (within each time below)")
        for batch in (1000, 10):
            t0 = time.perf_counter()
            r = dagprop_delays(sched, src, dst, min_s, prim, args.days, 1, batch=batch)
            dt = time.perf_counter() - t0
            assert r["mean"].shape == (n,)
            print(f"  {name}, batch {batch}: {dt:.2f} s ({dt / args.days * 1e3:.2f} ms a day)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
