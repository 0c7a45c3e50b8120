"""Benchmark and check: two operating days of the sample, one without temporary restrictions and one with.

Runs the sample job (``jobs/nightly.toml``, into a scratch output root) for a day with no temporary
restriction in force (default Tuesday 2026-11-17: weekday service) and then, on the same cache, for a day
with three (Monday 2026-11-30: the same trains), then the second day again on an empty cache. Prints:

* the units each run computed and reused, and the wall time of the incremental run against the cold one;
* which interstation units each restriction reaches, found independently of the job (the restriction's
  stretch against :meth:`Line.window_m` of every interstation, for its direction and train type), and
  that every other unit's rows are byte-identical between the two days (the run's id and date columns
  dropped, Arrow IPC bytes compared per unit);
* per reached leg, the minimum running time (table (a), ratio 1.0) of both days and its rise against a
  closed form for the speed dip (a lower bound): braking from v1 to v2 at the service brake, the
  restricted length + train length at v2, accelerating back at no more than the maximum acceleration
  (+ g x the steepest fall of the line), where v1 is the lowest speed the unrestricted minimum-time run
  has around the restriction and v2 the restriction's on-board maximum.

Run: ``.venv/bin/python benchmarks/bench_day.py [--quiet-day D] [--busy-day D] [--out DIR]``
"""
from __future__ import annotations

import argparse
import hashlib
import re
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402
import pyarrow as pa  # noqa: E402
import pyarrow.compute as pc  # noqa: E402

from planner.api import running_time  # noqa: E402
from planner.io.parquet import RUN_FIELDS, read_dataset  # noqa: E402
from planner.job.config import load_job  # noqa: E402
from planner.job.day import day_inputs, day_line, with_day  # noqa: E402
from planner.job.pipeline import run_job  # noqa: E402
from planner.line.loader import load_line  # noqa: E402
from planner.line.model import DIRECTIONS, G  # noqa: E402
from planner.line.operating_day import reaches  # noqa: E402

UNIT_KEYS = ("direction", "train_type", "origin", "destination")


def job_file(scratch: Path, out: Path) -> Path:
    """The sample job with absolute paths and its output root in ``out``."""
    text = (ROOT / "jobs" / "nightly.toml").read_text()
    text = re.sub(r'^lines = \[.*?\]', f'lines = ["{ROOT / "lines" / "sample"}"]', text, flags=re.M)
    text = re.sub(r'^output_root = ".*?"', f'output_root = "{out}"', text, flags=re.M)
    text = re.sub(r'^feeds = \[.*?\]', f'feeds = ["{ROOT / "feeds" / "sample"}"]', text, flags=re.M)
    (scratch / "jobs").mkdir(parents=True, exist_ok=True)
    p = scratch / "jobs" / "job.toml"
    p.write_text(text)
    return p


def timed_run(job, day):
    t0 = time.perf_counter()
    s = run_job(with_day(job, day), show_progress=False)
    return s, time.perf_counter() - t0


def reached_units(line, restrictions) -> dict:
    """(type, direction, origin, destination) → restriction ids whose stretch reaches the unit's window."""
    out = {}
    for t in line.train_types:
        for d in DIRECTIONS:
            for a, b in line.interstations(d):
                lo, hi = line.window_m(a.station_id, b.station_id, t.train_type)
                hit = [r.restriction_id for r in restrictions
                       if reaches(r, d, t.train_type) and r.end_m > lo and r.start_m < hi]
                if hit:
                    out[(t.train_type, d, a.station_id, b.station_id)] = hit
    return out


