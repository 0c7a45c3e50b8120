"""A tiny but complete, valid line database written to disk, for tests.

``write_line_db(path, **overrides)`` writes every table of docs/line-database.md into the
folder ``path`` (whose name becomes the ``line_id`` unless ``line`` is
overridden). Override a table with a DataFrame (columns of the schema are
written with their declared types), a ``pyarrow.Table`` (written verbatim, for
wrong-type tests) or ``None`` (the file is not written). ``default_tables()``
returns fresh copies of the default DataFrames to edit. ``quick_job(lines, output_root, ...)``
is the text of a job file that runs such lines end to end in seconds.

The line: chainage 0 … 5000 m, stations A (200 m), B (2500 m), C (4800 m);
two train types EMU10 (constant cruise) and EMU6 (sawtooth); one down and one
up train; a small track network.
"""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from planner.line.schema import SCHEMA_VERSION, TABLES

N = None  # null


def default_tables(line_id: str = "tiny") -> dict[str, pd.DataFrame]:
    """Fresh DataFrames of the default tiny line (railway units, as on disk)."""
    return {
        "line": pd.DataFrame([dict(line_id=line_id, name="Tiny test line", start_m=0.0, end_m=5000.0,
                                   max_speed_kmh=100.0, schema_version=SCHEMA_VERSION)]),
        "stations": pd.DataFrame(
            [("A", "Aoba", 200.0, 260.0, 140.0, 200.0),
             ("B", "Bashi", 2500.0, 2560.0, 2440.0, 200.0),
             ("C", "Chuo", 4800.0, 4860.0, 4740.0, 200.0)],
            columns=["station_id", "name", "position_m", "stop_down_m", "stop_up_m", "platform_length_m"]),
        "gradients": pd.DataFrame(
            [(0.0, 1000.0, 0.0), (1000.0, 2000.0, 5.0), (2500.0, 3500.0, -10.0)],
            columns=["start_m", "end_m", "gradient_permil"]),
        "curves": pd.DataFrame(
            [(1200.0, 1600.0, 600.0), (3000.0, 3400.0, 800.0)],
            columns=["start_m", "end_m", "radius_m"]),
        "speed_limits": pd.DataFrame(
            [(1200.0, 1600.0, 80.0, "both", N, "curve", True),
             (2300.0, 2700.0, 60.0, "down", "EMU6", "turnout", False),
             (4000.0, 4200.0, 70.0, "up", N, "civil", True)],
            columns=["start_m", "end_m", "limit_kmh", "direction", "train_type", "kind", "has_beacon"]),
        "beacons": pd.DataFrame(
            [("B1", 900.0, "down", "signal", "S1:G", True),
             ("B2", 1000.0, "down", "pattern_update", "P80@1200", True),
             ("B3", 4310.0, "up", "tasc", "T550", False),
             ("B4", 2000.0, "up", "other", "", False)],
            columns=["beacon_id", "position_m", "direction", "kind", "telegram", "evaluation_point"]),
        "signals": pd.DataFrame(
            [("SG1", 1000.0, "down"), ("SG2", 3000.0, "up")],
            columns=["signal_id", "position_m", "direction"]),
        "rolling_stock": pd.DataFrame(
            [dict(train_type="EMU10", length_m=200.0, empty_mass_t=320.0, full_load_mass_t=150.0,
                  rotating_mass_factor=0.08, max_speed_kmh=110.0, max_accel_kmh_s=3.0, davis_a_kN=5.0,
                  davis_b_kN_per_kmh=0.036, davis_c_kN_per_kmh2=0.0036, service_brake_kmh_s=3.6,
                  stop_brake_kmh_s=3.9, atsp_pattern_kmh_s=2.9, brake_comfort_kmh_s=3.2,
                  jerk_limit_kmh_s2=7.2, speed_margin_kmh=3.0, cruise="constant", coast_band_kmh=0.0),
             dict(train_type="EMU6", length_m=120.0, empty_mass_t=200.0, full_load_mass_t=90.0,
                  rotating_mass_factor=0.1, max_speed_kmh=100.0, max_accel_kmh_s=2.5, davis_a_kN=3.0,
                  davis_b_kN_per_kmh=0.02, davis_c_kN_per_kmh2=0.002, service_brake_kmh_s=3.5,
                  stop_brake_kmh_s=3.5, atsp_pattern_kmh_s=2.8, brake_comfort_kmh_s=3.0,
                  jerk_limit_kmh_s2=5.0, speed_margin_kmh=2.0, cruise="sawtooth", coast_band_kmh=10.0)]),
        "traction": pd.DataFrame(
            [("EMU10", 0.0, 300.0), ("EMU10", 40.0, 300.0), ("EMU10", 120.0, 100.0),
             ("EMU6", 0.0, 200.0), ("EMU6", 35.0, 200.0), ("EMU6", 100.0, 70.0)],
            columns=["train_type", "speed_kmh", "effort_kN"]),
        "timetable": pd.DataFrame(
            [("101", "EMU10", "down", 0, "A", N, 21600.0, True),
             ("101", "EMU10", "down", 1, "B", 21800.0, 21830.0, True),
             ("101", "EMU10", "down", 2, "C", 22100.0, N, True),
             ("202", "EMU6", "up", 0, "C", N, 22000.0, True),
             ("202", "EMU6", "up", 1, "B", 22200.0, 22200.0, False),
             ("202", "EMU6", "up", 2, "A", 22500.0, N, True)],
            columns=["train_id", "train_type", "direction", "seq", "station_id", "arrival_s",
                     "departure_s", "stops"]),
        "nodes": pd.DataFrame(
            [("N1", "boundary", 0.0, "IXL1", N, "1"),
             ("N2", "stop", 260.0, "IXL1", "A", "1"),
             ("N3", "switch", 1000.0, "IXL1", N, "1"),
             ("N4", "end", 5000.0, "IXL2", N, "1")],
            columns=["node_id", "kind", "position_m", "interlocking", "station_id", "track"]),
        "edges": pd.DataFrame(
            [("E1", "N1", "N2", 260.0, "1"), ("E2", "N2", "N3", 740.0, "1"), ("E3", "N3", "N4", 4000.0, "1")],
            columns=["edge_id", "from_node", "to_node", "length_m", "track"]),
    }


