"""Blocking-time windows (docs/design.md §8, step 3): when each train claims each switch and section, and overlaps.

Takes the track graph, a train's route and its predicted trajectory; gives
:class:`Windows`, parallel arrays with one entry per resource use
(:func:`occupation_windows`), and the overlapping pairs of windows of
different trains on one resource (:func:`find_overlaps`).

A resource (a section, or a switch node) is claimed from
``entry − setting_s − approach_s`` (route setting, then sight and reaction
while the train approaches the signal at the entry) until
``clear + release_s``, where *entry* is when the front moves past the
resource's entry (where the train stands with its front at the entry, as at
its origin and at every stop whose stop node begins the next section, its
departure) and *clear* is when the tail has passed the exit (front at exit +
train length, from the same run curve, so a train that stops holds the
sections under it through its dwell). This is the blocking-time model of
Pachl, *Railway Operation and Control*, ch. 4, and Hansen & Pachl, *Railway
Timetabling & Operations*, ch. 4. The parameters are :class:`BlockingParams`
(the job file's ``[conflicts]`` table).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import sign
from planner.network.arrivals import Trajectory
from planner.network.routes import KIND_NODE, KIND_SECTION, Route, TrackGraph


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
