"""Evaluation points: where the on-board logic re-evaluates the remaining time (docs/design.md §3).

There are two kinds of points: points the vehicle finds by its **odometer**
(running distance since the departure stop marker, corrected at beacons) and
**beacons** whose position it knows exactly. Per interstation and direction
the points are, in running order:

* ``dep`` (kind ``departure``) — the departure (running distance 0, the
  origin's stop marker);
* ``dep+200`` (kind ``after_departure``) — a point shortly after departure
  (200 m by default, configurable; left out when the interstation is not
  longer than that);
* ``dep+<s>`` (kind ``interval``) — with an interval I (``[tables]
  eval_interval_m``; default none, i.e. beacons only), points at a regular
  interval after the point after departure, at running distance
  ``s_k = a + k·I`` (k = 1, 2, … while s_k is short of the arrival stop marker; a
  is the distance of the point after departure, 0 when there is none). This is
  the published method's choice: it gives the logic authority closer to the
  stop than the last block signal;
* every beacon read in that direction and flagged ``evaluation_point`` (kind
  ``beacon``), strictly between the two stations' stop markers, under its
  ``beacon_id``. Block lengths of 550–1,000 m give their spacing.

A leg with **no** beacon evaluation point (a line without ATS-P beacons, an
imported line) would have nothing after ``dep+200``: on a 60 km leg the
nearest rule then misses the designated arrival by up to the whole sweep
(60 s). Without an interval of its own, such a leg gets interval points at
the *fill interval* (``fill_interval_m``): the tables choose it from the
train's speed, the distance run in ``[tables] eval_auto_s`` seconds (30 s by
default) at the leg's on-board maximum (:func:`auto_interval_m`), about the
spacing the sample line's beacons have (14–35 s at its maximum). A leg with
beacons keeps exactly its beacons. The nightly job and the commands
(``planner tables --eval-auto``, ``planner margins``) fill by default; the
library functions only when given ``eval_auto_s`` / ``fill_interval_m``.

The vehicle evaluates at a point when its odometer passes it. The simulator
takes the odometer as exact (no position error is modelled): an odometer point
is exactly where its running distance says, like a beacon.

Positions are given twice: ``s_m``, the running distance from the departure
stop marker (what the simulator integrates over), and ``position_m``, the
chainage (what the line database and the vehicle's beacon list use):
``position_m = stop_origin + sign(direction) · s_m``.

Two points at the same running distance would be the same decision twice; the
later one in the order above is dropped (a beacon exactly 200 m after the
departure replaces nothing and is not listed twice, nor does an interval point
on a beacon). The points do not depend on the train type; the datasets still
carry it because tables are per type.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from planner.errors import InputError
from planner.line.model import Line

DEFAULT_AFTER_DEPARTURE_M = 200.0
"""Default distance of the point after departure [m] (docs/design.md §3)."""
DEFAULT_INTERVAL_M = None
"""Default interval of the odometer points: none (beacons only, as before issue 22)."""
DEFAULT_AUTO_S = 30.0
"""The nightly job's default fill interval in seconds of running at the leg's maximum (``[tables]
eval_auto_s``): the sample line's beacons stand 14–35 s apart at its maximum, and on a 60 km
beacon-less leg 30 s (about 1 km at 130 km/h) brings the nearest rule's worst arrival error from
60 s to 1.5–2 s (``benchmarks/bench_eval_auto.py``)."""
AUTO_ROUND_M = 10.0
"""The fill interval is rounded to this [m], so the points' ids stay short (``dep+1290``)."""
MIN_INTERVAL_M = 50.0
"""Smallest interval accepted [m]. Each point costs n_r² rows of table (b) (and a decision on
board); a point every 50 m is already finer than the vehicle's odometer knows its position
between beacons, and a smaller value is almost surely a unit mistake (km for m)."""
SAME_POINT_M = 1e-6
"""Points closer than this [m] are one point (far below any grid step)."""
KINDS = ("departure", "after_departure", "interval", "beacon")
"""Kinds of evaluation point; the order is the precedence when two fall on the same place."""


