"""Make a line database N times the sample line, with a proportionate timetable (issue 20).

Run ``.venv/bin/python benchmarks/big_line.py --copies 10 --out DIR``: writes the line
database folder ``DIR/sample-x10`` (its ``line_id``) and prints its path. Used by
``benchmarks/bench_scaling.py``; never committed (a generated output).

The big line is ``N`` copies of ``lines/sample`` laid end to end along the chainage,
``GAP_M`` of plain level track between one copy's end buffer and the next copy's
start (so the terminus of one copy and the origin of the next are an ordinary
interstation of ``GAP_M`` + 400 m, longer than the 550 m stop approach). Every
table is the sample's table repeated with the chainage shifted by
``k * (L + GAP_M)``; every id (stations, beacons, signals, nodes, edges,
interlockings, trains) takes the suffix ``-kNN`` of its copy, so ids stay unique and
path-safe (``[A-Za-z0-9._-]``), and station and signal ids inside beacon telegrams
follow. The track network is joined: the two buffer stops at each junction become
``boundary`` nodes linked by a ``GAP_M`` edge per main track.

Timetable: every sample train once per copy (id suffix ``-kNN``), calling at that copy's
stations at its sample times, so the big line has ``N`` times the trains, calls, legs and
route conflicts of the sample, and each copy's traffic is the sample's, crossing for
crossing. No train runs over a junction. (An earlier version ran every sample train
through all copies with one period; that shifted the up trains against the down trains
differently in each copy and gave 3,346 conflicts on 10 copies for the sample's 16: not
a proportionate timetable.)
"""
from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "lines" / "sample"
GAP_M = 2_000.0  # plain track between one copy's end buffer and the next copy's start buffer
GAP_RUN_S = 180.0  # scheduled run from one copy's terminus to the next copy's origin (2.4 km)
DWELL_S = 30.0  # dwell where a terminus became an ordinary stop
PATH_ID = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,63}")


def _sfx(k: int) -> str:
    return f"-k{k:02d}"


def _read(name: str) -> tuple[pd.DataFrame, pa.Schema]:
    t = pq.read_table(SAMPLE / f"{name}.parquet")
    return t.to_pandas(), t.schema


def _rename(values: pd.Series, k: int) -> pd.Series:
    return values.map(lambda s: None if s is None or (isinstance(s, float) and math.isnan(s)) else f"{s}{_sfx(k)}")


def _copies(name: str, n: int, offset_m: float, shift: tuple[str, ...], ids: tuple[str, ...]) -> pd.DataFrame:
    """The sample table ``name`` repeated ``n`` times, columns ``shift`` moved by ``k * offset_m``,
    columns ``ids`` renamed with the copy's suffix."""
    df, _ = _read(name)
    parts = []
    for k in range(n):
        c = df.copy()
        for col in shift:
            c[col] = c[col] + k * offset_m
        for col in ids:
            c[col] = _rename(c[col], k)
        parts.append(c)
    return pd.concat(parts, ignore_index=True)


def _telegrams(beacons: pd.DataFrame, n: int, stations: set[str], signals: set[str]) -> pd.Series:
    """Station and signal ids inside each telegram (fields between ':') renamed like the tables."""
    per_copy = len(beacons) // n
    out = []
    for row, tel in enumerate(beacons["telegram"]):
        k = row // per_copy
        fields = [f"{f}{_sfx(k)}" if f in stations or f in signals else f for f in tel.split(":")]
        out.append(":".join(fields))
    return pd.Series(out, index=beacons.index)


def _network(n: int, offset_m: float, L: float) -> tuple[pd.DataFrame, pd.DataFrame]:
    nodes = _copies("nodes", n, offset_m, ("position_m",), ("node_id", "interlocking", "station_id"))
    edges = _copies("edges", n, offset_m, (), ("edge_id", "from_node", "to_node"))
    base, _ = _read("nodes")
    ends = base[base["kind"] == "end"]
    first = ends[ends["position_m"] == ends["position_m"].min()]
    last = ends[ends["position_m"] == ends["position_m"].max()]
    joins = []
    for k in range(n - 1):
        for track in sorted(set(first["track"]) & set(last["track"])):
            a = f"{last[last['track'] == track]['node_id'].iloc[0]}{_sfx(k)}"
            b = f"{first[first['track'] == track]['node_id'].iloc[0]}{_sfx(k + 1)}"
            nodes.loc[nodes["node_id"].isin([a, b]), "kind"] = "boundary"
            joins.append({"edge_id": f"JOIN-{track}{_sfx(k)}", "from_node": a, "to_node": b,
                          "length_m": offset_m - L, "track": track})
    return nodes, pd.concat([edges, pd.DataFrame(joins)], ignore_index=True)


