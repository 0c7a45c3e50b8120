"""The same network and primary delays in mc_dagprop, a C++ Monte Carlo engine for delay propagation on DAGs
(PyPI ``mc_dagprop`` 0.9.1; a test and benchmark dependency only: ``make test`` builds it from source).

**mc_dagprop's Monte Carlo model** (read from ``src/mc_dagprop/monte_carlo/_core.cpp`` of the 0.9.1 sdist).
``Event(id, EventTimestamp(earliest, latest, actual))``: the engine reads ``earliest`` only (``latest`` and
``actual`` are carried, never used). ``DagContext(events, activities, precedence_list, max_delay)``:
``activities`` maps a pair ``(src, dst)`` to ``Activity(idx, minimal_duration D, activity_type)`` (so at most one
activity per pair; the key is not read otherwise: ``idx`` places it); ``precedence_list`` is
``[(dst, [(src, idx), ...]), ...]`` with one entry per event (a second entry for the same ``dst`` replaces the
first), sorted topologically by the engine (``RuntimeError`` on a cycle). Each run draws, for every activity whose
type has a generator, its duration ``D + extra`` (an activity of a type without one keeps ``D``, never redrawn).
``GenericDelayGenerator`` keeps one distribution per type (the last one set wins; type -1 is reserved):
``add_constant(t, f)``: extra = ``f · D``; ``add_exponential(t, lambda_, max_scale)``: extra = ``X · D`` where
``X`` is exponential of **mean** ``lambda_`` (the C++ builds ``exponential_distribution(1 / lambda_)``), redrawn
while ``X > max_scale`` (a truncation, not a cap; ``inf``: none): scaled by the activity's duration, so an
activity of duration 0 gets no delay; ``add_gamma(t, k, s, max_scale)``: the same with a gamma(k, s);
``add_empirical_absolute(t, values, weights)``: extra = a value drawn with probability weight / Σweights,
whatever ``D``; ``add_empirical_relative(t, factors, weights)``: extra = factor · ``D``. Then, in topological
order, an event is realized at
``min(max(earliest, max over (src, idx) of min(realized[src] + duration[idx], ub)), ub)`` with
``ub = earliest + max_delay`` (``max_delay`` ≥ 0; ``inf``: no cap). ``MonteCarloPropagator(ctx, gen).run(seed)``
reseeds the propagator's own xoshiro256++ with the 32-bit int ``seed`` (through splitmix64; the generator's own
seed, ``set_seed``, is never used) and returns a ``SimResult``: ``realized`` (per event), ``durations`` (per
activity, with the extra) and ``cause_event`` (the binding predecessor, ties to the last, or -1), numpy arrays
(each property copies the whole result first; the result's buffer, ``np.asarray(result)``, is ``realized`` in
place); ``run_many(seeds)`` is those runs in turn, without the GIL, one thread: a list of ``SimResult``.

**planner's rule** (:mod:`planner.delay.propagate`) puts an event's primary delay after the maximum:
``x_e = max(s_e, max_a (x_src(a) + min_a)) + p_e``, ``p_e ≥ 0``. The mapping, with ``max_delay = inf`` and event
``e`` of the network kept as mc_dagprop's event ``e`` (earliest ``s_e``, so ``realized[e] − s_e`` is ``z_e``):

* no primary delay: ``e`` takes its incoming activities (duration ``min_a``, no generator): the rule's own
  additions and maximum, to the bit (planner's kernel works in delays, ``z_src − slack``: equal to round-off);
* any primary delay: a *pre-event* ``e'`` (earliest ``s_e``) takes ``e``'s incoming activities, so
  ``x_e' = max(s_e, max_a (x_src + min_a))``, and an activity ``e' → e`` carries the delay
  (``x_e = max(s_e, x_e' + p) = x_e' + p`` as ``p ≥ 0``):
  ``("fixed", d)``: duration ``d``, no generator (exact, to the bit: the rule's one addition);
  ``("empirical", v)``: duration 0, ``add_empirical_absolute(v, equal weights)`` (exact);
  ``("exponential", q, m)``: mc_dagprop has no "with probability q" (one distribution per activity), and its
  exponential is scaled by the duration, so duration 0 carries none. Both are met exactly by memorylessness: a
  helper event ``h`` (earliest ``s_e``), ``e' → h`` of duration 1 s with ``add_exponential(m, inf)``
  (``x_h = x_e' + 1 + X``, ``X`` exponential of mean ``m``), ``h → e`` of duration ``−(1 + c)`` with
  ``c = −m ln q``, and ``e' → e`` of duration 0: ``x_e = x_e' + max(0, X − c)``; ``P(X > c) = e^{−c/m} = q`` and
  ``X − c`` given ``X > c`` is again exponential of mean ``m``, so ``max(0, X − c)`` is exactly 0 with
  probability ``1 − q``, else exponential of mean ``m`` (``q = 1``: ``c = 0``). Exact in distribution; the values
  differ from the exact sum by the round-off of two more additions (~1e-11 s at 1e5 s).

Two activities between the same pair of events become one with the larger minimum (mc_dagprop keys activities
by the pair): ``max(x + m1, x + m2) = x + max(m1, m2)``, also in float64. Day ``d`` of a run seeded ``seed`` is
mc_dagprop's run with seed ``(b + d) mod 2³¹``, ``b`` drawn from ``SeedSequence(seed)``.
"""
from __future__ import annotations

