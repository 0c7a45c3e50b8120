"""The day's event–activity network: every arrival and departure, and the minimum times between them.

Takes the trains of a day with their scheduled and planned event times, the minimum running time of
each leg, the minimum dwell, the blocking-time windows of the conflict check and an order of the
trains on every resource; gives a :class:`DelayNetwork` (parallel arrays, no pandas) in which delay
propagates (:mod:`planner.delay.propagate`).

**Events**: per running train, the departure from its origin, an arrival and a departure at every
intermediate stop, the arrival at its destination (passes are run through). Each has its scheduled
time ``sched_s`` (the timetable) and its *planned* time ``plan_s`` (the conflict check's trajectory:
the schedule, or later where a leg cannot be run in its scheduled time).

**Activities** ``src → dst`` with a minimum duration ``min_s``; its **slack** is
``sched_s[dst] − sched_s[src] − min_s`` (negative: the schedule cannot hold it):

* ``run``: departure → next arrival, the leg's minimum running time for the train's type on the day
  (its restrictions in force), the same run curves the conflict check predicts the train with;
* ``dwell``: arrival → departure at a stop, the minimum dwell;
* ``headway``: train A's event → the next train B's event on a resource (a section or a switch).
  A's window on the resource closes ``endA − plan_s[eA]`` after A's *anchor* event ``eA`` (its last
  event at or before the close); B's opens ``startB − plan_s[eB]`` after its anchor ``eB`` (its last
  event at or before its front enters). B may open only once A's has closed, so
  ``min_s = (endA − plan_s[eA]) − (startB − plan_s[eB])``; on a day that runs as planned its slack is
  the pair's *buffer* ``startB − endA`` (:mod:`planner.network.headways`). Both offsets stay as planned
  when the anchors move: a late train runs the same curve later. Following trains and, on single
  track, opposing trains get one each way they meet;
* ``connection``: a turnaround or a connection of the job (train A's arrival feeds train B's
  departure with a minimum time).

The order of the trains on a resource is an input (:func:`order_key`): the predicted day takes the
one the conflict check decides for the day as it runs (:mod:`planner.delay.predicted`). A headway
that would close a cycle with the others (an order the trains cannot keep, which only a deadlock
gives) is left out and counted (``dropped``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

ARRIVAL, DEPARTURE = 0, 1
EVENT_KINDS = ("arrival", "departure")
RUN, DWELL, HEADWAY, CONNECTION = 0, 1, 2, 3
ACTIVITY_KINDS = ("run", "dwell", "headway", "connection")
TOL_S = 1e-6
"""Times this close [s] are the same instant when an anchor is looked up (round-off of two run curves)."""


@dataclass(frozen=True, eq=False)
class TrainEvents:
    """The events of one train, in running order (``kind`` ARRIVAL/DEPARTURE, one entry per event)."""

    train_id: str
    train_type: str
    direction: str
    station: tuple[str, ...]
    seq: tuple[int, ...]
    kind: np.ndarray
    sched_s: np.ndarray
    plan_s: np.ndarray
    run_min_s: np.ndarray
    """Minimum running time of each leg (one fewer than the stops) [s]."""


@dataclass(frozen=True, eq=False)
class DelayNetwork:
    """Events and activities of one day, as parallel arrays; ``order`` is a topological order of the events."""

    train_ids: tuple[str, ...]
    train_types: tuple[str, ...]
    ev_train: np.ndarray        # int, index into train_ids
    ev_station: tuple[str, ...]
    ev_seq: np.ndarray          # int, the call's seq in the timetable
    ev_kind: np.ndarray         # int8, ARRIVAL / DEPARTURE
    ev_origin: np.ndarray       # bool: the departure from the train's origin
    sched_s: np.ndarray
    plan_s: np.ndarray
    act_src: np.ndarray
    act_dst: np.ndarray
    act_kind: np.ndarray        # int8, RUN / DWELL / HEADWAY / CONNECTION
    min_s: np.ndarray
    slack_s: np.ndarray
    act_place: tuple[str, ...]  # headway: the resource's id; else ""
    order: np.ndarray
    in_ptr: np.ndarray          # CSR of the activities into each event: in_act[in_ptr[e]:in_ptr[e + 1]]
    in_act: np.ndarray
    dropped: int = 0
    places: dict[str, str] = field(default_factory=dict)
    """Resource id → where it is, in words (station, track), for pages."""

    @property
    def n_events(self) -> int:
        return len(self.sched_s)

    @property
    def n_activities(self) -> int:
        return len(self.act_src)

    def without(self, kinds: Sequence[int]) -> "DelayNetwork":
        """The same events with the activities of ``kinds`` left out (each train alone: headways, connections)."""
        keep = ~np.isin(self.act_kind, np.asarray(kinds))
        return _assemble(self, keep)


def train_events(train_id: str, train_type: str, direction: str, stops: Sequence[tuple[str, int, float, float]],
                 plan: Sequence[tuple[float, float]], run_min_s: Sequence[float]) -> TrainEvents:
    """One train's events from its stop calls.

    ``stops``: (station, seq, scheduled arrival, scheduled departure) per stop call, in running order (a missing
    time NaN: the other one stands in for it); ``plan``: (planned arrival, planned departure) per stop call.
    The origin gives its departure, the destination its arrival, every stop between both.
    """
    st, sq, kind, sched, pl = [], [], [], [], []
    last = len(stops) - 1
    for i, ((sid, seq, arr, dep), (parr, pdep)) in enumerate(zip(stops, plan)):
        arr = dep if np.isnan(arr) else arr
        dep = arr if np.isnan(dep) else dep
        for k, s, p in ((ARRIVAL, arr, parr), (DEPARTURE, dep, pdep)):
            if (k == ARRIVAL and i == 0) or (k == DEPARTURE and i == last):
                continue
            st.append(sid)
            sq.append(seq)
            kind.append(k)
            sched.append(s)
            pl.append(p)
    return TrainEvents(train_id, train_type, direction, tuple(st), tuple(sq), np.asarray(kind, dtype=np.int8),
                       np.asarray(sched, dtype=float), np.asarray(pl, dtype=float), np.asarray(run_min_s, dtype=float))


def anchors(plan_s: np.ndarray, first: int, at_s: np.ndarray) -> np.ndarray:
    """Global index of a train's last event at or before each time (its first event for earlier times)."""
    k = np.searchsorted(plan_s, np.asarray(at_s, dtype=float) + TOL_S, side="right") - 1
    return first + np.maximum(k, 0)


