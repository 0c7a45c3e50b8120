"""Route conflicts on the track network: routes, arrival at nodes, blocking-time windows, conflicts.

The steps follow DESIGN §8 and the networked-interlocking method it condenses:

1. **Route search** (:func:`plan_routes`). The track network is an undirected
   graph of track pieces (edges) between nodes (switches, stop targets,
   interlocking boundaries, track ends). A train's route runs from the stop
   node of its origin to the stop node of its destination through the stop
   node of every call where it stops, and is *monotone in chainage* in its
   running direction (a train never reverses on its way). Boundary nodes are
   ordinary nodes on the path, so routes cross interlocking areas freely.
   Among the monotone paths the search minimises, in this order, the metres
   run on tracks of the other direction and the number of turnouts taken
   (track changes), so a train keeps to its own main track. The platform a
   stopping train takes: the *loop* when a same-direction train overtakes it
   while it stands (its arrival < the other's passing time < its departure;
   also when the other stops there entirely within its stand, the
   cross-platform overtake), otherwise the *main* (the platform of the
   least-turnout through route).
2. **Arrival prediction** (:class:`Trajectory`). The front of the train runs
   each interstation (stop to stop; passes run through) along a run curve
   (chainage, time from departure) taken at the train's scheduled running
   time, so braking for stop targets and restrictions is in it. The first
   time the front reaches a chainage is the node's predicted arrival.
3. **Blocking-time windows** (:func:`occupation_windows`). A resource (a
   section, or a switch node) is claimed from
   ``entry − setting_s − approach_s`` (route setting, then sight and reaction
   while the train approaches the signal at the entry) until
   ``clear + release_s``, where *entry* is when the front moves past the
   resource's entry (where the train stands with its front at the entry, as
   at its origin and at every stop whose stop node begins the next section,
   its departure) and *clear* is when the tail has passed the exit (front at
   exit + train length, from the same run curve, so a train that stops holds
   the sections under it through its dwell). This is the
   blocking-time model of Pachl, *Railway Operation and Control*, ch. 4, and
   Hansen & Pachl, *Railway Timetabling & Operations*, ch. 4. Sections are
   the edges split at the block signals of ``signals.parquet`` that govern
   their track, so a section is a block section where the line is signalled.
4. **Conflicts** (:func:`find_overlaps`, :func:`detect_conflicts`). Windows
   are sorted per resource and swept, so only neighbours in time are
   compared. Overlapping windows of two trains on consecutive shared
   resources form one conflict, decided once with the rules of DESIGN §8:

   * opposing trains that would both be inside a shared single-track
     stretch (≥ 2 resources, so each would hold one the other needs) are a
     **deadlock**: the train that leaves the stretch earlier goes first and the
     other waits before the stretch until it is clear (rule ``no-deadlock``);
   * same-direction trains whose routes pass the same interlocking boundary
     keep the timetable's departure order (rule ``timetable-order``: the
     earlier departure from the last call before the conflict goes first);
   * otherwise the train that leaves the shared section earlier goes first
     (rule ``leaves-first``).

   The delay imposed on the other train is how far its windows must move so
   that each starts after the first train's window on the same resource ends
   (for the usual case exactly the overlap). Delays are not propagated to later
   conflicts: the report lists each conflict of the timetable as planned.

Conventions the route search relies on (the sample line follows them):
track names beginning with ``D`` are down tracks, ``U`` up tracks, anything
else is used in both directions (single track, crossovers); a ``stop`` node
belongs to the station in its ``station_id`` (else to the station whose stop
marker is nearest, within the platform length) and serves the directions of
its track.
"""
from __future__ import annotations

import dataclasses
import heapq
import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import Line, Train, sign

__all__ = [
    "BlockingParams",
    "RouteNotFoundError",
    "TrackGraph",
    "Route",
    "Trajectory",
    "Windows",
    "ConflictReport",
    "RunCurveSource",
    "SimulatorCurves",
    "overtaken_calls",
    "plan_routes",
    "build_trajectory",
    "occupation_windows",
    "find_overlaps",
    "detect_conflicts",
    "check_conflicts",
    "interstation_keys",
    "simulate_interstation",
    "stretched_curve",
    "conflicts_table",
    "write_conflicts",
    "track_direction",
    "would_deadlock",
]

RULE_DEADLOCK = "no-deadlock"
RULE_ORDER = "timetable-order"
RULE_LEAVES_FIRST = "leaves-first"


# ---------------------------------------------------------------------------
# Parameters
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class BlockingParams:
    """Blocking-time parameters of the occupation windows (the job file's ``[conflicts]`` table).

    Attributes
    ----------
    setting_s : float
        Route setting (formation and locking) time before the approach starts [s].
        Default 10 s, a typical relay/electronic interlocking figure.
    approach_s : float
        Sight and reaction time plus approach running before the train reaches
        the entry signal/node of a resource [s]. Default 20 s.
    release_s : float
        Route release time after the tail has cleared the exit [s]. Default 5 s.
    terminal_s : float
        How long a train stays on its destination platform after arriving [s]
        (it has no later route here); default 0 s, so only the windows behind the
        destination stop end at the arrival (+ release).
    node_kinds : tuple of str
        Node kinds that are resources of their own (``switch``: a turnout is
        claimed by one train at a time, whichever legs the trains use). Stop,
        boundary and end nodes are points: they belong to the sections around them.
    """

    setting_s: float = 10.0
    approach_s: float = 20.0
    release_s: float = 5.0
    terminal_s: float = 0.0
    node_kinds: tuple[str, ...] = ("switch",)

    def __post_init__(self) -> None:
        for name in ("setting_s", "approach_s", "release_s", "terminal_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"[conflicts] {name}: must be a finite number ≥ 0 s, found {v!r}")

    @property
    def lead_s(self) -> float:
        """Time a window opens before the front reaches the entry: setting + approach [s]."""
        return self.setting_s + self.approach_s

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None, *, where: str = "[conflicts]") -> "BlockingParams":
        """Parameters from a job file's ``[conflicts]`` table (or any mapping).

        Unknown keys raise :class:`~planner.errors.InputError` naming the key;
        ``enabled`` (the job's on/off switch) is accepted and ignored here.
        """
        if data is None:
            return cls()
        if dataclasses.is_dataclass(data) and not isinstance(data, type):
            data = dataclasses.asdict(data)
        known = {f.name for f in dataclasses.fields(cls)}
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key == "enabled":
                continue
            if key not in known:
                raise InputError(f"{where} {key}: unknown key; known keys: enabled, {', '.join(sorted(known))}")
            if key == "node_kinds":
                if isinstance(value, str) or not all(isinstance(x, str) for x in value):
                    raise InputError(f"{where} node_kinds: expected a list of node kinds, found {value!r}")
                kwargs[key] = tuple(value)
            else:
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise InputError(f"{where} {key}: expected a number of seconds, found {value!r}")
                kwargs[key] = float(value)
        return cls(**kwargs)


