"""The target-speed ratio grid (docs/design.md §3).

The on-board logic drives at a target speed ``ratio × maximum speed(x)``. The
tables are computed for a finite set of ratios, from 100 % down until
``ratio × the leg's maximum`` reaches the minimum target speed (20 km/h by
default): the highest on-board maximum of that train on that leg
(:func:`leg_max_speed_ms`: restrictions, line and train maximum, minus the speed
margin), so a 36 km/h train's table stops at 20/36, not at 20 km/h over a
120 km/h line maximum (2.4 km/h).
Low ratios change the running time a lot per step, so the default grid is
coarse at the top and fine at the bottom: 10 % steps from 100 % to 70 %, then
5 % steps.

The floor ratio
---------------
The floor ``r_min = v_target_min / v_leg_max`` is generally not on the 5 %
grid (20/117 = 0.1709). A piece that ends at ``floor`` (as the default does)
*includes* it as its last entry even when the step does not land on it: the
slowest table column is then exactly the slowest running the on-board method
allows, so the range of designated times that can be stretched to is as large
as the method permits, and no column drives below the minimum target speed.
The floor is left out when a grid ratio lies less than ``FLOOR_MERGE`` above
it (a column differing from its neighbour by a rounding error helps nobody).
Ratios below the floor are always dropped, also from explicit lists.

Spec strings
------------
A grid is described by comma-separated ``start:stop:step`` pieces, each running
from ``start`` down to ``stop`` inclusive (``stop`` may be ``floor`` for the
floor ratio), and/or single values: ``"1.0:0.7:0.1,0.7:floor:0.05"`` is the
default, ``"1,0.9,0.75,0.5"`` an explicit list. Ratios below the floor are
dropped (they would drive below the minimum target speed); values are rounded
to ``DECIMALS`` places so that 0.7 from two pieces is one ratio.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from planner.errors import InputError
from planner.line.units import KMH

MIN_TARGET_SPEED_MS = 20.0 * KMH
"""Default minimum target speed [m/s] (20 km/h, docs/design.md §3)."""
DEFAULT_SPEC = "1.0:0.7:0.1,0.7:floor:0.05"
"""Default grid: 10 % steps down to 70 %, then 5 % steps down to the floor."""
DECIMALS = 6
"""Ratios are rounded to this many decimals (1e-6 of the maximum speed is far below any effect)."""
FLOOR_MERGE = 0.005
"""A grid ratio this close above the floor (0.5 % of maximum speed) stands for it."""
MAX_RATIOS = 1000
"""Most ratios one piece may give: each ratio is a column of every table (and a simulation per interstation);
ratios are rounded to 1e-6 anyway, and a grid of 1,000 is 0.1 % of the maximum speed apart."""


def floor_ratio(line_max_speed_ms: float, min_target_speed_ms: float = MIN_TARGET_SPEED_MS) -> float:
    """Lowest ratio allowed: ``min_target_speed / line maximum`` (at most 1).

    Parameters
    ----------
    line_max_speed_ms : float
        Line maximum speed [m/s].
    min_target_speed_ms : float
        Minimum target speed [m/s].

    Examples
    --------
    >>> round(floor_ratio(100 / 3.6), 3)
    0.2
    """
    if not line_max_speed_ms > 0:
        raise InputError(f"line maximum speed must be > 0 m/s, got {line_max_speed_ms}")
    return min(1.0, float(min_target_speed_ms) / float(line_max_speed_ms))


def leg_max_speed_ms(line, train_type: str, origin: str, destination: str) -> float:
    """The highest on-board maximum of ``train_type`` on the leg ``origin`` → ``destination`` [m/s].

    The run curves' own maximum (:func:`planner.physics.track.make_track`: every restriction held
    until the tail clears, the line and the train maximum, minus the speed margin), whose
    ``ratio ×`` is the target speed: the fastest the train is ever driven on the leg.
    """
    from planner.physics.track import SimSettings, make_track

    track = make_track(line, train_type, origin, destination, settings=SimSettings(ds_m=1e9))  # breakpoints only
    return float(np.max(track.vmax_interval_ms))


def leg_ratio_grid(spec, line, train_type: str, origin: str, destination: str,
                   min_target_speed_ms: float = MIN_TARGET_SPEED_MS) -> np.ndarray:
    """:func:`ratio_grid` with the floor of one leg and train: ratio × :func:`leg_max_speed_ms` = the minimum target.

    Examples
    --------
    >>> from planner.line import testing
    >>> slow = testing.train_type(max_speed_kmh=36.0)
    >>> line = testing.line(max_speed_kmh=120.0, train_types=[slow])
    >>> leg_ratio_grid(None, line, "T", "S0", "S1")[-3:].tolist()
    [0.65, 0.6, 0.555556]
    """
    return ratio_grid(spec, line_max_speed_ms=leg_max_speed_ms(line, train_type, origin, destination),
                      min_target_speed_ms=min_target_speed_ms)


def _piece(text: str, floor: float, where: str) -> list[float]:
    parts = text.split(":")
    try:
        if len(parts) == 1:
            return [float(parts[0])]
        if len(parts) != 3:
            raise ValueError
        start = float(parts[0])
        stop = floor if parts[1].strip().lower() == "floor" else float(parts[1])
        step = float(parts[2])
        if parts[1].strip().lower() == "floor" and start < floor and step > 0:
            return [floor]  # the whole piece lies below the floor: only the floor is left of it
    except ValueError:
        raise InputError(
            f"--ratios piece {text!r} in {where!r}: expected 'start:stop:step' or a single ratio, "
            "e.g. '1.0:0.7:0.1,0.7:floor:0.05'"
        ) from None
    if not (step > 0 and start >= stop and math.isfinite(start) and math.isfinite(stop)):
        raise InputError(
            f"--ratios piece {text!r}: needs start >= stop and step > 0 (ratios run downwards), e.g. '1.0:0.7:0.1'"
        )
    if (start - stop) / step + 1 > MAX_RATIOS:
        raise InputError(f"--ratios piece {text!r} gives more than {MAX_RATIOS} ratios; use a larger step")
    n = int(math.floor((start - stop) / step + 1e-9))
    out = [start - i * step for i in range(n + 1)]
    # the stop value itself belongs to the piece even when the step does not land on it exactly
    if out[-1] - stop > 1e-9:
        out.append(stop)
    return out


def ratio_grid(
    spec: str | Sequence[float] | None = None,
    *,
    line_max_speed_ms: float,
    min_target_speed_ms: float = MIN_TARGET_SPEED_MS,
) -> np.ndarray:
    """The ratio grid, sorted from high to low (1.0 first).

    Parameters
    ----------
    spec : str, sequence of float or None
        Spec string (see module doc), an explicit list of ratios, or None for
        :data:`DEFAULT_SPEC`.
    line_max_speed_ms : float
        Line maximum speed [m/s]; with ``min_target_speed_ms`` sets the floor.
    min_target_speed_ms : float
        Minimum target speed [m/s], default 20 km/h.

    Returns
    -------
    ndarray
        Distinct ratios in (0, 1], descending, none below the floor; the floor
        itself is appended when the grid does not reach it (module doc).

    Raises
    ------
    InputError
        A malformed spec, a ratio outside (0, 1], or nothing left above the floor.

    Examples
    --------
    >>> ratio_grid(line_max_speed_ms=100 / 3.6).tolist()
    [1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2]
    """
    floor = floor_ratio(line_max_speed_ms, min_target_speed_ms)
    if spec is None:
        spec = DEFAULT_SPEC
    if isinstance(spec, str):
        if not spec.strip():
            raise InputError("--ratios is empty; give e.g. '1.0:0.7:0.1,0.7:floor:0.05' or '1,0.9,0.8'")
        values: list[float] = []
        for piece in spec.split(","):
            values.extend(_piece(piece.strip(), floor, spec))
    else:
        values = [float(v) for v in spec]
    raw = np.asarray(values, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):  # 1e308 × 10^DECIMALS: refused below by its own value
        arr = np.round(raw, DECIMALS)
    bad = raw[~((arr > 0) & (arr <= 1.0))]
    if bad.size:
        raise InputError(f"--ratios: ratio {bad[0]:g} is outside (0, 1]; ratios are fractions of the maximum speed")
    fl = round(floor, DECIMALS)
    kept = np.unique(arr[arr >= fl - 10.0 ** -DECIMALS])[::-1]
    if kept.size == 0:
        raise InputError(
            f"--ratios: every ratio is below the floor {floor:.4f} "
            f"(minimum target speed / line maximum); give ratios >= {floor:.4f}"
        )
    if kept.size >= 2 and kept[-1] == fl and kept[-2] - fl < FLOOR_MERGE:
        # a grid ratio just above the floor already stands for it
        kept = kept[:-1]
    return kept.copy()
