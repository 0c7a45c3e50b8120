"""Load a line database folder into the SI domain model.

:func:`load_line` reads every table of schema v1 (:mod:`planner.line.schema`) with
pyarrow, validates all of them (:mod:`planner.line.validate`), converts railway
units to SI exactly once, and returns frozen dataclasses of
:mod:`planner.line.model`. No DataFrame leaves this module.

Unit conversions (the only place they happen for line data):

======================  ================  ======================
column                  factor            SI field
======================  ================  ======================
``*_kmh``               ÷ 3.6             m/s
``*_kmh_s``             ÷ 3.6             m/s²
``jerk_limit_kmh_s2``   ÷ 3.6             m/s³
``*_t``                 × 1000            kg
``*_kN``                × 1000            N
``davis_b_kN_per_kmh``  × 1000 × 3.6      N/(m/s)
``davis_c_kN_per_kmh2`` × 1000 × 3.6²     N/(m/s)²
``gradient_permil``     × 1e-3            rise per metre
======================  ================  ======================

The Davis factors follow from R = B·v_kmh = B·3.6·v_ms: a coefficient per
km/h is 3.6 times larger per m/s (3.6² for the quadratic term).
"""
from __future__ import annotations

import dataclasses

import hashlib
import math
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from planner.errors import InputError, LineValidationError, Violation
from planner.io.parquet import read_file
from planner.line.model import (
    Beacon,
    Call,
    Edge,
    Line,
    Network,
    Node,
    Segments,
    Signal,
    SpeedLimit,
    Station,
    Train,
    TrainType,
)
from planner.line.schema import TABLES
from planner.line.units import KMH, KMH_S, KMH_S2, KN, PERMIL, TONNE
from planner.line.validate import check_tables
from planner.line.conform import TableView


def source_digest(line_dir: str | Path) -> str:
    """SHA-256 over the ``*.parquet`` files of a line folder, as hex.

    Files are taken in sorted name order; for each, the UTF-8 name, a NUL byte,
    the byte length as 8-byte big-endian and the bytes are hashed, so that no
    two different folders share a byte stream. Other files (README, build
    script) do not count: they do not change what is loaded.
    """
    h = hashlib.sha256()
    for f in sorted(Path(line_dir).glob("*.parquet"), key=lambda p: p.name):
        if not f.is_file():
            continue
        data = f.read_bytes()
        h.update(f.name.encode("utf-8") + b"\0" + len(data).to_bytes(8, "big"))
        h.update(data)
    return h.hexdigest()


def read_tables(line_dir: Path) -> dict[str, pa.Table | Violation | None]:
    """Read each schema table: the table, a Violation if unreadable, None if absent."""
    raw: dict[str, pa.Table | Violation | None] = {}
    for name, spec in TABLES.items():
        f = line_dir / spec.file
        if not f.exists():
            raw[name] = None
        elif not f.is_file():
            raw[name] = Violation(spec.file, None, None, "is not a file; expected one Parquet file")
        else:
            try:
                raw[name] = read_file(f)
            except (pa.ArrowException, OSError, ValueError) as e:
                # pyarrow prefixes the absolute path; the message already names the file
                why = str(e).splitlines()[0] if str(e) else type(e).__name__
                why = re.sub(r"^Could not open Parquet input source '[^']*': ", "", why).replace(str(f), spec.file)
                raw[name] = Violation(spec.file, None, None, f"is not a readable Parquet file ({why})")
    return raw


def _line_dir(path: str | Path) -> Path:
    line_dir = Path(path)
    if not line_dir.is_dir():
        what = "is not a folder" if line_dir.exists() else "does not exist"
        raise InputError(f"line database {str(path)!r} {what}; give the folder that holds line.parquet")
    return line_dir


def check_line(path: str | Path) -> list[Violation]:
    """Every violation in the line database at ``path`` (empty list = valid)."""
    from planner.line.upgrade import upgrade_tables

    line_dir = _line_dir(path)
    _, violations = check_tables(line_dir.resolve().name, upgrade_tables(read_tables(line_dir))[0])
    return violations


