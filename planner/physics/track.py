"""The track one run sees: an interstation for one train type on the integrator's grid.

:func:`make_track` turns a :class:`~planner.line.model.Line`, a train type and two
stations into a :class:`Track`: grid nodes in running distance (every restriction,
gradient and curve change, and the same plus the train length, is a node), the
on-board maximum speed per node and interval, and the train-averaged gradient and
curve resistance. :class:`SimSettings` holds the step. All in SI.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from planner.errors import InputError
from planner.line.model import Line, TrainType
from planner.physics import dynamics, speed_profile

NODE_TOL_M = 1e-6
"""Two running distances closer than this are the same grid node [m]."""


@dataclass(frozen=True)
class SimSettings:
    """Integrator settings.

    Attributes
    ----------
    ds_m : float
        Largest distance step [m]; breakpoints are always grid nodes, and the
        gaps between them are divided evenly into steps of at most ``ds_m``
        (shorter where the on-board maximum is below 40 km/h: :func:`_grid`).
    """

    ds_m: float = 1.0

    def __post_init__(self):
        if not (self.ds_m > 0 and math.isfinite(self.ds_m)):
            raise InputError(f"distance step ds_m must be a positive number of metres, got {self.ds_m}")


@dataclass(frozen=True, eq=False)
class Track:
    """One interstation, direction and train type: everything the integrator needs.

    Node arrays have shape (m,), interval arrays (m − 1,).

    Attributes
    ----------
    length_m : float
        Departure stop marker → arrival stop marker [m].
    s_m : ndarray
        Grid nodes, running distance 0 … length_m [m].
    chainage_m : ndarray
        Chainage of each node [m] (``x0_m + direction_sign · s_m``).
    vmax_ms : ndarray
        On-board maximum speed at each node [m/s] (lower of the two intervals around it).
    vmax_interval_ms : ndarray
        On-board maximum speed inside each grid interval [m/s].
    gradient : ndarray
        Gradient averaged over the train at each node [rise/m], positive rising
        in the running direction.
    curve_specific : ndarray
        Curve resistance per weight averaged over the train at each node [N/N].
    x0_m : float
        Chainage of the departure stop marker [m].
    direction_sign : int
        +1 running ``down`` (chainage grows with s), −1 ``up``.
    train_length_m : float
        Length of the train the averages and tail clearing were built for [m].
    settings : SimSettings
        The settings the grid was built with.
    """

    line_id: str
    origin: str
    destination: str
    direction: str
    train_type: str
    length_m: float
    s_m: np.ndarray
    chainage_m: np.ndarray
    vmax_ms: np.ndarray
    vmax_interval_ms: np.ndarray
    gradient: np.ndarray
    curve_specific: np.ndarray
    x0_m: float
    direction_sign: int
    train_length_m: float
    settings: SimSettings = SimSettings()

    def node_index(self, s_m: float) -> int:
        """Index of the grid node at running distance ``s_m``.

        Raises
        ------
        InputError
            If ``s_m`` is not a grid node (pass it to ``make_track(nodes_m=...)``).
        """
        i = int(np.searchsorted(self.s_m, s_m))
        for j in (i - 1, i):
            if 0 <= j < len(self.s_m) and abs(self.s_m[j] - s_m) <= NODE_TOL_M:
                return j
        raise InputError(
            f"running distance {s_m} m is not a grid node of {self.origin}->{self.destination} "
            f"(0 … {self.length_m} m); pass it to make_track(nodes_m=...)")

    def position_m(self, s_m):
        """Chainage [m] of running distance ``s_m``."""
        return self.x0_m + self.direction_sign * np.asarray(s_m, dtype=float)

    def ceiling_sq(self, ratio, train: TrainType) -> np.ndarray:
        """Ceiling squared at every node for each ratio, shape (n, m) [m²/s²] (for checks and plots)."""
        target = np.multiply.outer(np.atleast_1d(np.asarray(ratio, dtype=float)), self.vmax_ms)
        return speed_profile.ceiling_sq(self.s_m, target, train.service_brake_ms2,
                                        self.length_m, train.stop_brake_ms2)


SLOW_MS = 40.0 / 3.6
"""Below this on-board maximum a gap's steps are shortened (:func:`_grid`)."""
SLOW_FINEST = 1.0 / 16.0
"""The shortest step of a slow gap, as a part of ``ds_m`` (reached at a quarter of :data:`SLOW_MS`)."""