def to_arrow(name: str, df: pd.DataFrame) -> pa.Table:
    """DataFrame → pyarrow table, schema columns with their declared types, extras inferred."""
    schema = TABLES[name].schema if name in TABLES else pa.schema([])
    arrays, fields = [], []
    for c in df.columns:
        typ = schema.field(c).type if c in schema.names else None
        arr = pa.array(df[c].tolist() if typ is not None else df[c], type=typ, from_pandas=True)
        arrays.append(arr)
        fields.append(pa.field(c, arr.type))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def write_line_db(path: str | Path, **overrides) -> Path:
    """Write the tiny valid line DB to folder ``path`` with tables replaced by ``overrides``.

    Parameters
    ----------
    path : str or Path
        Target folder (created); its name is the default ``line_id``.
    **overrides : DataFrame, pyarrow.Table or None
        Per table name (``gradients=...``): replacement content, or None to
        leave the file out. Unknown names are written as extra tables.
    """
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    tables: dict[str, object] = dict(default_tables(path.name))
    tables.update(overrides)
    for name, content in tables.items():
        if content is None:
            continue
        table = content if isinstance(content, pa.Table) else to_arrow(name, content)
        pq.write_table(table, path / f"{name}.parquet")
    return path


QUICK_SECTIONS = """[stops]
adhesion_kmh_s = "2.5:3.5:0.5"
[closed_loop]
modes = ["nearest"]
horizon_s = 6.0
step_s = 3.0
[bundles]
allow_development_key = true
[parallel]
n_jobs = 1
"""
"""Everything but ``[job]`` of :func:`quick_job`: three adhesion levels, a short nearest-mode closed loop,
the development key, one worker process."""


def quick_job(lines: list, output_root: str, **job_keys) -> str:
    """The text of a job file for end-to-end runs of tiny lines: ``[job]`` with ``lines``, ``output_root``
    and ``job_keys`` (e.g. ``keep_runs=3``, ``run_date="2026-01-01"``), then :data:`QUICK_SECTIONS`."""
    keys = {"lines": [str(x) for x in lines], "output_root": str(output_root), **job_keys}
    return "[job]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in keys.items()) + QUICK_SECTIONS
