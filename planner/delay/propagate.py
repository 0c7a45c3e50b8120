"""Delay propagation over the day's event–activity network, many days at once.

Takes a :class:`~planner.delay.network.DelayNetwork` and each event's own (primary) delay on each
simulated day; gives every event's delay. In the network's topological order, event ``e`` happens at

    x_e = max(sched_e, max over activities a into e of (x_src(a) + min_a)) + p_e

(its schedule or the latest activity into it, whichever is later, then its own primary delay ``p_e``;
a train never departs before its schedule). In delays ``z = x − sched`` this is

    z_e = max(0, max_a (z_src(a) − slack_a)) + p_e

which is what the kernel computes: one subtraction, one maximum and one addition per activity and
day, in float64, the same bytes on every run. Days are the inner, contiguous axis, so one event's
update is a loop over days the compiler vectorises; chunks of days run in parallel on the job's
workers (:mod:`planner.delay.montecarlo`).

Besides the delays, the kernel accumulates per activity how much delay it *transmitted* (on days it is
the binding activity into its event, ties to the first: ``z_src − slack``) and how much its slack
*absorbed* (``min(z_src, slack)`` where both are positive: the delay that came in and did not come out).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from planner.delay.network import DelayNetwork


@njit(cache=False, nogil=True)
def _kernel(order, in_ptr, in_act, act_src, slack, prim, z, push, binds, absorbed):  # pragma: no cover - compiled
    n_days = z.shape[1]
    best = np.empty(n_days)
    for e in order:
        for d in range(n_days):
            best[d] = 0.0
        for k in range(in_ptr[e], in_ptr[e + 1]):
            a = in_act[k]
            s = act_src[a]
            sl = slack[a]
            for d in range(n_days):
                v = z[s, d] - sl
                if v > best[d]:
                    best[d] = v
        if push.shape[0] > 0:
            # attribution: the first activity reaching the maximum transmits it; every positive slack absorbs
            for d in range(n_days):
                done = False
                for k in range(in_ptr[e], in_ptr[e + 1]):
                    a = in_act[k]
                    zs = z[act_src[a], d]
                    sl = slack[a]
                    v = zs - sl
                    if not done and v > 0.0 and v == best[d]:
                        push[a] += v
                        binds[a] += 1
                        done = True
                    if sl > 0.0 and zs > 0.0:
                        absorbed[a] += zs if zs < sl else sl
        for d in range(n_days):
            z[e, d] = best[d] + prim[e, d]


def propagate(net: DelayNetwork, primary: np.ndarray | None = None, *, days: int | None = None,
              attribution: bool = False):
    """Every event's delay [s] on each day: ``(n_events, days)``.

    Parameters
    ----------
    primary : ndarray (n_events, days), optional
        Each event's own delay per day [s]; none: no primary delay, one day.
    attribution : bool
        Also return (transmitted [s], binding days, absorbed [s]) per activity, summed over the days.
    """
    if primary is None:
        primary = np.zeros((net.n_events, 1 if days is None else int(days)))
    prim = np.ascontiguousarray(primary, dtype=np.float64)
    if prim.shape[0] != net.n_events:
        raise ValueError(f"primary delays for {prim.shape[0]} events, the network has {net.n_events}")
    z = np.empty_like(prim)
    na = net.n_activities if attribution else 0
    push, binds, absorbed = np.zeros(na), np.zeros(na, dtype=np.int64), np.zeros(na)
    _kernel(net.order, net.in_ptr, net.in_act, net.act_src, np.ascontiguousarray(net.slack_s, dtype=np.float64),
            prim, z, push, binds, absorbed)
    return (z, push, binds, absorbed) if attribution else z


def binding(net: DelayNetwork, z: np.ndarray) -> np.ndarray:
    """For a single day's delays ``z`` (n_events,): the activity that set each event's delay (the first reaching
    the maximum, when it is positive), else -1."""
    out = np.full(net.n_events, -1, dtype=np.int64)
    if net.n_activities == 0:
        return out
    push = z[net.act_src] - net.slack_s
    for e in range(net.n_events):
        lo, hi = net.in_ptr[e], net.in_ptr[e + 1]
        if hi == lo:
            continue
        acts = net.in_act[lo:hi]
        v = push[acts]
        j = int(np.argmax(v))
        if v[j] > 0.0:
            out[e] = int(acts[j])
    return out