def _grid(breaks: np.ndarray, ds_m: float, vmax_ms: np.ndarray) -> np.ndarray:
    """Breakpoints (sorted, unique, 0 … L) with every gap divided evenly into steps ≤ ds_m; in a gap whose
    on-board maximum ``vmax_ms`` (one per gap) is below :data:`SLOW_MS`, into steps ≤ ds_m × (vmax / SLOW_MS)²,
    and no shorter than ds_m × :data:`SLOW_FINEST`.

    Why slow gaps get shorter steps: a target there can be a crawl (a low ratio of a 20 km/h restriction is 4
    km/h). A step of length Δs at acceleration a changes the speed by about a Δs / v, a part a Δs / v² of itself,
    so at a crawl one step of power or coasting changes the speed by a large part of itself and a sawtooth
    vehicle's cycle between its band and its target is a few steps long (the sample line's 20 km/h restriction
    at the lowest ratio: 12 s off a remaining time of 400 s with 1 m steps, 0.01 s with these).
    Steps ∝ v² keep that part what it is at :data:`SLOW_MS`."""
    gaps = np.diff(breaks)
    steps = ds_m * np.clip((np.asarray(vmax_ms) / SLOW_MS) ** 2, SLOW_FINEST, 1.0)
    nsub = np.maximum(np.ceil(gaps / steps - 1e-9).astype(int), 1)
    pieces = [np.linspace(a, b, k, endpoint=False) for a, b, k in zip(breaks[:-1], breaks[1:], nsub)]
    return np.concatenate(pieces + [breaks[-1:]])


def make_track(line: Line, train_type: str, origin: str, destination: str, *,
               settings: SimSettings = SimSettings(), nodes_m: Sequence[float] = ()) -> Track:
    """Build the :class:`Track` of one interstation for one train type.

    The direction follows from the two stations. Grid breakpoints: restriction
    entry, exit and exit + train length (tail clears); every gradient and curve
    change and the same + train length (where the train-averaged force has a
    kink); ``nodes_m``; the arrival marker.

    Parameters
    ----------
    line : Line
    train_type, origin, destination : str
    settings : SimSettings
    nodes_m : sequence of float
        Extra running distances [m] from the departure marker that must be exact
        grid nodes (evaluation points, ratio changes, snapshots).

    Only the slice of the line the run can see (:meth:`planner.line.model.Line.window`) is
    read, so the work grows with the interstation, not with the line's gradient and
    curve tables (a 10-million-row gradient table made every whole-line call take
    seconds and gigabytes: the train graph's and the conflict check's).

    Raises
    ------
    UnknownNameError, InputError, InfeasibleError
    """
    line = line.window(origin, destination, train_type)
    train = line.train_type(train_type)
    ext = line.run_between(origin, destination)
    direction, sg, x0, x1, length = ext.direction, ext.sign, ext.start_m, ext.end_m, ext.length_m
    if not length > 0:
        raise InputError(f"stop markers of {origin} ({x0} m) and {destination} ({x1} m) leave no "
                         f"distance to run {direction}; check stop_{direction}_m in stations.parquet")
    lt = train.length_m
    spans = speed_profile.restriction_spans(line, train, direction, x0)
    brk = [0.0, length]
    for sp in spans:
        brk += [sp.s_from_m, sp.s_exit_m, sp.s_to_m]
    for seg in (line.gradients, line.curves):
        edges = sg * (np.concatenate([seg.start_m, seg.end_m]) - x0)
        brk += list(edges) + list(edges + lt)
    for s in nodes_m:
        if not (-NODE_TOL_M <= s <= length + NODE_TOL_M):
            raise InputError(f"node {s} m lies outside the interstation {origin}->{destination} "
                             f"(0 … {length} m)")
        brk.append(float(s))
    b = np.unique(np.clip(np.asarray(brk, dtype=float), 0.0, length))
    b = b[np.concatenate([[True], np.diff(b) > NODE_TOL_M])]
    b[-1] = length
    vmax = functools.partial(speed_profile.onboard_max_ms, spans=spans, line_max_ms=line.max_speed_ms,
                             vehicle_max_ms=train.max_speed_ms, margin_ms=train.speed_margin_ms)
    s = _grid(b, settings.ds_m, vmax(0.5 * (b[:-1] + b[1:])))
    vint = vmax(0.5 * (s[:-1] + s[1:]))
    chain = x0 + sg * s
    return Track(
        line_id=line.line_id, origin=origin, destination=destination, direction=direction,
        train_type=train_type, length_m=float(length), s_m=s, chainage_m=chain,
        vmax_ms=speed_profile.node_values(vint), vmax_interval_ms=vint,
        gradient=dynamics.running_gradient(line.gradients, chain, lt, sg),
        curve_specific=dynamics.curve_specific_resistance(line.curves, chain, lt, sg),
        x0_m=float(x0), direction_sign=sg, train_length_m=lt, settings=settings,
    )