class RouteNotFoundError(InputError):
    """No monotone route exists on the track network for a timetabled train."""

    key = "network.no_route"


# ---------------------------------------------------------------------------
# Graph
# ---------------------------------------------------------------------------
def track_direction(track: str | None) -> str:
    """Direction a track is run in by convention: ``D…`` → down, ``U…`` → up, else ``both``."""
    if not track:
        return "both"
    c = track[0].upper()
    return "down" if c == "D" else "up" if c == "U" else "both"


def _serves(track: str | None, direction: str) -> bool:
    return track_direction(track) in ("both", direction)


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
        nodes = sorted(net.nodes, key=lambda n: n.node_id)
        self.node_ids = [n.node_id for n in nodes]
        self.index = {nid: i for i, nid in enumerate(self.node_ids)}
        self.kind = [n.kind for n in nodes]
        self.pos_m = np.array([n.position_m for n in nodes], dtype=float)
        self.interlocking = [n.interlocking for n in nodes]
        self.edges = sorted(net.edges, key=lambda e: e.edge_id)
        self.edge_ids = [e.edge_id for e in self.edges]
        self.edge_track = [e.track for e in self.edges]
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
            td = track_direction(e.track)
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

    def candidates(self, station_id: str, direction: str) -> list[int]:
        """Stop nodes where a train running ``direction`` can stop at ``station_id``.

        Per platform track the stop node nearest the direction's stop marker;
        tracks that serve the direction are preferred; if none does (a
        single-platform terminus), every platform track of the station.
        """
        st = self.line.station(station_id)
        target = st.stop_m(direction)
        nodes = self.stops_of.get(station_id, [])
        own = [i for i in nodes if _serves(self.node_track[i], direction)] or list(nodes)
        best: dict[str | None, int] = {}
        for i in sorted(own):
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


def _interval(c) -> tuple[float, float]:
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
            a, d = _interval(c)
            stands = c.stops and 0 < k < last
            at[(c.station_id, t.direction)].append((a, d, stands, t.train_id, c.seq))
    out: dict[str, set[int]] = defaultdict(set)
    for calls in at.values():
        calls.sort()
        for a, d, stands, tid, seq in calls:
            if not stands or not d > a:
                continue
            for a2, d2, _, tid2, _ in calls:
                if a2 >= d:
                    break
                if tid2 != tid and a < a2 and d2 < d:
                    out[tid].add(seq)
                    break
    return dict(out)


def _search(g: TrackGraph, train: Train, waypoints: list[tuple[str, list[int]]]) -> tuple[list[int], list[int]]:
    """Least-cost monotone path through one node of each waypoint set, in order.

    Cost, compared lexicographically: metres on tracks of the other direction,
    turnouts taken (consecutive edges on different tracks), edges. Dijkstra over
    states (waypoints reached, node, current track); monotone in chainage, so
    the state graph is acyclic and finite.
    """
    sgn = sign(train.direction)
    first = set(waypoints[0][1])
    heap: list = []
    for n in sorted(first):
        heapq.heappush(heap, (0.0, 0, 0, 1, n, g.node_track[n] or "", -1, None))
    best: dict[tuple[int, int, str], tuple] = {}
    parents: dict[tuple[int, int, str], tuple] = {}
    furthest = (-math.inf, sorted(first)[0] if first else -1, 1)
    wp_sets = [set(w[1]) for w in waypoints]
    while heap:
        wrong, turns, n_e, layer, n, trk, e_in, parent = heapq.heappop(heap)
        key = (layer, n, trk)
        if key in best:
            continue
        best[key] = (wrong, turns, n_e)
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
            w = wrong + (0.0 if _serves(tr, train.direction) else abs(g.pos_m[m] - g.pos_m[n]))
            t2 = turns + (1 if (trk and tr != trk) else 0)
            nl = layer + 1 if m in wp_sets[layer] else layer
            if (nl, m, tr) not in best:
                heapq.heappush(heap, (w, t2, n_e + 1, nl, m, tr, e, key))
    _, n_last, layer = furthest
    want_sid, want = waypoints[min(layer, len(waypoints) - 1)]
    raise RouteNotFoundError(
        f"train {train.train_id} ({train.direction}): no route on the track network to the stop of station "
        f"{want_sid} (stop nodes {', '.join(g.node(i) for i in want)}); last reachable node "
        f"{g.node(n_last)} at chainage {g.pos_m[n_last]:.1f} m; check edges.parquet around it"
    )


def _route_for(g: TrackGraph, train: Train, loops: set[int]) -> Route:
    calls = [c for k, c in enumerate(train.calls) if c.stops or k in (0, len(train.calls) - 1)]
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


