"""Minimum headway per resource (after the conflicts): how closely the timetable's trains follow on each
switch and section, and how closely they could.

Takes the track graph, the trains and their :class:`Windows`; gives one record
per resource that two or more trains use (the columns of the ``headways``
dataset, :func:`resource_headways`).

Definitions, for a train A whose window on a resource is followed by train B's
(both windows open the same lead, setting + approach, before the front enters):

* **headway** = B's window opening − A's window opening: the time between the
  two fronts entering the resource, as planned;
* **minimum headway** = A's blocking time on the resource, window close − window
  open: the least headway at which B's window opens only after A's has closed.
  It depends on the leading train alone (its speed through the resource, a
  dwell with its tail inside it, its length, the blocking-time parameters);
* **buffer** = headway − minimum headway = B's opening − A's closing: the free
  time between the two occupations; negative, the windows overlap by that much
  and the pair is a conflict (:mod:`planner.network.priority`).

Per resource the record is the *tightest* pair: the following train B and the
earlier train A whose window closes last before B's opens (the smallest buffer
over all pairs, not only neighbours: a long window can overlap two later ones;
of equal buffers, :data:`TIE_S`, the earliest pair).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from planner.line.model import Train
from planner.network.routes import KIND_NAMES, TrackGraph
from planner.network.windows import Windows


TIE_S = 1e-3
"""Buffers this close [s] are equal (they differ by the round-off of two run curves): the earliest pair is taken."""


def resource_headways(g: TrackGraph, trains: Sequence[Train], w: Windows) -> list[dict[str, Any]]:
    """The tightest pair of following trains on every resource two or more trains use.

    Returns
    -------
    list of dict
        One record per resource, in resource order (kind, then index): where it
        is, ``n_trains``, the pair (``train_a`` then ``train_b``), ``a_start_s``,
        ``headway_s``, ``min_headway_s``, ``buffer_s`` (module doc).
    """
    if len(w) == 0:
        return []
    key = w.res.astype(np.int64) * 2 + w.kind.astype(np.int64)
    order = np.lexsort((w.train, w.start_s, key))  # per resource, by opening (train index breaks ties)
    bounds = np.flatnonzero(np.r_[True, key[order][1:] != key[order][:-1], True])
    out: list[dict[str, Any]] = []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        idx = order[lo:hi]
        if len(idx) < 2:
            continue
        start, end = w.start_s[idx], w.end_s[idx]
        # for each window after the first: the earlier window that closes last (running argmax of the ends)
        run = np.maximum.accumulate(end)
        arg = np.zeros(len(idx), dtype=np.int64)
        for k in range(1, len(idx)):
            arg[k] = k if end[k] > end[arg[k - 1]] else arg[k - 1]
        buf = start[1:] - run[:-1]
        # the following window of the tightest pair; buffers within TIE_S of the smallest are ties: the earliest
        j = int(np.flatnonzero(buf <= buf.min() + TIE_S)[0]) + 1
        a, b = int(idx[arg[j - 1]]), int(idx[j])
        kind, res = int(w.kind[a]), int(w.res[a])
        flo, fhi = g.resource_extent(kind, res)
        sid, dist = g.resource_station(kind, res)
        out.append({
            "resource_kind": KIND_NAMES[kind],
            "resource_id": g.resource_id(kind, res),
            "interlocking": g.resource_interlocking(kind, res),
            "track": g.resource_track(kind, res) or "",
            "station_id": sid,
            "station_name": g.line.station(sid).name,
            "station_distance_m": float(dist),
            "from_m": flo,
            "to_m": fhi,
            "n_trains": int(len(idx)),
            "train_a": trains[int(w.train[a])].train_id,
            "train_b": trains[int(w.train[b])].train_id,
            "a_start_s": float(w.start_s[a]),
            "headway_s": float(w.start_s[b] - w.start_s[a]),
            "min_headway_s": float(w.end_s[a] - w.start_s[a]),
            "buffer_s": float(w.start_s[b] - w.end_s[a]),
        })
    return out
