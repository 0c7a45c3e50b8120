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

from planner.delay.network import DelayNetwork

SOURCES = ("planner.delay.kernel",)
"""The modules whose bytes name a build of the kernels (read without importing them: a just-in-time kernel
compiles when first called, never for ``planner kernels status``)."""
_k = None  # the kernels: their build (planner.io.compiled) or planner.delay.kernel, chosen on first use


def _kernels():
    """The propagation's entry points: the module built at install for these sources, else the just-in-time one."""
    global _k
    if _k is None:
        from planner.delay import kernel
        from planner.io import compiled

        _k = compiled.load("delay", SOURCES) or kernel
    return _k


def histogram(z: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Days per delay bin of each event, ``(n_events, len(edges) + 1)`` (:func:`planner.delay.kernel.histogram`)."""
    hist = np.zeros((z.shape[0], len(edges) + 1), dtype=np.int64)
    _kernels().histogram(np.ascontiguousarray(z, dtype=np.float64), np.ascontiguousarray(edges, dtype=np.float64), hist)
    return hist


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
    i8 = (lambda a: np.ascontiguousarray(a, dtype=np.int64))
    _kernels().propagate(i8(net.order), i8(net.in_ptr), i8(net.in_act), i8(net.act_src),
                         np.ascontiguousarray(net.slack_s, dtype=np.float64), prim, z, push, binds, absorbed)
    return (z, push, binds, absorbed) if attribution else z


def binding(net: DelayNetwork, z: np.ndarray) -> np.ndarray:
    """For a single day's delays ``z`` (n_events,): the activity that set each event's delay (the first reaching
    the maximum, when it is positive), else -1. Vectorised over the events' incoming lists."""
    out = np.full(net.n_events, -1, dtype=np.int64)
    if net.n_activities == 0:
        return out
    acts = np.asarray(net.in_act, dtype=np.int64)  # grouped by event, in_ptr the bounds
    push = z[net.act_src[acts]] - net.slack_s[acts]
    lo = np.asarray(net.in_ptr[:-1], dtype=np.int64)
    has = np.asarray(net.in_ptr[1:], dtype=np.int64) > lo
    starts = lo[has]
    best = np.maximum.reduceat(push, starts)
    seg = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(push)]))
    pos = np.where(push == best[seg], np.arange(len(push)), len(push))
    first = np.minimum.reduceat(pos, starts)
    ev = np.flatnonzero(has)
    ok = best > 0.0
    out[ev[ok]] = acts[first[ok]]
    return out
