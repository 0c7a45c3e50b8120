"""Tiny made-up lines built in memory, for tests, examples and closed-form checks.

Everything here takes railway units at the edge (km/h, ‰, t, kN, km/h/s), like
the line database does, and converts once.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from planner.line.schema import SCHEMA_VERSION
from planner.line.model import Call, Line, Segments, SpeedLimit, Station, Train, TrainType
from planner.line.units import KMH, KMH_S, KMH_S2, TONNE, KN


def train_type(
    name: str = "T",
    *,
    length_m: float = 100.0,
    empty_mass_t: float = 300.0,
    full_load_mass_t: float = 100.0,
    rotating_mass_factor: float = 0.0,
    max_speed_kmh: float = 120.0,
    max_accel_kmh_s: float = 100.0,
    davis_a_kN: float = 0.0,
    davis_b_kN_per_kmh: float = 0.0,
    davis_c_kN_per_kmh2: float = 0.0,
    service_brake_kmh_s: float = 3.6,
    stop_brake_kmh_s: float = 3.6,
    atsp_pattern_kmh_s: float = 3.0,
    brake_comfort_kmh_s: float = 3.6,
    jerk_limit_kmh_s2: float = 3.6,
    speed_margin_kmh: float = 0.0,
    cruise: str = "constant",
    coast_band_kmh: float = 5.0,
    traction: Sequence[tuple[float, float]] = ((0.0, 300.0), (200.0, 300.0)),
) -> TrainType:
    """A train type from railway units. Defaults: constant 300 kN force, no resistance.

    ``traction`` is a sequence of (speed_kmh, effort_kN) points.
    """
    tr = np.asarray(traction, dtype=float)
    return TrainType(
        train_type=name,
        length_m=length_m,
        empty_mass_kg=empty_mass_t * TONNE,
        full_load_mass_kg=full_load_mass_t * TONNE,
        rotating_mass_factor=rotating_mass_factor,
        max_speed_ms=max_speed_kmh * KMH,
        max_accel_ms2=max_accel_kmh_s * KMH_S,
        davis_a_N=davis_a_kN * KN,
        davis_b_N_per_ms=davis_b_kN_per_kmh * KN / KMH,
        davis_c_N_per_ms2=davis_c_kN_per_kmh2 * KN / KMH**2,
        service_brake_ms2=service_brake_kmh_s * KMH_S,
        stop_brake_ms2=stop_brake_kmh_s * KMH_S,
        atsp_pattern_ms2=atsp_pattern_kmh_s * KMH_S,
        brake_comfort_ms2=brake_comfort_kmh_s * KMH_S,
        jerk_limit_ms3=jerk_limit_kmh_s2 * KMH_S2,
        speed_margin_ms=speed_margin_kmh * KMH,
        cruise=cruise,
        coast_band_ms=coast_band_kmh * KMH,
        traction_speed_ms=tr[:, 0] * KMH,
        traction_effort_N=tr[:, 1] * KN,
    )


def _segments(rows: Sequence[tuple[float, float, float]], scale: float) -> Segments:
    if not rows:
        return Segments.empty()
    a = np.asarray(rows, dtype=float)
    return Segments(a[:, 0].copy(), a[:, 1].copy(), a[:, 2] * scale)


def line(
    *,
    length_m: float = 3000.0,
    stations: Sequence[float] | None = None,
    max_speed_kmh: float | None = 100.0,
    gradients: Sequence[tuple[float, float, float]] = (),
    curves: Sequence[tuple[float, float, float]] = (),
    limits: Sequence[tuple[float, float, float]] = (),
    train_types: Sequence[TrainType] | None = None,
    line_id: str = "test",
) -> Line:
    """A small line in memory.

    Parameters
    ----------
    length_m : float
        Line length [m]; chainage runs 0 … length_m.
    stations : sequence of float, optional
        Stop-marker chainages [m] (the same for both directions); default both ends.
    gradients : sequence of (start_m, end_m, gradient_permil)
    curves : sequence of (start_m, end_m, radius_m)
    limits : sequence of (start_m, end_m, limit_kmh), both directions, all types
    train_types : default ``[train_type()]``
    """
    pos = list(stations) if stations is not None else [0.0, length_m]
    st = tuple(
        Station(f"S{i}", f"Station {i}", p, p, p, 200.0) for i, p in enumerate(pos)
    )
    sl = tuple(
        SpeedLimit(a, b, v * KMH, "both", None, "civil", True, row=i)
        for i, (a, b, v) in enumerate(limits)
    )
    tts = tuple(train_types) if train_types is not None else (train_type(),)
    trains = (
        Train("1", tts[0].train_type, "down", (
            Call(0, st[0].station_id, float("nan"), 0.0, True),
            Call(1, st[-1].station_id, 600.0, float("nan"), True),
        )),
    )
    return Line(
        line_id=line_id,
        name=f"Test line {line_id}",
        start_m=0.0,
        end_m=length_m,
        max_speed_ms=(float("inf") if max_speed_kmh is None else max_speed_kmh) * KMH,  # None: no line maximum
        schema_version=SCHEMA_VERSION,
        stations=st,
        gradients=_segments(gradients, 1e-3),
        curves=_segments(curves, 1.0),
        speed_limits=sl,
        beacons=(),
        signals=(),
        train_types=tts,
        trains=trains,
    )
