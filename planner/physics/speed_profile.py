"""On-board maximum-speed profile and braking curves (docs/design.md §2, §3).

Positions here are *running distances* ``s`` [m]: metres from the departure
stop marker, increasing in the running direction, so ``chainage = x0 + σ s``
with σ = +1 for ``down`` and −1 for ``up``.

The profile is built in three steps, as a speed-check device sees it:

1. **on-board maximum** ``V(s)``: min(line maximum, vehicle maximum, every
   restriction that applies to the direction and train type, held from its start
   until the tail clears its end) − the vehicle's speed margin;
2. **target** ``ratio × V(s)``;
3. **ceiling**: the target lowered by the speed-check braking curve at the
   service-brake deceleration ``b`` ahead of every drop,
   ``c²(s) = min_{s' ≥ s} (T²(s') + 2 b (s' − s))``, and by the stopping-brake
   curve onto the arrival marker, ``v² ≤ 2 b_stop (L − s)``.

Braking at constant deceleration is a straight line in (s, v²), which is why
the ceiling is kept squared: it is then exact between grid nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.errors import InfeasibleError
from planner.line.model import Line, TrainType, sign
from planner.line.units import kmh


@dataclass(frozen=True)
class RestrictionSpan:
    """A speed restriction as the train's front sees it, in running distance.

    The front is limited from ``s_from_m`` (entering the restricted stretch)
    until ``s_to_m`` = exit of the stretch + train length (the tail has cleared).
    """

    s_from_m: float
    s_exit_m: float
    s_to_m: float
    limit_ms: float
    row: int
    ident: str = ""
    """The restriction's id (:attr:`planner.line.model.SpeedLimit.ident`)."""


def restriction_spans(line: Line, train: TrainType, direction: str, x0_m: float) -> list[RestrictionSpan]:
    """Restrictions that apply to ``direction`` and ``train``, mapped to running distance.

    A ``down`` train enters a restriction [start_m, end_m] at start_m; an ``up``
    train enters it at end_m and clears it when its front reaches
    start_m − train length.
    """
    sg = sign(direction)
    out = []
    for r in line.limits_for(direction, train.train_type):
        a, b = sg * (r.start_m - x0_m), sg * (r.end_m - x0_m)
        s_from, s_exit = min(a, b), max(a, b)
        out.append(RestrictionSpan(s_from, s_exit, s_exit + train.length_m, r.limit_ms, r.row, r.ident))
    return out


def onboard_max_ms(s_m, spans: list[RestrictionSpan], line_max_ms: float, vehicle_max_ms: float,
                   margin_ms: float) -> np.ndarray:
    """On-board maximum speed at running distances ``s_m`` [m/s].

    ``min(line max, vehicle max, limits of the spans holding s) − margin``. A
    span holds on the closed interval [s_from_m, s_to_m]; evaluate at interval
    midpoints to get the value inside a grid interval.

    Raises
    ------
    InfeasibleError
        Where the margin leaves no positive speed.
    """
    s = np.asarray(s_m, dtype=float)
    v = np.full(s.shape, min(line_max_ms, vehicle_max_ms))
    for sp in spans:
        held = (s >= sp.s_from_m) & (s <= sp.s_to_m)
        v = np.where(held, np.minimum(v, sp.limit_ms), v)
    v = v - margin_ms
    if np.any(v <= 0.0):
        raise InfeasibleError(
            f"speed margin {kmh(margin_ms):.1f} km/h leaves no positive on-board maximum "
            f"(lowest limit {kmh(float(np.min(v + margin_ms))):.1f} km/h); lower speed_margin_kmh "
            "in rolling_stock.parquet or raise the restriction")
    return v


def node_values(interval_values: np.ndarray) -> np.ndarray:
    """Value at each grid node from the values on the intervals around it (the lower one).

    A speed at a node is the end of one interval and the start of the next, so it
    must respect both limits: at a restriction's start the low limit already
    holds, at its (held) end it still holds.
    """
    iv = np.asarray(interval_values, dtype=float)
    out = np.empty(iv.shape[:-1] + (iv.shape[-1] + 1,))
    out[..., 0] = iv[..., 0]
    out[..., -1] = iv[..., -1]
    out[..., 1:-1] = np.minimum(iv[..., :-1], iv[..., 1:])
    return out


def braking_ceiling_sq(s_m: np.ndarray, target_ms: np.ndarray, brake_ms2: float, axis: int = -1) -> np.ndarray:
    """Speed-check ceiling squared [m²/s²]: the target lowered by braking curves to every drop ahead.

    ``c²(s_k) = min_{j ≥ k} (T²(s_j) + 2 b (s_j − s_k))`` — the backward recursion
    ``c²_k = min(T²_k, c²_{k+1} + 2 b Δs)`` written as a reverse cumulative
    minimum, so it vectorises over many targets (one per ratio) at once.

    Parameters
    ----------
    s_m : ndarray
        Grid nodes [m], increasing along ``axis``, broadcastable to ``target_ms``.
    target_ms : ndarray
        Target speed at each node [m/s]; nodes along ``axis``.
    brake_ms2 : float
        Service-brake deceleration [m/s²], > 0.
    axis : int
        The node axis.

    Examples
    --------
    >>> import numpy as np
    >>> braking_ceiling_sq(np.array([0., 10., 20.]), np.array([10., 10., 0.]), 1.0).tolist()
    [40.0, 20.0, 0.0]
    """
    lin = 2.0 * brake_ms2 * np.asarray(s_m, dtype=float)
    key = np.square(target_ms) + lin
    rev = np.flip(key, axis=axis)
    env = np.flip(np.minimum.accumulate(rev, axis=axis), axis=axis)
    return env - lin


def stop_curve_sq(s_m: np.ndarray, length_m: float, stop_brake_ms2: float) -> np.ndarray:
    """Stopping-brake curve squared onto the arrival marker: ``2 b_stop (L − s)`` [m²/s²]."""
    return 2.0 * stop_brake_ms2 * np.maximum(length_m - np.asarray(s_m, dtype=float), 0.0)


def ceiling_sq(s_m: np.ndarray, target_ms: np.ndarray, brake_ms2: float, length_m: float,
               stop_brake_ms2: float, axis: int = -1) -> np.ndarray:
    """The full ceiling squared: braking curves to lower targets ahead and the station stop."""
    return np.minimum(braking_ceiling_sq(s_m, target_ms, brake_ms2, axis=axis),
                      stop_curve_sq(s_m, length_m, stop_brake_ms2))