def _stops_on(nodes: list[int], wps: list[tuple[str, list[int]]]) -> list[int]:
    """The node of each waypoint set the path takes, in order."""
    out, j = [], 0
    for n in nodes:
        if j < len(wps) and n in wps[j][1]:
            out.append(n)
            j += 1
    return out


def plan_routes(line: Line, graph: TrackGraph | None = None,
                trains: Sequence[Train] | None = None) -> dict[str, Route]:
    """Route every timetabled train over the track network.

    Parameters
    ----------
    line : Line
        Line with a track network and a timetable.
    graph : TrackGraph, optional
        Prebuilt graph of ``line`` (built if omitted).
    trains : sequence of Train, optional
        Trains to route (default: the whole timetable). Overtaking is judged
        against the whole timetable either way.

    Returns
    -------
    dict
        ``train_id`` → :class:`Route`, in timetable order.

    Raises
    ------
    RouteNotFoundError
        Naming the train and the last node it could reach.
    """
    g = graph or TrackGraph(line)
    loops = overtaken_calls(line.trains)
    cache: dict[tuple, Route] = {}
    out: dict[str, Route] = {}
    for t in (trains if trains is not None else line.trains):
        lp = loops.get(t.train_id, set())
        pattern = (t.direction, tuple((c.station_id, c.stops, c.seq in lp) for c in t.calls))
        r = cache.get(pattern)
        if r is None:
            r = _route_for(g, t, lp)
            cache[pattern] = r
        out[t.train_id] = dataclasses.replace(r, train_id=t.train_id)
    return out


# ---------------------------------------------------------------------------
# Arrival prediction
# ---------------------------------------------------------------------------
RunCurve = tuple[np.ndarray, np.ndarray]
"""(chainage_m, time_s): the front's chainage and the time since departure along one interstation run."""

RunCurveSource = Callable[[str, str, str, float], RunCurve]
"""``source(train_type, origin, destination, scheduled_s) -> (chainage_m, time_s)``.

The run curve of the front from the origin's stop marker to the destination's,
at the driving the vehicle uses for the scheduled running time ``scheduled_s``
(time from departure; the last time is the running time)."""


STAND_TOL_M = 1e-6
"""Chainages this close [m] are the same point for :meth:`Trajectory.front_leaves` (round-off only)."""


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Predicted front position over the whole run of one train.

    ``u_m`` is the running coordinate sign(direction) × chainage [m]
    (non-decreasing; repeated at stops), ``t_s`` the absolute time [s after
    midnight] (non-decreasing; arrival then departure at each stop).
    """

    train_id: str
    direction: str
    u_m: np.ndarray
    t_s: np.ndarray

    @property
    def end_s(self) -> float:
        """Arrival at the destination [s]."""
        return float(self.t_s[-1])

    def front_time(self, chainage_m) -> np.ndarray:
        """First time the front reaches each chainage [s]; +inf beyond the destination.

        Linear in time between curve samples; a chainage exactly at a stop gives
        the arrival there. Chainages before the origin give the departure.
        """
        q = sign(self.direction) * np.asarray(chainage_m, dtype=float)
        u, t = self.u_m, self.t_s
        i = np.searchsorted(u, q, side="left")
        out = np.full(q.shape, np.inf)
        inside = i < len(u)
        ii = np.clip(i, 1, len(u) - 1)
        u0, u1, t0, t1 = u[ii - 1], u[ii], t[ii - 1], t[ii]
        du = np.where(u1 > u0, u1 - u0, 1.0)
        lin = t0 + (t1 - t0) * np.clip((q - u0) / du, 0.0, 1.0)
        exact = inside & (u[np.minimum(i, len(u) - 1)] == q)
        out = np.where(inside, lin, out)
        out = np.where(exact, t[np.minimum(i, len(u) - 1)], out)
        return np.where(q <= u[0], t[0], out)

    def front_leaves(self, chainage_m) -> np.ndarray:
        """Time the front moves on past each chainage [s]; +inf beyond the destination.

        The last time the front is at the chainage: where the train stands with
        its front there (a stop), the departure, as at the origin; elsewhere the
        same as :meth:`front_time`. A resource is entered when the front moves
        past its entry, so this is the entry time of blocking-time windows.
        Chainages within ``STAND_TOL_M`` of a sample count as that sample (the
        run curves of two interstations meet at the stop marker up to round-off).
        """
        q = sign(self.direction) * np.asarray(chainage_m, dtype=float)
        u, t = self.u_m, self.t_s
        j = np.searchsorted(u, q + STAND_TOL_M, side="right")  # first sample past q
        jj = np.clip(j, 1, len(u) - 1)
        u0, u1, t0, t1 = u[jj - 1], u[jj], t[jj - 1], t[jj]
        du = np.where(u1 > u0, u1 - u0, 1.0)
        lin = t0 + (t1 - t0) * np.clip((q - u0) / du, 0.0, 1.0)
        at = np.abs(u[np.maximum(j - 1, 0)] - q) <= STAND_TOL_M  # the front stands or passes at sample j − 1
        out = np.where(at, t[np.maximum(j - 1, 0)], lin)
        out = np.where(j >= len(u), np.where(at, t[-1], np.inf), out)
        return np.where(j == 0, t[0], out)


def build_trajectory(line: Line, train: Train, curves: RunCurveSource) -> Trajectory:
    """Chain the run curves of a train's interstations into one predicted front trajectory.

    Each interstation runs from a stopping call's departure to the next stopping
    call (passes in between are run through); its run curve is asked for the
    scheduled running time (next arrival − departure). A curve slower than the
    schedule makes the train late; lateness is absorbed by the next dwell
    (departure = max(scheduled departure, predicted arrival)) and not otherwise
    propagated.

    Parameters
    ----------
    curves : RunCurveSource
        Gives (chainage_m, time_s) per interstation.
    """
    sgn = sign(train.direction)
    last = len(train.calls) - 1
    calls = [c for k, c in enumerate(train.calls) if c.stops or k in (0, last)]
    us: list[np.ndarray] = []
    ts: list[np.ndarray] = []
    dep = calls[0].departure_s
    if math.isnan(dep):
        raise InputError(f"timetable.parquet train {train.train_id}: no departure time at the origin")
    for a, b in zip(calls[:-1], calls[1:]):
        sched = b.arrival_s - a.departure_s
        if math.isnan(sched) or sched <= 0:
            raise InputError(
                f"timetable.parquet train {train.train_id}: calls {a.seq}→{b.seq} need departure then a later arrival"
            )
        x, t = curves(train.train_type, a.station_id, b.station_id, sched)
        x = np.asarray(x, dtype=float)
        t = np.asarray(t, dtype=float)
        us.append(sgn * x)
        ts.append(dep + t)
        arr = dep + float(t[-1])
        nxt = b.departure_s
        dep = arr if math.isnan(nxt) else max(nxt, arr)
    u = np.concatenate(us)
    t = np.concatenate(ts)
    # Guard against round-off in the curves: the front never moves back, time never runs back.
    u = np.maximum.accumulate(u)
    t = np.maximum.accumulate(t)
    return Trajectory(train.train_id, train.direction, u, t)


def stretched_curve(x_m: np.ndarray, t_s: np.ndarray, scheduled_s: float) -> RunCurve:
    """First approximation of the run at a scheduled time: stretch time uniformly.

    t'(x) = t(x) · T_sched / T_min when the schedule is slower than the curve
    (T_sched ≥ T_min), else the curve unchanged (the train cannot be faster).
    Uniform stretching slows acceleration and braking as much as cruising,
    whereas the vehicle cruises slower at a lower target-speed ratio; the
    position-time error is therefore largest mid-run, at most a few seconds
    for typical supplements of 5–10 %.
    """
    t_min = float(t_s[-1])
    f = scheduled_s / t_min if scheduled_s > t_min > 0 else 1.0
    return np.asarray(x_m, dtype=float), np.asarray(t_s, dtype=float) * f


DEFAULT_RATIOS = (1.0, 0.975, 0.95, 0.925, 0.9, 0.875, 0.85, 0.8, 0.75, 0.7, 0.65, 0.6, 0.5, 0.4, 0.3)
"""Target-speed ratios simulated per interstation; schedules between two are interpolated."""


def simulate_interstation(line: Line, train_type: str, origin: str, destination: str,
                          ratios: Sequence[float], ds_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Run curves of one interstation at several target-speed ratios, in one lock-step batch.

    Returns
    -------
    chainage_m : ndarray (m,)
        Chainage of each grid node, departure marker to arrival marker [m].
    time_s : ndarray (n, m)
        Time from departure at each node, one row per ratio [s].
    """
    from planner.physics.track import SimSettings, make_track
    from planner.physics.run_curve import simulate

    track = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=ds_m))
    res = simulate(track, line.train_type(train_type), np.asarray(ratios, dtype=float), record=True)
    return np.asarray(track.position_m(res.s_m), dtype=float), np.asarray(res.t_s, dtype=float)