@dataclass(frozen=True)
class EvalPoint:
    """One evaluation point of an interstation in one direction.

    Attributes
    ----------
    eval_point_id : str
        ``dep``, ``dep+<metres>`` (odometer points) or the beacon id.
    s_m : float
        Running distance from the departure stop marker [m], 0 ≤ s < length.
    position_m : float
        Chainage [m].
    kind : str
        One of :data:`KINDS`: ``departure``, ``after_departure``, ``interval`` (odometer
        points) or ``beacon``.
    """

    eval_point_id: str
    s_m: float
    position_m: float
    kind: str = "beacon"


def odometer_id(s_m: float) -> str:
    """Id of an odometer point at running distance ``s_m``: ``dep+<metres>``, to the millimetre.

    Examples
    --------
    >>> odometer_id(200.0), odometer_id(1450.25), odometer_id(123456.0)
    ('dep+200', 'dep+1450.25', 'dep+123456')
    """
    txt = f"{float(s_m):.3f}".rstrip("0").rstrip(".")
    return f"dep+{txt}"


def interstation_length_m(line: Line, origin: str, destination: str) -> float:
    """Running distance from the origin's stop marker to the destination's [m]."""
    return line.run_between(origin, destination).length_m


def check_interval(interval_m: float | None, where: str = "--eval-interval") -> float | None:
    """The interval as a float, None for none (None or 0); InputError naming ``where`` otherwise."""
    if interval_m is None or interval_m == 0:
        return None
    x = float(interval_m)
    if not math.isfinite(x) or x < MIN_INTERVAL_M:
        raise InputError(f"{where} must be 0 (beacons only) or at least {MIN_INTERVAL_M:g} m, got {interval_m}")
    return x


def check_auto(seconds: float | None, where: str = "--eval-auto") -> float | None:
    """The fill interval's seconds as a float, None for none (None or 0); InputError naming ``where`` otherwise."""
    if seconds is None or seconds == 0:
        return None
    x = float(seconds)
    if not (math.isfinite(x) and x > 0):
        raise InputError(f"{where} must be 0 (no fill) or a number of seconds > 0, got {seconds}")
    return x


def auto_interval_m(vmax_ms: float, seconds: float | None) -> float | None:
    """Fill interval [m]: the distance run in ``seconds`` at ``vmax_ms``, rounded to :data:`AUTO_ROUND_M`,
    at least :data:`MIN_INTERVAL_M`; None when ``seconds`` is None or 0.

    Examples
    --------
    >>> auto_interval_m(130 / 3.6, 30.0), auto_interval_m(1.0, 30.0), auto_interval_m(30.0, None)
    (1080.0, 50.0, None)
    """
    s = check_auto(seconds)
    if s is None:
        return None
    return max(MIN_INTERVAL_M, round(s * float(vmax_ms) / AUTO_ROUND_M) * AUTO_ROUND_M)


def interval_distances(length_m: float, interval_m: float | None,
                       after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M) -> list[float]:
    """Running distances of the interval points: ``a + k·I`` for k = 1, 2, … short of ``length_m`` [m].

    ``a`` is the point after departure (0 when there is none, or when it lies beyond the
    interstation).

    Examples
    --------
    >>> interval_distances(1800.0, 500.0)
    [700.0, 1200.0, 1700.0]
    >>> interval_distances(1000.0, 500.0, None)
    [500.0]
    """
    iv = check_interval(interval_m)
    if iv is None:
        return []
    a = float(after_departure_m or 0.0)
    if a >= length_m:
        a = 0.0
    n = math.ceil((length_m - a) / iv) - 1  # largest k with a + k·I < length
    return [a + k * iv for k in range(1, n + 1) if a + k * iv < length_m]


