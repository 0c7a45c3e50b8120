"""Sections of a line: stretches of track whose trains never meet the trains of another stretch.

The conflict check and the day as it will run look at trains together: two trains conflict only on a
resource both use, and a delay passes from one train to another only through such a resource or a
connection. So a line whose timetable falls into groups of trains that share no stretch of track (a
network of lines joined end to end, each with its own trains) can be checked group by group, and every
group's answer is the one the whole line gives for its trains.

:func:`line_sections` finds the groups. Each routed train covers a chainage span: every node and track
piece of its route, the stop markers of its calls and each of its legs' windows (one train length
beyond the stop markers, :meth:`planner.line.model.Line.window_m`); trains joined by a connection cover
the hull of both spans. Spans that overlap or touch are merged; each merged span with its trains is a
:class:`Section`. Two sections are therefore apart along the line, not only on different tracks: a
station, a switch or a stretch of plain line belongs to one section at most, so the sections' datasets
add up row by row (a station's statistics come from one section).

:func:`section_line` is the line as a section's unit sees it: its trains, the stations of its span and
the nearest one beyond each end (a resource is named by its nearest station), the gradients, curves,
restrictions, beacons and signals that reach into the span (whole), and the track network's nodes in the
span with every track piece that touches one of them (so each node keeps all of its track pieces). Every
route, window, conflict and delay of the section's trains is the same as on the whole line (checked by
``tests/test_sections.py`` against the whole line's answers); what a section unit ships, and what its
cache key digests, is its own stretch, so an edit of one stretch recomputes that stretch alone.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterable, Sequence

import numpy as np

from planner.line.model import Line, Network, Segments


@dataclass(frozen=True)
class Section:
    """Trains that share track only with each other, and the chainage span they cover [m]."""

    train_ids: tuple[str, ...]
    """In the line's timetable order."""
    lo_m: float
    hi_m: float


def train_span(line: Line, graph, route, train, edge_ends: np.ndarray | None = None) -> tuple[float, float]:
    """Chainage span [m] a train covers (module doc): its route's nodes and track pieces (``route`` None: a train
    the network cannot carry), and one train length (and 1 m) beyond its calls' stations (their reference
    positions and both stop markers): every leg's window (:meth:`planner.line.model.Line.window_m`) lies in it.
    ``edge_ends``: the lower and upper chainage of each of the graph's edges (:func:`edge_ends`), made once."""
    pad = line.train_type(train.train_type).length_m + 1.0
    xs = []
    for c in train.calls:
        st = line.station(c.station_id)
        xs += (st.position_m, st.stop_down_m, st.stop_up_m)
    lo, hi = min(xs) - pad, max(xs) + pad
    if route is not None and len(route.node_idx):
        p = graph.pos_m[np.asarray(route.node_idx, dtype=np.int64)]
        lo, hi = min(lo, float(p.min())), max(hi, float(p.max()))
    if route is not None and len(route.edge_idx):
        e = (edge_ends if edge_ends is not None else _edge_ends(graph))[np.asarray(route.edge_idx, dtype=np.int64)]
        lo, hi = min(lo, float(e[:, 0].min())), max(hi, float(e[:, 1].max()))
    return lo, hi


def _edge_ends(graph) -> np.ndarray:
    """``(n_edges, 2)``: the lower and upper chainage of each edge of the track graph [m]."""
    ends = np.array([[graph.pos_m[graph.index[e.from_node]], graph.pos_m[graph.index[e.to_node]]]
                     for e in graph.edges], dtype=float).reshape(-1, 2)
    return np.sort(ends, axis=1)


def line_sections(line: Line, graph, routes: dict, connections: Iterable[tuple[str, str, str, float]] = ()
                  ) -> list[Section]:
    """The sections of a line's trains in chainage order (``routes``: ``train_id`` → route, from
    :func:`planner.network.routes.plan_routes` on ``graph``; a train without one, which the check will report
    as unrouted, goes by its calls); ``connections``: the job's (train A, train B, station, minimum) links,
    whose trains share a section."""
    trains = list(line.trains)
    if not trains:  # one section, the whole line: its check and its datasets are those of a day without trains
        return [Section((), line.start_m, line.end_m)]
    ends = _edge_ends(graph) if graph is not None else None
    span = {t.train_id: train_span(line, graph, routes.get(t.train_id), t, ends) for t in trains}
    for a, b, _station, _m in connections:  # a delay passes along a connection: both trains in one section
        if a in span and b in span:
            span[a] = span[b] = (min(span[a][0], span[b][0]), max(span[a][1], span[b][1]))
    order = sorted(span, key=lambda tid: span[tid])
    groups: list[list] = []  # [lo, hi, ids]
    for tid in order:
        lo, hi = span[tid]
        if groups and lo <= groups[-1][1]:
            groups[-1][1] = max(groups[-1][1], hi)
            groups[-1][2].add(tid)
        else:
            groups.append([lo, hi, {tid}])
    return [Section(tuple(t.train_id for t in trains if t.train_id in ids), lo, hi) for lo, hi, ids in groups]


