"""Route search on the track network (docs/design.md §8, step 1): the track graph, overtaking, each train's route.

Takes a :class:`~planner.line.model.Line` with ``network`` and a timetable;
gives a :class:`TrackGraph` (nodes, edges, and the sections: edges split at
the block signals of ``signals.parquet`` that govern their track) and one
:class:`Route` per train (:func:`plan_routes`).

The track network is an undirected graph of track pieces (edges) between
nodes (switches, stop targets, interlocking boundaries, track ends). A
train's route runs from the stop node of its origin to the stop node of its
destination through the stop node of every call where it stops, and is
*monotone in chainage* in its running direction (a train never reverses on
its way). Boundary nodes are ordinary nodes on the path, so routes cross
interlocking areas freely. Among the monotone paths the search minimises, in
this order, the metres run on tracks of the other direction, the metres run on
tracks used in both directions, and the number of turnouts taken (track
changes), so a train keeps to its own main track, and takes a track used both
ways (single track, a main signalled both ways, a crossover) only where no
track of its own direction leads on. The
platform a stopping train takes: the *loop* when a same-direction train
overtakes it while it stands (its arrival < the other's passing time < its
departure; also when the other stops there entirely within its stand, the
cross-platform overtake), otherwise the *main* (the platform of the
least-turnout through route).

Conventions the route search relies on (the sample line follows them): a
track's direction is its edges' ``direction`` column (down, up, both); where
that is null or absent, track names beginning with ``D`` are down tracks, ``U``
up tracks, anything else is used in both directions (single track,
crossovers); a ``stop`` node
belongs to the station in its ``station_id`` (else to the station whose stop
marker is nearest, within the platform length) and serves the directions of
its track.
"""
from __future__ import annotations

import bisect
import dataclasses
import heapq
import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import Line, Train, sign

KIND_NODE, KIND_SECTION = 0, 1
"""Kinds of resource a train claims: a switch node, or a section (a piece of an edge)."""
KIND_NAMES = ("node", "section")


class RouteNotFoundError(InputError):
    """No monotone route exists on the track network for a timetabled train."""

    key = "network.no_route"


# ---------------------------------------------------------------------------
# Graph
# ---------------------------------------------------------------------------
def track_direction(track: str | None, direction: str | None = None) -> str:
    """Direction a track is run in: ``direction`` (the edges' column) where given, else by the name's
    convention: ``D…`` → down, ``U…`` → up, else ``both``."""
    if direction:
        return direction
    if not track:
        return "both"
    c = track[0].upper()
    return "down" if c == "D" else "up" if c == "U" else "both"


