"""Shared helpers for the bundle tests (no tests here): a small line, synthetic tables, forging.

The forging helpers re-implement the bundle format from its description (ustar
via the standard ``tarfile`` module, canonical JSON manifest, Ed25519 via
``cryptography``) instead of calling the builder, so verify is tested against
an independent writer.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import tarfile

import pyarrow as pa
import pyarrow.parquet as pq

from planner.line import testing
from planner.line.model import Beacon, Call, Train

LINE_ID = "tl"
BUILT_AT_S = 1767225600
"""2026-01-01T00:00:00Z: a fixed build time, so builds in the tests are reproducible."""


def release(version: int = 1, built_at_s: int = BUILT_AT_S, valid_days: float = 3650.0, development: bool = False):
    """A Release for the tests: fixed build time, ten years valid unless said otherwise."""
    from planner.bundle.manifest import Release

    return Release(version, built_at_s, int(valid_days * 86400), development)


def make_line():
    """5 km line, stations at 0/2500/5000 m, restrictions (one pair too close), beacons, two types."""
    e10 = testing.train_type("E10", length_m=100.0, max_speed_kmh=110.0, atsp_pattern_kmh_s=2.5,
                             speed_margin_kmh=3.0)
    e6 = testing.train_type("E6", length_m=60.0, max_speed_kmh=90.0, atsp_pattern_kmh_s=3.0,
                            speed_margin_kmh=2.0)
    ln = testing.line(length_m=5000.0, stations=[0.0, 2500.0, 5000.0], max_speed_kmh=100.0,
                      limits=[(1000.0, 1300.0, 60.0), (1400.0, 1500.0, 45.0), (3000.0, 3200.0, 80.0),
                              (4200.0, 4400.0, 70.0)],
                      train_types=[e10, e6], line_id=LINE_ID)
    limits = tuple(dataclasses.replace(s, has_beacon=(s.row == 2)) for s in ln.speed_limits)
    beacons = (
        Beacon("B1", 500.0, "down", "signal", "S:G", True),
        Beacon("B2", 900.0, "down", "signal", "S:G", False),
        Beacon("B3", 2000.0, "down", "pattern_update", "P80@3000", True),
        Beacon("B4", 3500.0, "down", "signal", "S:Y", True),
        Beacon("U1", 4000.0, "up", "signal", "S:G", True),
        Beacon("U2", 1800.0, "up", "signal", "S:R", True),
    )
    nan = float("nan")
    trains = (
        Train("101", "E10", "down", (Call(0, "S0", nan, 600.0, True), Call(1, "S1", 800.0, 830.0, True),
                                      Call(2, "S2", 1030.0, nan, True))),
        Train("103", "E10", "down", (Call(0, "S0", nan, 300.0, True), Call(1, "S1", 500.0, 500.0, False),
                                      Call(2, "S2", 700.0, nan, True))),
        Train("202", "E6", "up", (Call(0, "S2", nan, 900.0, True), Call(1, "S1", 1100.0, 1130.0, True),
                                   Call(2, "S0", 1330.0, nan, True))),
    )
    return dataclasses.replace(ln, speed_limits=limits, beacons=beacons, trains=trains,
                               source_digest="ab" * 32)


def synthetic_tables(line, direction: str, train_type: str, ratios=(1.0, 0.8, 0.6),
                     pad_rows: int = 0) -> dict[str, pa.Table]:
    """eval_points / table_a / table_b / table_c / table_d / stop_summary / stop_samples with made-up values.

    Columns as the tables step writes them (planner.tables.build), plus the partition
    columns as :func:`planner.bundle.assemble.read_partition` adds them. ``pad_rows``
    adds extra stop_samples rows to make a big bundle.
    """
    pairs = line.interstations(direction)
    beacon_pts = {b.beacon_id: b.position_m for b in line.beacons_for(direction) if b.evaluation_point}
    ep, ta, tb, tc, td = [], [], [], [], []
    for a, b in pairs:
        lo, hi = sorted((a.position_m, b.position_m))
        pts = [("dep", a.position_m, 0.0), ("dep+200", a.position_m + (200 if direction == "down" else -200), 200.0)]
        pts += [(k, p, abs(p - a.position_m)) for k, p in beacon_pts.items() if lo < p < hi]
        for pid, pos, dist in pts:
            ep.append(dict(origin=a.station_id, destination=b.station_id, eval_point_id=pid,
                           eval_position_m=pos, eval_distance_m=dist))
        for r in ratios:
            ta.append(dict(origin=a.station_id, destination=b.station_id, ratio=r,
                           running_time_s=150.0 / r, energy_kwh=10.0 * r))
        for pid, pos, dist in pts:
            for r1 in ratios:
                for r2 in ratios:
                    tb.append(dict(origin=a.station_id, destination=b.station_id, eval_point_id=pid,
                                   eval_position_m=pos, ratio_before=r1, ratio_after=r2,
                                   remaining_time_s=120.0 / r2, elapsed_time_s=dist / (20.0 * r1)))
            for r in ratios:
                tc.append(dict(origin=a.station_id, destination=b.station_id, eval_point_id=pid,
                               eval_position_m=pos, ratio=r, remaining_time_s=120.0 / r,
                               remaining_time_ref_s=125.0 / r, ref_load=1.0, ref_traction_factor=0.9,
                               speed_kmh=60.0 * r))
        pid, pos, _ = pts[-1]
        for v in (0.0, 2.0, 4.0):
            for r in ratios:
                td.append(dict(origin=a.station_id, destination=b.station_id, eval_point_id=pid,
                               eval_position_m=pos, speed_kmh=v, powering=True, ratio_after=r,
                               remaining_time_s=30.0 / r, remaining_time_ref_s=31.0 / r))
    ss = [dict(station_id=b.station_id, origin=a.station_id, adhesion_kmh_s=x, feasible=True, stop_time_s=20.0 + x,
               start_distance_m=300.0 - x) for a, b in pairs for x in (2.5, 3.0, 3.5)]
    sm = [dict(station_id=b.station_id, adhesion_kmh_s=x, t_s=float(k), v_kmh=60.0 - k)
          for _, b in pairs for x in (2.5, 3.5) for k in range(4)]
    sm += [dict(station_id="S1", adhesion_kmh_s=9.0, t_s=float(k), v_kmh=float(k % 97)) for k in range(pad_rows)]
    out = {}
    for name, rows in (("eval_points", ep), ("table_a", ta), ("table_b", tb), ("table_c", tc), ("table_d", td),
                       ("stop_summary", ss),
                       ("stop_samples", sm)):
        t = pa.Table.from_pylist(rows)
        for col, val in (("line", line.line_id), ("direction", direction), ("train_type", train_type)):
            t = t.append_column(col, pa.array([val] * t.num_rows, type=pa.string()))
        out[name] = t
    return out


def all_tables(line, direction="down", train_type="E10", **kw) -> dict[str, pa.Table]:
    from planner.bundle.assemble import line_tables

    return {**line_tables(line, direction, train_type), **synthetic_tables(line, direction, train_type, **kw)}


# --- an independent writer, for forged (validly signed but wrong) bundles ----------
def parquet(t: pa.Table) -> bytes:
    buf = io.BytesIO()
    pq.write_table(t, buf)
    return buf.getvalue()


def manifest_for(files: dict[str, bytes], rows: dict[str, int], *, key, missing=(), **over) -> dict:
    from cryptography.hazmat.primitives import serialization

    raw = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    m = {
        "format": "planner-onboard-db", "schema_version": 2, "line_id": LINE_ID, "direction": "down",
        "train_type": "E10", "software_version": "test", "writer": "test", "line_digest": "",
        "line_schema_version": 1, "key_id": hashlib.sha256(raw).hexdigest(), "key_kind": "production",
        "bundle_version": 1, "built_at": "2026-01-01T00:00:00Z", "expires": "2099-01-01T00:00:00Z",
        "files": [{"name": n, "size": len(d), "sha256": hashlib.sha256(d).hexdigest(), "rows": rows[n]}
                  for n, d in sorted(files.items())],
        "missing": sorted(missing),
    }
    m.update(over)
    return m


def canonical(m) -> bytes:
    return json.dumps(m, sort_keys=True, separators=(",", ":")).encode()


def tar_bytes(members, *, fmt=tarfile.USTAR_FORMAT) -> bytes:
    """A tar from ``(name, data)`` pairs or ``(TarInfo, data)`` pairs, in the given order.

    Written with the standard library's own writer, then normalised to end in
    exactly two zero blocks like the planner's writer does.
    """
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=fmt) as tf:
        for item, data in members:
            info = item if isinstance(item, tarfile.TarInfo) else tarfile.TarInfo(item)
            if data is not None and info.type in (tarfile.REGTYPE, tarfile.AREGTYPE):
                info.size = len(data)
                info.mode = 0o644
                tf.addfile(info, io.BytesIO(data))
            else:
                tf.addfile(info)
    raw = buf.getvalue().rstrip(b"\0")
    raw += b"\0" * (-len(raw) % 512)
    return raw + b"\0" * 1024


def forge(tables: dict[str, pa.Table], key, *, missing=None, sig=None, manifest=None, extra=(),
          drop=(), **over) -> bytes:
    """A bundle from ``tables`` signed with ``key`` by the independent writer."""
    from planner.bundle.manifest import EXPECTED_TABLES

    files = {f"{n}.parquet": parquet(t) for n, t in tables.items()}
    rows = {f"{n}.parquet": t.num_rows for n, t in tables.items()}
    if missing is None:
        missing = [t for t in EXPECTED_TABLES if t not in tables]
    m = manifest if manifest is not None else canonical(manifest_for(files, rows, key=key, missing=missing,
                                                                   **over))
    members = dict(files)
    members["manifest.json"] = m
    members["manifest.sig"] = key.sign(m) if sig is None else sig
    members.update(dict(extra))
    for d in drop:
        members.pop(d)
    return tar_bytes(sorted(members.items()))
