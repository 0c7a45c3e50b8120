"""The predicted day: the day's timetable with every delay carried forward, and who waits for whom.

Takes the conflict check of the day (:class:`~planner.network.check.ConflictCheck`: its trains, routes,
blocking-time windows and each train's planned times and minimum running times), the minimum dwell
and the job's connections; gives a :class:`PredictedDay`.

1. **Each train alone**: the network of its runs and dwells (:mod:`planner.delay.network`) with no
   primary delay. A leg that needs longer than scheduled (a restriction in force) makes the train late;
   the delay goes on into the next departure, never before arrival + the minimum dwell, and is worked
   off by the margins after it.
2. **The day as it runs**: each train's blocking-time windows moved by its own delay at their anchor
   events. Where they now overlap another train's, the conflict check's detector decides the pair
   with the rules it uses for the timetable (:func:`planner.network.priority.detect_conflicts`), which
   decides who goes first.
3. **Holding**: the order of the trains on every resource is the moved windows' (the train that waits
   behind the one that goes first); headways in that order join the network, and the delays propagate
   again. A train held by another waits before the resource, and its delay from then on says by whom.
   Every such wait is a **hold** (:func:`holds`): the conflicts of the day as it runs, cascades included
   (a held train that holds the next one).

On a day whose timetable is feasible and free of conflicts every predicted delay is 0.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from planner.delay.network import (ACTIVITY_KINDS, HEADWAY, DelayNetwork, build_network, train_events,
                                   window_anchors)
from planner.delay.propagate import binding, propagate


@dataclass(frozen=True, eq=False)
class PredictedDay:
    """The predicted day of one line (module doc).

    Attributes
    ----------
    net : DelayNetwork
        The day's network, headways in the predicted order.
    delay_s : ndarray
        Each event's predicted delay [s] (predicted − scheduled time).
    own_s : ndarray
        Each event's delay with the train alone on the line [s].
    cause : ndarray
        Per event, the activity that set its delay (``net`` index), −1 when it is on time or its delay only
        carries on from the event before (see :func:`cause_text`).
    conflicts : list of dict
        The detector's records for the windows moved by the trains' own delays (step 2 of the module doc:
        they order the trains); the day's conflicts are its holds (:func:`holds`).
    windows : Windows
        The blocking-time windows at the predicted times.
    """

    net: DelayNetwork
    delay_s: np.ndarray
    own_s: np.ndarray
    cause: np.ndarray
    conflicts: list
    windows: object

    @property
    def predicted_s(self) -> np.ndarray:
        return self.net.sched_s + self.delay_s


def day_events(check) -> list:
    """The events of every train the conflict check routed (:func:`planner.delay.network.train_events`)."""
    out = []
    for t, (calls_s, mins) in zip(check.trains, check.plans):
        stops = [(c.station_id, c.seq, c.arrival_s, c.departure_s) for c in t.stop_calls()]
        out.append(train_events(t.train_id, t.train_type, t.direction, stops, calls_s, mins))
    return out


def moved(w, a_start: np.ndarray, a_end: np.ndarray, shift_s: np.ndarray):
    """The windows with their opening moved as their start anchor, their close as their end anchor."""
    s0, s1 = shift_s[a_start], shift_s[a_end]
    return dataclasses.replace(w, entry_s=w.entry_s + s0, start_s=w.start_s + s0, exit_s=w.exit_s + s1,
                               clear_s=w.clear_s + s1, end_s=w.end_s + s1)


def predict_day(check, *, min_dwell_s: float | Callable[[str, str], float],
                connections: Sequence[tuple[str, str, str, float]] = ()) -> PredictedDay:
    """The predicted day (module doc)."""
    from planner.network.priority import detect_conflicts
    from planner.network.routes import KIND_NAMES

    g, trains = check.graph, check.trains
    evs = day_events(check)
    alone = build_network(evs, min_dwell_s=min_dwell_s, connections=connections)
    own = propagate(alone)[:, 0]
    w = check.windows
    sizes = [len(e.sched_s) for e in evs]
    a_start, a_end = window_anchors(w, sizes, alone.plan_s)
    shift = alone.sched_s + own - alone.plan_s
    w_own = moved(w, a_start, a_end, shift)
    routes = [check.routes[t.train_id] for t in trains]
    records = detect_conflicts(g, trains, routes, w_own) if len(w) else []
    rkey = np.asarray(w.res, dtype=np.int64) * 2 + np.asarray(w.kind, dtype=np.int64)
    names = {int(k): g.resource_id(int(k) % 2, int(k) // 2) for k in np.unique(rkey)}
    by_name = {(KIND_NAMES[k % 2], v): k for k, v in names.items()}
    index = {t.train_id: k for k, t in enumerate(trains)}
    wait = np.zeros(len(w))
    # each (resource, train)'s windows one slice of this order: a record's look-up is a search, not a pass
    n_tr = max(len(trains), 1)
    pair = rkey * n_tr + np.asarray(w.train, dtype=np.int64)
    by_pair = np.argsort(pair, kind="stable")
    sorted_pair = pair[by_pair]
    for r in records:  # the train that waits comes after the one that goes first, whatever their openings
        k = by_name.get((r["resource_kind"], r["resource_id"]))
        if k is None:
            continue
        p = k * n_tr + index[r["train_b"]]
        m = by_pair[np.searchsorted(sorted_pair, p, side="left"):np.searchsorted(sorted_pair, p, side="right")]
        wait[m] = np.maximum(wait[m], float(r["delay_s"]))
    places = {v: _place(g, k) for k, v in names.items()}
    net = build_network(evs, min_dwell_s=min_dwell_s, windows=w, resource_ids=_ids(names), key_s=w_own.start_s + wait,
                        connections=connections, places=places)
    z = propagate(net)[:, 0]
    return PredictedDay(net, z, own, binding(net, z), records,
                        moved(w, a_start, a_end, net.sched_s + z - net.plan_s))


def _ids(names: dict[int, str]) -> list[str]:
    out = [""] * (max(names) + 1 if names else 0)
    for k, v in names.items():
        out[k] = v
    return out


def _place(g, key: int) -> str:
    kind, res = key % 2, key // 2
    sid, dist = g.resource_station(kind, res)
    track = g.resource_track(kind, res) or ""
    name = g.line.station(sid).name
    where = f"{name}" if abs(dist) < 1.0 else f"{dist / 1000:+.1f} km from {name}"
    return f"{['switch', 'section'][kind]} {g.resource_id(kind, res)} ({where}{', track ' + track if track else ''})"


def holds(day: PredictedDay, planned: set = frozenset()) -> list[dict]:
    """Every wait of the predicted day: an event whose delay a headway (or a connection) sets, in event order.

    One record per held event: the train that goes first (``train_a``) and the one that waits (``train_b``), the
    resource, the waiting train's event, ``hold_s`` (its delay beyond what its own activities give it: the wait)
    and ``knock_on`` (the pair does not conflict there in the timetable as planned: ``planned`` holds
    ``(train_a, train_b, resource_id)`` of the planned conflict check, both orders)."""
    from planner.delay.network import CONNECTION, DEPARTURE

    net, z = day.net, day.delay_s
    out = []
    for e in np.flatnonzero(day.cause >= 0):
        a = int(day.cause[e])
        if net.act_kind[a] not in (HEADWAY, CONNECTION):
            continue
        lo, hi = net.in_ptr[e], net.in_ptr[e + 1]
        own = [z[net.act_src[b]] - net.slack_s[b] for b in net.in_act[lo:hi]
               if net.act_kind[b] not in (HEADWAY, CONNECTION)]
        hold = float(z[e] - max([0.0] + own))
        if hold <= 0.0:
            continue
        ta, tb = net.train_ids[int(net.ev_train[net.act_src[a]])], net.train_ids[int(net.ev_train[e])]
        rid = net.act_place[a]
        out.append({"train_a": ta, "train_b": tb, "activity": ACTIVITY_KINDS[int(net.act_kind[a])],
                    "resource_id": rid, "place": net.places.get(rid, rid), "station_id": net.ev_station[e],
                    "seq": int(net.ev_seq[e]), "event": "departure" if net.ev_kind[e] == DEPARTURE else "arrival",
                    "scheduled_s": float(net.sched_s[e]), "hold_s": hold,
                    "knock_on": (ta, tb, rid) not in planned})
    return out


LATE_S = 0.5
"""An event of the predicted day more than this late is late [s] (below it is the round-off of the timetable's
and the run curves' times; a delay shown in whole seconds reads at least +1): one threshold for every page, the
overview, the CLI and the train graph."""

GREW_S = 0.05
"""A delay that grows by no more than this [s] (round-off of two run curves, a leg scheduled at its minimum
to the tenth) carries on; it is not a cause of its own."""


def cause_text(day: PredictedDay, e: int) -> str:
    """Why event ``e`` is later than the event before it of its train (one phrase), or "" when it is not."""
    net = day.net
    a = int(day.cause[e])
    if a < 0:
        return ""
    kind = ACTIVITY_KINDS[int(net.act_kind[a])]
    src = int(net.act_src[a])
    if net.act_kind[a] == HEADWAY:
        other = net.train_ids[int(net.ev_train[src])]
        return f"held by {other} at {net.places.get(net.act_place[a], net.act_place[a])}"
    if kind == "connection":
        return f"waits for {net.train_ids[int(net.ev_train[src])]} at {net.act_place[a]}"
    grew = day.delay_s[e] - day.delay_s[src]
    if grew <= GREW_S:
        return ""
    if kind == "run":
        return (f"its run from {net.ev_station[src]} needs {net.min_s[a]:.1f} s, "
                f"{net.min_s[a] + net.slack_s[a]:.1f} s scheduled")
    return f"its minimum dwell of {net.min_s[a]:.0f} s, {net.min_s[a] + net.slack_s[a]:.0f} s scheduled"
