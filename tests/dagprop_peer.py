"""The same day's network and primary delays in mc_dagprop, a C++ Monte Carlo engine for delay propagation on
DAGs (PyPI ``mc_dagprop``, a test and benchmark dependency only: ``make test`` installs it).

mc_dagprop 0.9.1's model (read from its ``monte_carlo/_core.cpp``): each event has an ``earliest`` time; each
activity ``(src, dst)`` a base duration ``D`` and a type; a type's generator draws an extra duration per run:
``add_exponential(type, λ, max_scale)`` gives ``D · X`` with ``X`` exponential of **mean λ** redrawn while
above ``max_scale``; ``add_empirical_absolute(type, values, weights)`` a value independent of ``D``; an
activity of a type without a generator gets none. In topological order an event is realized at
``min(max(earliest, max over activities (src realized + D + extra)), earliest + max_delay)``; ``run(seed)``
reseeds the engine, ``run_many(seeds)`` runs them in turn without the GIL.

planner's rule (:mod:`planner.delay.propagate`) puts the primary delay on the event, after the maximum:
``x_e = max(s_e, max_a (x_src + min_a)) + p_e``. The mapping makes mc_dagprop compute exactly that:

* every event ``e`` becomes ``e`` realized 1 s late (earliest ``s_e + 1``); activities between two such events
  keep their minimum;
* an event with a primary delay gets a *pre-event* ``e'`` (earliest ``s_e``) that takes its incoming
  activities (minimum − 1 s: their source is realized 1 s late) and one activity ``e' → e`` of base 1 s
  carrying the delay: ``x_e − 1 = max(s_e, max_a (x_src + min_a)) + extra``;
* ``exponential`` with probability 1: ``add_exponential(type, mean, inf)`` on that 1 s base (exact);
  with probability ``q < 1`` mc_dagprop has no mixture, so the delay is ``add_empirical_absolute`` over
  0 (weight 1 − q) and K = 2,000 equal-probability slices of the exponential, each at its conditional mean
  (the mean is exact, the spread within 0.01 %): exact in the mean, which is what the comparison reads;
* ``empirical``: ``add_empirical_absolute(values, equal weights)`` (exact); ``fixed``: ``[d]`` (exact).

Two activities between the same two events (mc_dagprop keys activities by the pair) become the one with the
larger minimum: the same maximum.
"""
from __future__ import annotations

import math

import numpy as np

SHIFT_S = 1.0
EXP_SLICES = 2000


def exponential_slices(q: float, mean: float, k: int = EXP_SLICES) -> tuple[list[float], list[float]]:
    """0 with weight 1 − q, and k equal-probability slices of an exponential of mean ``mean`` at their
    conditional means (weight q / k each): a distribution with exactly the mean q · mean."""
    u = np.arange(k) / k  # lower slice edges in probability
    a = -mean * np.log1p(-u)  # their quantiles; the last slice runs to +inf
    b = np.r_[a[1:], np.inf]
    # E[X | a < X < b] for an exponential: mean + (a e^{-a/m} − b e^{-b/m}) / (e^{-a/m} − e^{-b/m})
    ea, eb = np.exp(-a / mean), np.exp(-b / mean)
    bb = np.r_[b[:-1] * eb[:-1], 0.0]  # b e^{-b/m} → 0 as b → inf
    cond = mean + (a * ea - bb) / (ea - eb)
    return [0.0] + cond.tolist(), [1.0 - q] + [q / k] * k


def peer_primary(net, rules) -> list:
    """planner's primary-delay rules as the adapter's per-event list (:func:`dagprop_delays`)."""
    from planner.delay.primary import groups

    out: list = [None] * net.n_events
    for r, idx in groups(net, list(rules)):
        spec = (("exponential", r.probability, r.mean_s) if r.distribution == "exponential"
                else ("empirical", np.asarray(r.values, dtype=float)))
        for e in idx:
            out[int(e)] = spec
    return out


def _context(sched_s, src, dst, min_s, primary):
    from mc_dagprop import Activity, DagContext, Event, EventTimestamp, GenericDelayGenerator

    n = len(sched_s)
    types: dict = {}
    gen = GenericDelayGenerator()
    pre = {}
    events = [Event(str(e), EventTimestamp(float(sched_s[e]) + SHIFT_S, 1e18, 0.0)) for e in range(n)]
    for e, spec in enumerate(primary):
        if spec is None:
            continue
        key = (spec[0], tuple(np.atleast_1d(spec[1:]).ravel().tolist()) if spec[0] != "empirical"
               else tuple(np.asarray(spec[1], dtype=float).tolist()))
        if key not in types:
            t = len(types) + 1
            types[key] = t
            if spec[0] == "fixed":
                gen.add_empirical_absolute(t, [float(spec[1])], [1.0])
            elif spec[0] == "exponential" and spec[1] >= 1.0:
                gen.add_exponential(t, float(spec[2]), math.inf)
            elif spec[0] == "exponential":
                v, w = exponential_slices(float(spec[1]), float(spec[2]))
                gen.add_empirical_absolute(t, v, w)
            elif spec[0] == "empirical":
                v = np.asarray(spec[1], dtype=float)
                gen.add_empirical_absolute(t, v.tolist(), [1.0] * len(v))
            else:
                raise ValueError(f"unknown primary delay {spec!r}")
        pre[e] = (len(events), types[key])
        events.append(Event(f"{e}'", EventTimestamp(float(sched_s[e]), 1e18, 0.0)))
    edges: dict = {}
    for s, d, m in zip(np.asarray(src).tolist(), np.asarray(dst).tolist(), np.asarray(min_s, dtype=float).tolist()):
        target, m = (pre[d][0], m - SHIFT_S) if d in pre else (d, m)
        if (s, target) not in edges or m > edges[(s, target)][0]:
            edges[(s, target)] = (m, 0)
    for e, (p, t) in pre.items():
        edges[(p, e)] = (SHIFT_S, t)
    acts, preds = {}, {}
    for i, ((s, d), (m, t)) in enumerate(sorted(edges.items())):
        acts[(s, d)] = Activity(i, m, t)
        preds.setdefault(d, []).append((s, i))
    return DagContext(events, acts, sorted(preds.items()), 1e18), gen, n


def dagprop_delays(sched_s, src, dst, min_s, primary, days, seed, *, batch=500, keep=False):
    """Delays ``x − s`` of every event over ``days`` runs of mc_dagprop (seeds ``seed · 10⁶ + day``): a dict of
    ``mean`` and ``std`` per event, and ``all`` (days × events) with ``keep``."""
    from mc_dagprop import MonteCarloPropagator

    ctx, gen, n = _context(sched_s, src, dst, min_s, primary)
    sim = MonteCarloPropagator(ctx, gen)
    base = np.asarray(sched_s, dtype=float) + SHIFT_S
    s1, s2 = np.zeros(n), np.zeros(n)
    rows = []
    for lo in range(0, int(days), batch):
        res = sim.run_many([int(seed) * 1_000_000 + d for d in range(lo, min(lo + batch, int(days)))])
        z = np.array([r.realized[:n] for r in res]) - base
        s1 += z.sum(axis=0)
        s2 += (z * z).sum(axis=0)
        if keep:
            rows.append(z)
    mean = s1 / days
    out = {"mean": mean, "std": np.sqrt(np.maximum(s2 / days - mean ** 2, 0.0) * days / max(days - 1, 1))}
    if keep:
        out["all"] = np.concatenate(rows)
    return out