def unit_bytes(run_dir: Path, dataset: str) -> dict:
    """Per unit (direction, type, origin, destination), SHA-256 of its rows as Arrow IPC (run columns dropped)."""
    t = read_dataset(run_dir, dataset)
    t = t.drop_columns([c for c, _, _ in RUN_FIELDS if c in t.column_names])
    if "destination" not in t.column_names and "station_id" in t.column_names:  # a stop: the unit's arrival
        t = t.rename_columns(["destination" if c == "station_id" else c for c in t.column_names])
    keys = [k for k in UNIT_KEYS if k in t.column_names and k != "origin"]
    if len(keys) < 3:
        return {}
    out = {}
    cols = [t.column(k).to_pylist() for k in keys]
    groups: dict = {}
    for i, k in enumerate(zip(*cols)):
        groups.setdefault(k, []).append(i)
    for k, idx in groups.items():
        part = t.take(pa.array(idx))
        sink = pa.BufferOutputStream()
        with pa.ipc.new_stream(sink, part.schema) as w:
            w.write_table(part)
        d, tt, de = k
        out[(tt, d, de)] = hashlib.sha256(sink.getvalue().to_pybytes()).hexdigest()
    return out


def min_times(run_dir: Path) -> dict:
    t = read_dataset(run_dir, "table_a")
    t = t.filter(pc.equal(t.column("ratio"), 1.0))
    return {(r["train_type"], r["direction"], r["origin"], r["destination"]): r["running_time_s"]
            for r in t.select(["train_type", "direction", "origin", "destination", "running_time_s"]).to_pylist()}


def dip_bound(static, line_day, r, tt: str, o: str, d: str) -> tuple[float, float]:
    """Closed-form lower bound of the time lost to restriction ``r`` on leg o→d, and v1 [km/h]."""
    train = static.train_type(tt)
    v2 = r.limit_ms - train.speed_margin_ms
    b = train.service_brake_ms2
    a = train.max_accel_ms2 + G * max(0.0, float(np.max(np.abs(static.gradients.value), initial=0.0)))
    base = running_time(static, tt, o, d).curve
    vmax = min(static.max_speed_ms, train.max_speed_ms)
    lo = r.start_m - train.length_m - vmax ** 2 / (2 * a) - 5
    hi = r.end_m + train.length_m + vmax ** 2 / (2 * a) + 5
    x, v = base["position_m"].to_numpy(), base["speed_kmh"].to_numpy() / 3.6
    inside = (x >= max(lo, min(x))) & (x <= min(hi, max(x)))
    # clipped to the leg: the part of the restriction the leg runs, its own stretch only
    a_m, b_m = max(r.start_m, min(x)), min(r.end_m, max(x))
    v1 = float(v[inside].min()) if inside.any() else 0.0
    if v1 <= v2 or b_m <= a_m:
        return 0.0, v1 * 3.6
    held = (b_m - a_m) + train.length_m
    # the held stretch is inside the leg only up to the arrival marker
    held = min(held, abs(x[-1] - (a_m if d_sign(static, o, d) > 0 else b_m)))
    loss = held * (1 / v2 - 1 / v1) + (v1 - v2) ** 2 / (2 * v1) / b
    if abs(x[-1] - (b_m if d_sign(static, o, d) > 0 else a_m)) > train.length_m + v1 ** 2 / (2 * a):
        loss += (v1 - v2) ** 2 / (2 * v1) / a  # room to accelerate back before the arrival braking
    return loss, v1 * 3.6


def stretch_bound(static, r, tt: str, o: str, d: str) -> float:
    """Lower bound without the closed form's premise: over the held stretch (restriction + train length,
    within the leg) the restricted run is at most v2 and the unrestricted one runs its own curve, so the
    loss is at least the integral of max(0, 1/v2 - 1/v_unrestricted) there."""
    train = static.train_type(tt)
    v2 = r.limit_ms - train.speed_margin_ms
    c = running_time(static, tt, o, d).curve
    x, v = c["position_m"].to_numpy(), c["speed_kmh"].to_numpy() / 3.6
    sg = d_sign(static, o, d)
    entry, clear = (r.start_m, r.end_m + train.length_m) if sg > 0 else (r.end_m, r.start_m - train.length_m)
    s = sg * (x - x[0])
    s_in, s_out = sg * (entry - x[0]), sg * (clear - x[0])
    m = (s >= s_in) & (s <= s_out) & (v > 0)
    if m.sum() < 2:
        return 0.0
    f = np.maximum(0.0, 1 / v2 - 1 / v[m])
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(s[m])))