class SimulatorCurves:
    """Run curves from the run-curve simulator at the ratio that meets the schedule, cached per interstation.

    For each (train type, origin, destination) the simulator runs a batch of
    target-speed ratios once (one lock-step batch costs about as much as one
    run). A scheduled running time between the times of two neighbouring
    ratios r₁ > r₂ gets the convex combination of their curves,
    t(x) = (1 − w) t₁(x) + w t₂(x) with w = (T − T₁)/(T₂ − T₁), which is
    monotone, ends exactly at T, and is what running at an intermediate ratio
    looks like to within the difference of the two neighbours. Slower than
    the lowest ratio: that curve stretched uniformly; faster than ratio 1.0:
    the ratio-1.0 curve (the train runs late).

    Parameters
    ----------
    line : Line
    mode : {"match", "stretch"}
        ``match`` as above; ``stretch``: the ratio-1.0 curve stretched
        uniformly in time (:func:`stretched_curve`), a first approximation.
    ratios : sequence of float
        Ratio grid, descending from 1.0.
    ds_m : float
        Integration step [m]. The conflict check needs times to about a second
        (blocking times are tens of seconds); on the sample line 10 m and 5 m
        steps find the same 62 conflicts with total delays of 804.8 s and
        804.5 s, and 10 m costs a tenth of the 1 m tables.
    n_jobs : int
        joblib processes for :meth:`prepare`.
    """

    def __init__(self, line: Line, *, mode: str = "match", ratios: Sequence[float] = DEFAULT_RATIOS,
                 ds_m: float = 10.0, n_jobs: int = 1):
        if mode not in ("match", "stretch"):
            raise InputError(f"run-curve mode must be 'match' or 'stretch', found {mode!r}")
        r = tuple(sorted({float(x) for x in ratios}, reverse=True))
        if not r or r[0] != 1.0 or r[-1] <= 0:
            raise InputError(f"run-curve ratios must start at 1.0 and stay > 0, found {ratios!r}")
        self.line, self.mode, self.ratios, self.ds_m, self.n_jobs = line, mode, r, ds_m, n_jobs
        self._tables: dict[tuple[str, str, str], tuple[np.ndarray, np.ndarray]] = {}

    @property
    def simulated(self) -> int:
        """Interstations simulated so far."""
        return len(self._tables)

    def prepare(self, keys: Iterable[tuple[str, str, str]],
                progress: Callable[[int, int], None] | None = None) -> None:
        """Simulate every (train_type, origin, destination) not cached yet, in parallel."""
        todo = sorted(set(keys) - set(self._tables))
        if not todo:
            return
        ratios = self.ratios if self.mode == "match" else (1.0,)
        if self.n_jobs == 1:
            for k, key in enumerate(todo):
                self._store(key, simulate_interstation(self.line, *key, ratios, self.ds_m))
                if progress:
                    progress(k + 1, len(todo))
            return
        from joblib import Parallel, delayed

        out = Parallel(n_jobs=self.n_jobs)(
            delayed(simulate_interstation)(self.line, *key, ratios, self.ds_m) for key in todo)
        for key, tab in zip(todo, out):
            self._store(key, tab)
        if progress:
            progress(len(todo), len(todo))

    def _store(self, key, tab) -> None:
        x, T = tab
        # Rows in order of running time, so neighbours bracket a schedule even where a
        # sawtooth vehicle's time is not quite monotone in the ratio.
        self._tables[key] = (x, T[np.argsort(T[:, -1], kind="stable")])

    def table(self, train_type: str, origin: str, destination: str) -> tuple[np.ndarray, np.ndarray]:
        key = (train_type, origin, destination)
        if key not in self._tables:
            self.prepare([key])
        return self._tables[key]

    def __call__(self, train_type: str, origin: str, destination: str, scheduled_s: float) -> RunCurve:
        x, T = self.table(train_type, origin, destination)
        ends = T[:, -1]
        if self.mode == "stretch" or scheduled_s <= ends[0]:
            return stretched_curve(x, T[0], scheduled_s)
        if scheduled_s >= ends[-1]:
            return stretched_curve(x, T[-1], scheduled_s)
        k = int(np.searchsorted(ends, scheduled_s))  # ends rise as the ratio falls
        k = min(max(k, 1), len(ends) - 1)
        w = (scheduled_s - ends[k - 1]) / (ends[k] - ends[k - 1])
        return x, (1.0 - w) * T[k - 1] + w * T[k]