import math

import numpy as np

SEED_MOD = 2 ** 31  # mc_dagprop's seed is a C int


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


def _delays(spec, e) -> bool:
    """Whether ``spec`` delays at all (not for None, ``("fixed", 0)``, q = 0 or a mean of 0); raises on a
    malformed one."""
    if spec is None:
        return False
    kind, args = spec[0], spec[1:]
    if kind == "fixed" and len(args) == 1 and math.isfinite(args[0]) and args[0] >= 0.0:
        return args[0] > 0.0
    if (kind == "exponential" and len(args) == 2 and 0.0 <= args[0] <= 1.0 and math.isfinite(args[1])
            and args[1] >= 0.0):
        return args[0] > 0.0 and args[1] > 0.0
    if kind == "empirical" and len(args) == 1:
        v = np.asarray(args[0], dtype=float)
        if v.ndim == 1 and len(v) and np.isfinite(v).all() and (v >= 0.0).all():
            return True
    raise ValueError(f"event {e}: primary delay {spec!r} is not None, ('fixed', d ≥ 0), "
                     f"('exponential', 0 ≤ q ≤ 1, mean ≥ 0) or ('empirical', 1-D values ≥ 0)")


def build(sched_s, src, dst, min_s, primary):
    """mc_dagprop's context and delay generator for the network (module doc): ``(DagContext,
    GenericDelayGenerator)``; events ``0 .. n_ev − 1`` are the network's, helpers follow."""
    from mc_dagprop import Activity, DagContext, Event, EventTimestamp, GenericDelayGenerator

    sched = np.asarray(sched_s, dtype=np.float64)
    src, dst = np.asarray(src, dtype=np.int64), np.asarray(dst, dtype=np.int64)
    mins = np.asarray(min_s, dtype=np.float64)
    n = len(sched)
    if not (len(src) == len(dst) == len(mins)) or len(primary) != n:
        raise ValueError(f"{len(src)}/{len(dst)}/{len(mins)} activity columns and {len(primary)} primary delays "
                         f"for {n} events")
    if len(src) and (min(src.min(), dst.min()) < 0 or max(src.max(), dst.max()) >= n):
        raise ValueError("an activity names an event outside 0 .. n_ev - 1")
    ts = sched.tolist()
    # earliest = the schedule; latest and actual are not read by the engine (latest: none, actual: the schedule)
    events = [Event(str(e), EventTimestamp(ts[e], math.inf, ts[e])) for e in range(n)]
    gen = GenericDelayGenerator()
    types: dict = {}  # one activity type per distribution: exponential per mean, empirical per value list
    seen: dict = {}  # id of an empirical spec's array (alive in `primary` meanwhile) -> its type

    def typed(key, add):
        if key not in types:
            types[key] = len(types)
            add(types[key])  # the generator's distribution for that type, once
        return types[key]

    carry = []  # the activities that carry primary delays: (src, dst, duration, type; -1: no generator)

    def helper(e, mark):
        events.append(Event(f"{e}{mark}", EventTimestamp(ts[e], math.inf, ts[e])))
        return len(events) - 1

    into = list(range(n))  # where each event's incoming activities end: itself, or its pre-event
    for e, spec in enumerate(primary):
        if not _delays(spec, e):
            continue
        pre = into[e] = helper(e, "'")
        if spec[0] == "fixed":
            carry.append((pre, e, float(spec[1]), -1))
        elif spec[0] == "empirical":
            if id(spec[1]) not in seen:  # many events share one array (a rule's): its values read once
                v = np.asarray(spec[1], dtype=float).tolist()
                seen[id(spec[1])] = typed(("empirical", tuple(v)),
                                          lambda t: gen.add_empirical_absolute(t, v, [1.0] * len(v)))
            t = seen[id(spec[1])]
            carry.append((pre, e, 0.0, t))
        else:
            q, m = float(spec[1]), float(spec[2])
            t = typed(("exponential", m), lambda t: gen.add_exponential(t, m, math.inf))
            h = helper(e, "^")
            carry += [(pre, h, 1.0, t), (h, e, -(1.0 + (-m * math.log(q))), -1), (pre, e, 0.0, -1)]
    merged: dict = {}  # the network's activities by pair of events, the larger minimum of two
    for s, d, m in zip(src.tolist(), dst.tolist(), mins.tolist()):
        key = (s, into[d])
        if key not in merged or m > merged[key]:
            merged[key] = m
    # helpers are new events, so no carrying activity shares a pair with the network's (src < n_ev, no helper)
    activities, preds = {}, {}
    for i, (s, d, dur, t) in enumerate([(s, d, m, -1) for (s, d), m in merged.items()] + carry):
        activities[(s, d)] = Activity(i, dur, t)
        preds.setdefault(d, []).append((s, i))
    return DagContext(events, activities, list(preds.items()), math.inf), gen