def load_line(path: str | Path, warnings: list[Violation] | None = None) -> Line:
    """Load, validate and convert the line database folder ``path``.

    Parameters
    ----------
    path : str or Path
        Folder with the Parquet tables of docs/line-database.md; any name (the line id
        is ``line.parquet``'s ``line_id``).
    warnings : list, optional
        When given, findings that are legitimate on some railways (a train
        longer than its platform) are appended to it; they never refuse the line.

    Returns
    -------
    Line
        The line in SI units, with ``source_digest`` (see :func:`source_digest`)
        and ``source_path`` set.

    Raises
    ------
    InputError
        ``path`` is not a folder.
    LineValidationError
        The database breaks any rule; ``.violations`` lists all of them.

    Examples
    --------
    >>> line = load_line("lines/sample")             # doctest: +SKIP
    >>> line.train_type("EMU10").stop_brake_ms2      # doctest: +SKIP
    1.0833333333333333
    """
    from planner.line.upgrade import upgrade_tables

    line_dir = _line_dir(path)
    raw, upgraded = upgrade_tables(read_tables(line_dir))  # an earlier schema read as the current one
    views, violations = check_tables(line_dir.resolve().name, raw, warnings)
    if violations:
        raise LineValidationError(str(path), violations)
    line = _build(views, source_digest(line_dir), str(path))
    return dataclasses.replace(line, upgrade_notes=tuple(upgraded)) if upgraded else line


# --------------------------------------------------------------------------- model building
def _f(x) -> float:
    return float(x)


def _opt_float(x) -> float | None:
    return None if x is None or (isinstance(x, float) and np.isnan(x)) else float(x)


def _opt_str(x) -> str | None:
    return None if x is None else str(x)


def _segments(t: TableView, value_col: str, scale: float) -> Segments:
    if t.n == 0:
        return Segments.empty()
    return Segments(
        np.array(t["start_m"], dtype=float),
        np.array(t["end_m"], dtype=float),
        np.array(t[value_col], dtype=float) * scale,
    )


def _train_types(rs: TableView, tr: TableView) -> tuple[TrainType, ...]:
    out = []
    for i in range(rs.n):
        name = rs["train_type"][i]
        rows = [j for j in range(tr.n) if tr["train_type"][j] == name]
        rows.sort(key=lambda j: tr["speed_kmh"][j])
        out.append(TrainType(
            train_type=name,
            length_m=_f(rs["length_m"][i]),
            empty_mass_kg=_f(rs["empty_mass_t"][i]) * TONNE,
            full_load_mass_kg=_f(rs["full_load_mass_t"][i]) * TONNE,
            rotating_mass_factor=_f(rs["rotating_mass_factor"][i]),
            max_speed_ms=_f(rs["max_speed_kmh"][i]) * KMH,
            max_accel_ms2=_f(rs["max_accel_kmh_s"][i]) * KMH_S,
            davis_a_N=_f(rs["davis_a_kN"][i]) * KN,
            davis_b_N_per_ms=_f(rs["davis_b_kN_per_kmh"][i]) * KN / KMH,
            davis_c_N_per_ms2=_f(rs["davis_c_kN_per_kmh2"][i]) * KN / KMH**2,
            service_brake_ms2=_f(rs["service_brake_kmh_s"][i]) * KMH_S,
            stop_brake_ms2=_f(rs["stop_brake_kmh_s"][i]) * KMH_S,
            atsp_pattern_ms2=_f(rs["atsp_pattern_kmh_s"][i]) * KMH_S,
            brake_comfort_ms2=_f(rs["brake_comfort_kmh_s"][i]) * KMH_S,
            jerk_limit_ms3=_f(rs["jerk_limit_kmh_s2"][i]) * KMH_S2,
            speed_margin_ms=_f(rs["speed_margin_kmh"][i]) * KMH,
            cruise=str(rs["cruise"][i]),
            coast_band_ms=_f(rs["coast_band_kmh"][i]) * KMH,
            traction_speed_ms=np.array([tr["speed_kmh"][j] for j in rows], dtype=float) * KMH,
            traction_effort_N=np.array([tr["effort_kN"][j] for j in rows], dtype=float) * KN,
        ))
    return tuple(out)