# ---------------------------------------------------------------------------
# Occupation windows
# ---------------------------------------------------------------------------
KIND_NODE, KIND_SECTION = 0, 1
KIND_NAMES = ("node", "section")


@dataclass(frozen=True, eq=False)
class Windows:
    """Blocking-time windows of one or more trains, as parallel arrays (one entry per resource use).

    ``kind`` 0 node / 1 section; ``res`` the node or edge index in the graph;
    ``item`` the position in the train's route sequence (node k → 2k, edge k →
    2k+1), so consecutive resources have close items. Times in s after midnight.
    """

    train: np.ndarray      # int, index into the trains list
    kind: np.ndarray       # int8
    res: np.ndarray        # int
    item: np.ndarray       # int
    from_m: np.ndarray     # entry chainage [m]
    to_m: np.ndarray       # exit chainage [m]
    entry_s: np.ndarray    # front moves past the entry (at a stop: departs)
    exit_s: np.ndarray     # front reaches the exit
    clear_s: np.ndarray    # tail passes the exit
    start_s: np.ndarray    # window opens = entry − setting − approach
    end_s: np.ndarray      # window closes = clear + release

    def __len__(self) -> int:
        return len(self.start_s)

    @staticmethod
    def concat(parts: Sequence["Windows"]) -> "Windows":
        names = [f.name for f in dataclasses.fields(Windows)]
        if not parts:
            return Windows(**{n: np.zeros(0) for n in names})
        return Windows(**{n: np.concatenate([getattr(p, n) for p in parts]) for n in names})


def occupation_windows(g: TrackGraph, route: Route, traj: Trajectory, length_m: float,
                       params: BlockingParams, train_index: int = 0) -> Windows:
    """Blocking-time windows of one train on every section and switch of its route.

    For a resource entered at chainage e and left at x (e = x for a switch):

        start = t_leave(e) − setting_s − approach_s
        end   = t_front(x + L) + release_s      (tail clear: front one train length past x)

    t_front is the first time the predicted front reaches a chainage
    (:meth:`Trajectory.front_time`), t_leave the last, when it moves on
    (:meth:`Trajectory.front_leaves`): the two differ only where the train
    stands, so the section after a stop opens at departure − lead, at every
    stop as at the origin, while the sections the standing train fills stay
    claimed until its tail clears them after departure. Where x + L lies beyond the
    destination the tail never clears during the run, and the window ends at
    arrival + terminal_s + release_s. Sections are the route's edges, split at
    block signals (:class:`TrackGraph`).

    Parameters
    ----------
    length_m : float
        Train length L [m].
    """
    sgn = sign(route.direction)
    kinds: list[int] = []
    ids: list[int] = []
    items: list[int] = []
    ent: list[float] = []
    ext: list[float] = []
    item = 0
    for k, n in enumerate(route.node_idx.tolist()):
        if g.kind[n] in params.node_kinds:
            kinds.append(KIND_NODE), ids.append(n), items.append(item)
            ent.append(g.pos_m[n]), ext.append(g.pos_m[n])
        item += 1
        if k < len(route.edge_idx):
            pcs = g.edge_pieces[int(route.edge_idx[k])]
            for pc in (pcs if sgn > 0 else pcs[::-1]):
                lo, hi = g.piece_lo_m[pc], g.piece_hi_m[pc]
                kinds.append(KIND_SECTION), ids.append(pc), items.append(item)
                ent.append(lo if sgn > 0 else hi), ext.append(hi if sgn > 0 else lo)
                item += 1
    entry_m = np.asarray(ent, dtype=float)
    exit_m = np.asarray(ext, dtype=float)
    # Entered when the front moves past the entry (at a stop: the departure); left when it first reaches the exit.
    entry = traj.front_leaves(entry_m)
    exit_ = np.maximum(traj.front_time(exit_m), entry)
    clear = np.minimum(traj.front_time(exit_m + sgn * length_m), traj.end_s + params.terminal_s)
    m = len(kinds)
    return Windows(
        train=np.full(m, train_index, dtype=np.int64),
        kind=np.asarray(kinds, dtype=np.int8), res=np.asarray(ids, dtype=np.int64),
        item=np.asarray(items, dtype=np.int64), from_m=entry_m, to_m=exit_m,
        entry_s=entry, exit_s=exit_, clear_s=clear,
        start_s=entry - params.lead_s, end_s=clear + params.release_s,
    )