def evaluation_points(
    line: Line,
    origin: str,
    destination: str,
    *,
    after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M,
    interval_m: float | None = DEFAULT_INTERVAL_M,
    fill_interval_m: float | None = None,
) -> tuple[EvalPoint, ...]:
    """Evaluation points of one interstation, in running order.

    Parameters
    ----------
    line : Line
        The line.
    origin, destination : str
        Station ids; the direction follows from their chainages.
    after_departure_m : float or None
        Distance of the point after departure [m]; None or 0 leaves it out.
    interval_m : float or None
        Interval of the odometer points after the point after departure [m]; None or 0:
        none (departure, point after departure and beacons only).
    fill_interval_m : float or None
        Interval of the odometer points on a leg that has no beacon evaluation point and no
        ``interval_m`` [m] (module doc); None: none.

    Returns
    -------
    tuple of EvalPoint
        Sorted by ``s_m``; the first is always ``dep`` at s = 0.

    Raises
    ------
    InputError
        A negative ``after_departure_m``, an ``interval_m`` below :data:`MIN_INTERVAL_M`, or an
        interstation whose stop markers do not follow the running direction.

    Examples
    --------
    >>> from planner.line import testing
    >>> [p.eval_point_id for p in evaluation_points(testing.line(), "S0", "S1")]
    ['dep', 'dep+200']
    >>> [p.eval_point_id for p in evaluation_points(testing.line(), "S0", "S1", interval_m=1000)]
    ['dep', 'dep+200', 'dep+1200', 'dep+2200']
    >>> [p.eval_point_id for p in evaluation_points(testing.line(), "S0", "S1", fill_interval_m=1500)]
    ['dep', 'dep+200', 'dep+1700']
    """
    ext = line.run_between(origin, destination)
    d, sg, stop0, length = ext.direction, ext.sign, ext.start_m, ext.length_m
    if not length > 0:
        raise InputError(
            f"interstation {origin}->{destination} ({d}): stop markers do not follow the running direction "
            f"(length {length:.1f} m); fix stop_{d}_m in stations.parquet"
        )
    pts = [EvalPoint("dep", 0.0, stop0, "departure")]
    after = None
    if after_departure_m is not None and after_departure_m != 0:
        if after_departure_m < 0:
            raise InputError(f"--after-departure must be >= 0 m, got {after_departure_m}")
        if after_departure_m < length:
            after = float(after_departure_m)
            pts.append(EvalPoint(odometer_id(after), after, stop0 + sg * after, "after_departure"))
    beacons = []
    for b in line.beacons_on(ext):
        if not b.evaluation_point:
            continue
        if b.beacon_id == "dep" or b.beacon_id.startswith("dep+"):
            raise InputError(f"beacons.parquet: beacon_id {b.beacon_id!r} is flagged evaluation_point but "
                             "'dep' and 'dep+<m>' name the odometer evaluation points; rename the beacon")
        s = sg * (b.position_m - stop0)
        if 0.0 < s < length:
            beacons.append(EvalPoint(b.beacon_id, float(s), float(b.position_m), "beacon"))
    if check_interval(interval_m) is None and not beacons:
        interval_m = fill_interval_m  # no beacon and no interval: the fill interval (module doc)
    for s in interval_distances(length, interval_m, after):
        pts.append(EvalPoint(odometer_id(s), s, stop0 + sg * s, "interval"))
    pts += beacons
    pts.sort(key=lambda p: p.s_m)  # stable: odometer points before a beacon at the same place
    out: list[EvalPoint] = []
    for p in pts:
        if out and p.s_m - out[-1].s_m < SAME_POINT_M:
            continue
        out.append(p)
    return tuple(out)


def train_evaluation_points(
    line: Line,
    train_type: str,
    origin: str,
    destination: str,
    *,
    after_departure_m: float | None = DEFAULT_AFTER_DEPARTURE_M,
    interval_m: float | None = DEFAULT_INTERVAL_M,
    auto_s: float | None = None,
    settings=None,
) -> tuple[EvalPoint, ...]:
    """:func:`evaluation_points` of one train type, with the fill interval from its speed.

    On a leg without beacon evaluation points and without ``interval_m``, the fill interval is
    :func:`auto_interval_m` of ``auto_s`` seconds at the leg's on-board maximum for the train
    (the highest speed of its maximum-speed profile, :func:`planner.physics.track.make_track`).
    """
    pts = evaluation_points(line, origin, destination, after_departure_m=after_departure_m, interval_m=interval_m)
    if check_auto(auto_s) is None or check_interval(interval_m) is not None or any(p.kind == "beacon" for p in pts):
        return pts
    from planner.physics.track import SimSettings, make_track

    vmax = float(max(make_track(line, train_type, origin, destination, settings=settings or SimSettings()).vmax_ms))
    return evaluation_points(line, origin, destination, after_departure_m=after_departure_m, interval_m=interval_m,
                             fill_interval_m=auto_interval_m(vmax, auto_s))