class TrackGraph:
    """The track network as an index-based undirected graph, with stop nodes mapped to stations.

    Parameters
    ----------
    line : Line
        A line with ``line.network`` set; its stations give the stop markers.
    """

    def __init__(self, line: Line):
        net = line.network
        if net is None:
            raise InputError(
                f"line {line.line_id}: no track network; add nodes.parquet and edges.parquet to check conflicts"
            )
        self.line = line
        self._station_by_pos = np.argsort([s.position_m for s in line.stations], kind="stable")
        self._station_pos = np.array([line.stations[k].position_m for k in self._station_by_pos], dtype=float)
        nodes = sorted(net.nodes, key=lambda n: n.node_id)
        self.node_ids = [n.node_id for n in nodes]
        self.index = {nid: i for i, nid in enumerate(self.node_ids)}
        self.kind = [n.kind for n in nodes]
        self.pos_m = np.array([n.position_m for n in nodes], dtype=float)
        self.interlocking = [n.interlocking for n in nodes]
        self.edges = sorted(net.edges, key=lambda e: e.edge_id)
        self.edge_ids = [e.edge_id for e in self.edges]
        self.edge_track = [e.track for e in self.edges]
        self.edge_dir = [track_direction(e.track, e.direction) for e in self.edges]
        self.adj: list[list[tuple[int, int]]] = [[] for _ in nodes]
        for k, e in enumerate(self.edges):
            for end in (e.from_node, e.to_node):
                if end not in self.index:
                    raise InputError(
                        f"edges.parquet edge {e.edge_id}: node {end!r} is not in nodes.parquet; add it or fix the edge"
                    )
            a, b = self.index[e.from_node], self.index[e.to_node]
            self.adj[a].append((b, k))
            self.adj[b].append((a, k))
        # Track of each node: the nodes.parquet column where given, else the most common incident track.
        self.node_track: list[str | None] = []
        for i, n in enumerate(nodes):
            t = getattr(n, "track", None)
            if not t:
                tracks = sorted(self.edge_track[k] for _, k in self.adj[i])
                t = max(tracks, key=tracks.count) if tracks else None
            self.node_track.append(t)
        # Sections: each edge split at the block signals inside it that trains on its
        # track obey (down signals on down tracks, up on up, both on shared track), so a
        # section is a block section where signals exist and the whole track piece otherwise.
        sig = {d: np.array(sorted(x.position_m for x in line.signals if x.direction == d)) for d in ("down", "up")}
        self.edge_pieces: list[list[int]] = []
        self.piece_edge: list[int] = []
        lo_l: list[float] = []
        hi_l: list[float] = []
        self.piece_ids: list[str] = []
        for k, e in enumerate(self.edges):
            a, b = sorted((self.pos_m[self.index[e.from_node]], self.pos_m[self.index[e.to_node]]))
            td = self.edge_dir[k]
            cuts = [c for d in ("down", "up") if td in ("both", d)
                    for c in sig[d][(sig[d] > a + 1e-6) & (sig[d] < b - 1e-6)]]
            bounds = [a] + sorted(set(cuts)) + [b]
            ids = []
            for j in range(len(bounds) - 1):
                ids.append(len(self.piece_edge))
                self.piece_edge.append(k)
                lo_l.append(bounds[j])
                hi_l.append(bounds[j + 1])
                self.piece_ids.append(e.edge_id if len(bounds) == 2 else f"{e.edge_id}/{j + 1}")
            self.edge_pieces.append(ids)
        self.piece_lo_m = np.array(lo_l)
        self.piece_hi_m = np.array(hi_l)
        # Stop nodes per station.
        self.stops_of: dict[str, list[int]] = defaultdict(list)
        stations = {s.station_id: s for s in line.stations}
        for i, n in enumerate(nodes):
            if n.kind != "stop":
                continue
            sid = getattr(n, "station_id", None)
            if not sid:
                best = None
                for s in line.stations:
                    d = min(abs(n.position_m - s.stop_down_m), abs(n.position_m - s.stop_up_m))
                    if d <= s.platform_length_m and (best is None or d < best[0]):
                        best = (d, s.station_id)
                sid = best[1] if best else None
            if sid in stations:
                self.stops_of[sid].append(i)

    def node(self, i: int) -> str:
        return self.node_ids[i]

    def resource_id(self, kind: int, i: int) -> str:
        """node_id of a switch, or the section id: edge_id, ``edge_id/j`` for the j-th block of a split edge."""
        return self.node_ids[i] if kind == KIND_NODE else self.piece_ids[i]

    def resource_interlocking(self, kind: int, i: int) -> str:
        """Interlocking of a node, or of the lower-chainage end node of a section's edge."""
        if kind == KIND_NODE:
            return self.interlocking[i]
        e = self.edges[self.piece_edge[i]]
        a, b = self.index[e.from_node], self.index[e.to_node]
        return self.interlocking[a if self.pos_m[a] <= self.pos_m[b] else b]

    def resource_track(self, kind: int, i: int) -> str | None:
        return self.node_track[i] if kind == KIND_NODE else self.edge_track[self.piece_edge[i]]

    def resource_extent(self, kind: int, i: int) -> tuple[float, float]:
        """Lower and upper chainage of a resource [m] (a switch: its position twice)."""
        if kind == KIND_NODE:
            return float(self.pos_m[i]), float(self.pos_m[i])
        return float(self.piece_lo_m[i]), float(self.piece_hi_m[i])

    def resource_station(self, kind: int, i: int) -> tuple[str, float]:
        """The station a resource is named by, and how far it lies from it: ``(station_id, distance_m)``.

        The station whose reference chainage (``stations.parquet`` position_m)
        is nearest to the resource's extent [lo, hi]: distance 0 when the extent
        spans it (a platform track, the section into a stop), else the gap to
        the nearer end. Of two stations an extent spans (a section from one
        stop to the next) the one nearer its middle; on a tie the lower
        chainage.
        """
        lo, hi = self.resource_extent(kind, i)
        mid = 0.5 * (lo + hi)
        stations = self.line.stations
        pos = self._station_pos
        # the minimum of the key below is among the stations the extent spans and the nearest on either side
        # (with those as far, to the last bit); they are compared in the stations' order, as over all of them
        a = int(np.searchsorted(pos, lo, side="left"))
        b = int(np.searchsorted(pos, hi, side="right"))
        near = set(range(a, b))
        k = a - 1
        while k >= 0 and lo - pos[k] == lo - pos[a - 1]:
            near.add(k)
            k -= 1
        k = b
        while k < len(pos) and pos[k] - hi == pos[b] - hi:
            near.add(k)
            k += 1
        cands = sorted(int(self._station_by_pos[k]) for k in near)
        best = min((stations[k] for k in cands), key=lambda s: (max(lo - s.position_m, s.position_m - hi, 0.0),
                                                               abs(s.position_m - mid), s.position_m))
        return best.station_id, max(lo - best.position_m, best.position_m - hi, 0.0)

    def candidates(self, station_id: str, direction: str) -> list[int]:
        """Stop nodes where a train running ``direction`` can stop at ``station_id``.

        Per platform track the stop node nearest the direction's stop marker,
        every platform track of the station: the route's cost (metres run
        against a track's direction come first) chooses among them. Keeping
        only the platforms of tracks named for the direction misled where a
        track's name is wrong for part of its length.
        """
        st = self.line.station(station_id)
        target = st.stop_m(direction)
        nodes = self.stops_of.get(station_id, [])
        best: dict[str | None, int] = {}
        for i in sorted(nodes):
            t = self.node_track[i]
            if t not in best or abs(self.pos_m[i] - target) < abs(self.pos_m[best[t]] - target):
                best[t] = i
        return sorted(best.values())