# ---------------------------------------------------------------------------
# Conflict detection
# ---------------------------------------------------------------------------
def find_overlaps(resource: np.ndarray, start_s: np.ndarray, end_s: np.ndarray,
                  owner: np.ndarray, *, min_overlap_s: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """All pairs of windows of different owners that overlap on the same resource.

    Sort-and-sweep: windows are sorted by (resource, start); window i can only
    overlap the windows after it in that order whose start is before its end,
    found by one binary search per window. Cost O(n log n + pairs).

    Parameters
    ----------
    resource : int array (n,)
        Resource key of each window.
    start_s, end_s : float arrays (n,)
        Window bounds [s], start ≤ end.
    owner : int array (n,)
        Train of each window; windows of the same owner never conflict.
    min_overlap_s : float
        Overlaps must exceed this [s] (touching windows are not a conflict).

    Returns
    -------
    (i, j) : int arrays
        Indices into the inputs, i < j in sorted order, with
        min(end) − max(start) > min_overlap_s.
    """
    n = len(start_s)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    order = np.lexsort((start_s, resource))
    r, s, e = resource[order], start_s[order], end_s[order]
    # Search each end among the starts of its own resource: offset keys per resource.
    bounds = np.flatnonzero(np.r_[True, r[1:] != r[:-1], True])
    hi = np.empty(n, dtype=np.int64)
    for a, b in zip(bounds[:-1], bounds[1:]):
        hi[a:b] = a + np.searchsorted(s[a:b], e[a:b] - min_overlap_s, side="left")
    cnt = np.maximum(hi - np.arange(n) - 1, 0)
    ii = np.repeat(np.arange(n), cnt)
    first = np.repeat(np.cumsum(cnt) - cnt, cnt)
    jj = ii + 1 + (np.arange(cnt.sum()) - first)
    oi, oj = order[ii], order[jj]
    ov = np.minimum(end_s[oi], end_s[oj]) - np.maximum(start_s[oi], start_s[oj])
    keep = (owner[oi] != owner[oj]) & (ov > min_overlap_s)
    return oi[keep], oj[keep]


@dataclass(frozen=True, eq=False)
class ConflictReport:
    """Everything the conflict check found for one line.

    ``conflicts`` and ``occupation`` are pandas DataFrames with the columns of
    :data:`CONFLICTS_SCHEMA` and :data:`OCCUPATION_SCHEMA` (plus ``line``,
    ``direction``, ``train_type`` partition columns).
    """

    line_id: str
    params: BlockingParams
    routes: dict[str, Route]
    conflicts: Any
    occupation: Any
    summary: dict[str, Any] = field(default_factory=dict)

    def summary_lines(self) -> list[str]:
        s = self.summary
        out = [
            f"line {self.line_id}: {s['trains']} trains routed, {s['windows']} occupation windows "
            f"({s['loops']} loop stops for overtaking)",
            f"  conflicts: {s['conflicts']} between {s['pairs']} train pairs on {s['rows']} resources; "
            f"deadlocks avoided: {s['deadlocks']}",
        ]
        for rule, n in sorted(s["by_rule"].items()):
            out.append(f"    {rule}: {n}")
        out.append(f"  delay imposed: total {s['delay_total_s']:.1f} s, largest {s['delay_max_s']:.1f} s"
                   + ("; the largest, in time order:" if s["worst"] else ""))
        for row in s["worst"]:
            out.append(f"    {row}")
        for note in s["notes"]:
            out.append(f"  note: {note}")
        return out


def _departure_before(train: Train, chainage_m: float, stop_m: Mapping[str, float]) -> float:
    """Timetable departure (or passing) time of the train's last call at or before a chainage [s]."""
    sg = sign(train.direction)
    best = train.calls[0]
    for c in train.calls:
        if sg * stop_m[c.station_id] <= sg * chainage_m + 1e-6:
            best = c
    return _interval(best)[1]


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
    # Stable ids in time order.
    cids: dict[int, int] = {}
    for r in sorted(records, key=lambda r: (r["_t0"], r["train_a"], r["train_b"], r["_gid"])):
        cids.setdefault(r["_gid"], len(cids))
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
            "from_m": float(min(w.from_m[a], w.to_m[a])),
            "to_m": float(max(w.from_m[a], w.to_m[a])),
            "a_start_s": float(w.start_s[kp]),
            "a_end_s": float(w.end_s[kp]),
            "b_start_s": float(w.start_s[kq2]),
            "b_end_s": float(w.end_s[kq2]),
            "overlap_start_s": float(ov0),
            "overlap_end_s": float(ov1),
            "overlap_s": float(ov1 - ov0),
            "rule": rule,
            "decision": decision,
            "delay_s": float(delay),
            "deadlock": bool(deadlock),
            "stretch": st_name,
        })
    return out


