"""ATS-P data for the on-board DB: DB-fed speed-check patterns and beacon-match flags.

Pure functions on numpy arrays (no pandas, no I/O); docs/design.md §3 "ATS-P data in
the on-board DB".

Positions here are *running coordinates* ``s = sign(direction) × chainage``
[m], which increase in the running direction for both ``down`` and ``up``; use
:func:`to_running` / :func:`to_chainage` at the edges.

**Pattern start.** Only some restrictions have a ground beacon that sends their
ATS-P speed-check pattern. For the others the on-board logic feeds the same
telegram to the ATS-P unit, early enough that a train approaching at the top
speed ``v_high`` and braking at the ATS-P pattern deceleration ``b`` reaches the
restriction speed ``v_low`` exactly at the restriction start. Under constant
deceleration, v² = v_high² − 2 b x, so the pattern must begin

    d = (v_high² − v_low²) / (2 b)                                   (1)

before the restriction (zero when v_low ≥ v_high: no pattern is needed).

**Overwrite.** The on-board ATS-P unit holds one speed-restriction pattern; a
new telegram replaces the one it holds. A pattern fed at ``feed_i`` must stay
held until ``until_i`` (at least the restriction start; the bundle uses the
point where the train's tail has left the restriction). A telegram ``j`` fed
at ``feed_j`` with ``feed_i ≤ feed_j < until_i`` (``j ≠ i``) overwrites ``i``: the
two restrictions are too close together for DB-fed patterns.

**Beacon matching.** The vehicle recognises the beacon it has just passed by
comparing the received telegram with the one the DB says comes next. In a run
of two or more consecutive beacons (running order) with identical telegrams a
missed beacon cannot be detected, so none of them may correct the position.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np


def to_running(chainage_m, direction: str):
    """Running coordinate s = sign(direction) × chainage [m] (grows in the running direction)."""
    return _sign(direction) * np.asarray(chainage_m, dtype=float)


def to_chainage(s_m, direction: str):
    """Inverse of :func:`to_running`: chainage [m] from running coordinate [m]."""
    return _sign(direction) * np.asarray(s_m, dtype=float)


def _sign(direction: str) -> float:
    if direction == "down":
        return 1.0
    if direction == "up":
        return -1.0
    raise ValueError(f"direction must be 'down' or 'up', not {direction!r}")


def pattern_distance_m(v_high_ms, v_low_ms, decel_ms2):
    """Distance before the restriction at which the ATS-P pattern must begin [m].

    Parameters
    ----------
    v_high_ms : float or ndarray
        Highest speed a train can approach with [m/s] (line/vehicle maximum).
    v_low_ms : float or ndarray
        Restriction speed to be reached at the restriction start [m/s].
    decel_ms2 : float or ndarray
        ATS-P pattern deceleration of the vehicle [m/s²], > 0.

    Returns
    -------
    float or ndarray
        d = max(v_high² − v_low², 0) / (2 b) [m], equation (1) of the module
        docstring (constant-deceleration kinematics).
    """
    v_high = np.asarray(v_high_ms, dtype=float)
    v_low = np.asarray(v_low_ms, dtype=float)
    b = np.asarray(decel_ms2, dtype=float)
    if np.any(~(b > 0)):
        raise ValueError("ATS-P pattern deceleration must be > 0")
    d = np.maximum(v_high**2 - v_low**2, 0.0) / (2.0 * b)
    return d if d.ndim else float(d)


def overwrite_conflicts(feed_s_m, until_s_m, active=None) -> tuple[np.ndarray, np.ndarray]:
    """Which telegrams would overwrite a pattern the ATS-P unit must still hold.

    Parameters
    ----------
    feed_s_m : ndarray (n,)
        Running coordinate where each restriction's telegram is fed [m].
    until_s_m : ndarray (n,)
        Running coordinate until which each pattern must be held [m].
    active : ndarray of bool (n,), optional
        Restrictions that have a pattern at all (default: all). Inactive ones
        neither overwrite nor are overwritten.

    Returns
    -------
    overwrites : ndarray of int (n,)
        For each j, the index i of the pattern its telegram overwrites
        (``feed_i ≤ feed_j < until_i``, i ≠ j; the most recently fed such i), or −1.
    conflict : ndarray of bool (n,)
        True for every restriction that overwrites or is overwritten.
    """
    feed = np.asarray(feed_s_m, dtype=float)
    until = np.asarray(until_s_m, dtype=float)
    n = feed.shape[0]
    act = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    # hit[i, j]: telegram j arrives while pattern i must still be held.
    hit = (feed[:, None] <= feed[None, :]) & (feed[None, :] < until[:, None])
    hit &= act[:, None] & act[None, :]
    np.fill_diagonal(hit, False)
    overwrites = np.full(n, -1, dtype=np.int64)
    for j in np.flatnonzero(hit.any(axis=0)):
        cand = np.flatnonzero(hit[:, j])
        # The pattern held at feed_j is the one fed last before it; ties go to the lower index.
        overwrites[j] = cand[np.lexsort((cand, -feed[cand]))[0]]
    conflict = hit.any(axis=0) | hit.any(axis=1)
    return overwrites, conflict


def correction_usable(telegrams: Sequence[str]) -> np.ndarray:
    """Flag beacons whose telegram identifies them unambiguously.

    Parameters
    ----------
    telegrams : sequence of str
        Telegrams of one direction's beacons, in running order.

    Returns
    -------
    ndarray of bool
        False for every beacon in a run of ≥ 2 consecutive beacons with
        identical telegrams, True otherwise.
    """
    t = list(telegrams)
    n = len(t)
    same_as_next = np.array([t[i] == t[i + 1] for i in range(n - 1)], dtype=bool)
    usable = np.ones(n, dtype=bool)
    if n > 1:
        usable[:-1] &= ~same_as_next
        usable[1:] &= ~same_as_next
    return usable


def restriction_telegram(limit_kmh: float, distance_m: float, hold_m: float) -> str:
    """The speed-restriction telegram the on-board logic feeds to the ATS-P unit.

    Format ``P{limit:03d}D{distance:05d}L{hold:05d}``: restriction speed [km/h],
    distance from the feed point to the restriction start [m], length over
    which the speed must be held [m] (restriction length + train length). The
    speed and distance are rounded *down* and the length *up*, so the check
    the unit makes is never looser than the restriction.
    """
    if not (limit_kmh > 0 and distance_m >= 0 and hold_m >= 0):
        raise ValueError(f"bad telegram values: limit {limit_kmh} km/h, distance {distance_m} m, hold {hold_m} m")
    # The epsilons keep exact integers (e.g. 40.000000000000006 km/h after a round
    # trip through m/s) from flipping to the neighbour when rounded.
    v = math.floor(limit_kmh + 1e-9)
    d = math.floor(distance_m + 1e-9)
    h = math.ceil(hold_m - 1e-9)
    return f"P{v:03d}D{d:05d}L{h:05d}"