def plan_sections(line: Line, connections: Iterable[tuple[str, str, str, float]] = ()) -> list[Section]:
    """The sections of a line (:func:`line_sections` of its routes on its track graph; a line without a track
    network: of its trains' calls and legs alone, which is all a run of one sees there)."""
    from planner.network.routes import TrackGraph, plan_routes

    if line.network is None:
        return line_sections(line, None, {}, connections)
    graph = TrackGraph(line)
    return line_sections(line, graph, plan_routes(line, graph, unrouted={}), connections)


def part_names(n: int) -> list[str]:
    """The names of ``n`` sections' dataset files (``part-<name>.parquet``): their numbers, zero-padded to one
    width so that the files sort in the sections' order; ``0`` for a line of one section."""
    width = len(str(max(n - 1, 0)))
    return [f"{k:0{width}d}" for k in range(n)]


def section_line(line: Line, section: Section) -> Line:
    """The line as ``section``'s unit sees it (module doc); the line itself when the section holds every train."""
    if len(section.train_ids) == len(line.trains):
        return line
    lo, hi = section.lo_m, section.hi_m
    keep = set(section.train_ids)
    st = sorted(line.stations, key=lambda s: s.position_m)
    inside = [s for s in st if lo <= s.position_m <= hi]
    before = [s for s in st if s.position_m < lo][-1:]  # the nearest beyond each end (ties: all of them)
    after = [s for s in st if s.position_m > hi][:1]
    if before:
        before = [s for s in st if s.position_m == before[0].position_m]
    if after:
        after = [s for s in st if s.position_m == after[0].position_m]
    names = {s.station_id for s in before + inside + after}

    def seg(x: Segments) -> Segments:
        m = (x.end_m > lo) & (x.start_m < hi)
        return Segments(x.start_m[m], x.end_m[m], x.value[m])

    network = line.network
    if network is not None:
        at = {n.node_id: n.position_m for n in network.nodes}
        core = {nid for nid, x in at.items() if lo <= x <= hi}
        edges = tuple(e for e in network.edges if e.from_node in core or e.to_node in core)
        ends = core | {e.from_node for e in edges} | {e.to_node for e in edges}
        network = Network(tuple(n for n in network.nodes if n.node_id in ends), edges)
        xs = [at[n] for n in ends if n in at]
        sig_lo, sig_hi = (min(xs + [lo]), max(xs + [hi]))
    else:
        sig_lo, sig_hi = lo, hi
    return replace(
        line,
        stations=tuple(s for s in line.stations if s.station_id in names),
        gradients=seg(line.gradients), curves=seg(line.curves),
        speed_limits=tuple(x for x in line.speed_limits if x.end_m > lo and x.start_m < hi),
        beacons=tuple(b for b in line.beacons if lo <= b.position_m <= hi),
        signals=tuple(s for s in line.signals if sig_lo <= s.position_m <= sig_hi),
        trains=tuple(t for t in line.trains if t.train_id in keep),
        network=network,
    )


def stream_of(section: Section, line: Line) -> tuple[int, ...]:
    """The section's own stream of random draws for the simulated days (a spawn key after the chunk's): none
    for a section that holds the whole line's trains (the line's draws are those of a whole-line run),
    else a number from its first train's id, which an edit elsewhere does not change."""
    if len(section.train_ids) == len(line.trains):
        return ()
    import hashlib

    return (int.from_bytes(hashlib.sha256(section.train_ids[0].encode()).digest()[:4], "big"),)


def restricted(lifted: dict | None, section: Section) -> dict:
    """The lifted restrictions (``(train_id, leg)`` → ids) of the section's trains."""
    keep = set(section.train_ids)
    return {k: v for k, v in (lifted or {}).items() if k[0] in keep}


__all__: Sequence[str] = ("Section", "line_sections", "part_names", "plan_sections", "restricted", "section_line",
                          "stream_of", "train_span")
