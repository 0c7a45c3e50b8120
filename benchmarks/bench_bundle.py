"""Benchmark: on-board DB bundles for the sample line, per direction x train type.

Builds every bundle of ``lines/sample`` with a throw-away key and prints, per
bundle, its size, the build time (assembling the tables, Parquet encoding,
signing, atomic write) and the verify time (structure, signature, hashes,
schema, consistency), plus the tables each holds and the ones it misses.

The running-time tables and stopping patterns are computed first with
``planner.tables.build`` and ``planner.stopping.sweep`` (not timed; ``--tables DIR`` /
``--stops DIR`` reuse existing output folders instead, ``--no-tables`` /
``--no-stops`` leave them out).

Run: ``.venv/bin/python benchmarks/bench_bundle.py``
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.bundle.assemble import assemble  # noqa: E402
from planner.bundle.container import build_bundle  # noqa: E402
from planner.bundle.manifest import Release  # noqa: E402
from planner.bundle.verify import verify_bundle  # noqa: E402
from planner.bundle import signing  # noqa: E402


def _tables_dir(line, args, scratch: Path) -> Path | None:
    if args.tables:
        return Path(args.tables)
    if args.no_tables:
        return None
    try:
        from planner.tables.build import build_tables
        from planner.datasets.tables import write_tables
    except ImportError as e:
        print(f"  running-time tables: not available ({e})")
        return None
    t0 = time.perf_counter()
    write_tables(build_tables(line), scratch / "tables")
    print(f"  running-time tables computed for the benchmark in {time.perf_counter() - t0:.1f} s (not counted)")
    return scratch / "tables"


def _stops_dir(line, args, scratch: Path) -> Path | None:
    if args.stops:
        return Path(args.stops)
    if args.no_stops:
        return None
    try:
        from planner.stopping.sweep import stop_sweep
        from planner.datasets.stops import write_stops
    except ImportError as e:
        print(f"  stopping patterns: not available ({e})")
        return None
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:  # infeasible approaches: counted, not listed
        warnings.simplefilter("always")
        write_stops(stop_sweep(line), scratch / "stops")
    print(f"  stopping patterns computed for the benchmark in {time.perf_counter() - t0:.1f} s (not counted; "
          f"{len(caught)} approach x adhesion cases infeasible)")
    return scratch / "stops"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tables", help="existing output folder of `planner tables`")
    ap.add_argument("--stops", help="existing output folder of the stopping-pattern step")
    ap.add_argument("--no-tables", action="store_true", help="build without running-time tables")
    ap.add_argument("--no-stops", action="store_true", help="build without stopping patterns")
    ap.add_argument("--repeat", type=int, default=5, help="verify repetitions (the best is reported)")
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    print(f"bench_bundle: line {line.line_id}, {len(line.speed_limits)} restrictions, "
          f"{len(line.beacons)} beacons, {len(line.trains)} trains")
    with tempfile.TemporaryDirectory() as d:
        scratch = Path(d)
        priv, pub = signing.generate_keypair(scratch / "keys")
        key, pubkey = signing.load_private_key(priv), signing.load_public_key(pub)
        release = Release.issue()  # built now, valid 30 days: verify below accepts it
        tables_dir = _tables_dir(line, args, scratch)
        stops_dir = _stops_dir(line, args, scratch)
        rows = []
        for direction in ("down", "up"):
            for tt in (t.train_type for t in line.train_types):
                t0 = time.perf_counter()
                tables = assemble(line, direction, tt, tables_dir=tables_dir, stops_dir=stops_dir)
                t1 = time.perf_counter()
                info = build_bundle(tables, line_id=line.line_id, direction=direction, train_type=tt,
                                    out_dir=scratch / "out", private_key=key,
                                    line_digest=line.source_digest, release=release,
                                    line_schema_version=line.schema_version)
                t2 = time.perf_counter()
                best = float("inf")
                for _ in range(max(args.repeat, 1)):
                    v0 = time.perf_counter()
                    verify_bundle(info.path, pubkey)
                    best = min(best, time.perf_counter() - v0)
                rows.append((direction, tt, info, t1 - t0, t2 - t1, best))
        print(f"  {'bundle':<22} {'bytes':>10} {'assemble s':>11} {'build s':>8} {'verify s':>9}  tables (rows)")
        for direction, tt, info, ta, tb, tv in rows:
            held = ", ".join(f"{f.name.removesuffix('.parquet')}({f.rows})" for f in info.files)
            print(f"  {Path(info.path).name:<22} {info.size_bytes:>10} {ta:>11.3f} {tb:>8.3f} {tv:>9.3f}  {held}")
        print("  per train type (both directions):")
        for tt in sorted({r[1] for r in rows}):
            sel = [r for r in rows if r[1] == tt]
            print(f"    {tt:<6} {sum(r[2].size_bytes for r in sel):>10} bytes, build {sum(r[4] for r in sel):.3f} s, "
                  f"verify {sum(r[5] for r in sel):.3f} s")
        missing = sorted({m for r in rows for m in r[2].missing})
        print(f"  missing tables: {', '.join(missing) if missing else 'none'}")
        try:
            print(f"  load average during run: {os.getloadavg()[0]:.1f}")
        except OSError:
            pass


if __name__ == "__main__":
    main()
