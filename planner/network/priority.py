"""Conflicts and priority (docs/design.md §8, step 4): overlapping windows become conflicts, each decided once.

Takes the track graph, the trains, their routes and their :class:`Windows`;
gives one record (a dict of plain values, the columns of the ``conflicts``
dataset) per conflict and shared resource (:func:`detect_conflicts`).

Windows are sorted per resource and swept, so only neighbours in time are
compared. Overlapping windows of two trains on consecutive shared resources
form one conflict, decided once with the rules of docs/design.md §8:

* opposing trains that would both be inside a shared single-track stretch
  (≥ 2 resources, so each would hold one the other needs) are a **deadlock**
  (:func:`would_deadlock`): the train that leaves the stretch earlier goes
  first and the other waits before the stretch until it is clear (rule
  ``no-deadlock``);
* same-direction trains whose routes pass the same interlocking boundary
  keep the timetable's departure order (rule ``timetable-order``: the earlier
  departure from the last call before the conflict goes first);
* otherwise the train that leaves the shared section earlier goes first
  (rule ``leaves-first``).

The delay imposed on the other train is how far its windows must move so
that each starts after the first train's window on the same resource ends
(for the usual case exactly the overlap). Delays are not propagated to later
conflicts: the report lists each conflict of the timetable as planned.

Each record also says where the resource is (station, track, chainage extent:
:meth:`TrackGraph.resource_station`) and the two trains' headway there (the
time between their windows opening) against the minimum headway (the first
train's blocking time), defined in :mod:`planner.network.headways`. Conflicts
are numbered from 1 in time order.
"""
from __future__ import annotations

from collections import defaultdict
from typing import Any, Mapping, Sequence

import numpy as np

from planner.line.model import Train, sign
from planner.network.routes import KIND_NAMES, Route, TrackGraph, call_interval
from planner.network.windows import Windows, find_overlaps

RULE_DEADLOCK = "no-deadlock"
RULE_ORDER = "timetable-order"
RULE_LEAVES_FIRST = "leaves-first"


def _departure_before(train: Train, chainage_m: float, stop_m: Mapping[str, float]) -> float:
    """Timetable departure (or passing) time of the train's last call at or before a chainage [s]."""
    sg = sign(train.direction)
    best = train.calls[0]
    for c in train.calls:
        if sg * stop_m[c.station_id] <= sg * chainage_m + 1e-6:
            best = c
    return call_interval(best)[1]


def detect_conflicts(g: TrackGraph, trains: Sequence[Train], routes: Sequence[Route],
                     w: Windows) -> list[dict[str, Any]]:
    """Conflicts between the trains' windows, each with its priority decision and delay.

    Returns one record per (conflict, resource) where the two trains' windows
    overlap; records of one conflict share ``conflict_id``, ``train_a`` (goes
    first), ``train_b`` (waits), ``rule``, ``decision``, ``delay_s``.
    """
    line = g.line
    st_pos = {d: {s.station_id: s.stop_m(d) for s in line.stations} for d in ("down", "up")}
    rkey = w.res * 2 + w.kind
    i, j = find_overlaps(rkey, w.start_s, w.end_s, w.train)
    if len(i) == 0:
        return []
    # Orient each pair by train index so a pair's rows group together.
    swap = w.train[i] > w.train[j]
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    boundaries = [set(int(n) for n in r.node_idx if g.kind[n] == "boundary") for r in routes]
    # Per train: resource key → window index, for stretch intervals.
    by_train: dict[int, dict[int, int]] = defaultdict(dict)
    for k in range(len(w)):
        by_train[int(w.train[k])][int(rkey[k])] = k
    pairs: dict[tuple[int, int], list[tuple[int, int]]] = defaultdict(list)
    for a, b in zip(i.tolist(), j.tolist()):
        pairs[(int(w.train[a]), int(w.train[b]))].append((a, b))
    records: list[dict[str, Any]] = []
    for (ta, tb), rows in sorted(pairs.items(), key=lambda kv: (trains[kv[0][0]].train_id, trains[kv[0][1]].train_id)):
        A, B = trains[ta], trains[tb]
        rows.sort(key=lambda ab: w.item[ab[0]])
        # Group consecutive shared resources along A's route (a gap of one item is a
        # point node that is not a resource, e.g. a stop or boundary).
        groups: list[list[tuple[int, int]]] = [[rows[0]]]
        for ab in rows[1:]:
            if w.item[ab[0]] - w.item[groups[-1][-1][0]] <= 2 and abs(int(w.item[ab[1]]) - int(w.item[groups[-1][-1][1]])) <= 2:
                groups[-1].append(ab)
            else:
                groups.append([ab])
        if A.direction != B.direction:
            # One decision per shared single-track stretch, however many separate overlaps lie in it.
            merged: dict[tuple[int, ...], list[tuple[int, int]]] = {}
            for grp in groups:
                key = tuple(_shared_stretch(w, rkey, by_train, ta, tb, int(rkey[grp[0][0]])))
                merged.setdefault(key, []).extend(grp)
            groups = list(merged.values())
        for grp in groups:
            records.extend(_decide(g, A, B, grp, w, rkey, by_train, boundaries, ta, tb, st_pos, len(records)))
    # Stable ids in time order, numbered from 1 as a planner counts.
    cids: dict[int, int] = {}
    for r in sorted(records, key=lambda r: (r["_t0"], r["train_a"], r["train_b"], r["_gid"])):
        cids.setdefault(r["_gid"], len(cids) + 1)
    for r in records:
        r["conflict_id"] = cids[r.pop("_gid")]
        r.pop("_t0")
    return records