def d_sign(line, o, d) -> int:
    return 1 if line.direction_between(o, d) == "down" else -1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quiet-day", default="2026-11-17")
    ap.add_argument("--busy-day", default="2026-11-30")
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    scratch = Path(args.out or tempfile.mkdtemp(prefix="bench_day_"))
    job = load_job(job_file(scratch, scratch / "out"))
    cold_job = load_job(job_file(scratch / "cold", scratch / "cold" / "out"))

    quiet, t_quiet = timed_run(job, args.quiet_day)
    busy, t_busy = timed_run(job, args.busy_day)
    cold, t_cold = timed_run(cold_job, args.busy_day)
    print(f"{args.quiet_day} (cold cache): {t_quiet:.1f} s, computed {quiet.computed}")
    print(f"{args.busy_day} (incremental): {t_busy:.1f} s, computed {busy.computed}, reused {busy.reused}")
    print(f"{args.busy_day} (cold cache):  {t_cold:.1f} s, computed {cold.computed}")

    static = load_line(ROOT / "lines" / "sample")
    din = day_inputs(with_day(job, args.busy_day), static)
    assert not day_inputs(with_day(job, args.quiet_day), static).restrictions, "the quiet day has restrictions"
    reached = reached_units(static, din.restrictions)
    n_units = sum(len(static.interstations(d)) for d in DIRECTIONS) * len(static.train_types)
    print(f"restrictions in force on {args.busy_day}: {', '.join(r.restriction_id for r in din.restrictions)}; "
          f"they reach {len(reached)} of {n_units} interstation units (independent count); the job recomputed "
          f"{busy.computed.get('tables', 0)} tables units")

    for ds in ("table_a", "table_b", "table_c", "table_d", "eval_points", "stop_summary", "stop_samples",
               "closed_loop"):
        if not (quiet.run_dir / ds).is_dir():
            continue
        a, b = unit_bytes(quiet.run_dir, ds), unit_bytes(busy.run_dir, ds)
        if not a:
            print(f"  {ds}: no per-unit columns, not compared")
            continue
        changed = {k for k in set(a) | set(b) if a.get(k) != b.get(k)}
        stray = sorted(changed - {(t, d, de) for t, d, _, de in reached})
        print(f"  {ds}: {len(a)} units, {len(changed)} differ, all of them reached: {not stray}"
              + (f"; UNREACHED BUT CHANGED: {stray[:3]}" if stray else ""))

    mq, mb = min_times(quiet.run_dir), min_times(busy.run_dir)
    day = day_line(static, din)
    by_id = {r.restriction_id: r for r in din.restrictions}
    print("leg (type dir o->d) | restriction | v1 -> v2 km/h | min quiet s | min busy s | rise s | closed form s | "
          "stretch bound s | ok")
    bad = 0
    for k, ids in sorted(reached.items()):
        tt, d, o, de = k
        rise = mb[k] - mq[k]
        bound = stretch = 0.0
        v1s = []
        for rid in ids:
            lb, v1 = dip_bound(static, day, by_id[rid], tt, o, de)
            bound += lb
            stretch += stretch_bound(static, by_id[rid], tt, o, de)
            v1s.append(f"{v1:.0f}->{by_id[rid].limit_ms * 3.6 - static.train_type(tt).speed_margin_ms * 3.6:.0f}")
        ok = rise >= max(bound, stretch) - 1e-6
        bad += not ok
        print(f"{tt} {d} {o}->{de} | {','.join(ids)} | {' '.join(v1s)} | {mq[k]:.1f} | {mb[k]:.1f} | {rise:.1f} | "
              f"{bound:.1f} | {stretch:.1f} | {'yes' if ok else 'NO'}")
    same = [k for k in mq if k not in reached and mq[k] != mb.get(k)]
    print(f"unreached legs with another minimum: {len(same)}; reached legs below the closed form: {bad}")


if __name__ == "__main__":
    main()