def _trains(t: TableView) -> tuple[Train, ...]:
    """Trains in order of first appearance in the file, calls in seq order."""
    # the columns as Python lists, read once (indexing the arrays cell by cell was half of the 1.6 s this took on a
    # timetable of 427,200 calls); the same values: the object columns' own objects, the float columns' floats
    train_id, seq, station, arr, dep, stops = (t[c].tolist() for c in ("train_id", "seq", "station_id", "arrival_s",
                                                                       "departure_s", "stops"))
    rows_of: dict[str, list[int]] = {}
    for i, x in enumerate(train_id):
        rows_of.setdefault(x, []).append(i)
    out = []
    for tid, rows in rows_of.items():
        rows.sort(key=seq.__getitem__)
        calls = tuple(Call(int(seq[j]), str(station[j]), _f(arr[j]), _f(dep[j]), bool(stops[j])) for j in rows)
        out.append(Train(tid, str(t["train_type"][rows[0]]), str(t["direction"][rows[0]]), calls))
    return tuple(out)


def _network(views: dict[str, TableView]) -> Network | None:
    if "nodes" not in views or "edges" not in views:
        return None
    n, e = views["nodes"], views["edges"]
    nodes = tuple(
        Node(str(n["node_id"][i]), str(n["kind"][i]), _f(n["position_m"][i]), str(n["interlocking"][i]),
             station_id=_opt_str(n["station_id"][i]) if n.has("station_id") else None,
             track=_opt_str(n["track"][i]) if n.has("track") else None)
        for i in range(n.n)
    )
    edges = tuple(
        Edge(str(e["edge_id"][i]), str(e["from_node"][i]), str(e["to_node"][i]), _f(e["length_m"][i]),
             str(e["track"][i]), direction=_opt_str(e["direction"][i]) if e.has("direction") else None)
        for i in range(e.n)
    )
    return Network(nodes, edges)


def _build(views: dict[str, TableView], digest: str, source_path: str) -> Line:
    ln, st = views["line"], views["stations"]
    stations = tuple(
        Station(str(st["station_id"][i]), str(st["name"][i]), _f(st["position_m"][i]),
                _f(st["stop_down_m"][i]), _f(st["stop_up_m"][i]), _f(st["platform_length_m"][i]))
        for i in range(st.n)
    )
    sl = views["speed_limits"]
    limits = tuple(
        SpeedLimit(_f(sl["start_m"][i]), _f(sl["end_m"][i]), _f(sl["limit_kmh"][i]) * KMH,
                   str(sl["direction"][i]), _opt_str(sl["train_type"][i]), str(sl["kind"][i]),
                   bool(sl["has_beacon"][i]), row=i)
        for i in range(sl.n)
    )
    b = views["beacons"]
    beacons = tuple(
        Beacon(str(b["beacon_id"][i]), _f(b["position_m"][i]), str(b["direction"][i]), str(b["kind"][i]),
               str(b["telegram"][i]), bool(b["evaluation_point"][i]))
        for i in range(b.n)
    )
    sg = views.get("signals")
    signals = () if sg is None else tuple(
        Signal(str(sg["signal_id"][i]), _f(sg["position_m"][i]), str(sg["direction"][i]))
        for i in range(sg.n)
    )
    return Line(
        line_id=str(ln["line_id"][0]),
        name=str(ln["name"][0]),
        start_m=_f(ln["start_m"][0]),
        end_m=_f(ln["end_m"][0]),
        max_speed_ms=(_opt_float(ln["max_speed_kmh"][0]) or math.inf) * KMH,  # null: no line maximum
        schema_version=int(ln["schema_version"][0]),
        approach_m=_opt_float(ln["approach_m"][0]) if ln.has("approach_m") else None,
        running_side=_opt_str(ln["running_side"][0]) if ln.has("running_side") else None,
        stations=stations,
        gradients=_segments(views["gradients"], "gradient_permil", PERMIL),
        curves=_segments(views["curves"], "radius_m", 1.0),
        speed_limits=limits,
        beacons=beacons,
        signals=signals,
        train_types=_train_types(views["rolling_stock"], views["traction"]),
        trains=_trains(views["timetable"]),
        network=_network(views),
        source_digest=digest,
        source_path=source_path,
    )