def window_anchors(w, sizes: Sequence[int], plan_s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each window's anchor events (global indices): the train's last event at or before its front enters,
    and at or before the window closes (module doc). ``sizes``: the number of events of each train."""
    first = np.cumsum([0] + list(sizes))
    tr = np.asarray(w.train, dtype=np.int64)
    a_start = np.empty(len(w), dtype=np.int64)
    a_end = np.empty(len(w), dtype=np.int64)
    by_train = np.argsort(tr, kind="stable")  # each train's windows one slice: linear in the windows, not trains × windows
    bounds = np.flatnonzero(np.r_[True, tr[by_train][1:] != tr[by_train][:-1], True]) if len(tr) else []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        m = by_train[lo:hi]
        k = int(tr[m[0]])
        f = int(first[k])
        p = plan_s[f:int(first[k + 1])]
        a_start[m] = anchors(p, f, w.entry_s[m])
        a_end[m] = anchors(p, f, w.end_s[m])
    return a_start, a_end


def order_key(start_s: np.ndarray, shift_s: np.ndarray | None = None) -> np.ndarray:
    """The order of the windows on their resource: by opening, moved by how long a train waits (``shift_s``)."""
    return np.asarray(start_s, dtype=float) if shift_s is None else np.asarray(start_s, dtype=float) + shift_s


def build_network(trains: Sequence[TrainEvents], *, min_dwell_s, windows=None, resource_ids: Sequence[str] = (),
                  key_s: np.ndarray | None = None,
                  connections: Sequence[tuple[str, str, str, float]] = (),
                  places: dict[str, str] | None = None) -> DelayNetwork:
    """The day's network (module doc).

    Parameters
    ----------
    trains : sequence of TrainEvents
        In the order of the windows' ``train`` index.
    min_dwell_s : callable(station, train_type) -> float, or float
        Minimum dwell [s].
    windows : Windows, optional
        The conflict check's blocking-time windows (:class:`planner.network.windows.Windows`); none: no headways.
    resource_ids : sequence of str
        Name of each resource, by ``res * 2 + kind`` of the windows (for the activities' places).
    key_s : ndarray, optional
        Order of the windows on each resource (:func:`order_key`); default their opening.
    connections : sequence of (train A, train B, station, minimum [s])
        A's arrival at the station feeds B's departure there.
    """
    dwell = min_dwell_s if callable(min_dwell_s) else (lambda _s, _t, v=float(min_dwell_s): v)
    first = np.cumsum([0] + [len(t.sched_s) for t in trains])
    n = int(first[-1])
    cat = (lambda f: np.concatenate([f(t) for t in trains]) if trains else np.zeros(0))
    ev_train = np.repeat(np.arange(len(trains)), [len(t.sched_s) for t in trains]).astype(np.int64)
    ev_kind = cat(lambda t: t.kind).astype(np.int8)
    sched = cat(lambda t: t.sched_s).astype(float)
    plan = cat(lambda t: t.plan_s).astype(float)
    ev_seq = cat(lambda t: np.asarray(t.seq, dtype=np.int64)).astype(np.int64)
    ev_station = tuple(s for t in trains for s in t.station)
    ev_origin = np.zeros(n, dtype=bool)
    ev_origin[first[:-1][[len(t.sched_s) > 0 for t in trains]]] = True

    src, dst, kind, mins, place = [], [], [], [], []
    for k, t in enumerate(trains):
        f = int(first[k])
        leg = 0
        for i in range(len(t.sched_s) - 1):
            a, b = f + i, f + i + 1
            if t.kind[i] == DEPARTURE:
                src.append(a), dst.append(b), kind.append(RUN), mins.append(float(t.run_min_s[leg])), place.append("")
                leg += 1
            else:
                src.append(a), dst.append(b), kind.append(DWELL), place.append("")
                mins.append(float(dwell(t.station[i], t.train_type)))
    if windows is not None and len(windows):
        _headways(windows, trains, plan, resource_ids, key_s, src, dst, kind, mins, place)
    index = {t.train_id: k for k, t in enumerate(trains)}
    for a_id, b_id, station, m in connections:
        if a_id not in index or b_id not in index:
            continue  # a train that does not run on the day
        ea = _event_at(trains[index[a_id]], int(first[index[a_id]]), station, ARRIVAL)
        eb = _event_at(trains[index[b_id]], int(first[index[b_id]]), station, DEPARTURE)
        if ea is not None and eb is not None:
            src.append(ea), dst.append(eb), kind.append(CONNECTION), mins.append(float(m)), place.append(station)
    src_a = np.asarray(src, dtype=np.int64)
    dst_a = np.asarray(dst, dtype=np.int64)
    mins_a = np.asarray(mins, dtype=float)
    base = DelayNetwork(tuple(t.train_id for t in trains), tuple(t.train_type for t in trains), ev_train, ev_station,
                        ev_seq, ev_kind, ev_origin, sched, plan, src_a, dst_a, np.asarray(kind, dtype=np.int8), mins_a,
                        sched[dst_a] - sched[src_a] - mins_a if len(src_a) else np.zeros(0), tuple(place),
                        np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64),
                        places=dict(places or {}))
    return _assemble(base, np.ones(len(src_a), dtype=bool), acyclic=True)


def _event_at(t: TrainEvents, first: int, station: str, kind: int) -> int | None:
    for i, (s, k) in enumerate(zip(t.station, t.kind)):
        if s == station and k == kind:
            return first + i
    return None


def _headways(w, trains, plan, resource_ids, key_s, src, dst, kind, mins, place) -> None:
    """Headway activities between the trains that follow each other on every resource (module doc); ``w``: the
    conflict check's :class:`~planner.network.windows.Windows`."""
    tr = np.asarray(w.train, dtype=np.int64)
    a_start, a_end = window_anchors(w, [len(t.sched_s) for t in trains], plan)
    off_start = w.start_s - plan[a_start]
    off_end = w.end_s - plan[a_end]
    rkey = np.asarray(w.res, dtype=np.int64) * 2 + np.asarray(w.kind, dtype=np.int64)
    key = w.start_s if key_s is None else key_s
    order = np.lexsort((tr, key, rkey))
    bounds = np.flatnonzero(np.r_[True, rkey[order][1:] != rkey[order][:-1], True])
    pairs: dict[tuple[int, int], tuple[float, str]] = {}
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        idx = order[lo:hi]
        if len(idx) < 2:
            continue
        name = resource_ids[int(rkey[idx[0]])] if resource_ids else str(int(rkey[idx[0]]))
        last = idx[0]  # the earlier window that closes last
        for j in range(1, len(idx)):
            b = idx[j]
            for a in {idx[j - 1], last}:
                if tr[a] == tr[b]:
                    continue
                ea, eb = int(a_end[a]), int(a_start[b])
                m = float(off_end[a] - off_start[b])
                if (ea, eb) not in pairs or m > pairs[(ea, eb)][0]:
                    pairs[(ea, eb)] = (m, name)
            if w.end_s[b] > w.end_s[last]:
                last = b
    for (ea, eb), (m, name) in sorted(pairs.items()):
        src.append(ea), dst.append(eb), kind.append(HEADWAY), mins.append(m), place.append(name)


def _assemble(net: DelayNetwork, keep: np.ndarray, *, acyclic: bool = False) -> DelayNetwork:
    """``net`` with only the activities ``keep``, its topological order and incoming lists built; with
    ``acyclic``, headways that close a cycle are left out first (counted in ``dropped``)."""
    keep = np.asarray(keep, dtype=bool).copy()
    n = net.n_events
    dropped = net.dropped
    while True:
        order = _topological(n, net.act_src[keep], net.act_dst[keep])
        if len(order) == n or not acyclic:
            break
        # the events left are on or behind a cycle: of their headways, leave out those that run back in time
        stuck = np.ones(n, dtype=bool)
        stuck[order] = False
        bad = keep & (net.act_kind == HEADWAY) & stuck[net.act_src] & stuck[net.act_dst] & (
            net.plan_s[net.act_dst] < net.plan_s[net.act_src])
        if not bad.any():  # none runs back: the one that runs forward least goes
            cand = np.flatnonzero(keep & (net.act_kind == HEADWAY) & stuck[net.act_src] & stuck[net.act_dst])
            bad = np.zeros(len(keep), dtype=bool)
            if len(cand):
                bad[cand[np.argmin(net.plan_s[net.act_dst[cand]] - net.plan_s[net.act_src[cand]])]] = True
        if not bad.any():
            raise ValueError("the trains' own events form a cycle: a train's times run back")
        dropped += int(bad.sum())
        keep &= ~bad
    sel = np.flatnonzero(keep)
    src, dst = net.act_src[sel], net.act_dst[sel]
    by_dst = sel[np.argsort(dst, kind="stable")]
    in_ptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(in_ptr, dst + 1, 1)
    in_ptr = np.cumsum(in_ptr)
    # activities renumbered to the kept ones, in their old order
    renum = np.full(len(keep), -1, dtype=np.int64)
    renum[sel] = np.arange(len(sel))
    return DelayNetwork(net.train_ids, net.train_types, net.ev_train, net.ev_station, net.ev_seq, net.ev_kind,
                        net.ev_origin, net.sched_s, net.plan_s, src, dst, net.act_kind[sel], net.min_s[sel],
                        net.slack_s[sel], tuple(net.act_place[i] for i in sel), np.asarray(order, dtype=np.int64),
                        in_ptr, renum[by_dst], dropped, net.places)


def _topological(n: int, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Kahn's order of the events (ties by event index: a train's events in running order); shorter than ``n``
    when the activities have a cycle."""
    import heapq

    indeg = np.bincount(dst, minlength=n)
    out_order = np.argsort(src, kind="stable")
    out_ptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(out_ptr, src + 1, 1)
    out_ptr = np.cumsum(out_ptr)
    out_dst = dst[out_order].tolist()
    ptr = out_ptr.tolist()
    deg = indeg.tolist()
    heap = [e for e in range(n) if deg[e] == 0]
    heapq.heapify(heap)
    order = []
    while heap:
        e = heapq.heappop(heap)
        order.append(e)
        for k in range(ptr[e], ptr[e + 1]):
            d = out_dst[k]
            deg[d] -= 1
            if deg[d] == 0:
                heapq.heappush(heap, d)
    return np.asarray(order, dtype=np.int64)