def _timetable(n: int) -> pd.DataFrame:
    """Every sample train once per copy, in that copy only, at its sample times (module docstring)."""
    tt, _ = _read("timetable")
    out = []
    for k in range(n):
        c = tt.copy()
        c["train_id"] = _rename(c["train_id"], k)
        c["station_id"] = _rename(c["station_id"], k)
        out.append(c)
    return pd.concat(out, ignore_index=True).sort_values(["train_id", "seq"], ignore_index=True)


def build(copies: int, out_dir: Path) -> Path:
    """Write the big line database ``out_dir / f"sample-x{copies}"`` (replaced whole) and return it."""
    if copies < 1:
        raise SystemExit(f"--copies must be >= 1, got {copies}")
    line, line_schema = _read("line")
    L = float(line["end_m"].iloc[0] - line["start_m"].iloc[0])
    off = L + GAP_M
    line_id = f"sample-x{copies}"
    if not PATH_ID.fullmatch(line_id):
        raise SystemExit(f"line id {line_id!r} is not path-safe")
    tables: dict[str, pd.DataFrame] = {}
    big = line.copy()
    big["line_id"] = line_id
    big["name"] = f"{line['name'].iloc[0]} x{copies}"
    big["end_m"] = line["start_m"].iloc[0] + copies * L + (copies - 1) * GAP_M
    tables["line"] = big
    tables["stations"] = _copies("stations", copies, off, ("position_m", "stop_down_m", "stop_up_m"),
                                 ("station_id",))
    tables["stations"]["name"] = [f"{nm} {i // (len(tables['stations']) // copies) + 1}"
                                  for i, nm in enumerate(tables["stations"]["name"])]
    for name in ("gradients", "curves", "speed_limits"):
        tables[name] = _copies(name, copies, off, ("start_m", "end_m"), ())
    tables["signals"] = _copies("signals", copies, off, ("position_m",), ("signal_id",))
    tables["beacons"] = _copies("beacons", copies, off, ("position_m",), ("beacon_id",))
    stations, _ = _read("stations")
    signals, _ = _read("signals")
    tables["beacons"]["telegram"] = _telegrams(tables["beacons"], copies, set(stations["station_id"]),
                                               set(signals["signal_id"]))
    tables["rolling_stock"], _ = _read("rolling_stock")
    tables["traction"], _ = _read("traction")
    tables["nodes"], tables["edges"] = _network(copies, off, L)
    tables["timetable"] = _timetable(copies)
    for col in ("station_id", "beacon_id", "signal_id", "node_id", "edge_id", "train_id"):
        for t in tables.values():
            if col in t and not t[col].dropna().map(lambda s: bool(PATH_ID.fullmatch(s))).all():
                raise SystemExit(f"an id in column {col} is not path-safe")
    out_dir.mkdir(parents=True, exist_ok=True)
    final = out_dir / line_id
    tmp = Path(tempfile.mkdtemp(prefix=f".{line_id}.", dir=out_dir))
    try:
        for name, df in tables.items():
            schema = pq.read_schema(SAMPLE / f"{name}.parquet")
            pq.write_table(pa.Table.from_pandas(df[schema.names], schema=schema, preserve_index=False),
                           tmp / f"{name}.parquet")
        if final.exists():
            shutil.rmtree(final)
        os.replace(tmp, final)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)
    return final


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=10, help="how many sample lines end to end (default 10)")
    ap.add_argument("--out", type=Path, required=True, help="folder to write the line database folder into")
    args = ap.parse_args(argv)
    print(build(args.copies, args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