# ---------------------------------------------------------------------------
# Routes
# ---------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Route:
    """A train's route: nodes and edges in running order, and the stop node of each stopping call.

    ``loop_calls`` are the ``seq`` of calls where the train stands in a loop to
    be overtaken; ``notes`` says where a loop was wanted but the station has none.
    """

    train_id: str
    direction: str
    nodes: tuple[str, ...]
    edges: tuple[str, ...]
    node_idx: np.ndarray
    edge_idx: np.ndarray
    stop_nodes: dict[int, str]
    loop_calls: tuple[int, ...] = ()
    notes: tuple[str, ...] = ()


def call_interval(c) -> tuple[float, float]:
    """(arrival, departure) of a call; a pass or an end has the one time it has for both."""
    a, d = c.arrival_s, c.departure_s
    if math.isnan(a):
        a = d
    if math.isnan(d):
        d = a
    return a, d


def overtaken_calls(trains: Iterable[Train]) -> dict[str, set[int]]:
    """Calls where a stopping train is overtaken by a same-direction train while it stands.

    A train standing at a station from arrival *a* to departure *d* is overtaken
    when another train of the same direction passes that station at a time *p*
    with a < p < d, or stops there entirely inside (a, d) (it arrives later and
    leaves first). Such a call needs the loop track.

    Returns
    -------
    dict
        ``train_id`` → set of call ``seq`` that need the loop.
    """
    at: dict[tuple[str, str], list[tuple[float, float, bool, str, int]]] = defaultdict(list)
    for t in trains:
        last = len(t.calls) - 1
        for k, c in enumerate(t.calls):
            a, d = call_interval(c)
            stands = c.stops and 0 < k < last
            at[(c.station_id, t.direction)].append((a, d, stands, t.train_id, c.seq))
    out: dict[str, set[int]] = defaultdict(set)
    for calls in at.values():
        calls.sort()
        arrive = [c[0] for c in calls]
        ordered = not any(math.isnan(x) for x in arrive)
        for a, d, stands, tid, seq in calls:
            if not stands or not d > a:
                continue
            # the calls arriving after a, in order (those before cannot be inside): a search, not a pass from the
            # station's first call, which grew with the square of its calls
            for j in range(bisect.bisect_right(arrive, a) if ordered else 0, len(calls)):
                a2, d2, _, tid2, _ = calls[j]
                if a2 >= d:
                    break
                if tid2 != tid and a < a2 and d2 < d:
                    out[tid].add(seq)
                    break
    return dict(out)