# ---------------------------------------------------------------------------
# Whole-line check and datasets
# ---------------------------------------------------------------------------
def _schemas():
    import pyarrow as pa

    from planner.io.parquet import declare

    occ = declare([
        ("train_id", pa.string(), "timetabled train"),
        ("seq", pa.int32(), "order of the resource along the train's route, from 0"),
        ("resource_kind", pa.string(), "`node` (a switch) or `section` (a track piece, edge)"),
        ("resource_id", pa.string(), "node_id or edge_id in nodes.parquet / edges.parquet"),
        ("interlocking", pa.string(), "interlocking controlling the resource (of its entry node for a section)"),
        ("track", pa.string(), "track name of the section, or of the node"),
        ("from_m", pa.float64(), "chainage where the front enters the resource [m]"),
        ("to_m", pa.float64(), "chainage where the front leaves the resource [m]"),
        ("entry_s", pa.float64(), "predicted time the front enters the resource: passes its entry, or departs where it stands there [s after midnight]"),
        ("exit_s", pa.float64(), "predicted time the front reaches the exit [s after midnight]"),
        ("clear_s", pa.float64(), "predicted time the tail clears the exit (front one train length past it) [s after midnight]"),
        ("setting_s", pa.float64(), "route setting time before the approach [s]"),
        ("approach_s", pa.float64(), "sight/reaction and approach time before the entry [s]"),
        ("running_s", pa.float64(), "running time of the front through the resource, exit − entry; includes a dwell only where the train stops with its front inside the resource [s]"),
        ("clearing_s", pa.float64(), "clearing time: tail clears the exit after the front reached it [s]"),
        ("release_s", pa.float64(), "route release time after clearing [s]"),
        ("start_s", pa.float64(), "window opens: entry − setting − approach [s after midnight]"),
        ("end_s", pa.float64(), "window closes: clear + release [s after midnight]"),
    ], name="occupation", description="Blocking-time occupation windows of every train on every switch and section of its route")
    con = declare([
        ("conflict_id", pa.int32(), "conflict number, in time order; rows of one conflict share it"),
        ("train_a", pa.string(), "train that goes first by the decision"),
        ("train_b", pa.string(), "train that waits"),
        ("direction_a", pa.string(), "running direction of train_a"),
        ("direction_b", pa.string(), "running direction of train_b"),
        ("resource_kind", pa.string(), "`node` (a switch) or `section` (a track piece, edge)"),
        ("resource_id", pa.string(), "node_id or edge_id"),
        ("interlocking", pa.string(), "interlocking controlling the resource"),
        ("from_m", pa.float64(), "lower chainage of the resource [m]"),
        ("to_m", pa.float64(), "upper chainage of the resource [m]"),
        ("a_start_s", pa.float64(), "train_a's window opens [s after midnight]"),
        ("a_end_s", pa.float64(), "train_a's window closes [s after midnight]"),
        ("b_start_s", pa.float64(), "train_b's window opens [s after midnight]"),
        ("b_end_s", pa.float64(), "train_b's window closes [s after midnight]"),
        ("overlap_start_s", pa.float64(), "start of the overlap of the two windows [s after midnight]"),
        ("overlap_end_s", pa.float64(), "end of the overlap [s after midnight]"),
        ("overlap_s", pa.float64(), "overlap of the two windows on this resource [s]"),
        ("rule", pa.string(), "priority rule: `no-deadlock`, `timetable-order` or `leaves-first` (DESIGN §8)"),
        ("decision", pa.string(), "who goes first and why"),
        ("delay_s", pa.float64(), "delay the decision imposes on train_b: shift that opens each of its windows after train_a's close [s]"),
        ("deadlock", pa.bool_(), "the two opposing trains would deadlock on a single-track stretch without the decision"),
        ("stretch", pa.string(), "for deadlocks: the single-track stretch first..last resource; else empty"),
    ], name="conflicts", description="Overlapping occupation windows of two trains, with the priority decision and the delay it causes")
    return occ, con


def interstation_keys(trains: Iterable[Train]) -> list[tuple[str, str, str]]:
    """(train_type, origin, destination) of every interstation run (stop to stop) in the timetable."""
    out = []
    for t in trains:
        last = len(t.calls) - 1
        calls = [c for k, c in enumerate(t.calls) if c.stops or k in (0, last)]
        out += [(t.train_type, a.station_id, b.station_id) for a, b in zip(calls[:-1], calls[1:])]
    return out


def check_conflicts(line: Line, params: BlockingParams | Mapping[str, Any] | None = None, *,
                    curves: RunCurveSource | None = None,
                    progress: Callable[[int, int], None] | None = None,
                    curve_progress: Callable[[int, int], None] | None = None) -> ConflictReport:
    """Check a line's whole timetable for route conflicts on its track network.

    Parameters
    ----------
    line : Line
        Line with ``network`` and a timetable.
    params : BlockingParams or mapping, optional
        Blocking-time parameters (a job file's ``[conflicts]`` table works).
    curves : RunCurveSource, optional
        Run curves per interstation; default :class:`SimulatorCurves` (ratio
        matched to the schedule).
    progress : callable(done, total), optional
        Called after each train is predicted.
    curve_progress : callable(done, total), optional
        Called as run curves are simulated (before the trains are predicted).

    Returns
    -------
    ConflictReport
    """
    import pandas as pd

    p = params if isinstance(params, BlockingParams) else BlockingParams.from_dict(params)
    g = TrackGraph(line)
    trains = list(line.trains)
    routes_d = plan_routes(line, g)
    routes = [routes_d[t.train_id] for t in trains]
    src = curves or SimulatorCurves(line)
    if hasattr(src, "prepare"):
        src.prepare(sorted(set(interstation_keys(trains))), progress=curve_progress)
    parts = []
    for k, (t, r) in enumerate(zip(trains, routes)):
        traj = build_trajectory(line, t, src)
        parts.append(occupation_windows(g, r, traj, line.train_type(t.train_type).length_m, p, k))
        if progress:
            progress(k + 1, len(trains))
    w = Windows.concat(parts)
    records = detect_conflicts(g, trains, routes, w)
    conflicts = pd.DataFrame.from_records(records, columns=[f.name for f in _schemas()[1]] if not records else None)
    if len(conflicts):
        conflicts = conflicts[[f.name for f in _schemas()[1]]].sort_values(
            ["conflict_id", "from_m", "resource_kind", "resource_id"], kind="stable").reset_index(drop=True)
    conflicts.insert(0, "line", line.line_id)
    occupation = _occupation_frame(g, trains, routes, w, p, line.line_id)
    return ConflictReport(line.line_id, p, routes_d, conflicts, occupation,
                          _summary(trains, routes, w, conflicts))