def day_seeds(seed: int, days: int) -> np.ndarray:
    """mc_dagprop's seed of each day of a run seeded ``seed``: distinct for up to 2³¹ days."""
    b = int(np.random.SeedSequence(int(seed)).generate_state(1, dtype=np.uint64)[0]) % SEED_MOD
    return (b + np.arange(int(days), dtype=np.int64)) % SEED_MOD


def dagprop_delays(sched_s, src, dst, min_s, primary, days, seed, *, batch=1000, keep=False):
    """Delays of every event over `days` simulated days, computed by mc_dagprop.

    sched_s : float64 (n_ev,) scheduled time of each event [s]
    src, dst, min_s : (n_act,) activities: event src -> event dst with a minimum duration min_s [s]
        (the network is a DAG; events may have no incoming activity)
    primary : list of length n_ev; each item one of
        None                         no primary delay
        ("fixed", d)                 always d seconds
        ("exponential", q, mean)     with probability q an exponential delay with that mean, else 0
        ("empirical", values)        a value drawn uniformly from the 1-D array `values`
    Returns dict: mean (n_ev,), std (n_ev,) of the delay z_e = x_e - sched_s[e]; and "all" (days, n_ev) if keep.
    ``std`` is the sample standard deviation (ddof 1; 0 for one day). Each day is one mc_dagprop run
    (:func:`day_seeds`), ``batch`` runs per ``run_many`` call.
    """
    from mc_dagprop import MonteCarloPropagator

    days, batch = int(days), int(batch)
    if days < 1 or batch < 1:
        raise ValueError(f"days ({days}) and batch ({batch}) must be at least 1")
    ctx, gen = build(sched_s, src, dst, min_s, primary)
    sim = MonteCarloPropagator(ctx, gen)
    sched = np.asarray(sched_s, dtype=np.float64)
    n = len(sched)
    seeds = day_seeds(seed, days).tolist()
    count, mean, m2 = 0, np.zeros(n), np.zeros(n)  # running mean and sum of squared deviations (Chan et al.)
    rows = []
    for lo in range(0, days, batch):
        res = sim.run_many(seeds[lo:lo + batch])
        z = np.empty((len(res), n))
        for i, r in enumerate(res):
            # a SimResult's buffer is its realized times, read in place (``.realized`` copies the whole result:
            # times, durations and causes, ten times slower on a large DAG)
            z[i] = np.asarray(r)[:n]
        z -= sched
        k = len(z)
        bm = z.mean(axis=0)
        bm2 = ((z - bm) ** 2).sum(axis=0)
        delta = bm - mean
        tot = count + k
        mean = mean + delta * (k / tot)
        m2 = m2 + bm2 + delta ** 2 * (count * k / tot)
        count = tot
        if keep:
            rows.append(z)
    out = {"mean": mean, "std": np.sqrt(m2 / (count - 1)) if count > 1 else np.zeros(n)}
    if keep:
        out["all"] = np.concatenate(rows)
    return out