def _search(g: TrackGraph, train: Train, waypoints: list[tuple[str, list[int]]]) -> tuple[list[int], list[int]]:
    """Least-cost monotone path through one node of each waypoint set, in order.

    Cost, compared lexicographically: metres on tracks of the other direction,
    metres on tracks used in both directions (so such a track is the route only
    where no track of the train's own direction is: OSRD's ``B:`` tracks, one
    main of a double line signalled both ways beside the other's own main),
    turnouts taken (consecutive edges on different tracks), edges. Dijkstra over
    states (waypoints reached, node, current track); monotone in chainage, so
    the state graph is acyclic and finite.
    """
    sgn = sign(train.direction)
    first = set(waypoints[0][1])
    heap: list = []
    for n in sorted(first):
        heapq.heappush(heap, (0.0, 0.0, 0, 0, 1, n, g.node_track[n] or "", -1, None))
    best: dict[tuple[int, int, str], tuple] = {}
    parents: dict[tuple[int, int, str], tuple] = {}
    furthest = (-math.inf, sorted(first)[0] if first else -1, 1)
    wp_sets = [set(w[1]) for w in waypoints]
    while heap:
        wrong, both, turns, n_e, layer, n, trk, e_in, parent = heapq.heappop(heap)
        key = (layer, n, trk)
        if key in best:
            continue
        best[key] = (wrong, both, turns, n_e)
        parents[key] = (parent, e_in)
        if sgn * g.pos_m[n] > furthest[0] or (sgn * g.pos_m[n] == furthest[0] and layer > furthest[2]):
            furthest = (sgn * g.pos_m[n], n, layer)
        if layer == len(waypoints):
            nodes, edges = [], []
            k: Any = key
            while k is not None:
                nodes.append(k[1])
                p, e = parents[k]
                if e >= 0:
                    edges.append(e)
                k = p
            return nodes[::-1], edges[::-1]
        for m, e in g.adj[n]:
            if sgn * (g.pos_m[m] - g.pos_m[n]) <= 0:
                continue  # monotone in chainage: never back
            tr = g.edge_track[e]
            run = g.edge_dir[e]
            metres = abs(g.pos_m[m] - g.pos_m[n])
            w = wrong + (0.0 if run in ("both", train.direction) else metres)
            b = both + (metres if run == "both" else 0.0)
            t2 = turns + (1 if (trk and tr != trk) else 0)
            nl = layer + 1 if m in wp_sets[layer] else layer
            if (nl, m, tr) not in best:
                heapq.heappush(heap, (w, b, t2, n_e + 1, nl, m, tr, e, key))
    raise RouteNotFoundError(_no_route(g, train, waypoints, best, furthest))


def _no_route(g: TrackGraph, train: Train, waypoints: list[tuple[str, list[int]]], reached: dict,
              furthest: tuple) -> str:
    """Why the search found no route: the stop it could not reach, the node reached nearest before that stop
    on the train's way (not the furthest node of the search, which may have run past the stop on another
    track to the line's end), and where the network goes from there."""
    sgn = sign(train.direction)
    layer = max(k[0] for k in reached) if reached else furthest[2]
    want_sid, want = waypoints[min(layer, len(waypoints) - 1)]
    goal = min(sgn * g.pos_m[i] for i in want)  # the first stop node in the running direction
    before = [k[1] for k in reached if k[0] == layer and sgn * g.pos_m[k[1]] <= goal]
    n = max(before, key=lambda i: (sgn * g.pos_m[i], -i)) if before else furthest[1]
    ahead, behind = [], []
    for m, e in sorted(g.adj[n]):
        (ahead if sgn * (g.pos_m[m] - g.pos_m[n]) > 0 else behind).append(
            f"{g.node(m)} (track {g.edge_track[e] or '-'}, {g.pos_m[m]:.1f} m)")
    onward = ("; from there the network goes on only to " + ", ".join(ahead) if ahead
              else "; the network goes no further that way from there")
    back = f" (and back to {', '.join(behind)})" if behind else ""
    return (f"train {train.train_id} ({train.direction}): no route on the track network to the stop of station "
            f"{want_sid} (stop nodes {', '.join(f'{g.node(i)} at {g.pos_m[i]:.1f} m' for i in want)}); the route "
            f"reaches {g.node(n)} at chainage {g.pos_m[n]:.1f} m, {abs(goal - sgn * g.pos_m[n]):.1f} m before that "
            f"stop{onward}{back}; check edges.parquet and nodes.parquet around it")