def would_deadlock(start_a, end_a, start_b, end_b) -> bool:
    """Would two opposing trains deadlock on a chain of single-track resources if both ran as planned?

    The resources are indexed in train A's running order; train B runs them in
    the reverse order. Each train claims its resources in its running order at
    its window starts and releases them at its window ends. Claims are granted
    in time order; a train that asks for a resource the other holds stops and
    keeps everything it holds. A deadlock is a circular wait: a train asks for
    a resource that the stopped train holds, so each holds a resource the other
    needs (Coffman's conditions on a two-train chain).

    Parameters
    ----------
    start_a, end_a : arrays (k,)
        Train A's window per resource, in A's running order [s].
    start_b, end_b : arrays (k,)
        Train B's window per resource, same indexing [s].
    """
    k = len(start_a)
    ev = sorted([(float(start_a[i]), 0, i, i) for i in range(k)]
                + [(float(start_b[i]), 1, k - 1 - i, i) for i in range(k)])
    E = (end_a, end_b)
    granted: tuple[set, set] = (set(), set())
    stopped: list[float | None] = [None, None]
    for tau, t, _, r in ev:
        if stopped[t] is not None:
            continue
        o = 1 - t
        horizon = tau if stopped[o] is None else stopped[o]
        if r in granted[o] and E[o][r] > horizon:
            if stopped[o] is not None:
                return True
            stopped[t] = tau
        else:
            granted[t].add(r)
    return False


def _shared_stretch(w: Windows, rkey: np.ndarray, by_train, ta: int, tb: int, seed: int) -> list[int]:
    """Resource keys of the chain of resources shared by A and B around ``seed`` (contiguous along A's route)."""
    a_items = sorted((int(w.item[k]), int(rkey[k])) for k in by_train[ta].values())
    shared = set(by_train[ta]) & set(by_train[tb])
    pos = [x for x, (it, rk) in enumerate(a_items) if rk == seed][0]
    lo = hi = pos
    while lo > 0 and a_items[lo - 1][1] in shared and a_items[lo][0] - a_items[lo - 1][0] <= 2:
        lo -= 1
    while hi + 1 < len(a_items) and a_items[hi + 1][1] in shared and a_items[hi + 1][0] - a_items[hi][0] <= 2:
        hi += 1
    return [rk for _, rk in a_items[lo:hi + 1]]