def _occupation_frame(g: TrackGraph, trains, routes, w: Windows, p: BlockingParams, line_id: str):
    import pandas as pd

    tr = w.train
    kr = list(zip(w.kind.tolist(), w.res.tolist()))
    names = {x: (g.resource_id(*x), g.resource_interlocking(*x), g.resource_track(*x)) for x in set(kr)}
    rid = [names[x][0] for x in kr]
    il = [names[x][1] for x in kr]
    track = [names[x][2] for x in kr]
    seq = np.zeros(len(w), dtype=np.int32)
    for k in np.unique(tr):
        m = tr == k
        seq[m] = np.argsort(np.argsort(w.item[m], kind="stable"), kind="stable")
    df = pd.DataFrame({
        "line": line_id,
        "direction": [trains[k].direction for k in tr],
        "train_type": [trains[k].train_type for k in tr],
        "train_id": [trains[k].train_id for k in tr],
        "seq": seq,
        "resource_kind": np.array(KIND_NAMES, dtype=object)[w.kind.astype(int)],
        "resource_id": rid,
        "interlocking": il,
        "track": track,
        "from_m": w.from_m, "to_m": w.to_m,
        "entry_s": w.entry_s, "exit_s": w.exit_s, "clear_s": w.clear_s,
        "setting_s": p.setting_s, "approach_s": p.approach_s,
        "running_s": w.exit_s - w.entry_s, "clearing_s": w.clear_s - w.exit_s,
        "release_s": p.release_s,
        "start_s": w.start_s, "end_s": w.end_s,
    })
    return df.sort_values(["train_id", "seq"], kind="stable").reset_index(drop=True)


def _summary(trains, routes, w: Windows, conflicts) -> dict[str, Any]:
    notes = [f"train {r.train_id}: {n}" for r in routes for n in r.notes]
    s: dict[str, Any] = {
        "trains": len(trains), "windows": int(len(w)),
        "loops": sum(len(r.loop_calls) for r in routes), "notes": notes,
        "rows": int(len(conflicts)), "conflicts": 0, "pairs": 0, "deadlocks": 0,
        "by_rule": {}, "delay_total_s": 0.0, "delay_max_s": 0.0, "worst": [],
    }
    if len(conflicts):
        c = conflicts.groupby("conflict_id", sort=True).agg(
            train_a=("train_a", "first"), train_b=("train_b", "first"), rule=("rule", "first"),
            delay_s=("delay_s", "first"), deadlock=("deadlock", "first"), overlap_s=("overlap_s", "max"),
            resource=("resource_id", "first"), t0=("overlap_start_s", "min"), n=("resource_id", "size"))
        s["conflicts"] = int(len(c))
        s["pairs"] = int(len(c.groupby(["train_a", "train_b"]).size()))
        s["deadlocks"] = int(c["deadlock"].sum())
        s["by_rule"] = {k: int(v) for k, v in c["rule"].value_counts().sort_index().items()}
        s["delay_total_s"] = float(c["delay_s"].sum())
        s["delay_max_s"] = float(c["delay_s"].max())
        # the five largest delays, listed in time order (as the conflict ids run)
        worst = c.sort_values(["delay_s", "t0"], ascending=[False, True], kind="stable").head(5)
        worst = worst.sort_values(["t0"], kind="stable")
        s["worst"] = [
            f"#{cid}: {r.train_a} before {r.train_b} at {r.resource}"
            + (f" and {r.n - 1} more resource{'s' if r.n > 2 else ''}" if r.n > 1 else "")
            + f" ~{_hms(r.t0)}, overlap {r.overlap_s:.1f} s, delay {r.delay_s:.1f} s [{r.rule}]"
            for cid, r in worst.iterrows()
        ]
    return s


def _hms(t: float) -> str:
    t = int(round(t))
    return f"{t // 3600:02d}:{t // 60 % 60:02d}:{t % 60:02d}"


def conflicts_table(line: Line | str, params: BlockingParams | Mapping[str, Any] | None = None, *,
                    curves: RunCurveSource | None = None):
    """The conflicts table of a line, for reports (the margin HTML report calls this).

    Returns an empty DataFrame (with the columns) when the line has no track
    network. ``line`` may be a loaded Line or a line folder.
    """
    import pandas as pd

    if not isinstance(line, Line):
        from planner import load_line

        line = load_line(line)
    if line.network is None:
        return pd.DataFrame(columns=["line"] + [f.name for f in _schemas()[1]])
    return check_conflicts(line, params, curves=curves).conflicts


def write_conflicts(report: ConflictReport, out_dir) -> list:
    """Write ``conflicts`` and ``occupation`` datasets under ``out_dir`` (hive-partitioned, atomic files).

    ``conflicts/line=L/part-0.parquet`` (a conflict can involve both directions,
    so it is partitioned by line only) and
    ``occupation/line=L/direction=D/train_type=T/part-0.parquet``.
    """
    from pathlib import Path

    import pyarrow as pa

    from planner.io.parquet import write_parquet_atomic, write_partitioned

    occ_schema, con_schema = _schemas()
    out = Path(out_dir)
    written = []
    con = report.conflicts
    if len(con):
        written += write_partitioned(pa.Table.from_pandas(con, preserve_index=False), out, "conflicts",
                                     ("line",), schema=con_schema,
                                     sort_by=("conflict_id", "from_m", "resource_kind", "resource_id"))
    else:  # an empty file, so readers find the dataset and its schema
        path = out / "conflicts" / f"line={report.line_id}" / "part-0.parquet"
        write_parquet_atomic(con_schema.empty_table(), path)
        written.append(path)
    occ = report.occupation
    if len(occ):
        written += write_partitioned(pa.Table.from_pandas(occ, preserve_index=False), out, "occupation",
                                     schema=occ_schema, sort_by=("train_id", "seq"))
    return written