def _route_for(g: TrackGraph, train: Train, loops: set[int]) -> Route:
    calls = train.stop_calls()
    if len(calls) < 2:
        raise InputError(f"timetable.parquet train {train.train_id}: needs at least an origin and a destination")
    wps: list[tuple[str, list[int]]] = []
    for c in calls:
        cand = g.candidates(c.station_id, train.direction)
        if not cand:
            raise RouteNotFoundError(
                f"train {train.train_id} ({train.direction}): station {c.station_id} has no stop node; "
                f"add a `stop` node with station_id={c.station_id!r} to nodes.parquet"
            )
        wps.append((c.station_id, cand))
    nodes, edges = _search(g, train, wps)
    notes: list[str] = []
    taken: list[int] = []
    if loops:
        # The main platform is the one the least-turnout route takes; a loop is any other.
        chosen = _stops_on(nodes, wps)
        wps2 = list(wps)
        for j, c in enumerate(calls):
            if c.seq in loops:
                others = [i for i in wps[j][1] if i != chosen[j]]
                if others:
                    wps2[j] = (wps[j][0], others)
                    taken.append(c.seq)
                else:
                    notes.append(f"station {c.station_id}: overtaken while standing but no loop track")
        if taken:
            nodes, edges = _search(g, train, wps2)
            wps = wps2
    chosen = _stops_on(nodes, wps)
    return Route(
        train_id=train.train_id,
        direction=train.direction,
        nodes=tuple(g.node(i) for i in nodes),
        edges=tuple(g.edge_ids[k] for k in edges),
        node_idx=np.asarray(nodes, dtype=np.int64),
        edge_idx=np.asarray(edges, dtype=np.int64),
        stop_nodes={c.seq: g.node(chosen[j]) for j, c in enumerate(calls)},
        loop_calls=tuple(sorted(taken)),
        notes=tuple(notes),
    )


def runs_on(g: TrackGraph, route: Route, track: str, start_m: float, end_m: float) -> bool:
    """Whether ``route`` runs on ``track`` somewhere inside the stretch (start_m, end_m) of chainage."""
    for k in route.edge_idx.tolist():
        if g.edge_track[k] != track:
            continue
        e = g.edges[k]
        a, b = sorted((g.pos_m[g.index[e.from_node]], g.pos_m[g.index[e.to_node]]))
        if b > start_m and a < end_m:
            return True
    return False


def _stops_on(nodes: list[int], wps: list[tuple[str, list[int]]]) -> list[int]:
    """The node of each waypoint set the path takes, in order."""
    out, j = [], 0
    for n in nodes:
        if j < len(wps) and n in wps[j][1]:
            out.append(n)
            j += 1
    return out


def plan_routes(line: Line, graph: TrackGraph | None = None,
                trains: Sequence[Train] | None = None, *, unrouted: dict[str, str] | None = None) -> dict[str, Route]:
    """Route every timetabled train over the track network.

    Parameters
    ----------
    line : Line
        Line with a track network and a timetable.
    graph : TrackGraph, optional
        Prebuilt graph of ``line`` (built if omitted).
    trains : sequence of Train, optional
        Trains to route (default: the whole timetable). Overtaking is judged
        against the whole timetable either way (less the trains that cannot be routed).
    unrouted : dict, optional
        Given: a train that cannot be routed is left out of the result and written here
        (``train_id`` → the reason, one line), and the others are routed as on a timetable
        without it: overtaking is judged again without it, so a loop it would have taken
        by standing aside is not taken. Not given: the first such train raises.

    Returns
    -------
    dict
        ``train_id`` → :class:`Route`, in timetable order.

    Raises
    ------
    RouteNotFoundError
        Without ``unrouted``: naming the train, the stop it cannot reach, the node it
        reaches nearest before that stop and where the network goes from there.
    """
    g = graph or TrackGraph(line)
    wanted = list(trains if trains is not None else line.trains)
    left_out: dict[str, str] = {}
    while True:
        loops = overtaken_calls(t for t in line.trains if t.train_id not in left_out)
        cache: dict[tuple, Route | str] = {}
        out: dict[str, Route] = {}
        failed: dict[str, str] = {}
        for t in wanted:
            if t.train_id in left_out:
                continue
            lp = loops.get(t.train_id, set())
            pattern = (t.direction, tuple((c.station_id, c.stops, c.seq in lp) for c in t.calls))
            r = cache.get(pattern)
            if r is None:
                try:
                    r = _route_for(g, t, lp)
                except RouteNotFoundError as e:
                    if unrouted is None:
                        raise
                    r = str(e).replace(f"train {t.train_id} ", "train {train} ", 1)
                cache[pattern] = r
            if isinstance(r, str):
                failed[t.train_id] = r.replace("train {train} ", f"train {t.train_id} ", 1)
            else:
                out[t.train_id] = dataclasses.replace(r, train_id=t.train_id)
        if not failed:
            if unrouted is not None:
                unrouted.update((t.train_id, left_out[t.train_id]) for t in line.trains if t.train_id in left_out)
            return out
        left_out.update(failed)  # route the others again, as on a timetable without these