def _decide(g, A: Train, B: Train, grp, w: Windows, rkey, by_train, boundaries, ta, tb, st_pos, gid):
    """Priority decision and delay for one conflict (a group of consecutive overlapping resources)."""
    first = None
    rule = ""
    stretch: list[int] = []
    deadlock = False
    if A.direction != B.direction:
        stretch = _shared_stretch(w, rkey, by_train, ta, tb, int(rkey[grp[0][0]]))
        if len(stretch) >= 2:
            ka = [by_train[ta][rk] for rk in stretch]
            kb = [by_train[tb][rk] for rk in stretch]
            a0, a1 = w.start_s[ka].min(), w.end_s[ka].max()
            b0, b1 = w.start_s[kb].min(), w.end_s[kb].max()
            if would_deadlock(w.start_s[ka], w.end_s[ka], w.start_s[kb], w.end_s[kb]):
                deadlock = True
                rule = RULE_DEADLOCK
                a_first = (a1, A.train_id) <= (b1, B.train_id)
                first = "a" if a_first else "b"
                delay = (a1 - b0) if a_first else (b1 - a0)
    if not deadlock:
        ka = [a for a, _ in grp]
        kb = [b for _, b in grp]
        if A.direction == B.direction and (boundaries[ta] & boundaries[tb]):
            rule = RULE_ORDER
            x = w.from_m[ka[0]]
            da = _departure_before(A, x, st_pos[A.direction])
            db = _departure_before(B, x, st_pos[B.direction])
            first = "a" if (da, A.train_id) <= (db, B.train_id) else "b"
        else:
            rule = RULE_LEAVES_FIRST
            first = "a" if (w.end_s[ka].max(), A.train_id) <= (w.end_s[kb].max(), B.train_id) else "b"
        # Each of the waiting train's windows must open after the first train's closes.
        if first == "a":
            delay = max(0.0, float(np.max(w.end_s[ka] - w.start_s[kb])))
        else:
            delay = max(0.0, float(np.max(w.end_s[kb] - w.start_s[ka])))
    P, Q = (A, B) if first == "a" else (B, A)
    tp, tq = (ta, tb) if first == "a" else (tb, ta)
    if deadlock:
        keys = stretch
        ends = [g.resource_id(rk % 2, rk // 2) for rk in (keys[0], keys[-1])]
        st_name = f"{ends[0]}..{ends[1]}"
        kq = by_train[tq]
        # The waiting train holds at the node where it would enter the stretch.
        entry_items = sorted(keys, key=lambda rk: w.item[kq[rk]])
        k_in = kq[entry_items[0]]
        n_wait = g.resource_id(int(w.kind[k_in]), int(w.res[k_in]))
        decision = (f"{P.train_id} first; {Q.train_id} waits before single-track stretch {st_name} "
                    f"(enters at {n_wait}) until {P.train_id} has cleared it: both would hold a part the other needs")
    elif rule == RULE_ORDER:
        common = sorted(g.node_ids[n] for n in boundaries[ta] & boundaries[tb])
        decision = f"{P.train_id} first: timetable departure order through boundary {common[0]}"
        st_name = ""
    else:
        decision = f"{P.train_id} first: it leaves the shared section earlier"
        st_name = ""
    out = []
    for a, b in grp:
        kp, kq2 = (a, b) if first == "a" else (b, a)
        ov0 = max(w.start_s[a], w.start_s[b])
        ov1 = min(w.end_s[a], w.end_s[b])
        rk = int(rkey[a])
        rid = g.resource_id(rk % 2, rk // 2)
        il = g.resource_interlocking(rk % 2, rk // 2)
        sid, dist = g.resource_station(rk % 2, rk // 2)
        out.append({
            "_gid": gid,
            "_t0": float(min(w.start_s[a], w.start_s[b])),
            "train_a": P.train_id,
            "train_b": Q.train_id,
            "direction_a": P.direction,
            "direction_b": Q.direction,
            "resource_kind": KIND_NAMES[rk % 2],
            "resource_id": rid,
            "interlocking": il,
            "track": g.resource_track(rk % 2, rk // 2) or "",
            "station_id": sid,
            "station_name": g.line.station(sid).name,
            "station_distance_m": float(dist),
            "from_m": float(min(w.from_m[a], w.to_m[a])),
            "to_m": float(max(w.from_m[a], w.to_m[a])),
            "a_start_s": float(w.start_s[kp]),
            "a_end_s": float(w.end_s[kp]),
            "b_start_s": float(w.start_s[kq2]),
            "b_end_s": float(w.end_s[kq2]),
            "overlap_start_s": float(ov0),
            "overlap_end_s": float(ov1),
            "overlap_s": float(ov1 - ov0),
            "headway_s": float(w.start_s[kq2] - w.start_s[kp]),
            "min_headway_s": float(w.end_s[kp] - w.start_s[kp]),
            "rule": rule,
            "decision": decision,
            "delay_s": float(delay),
            "deadlock": bool(deadlock),
            "stretch": st_name,
        })
    return out
