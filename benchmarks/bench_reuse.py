"""Benchmark: exact reuse of identical runs (planner.physics.reuse), tables and closed loop of the sample.

The nightly job's tables step on the sample line (jobs/nightly.toml's [tables] settings, every
leg, direction and train type) in this one process, with reuse off and on in alternating pairs
(CPU time of the process, ``time.process_time``: the machine is shared, wall time says little),
then the same for the closed loop step (its [closed_loop] modes and scenarios on those tables).
Each pair's results are compared: every table dataset written to Parquet must be the same bytes,
and every closed-loop array the same bits; a difference fails the benchmark.

Run: ``.venv/bin/python benchmarks/bench_reuse.py [--pairs N]``
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.datasets.tables import write_tables  # noqa: E402
from planner.job.config import load_job  # noqa: E402
from planner.line.model import DIRECTIONS  # noqa: E402
from planner.line.units import KMH  # noqa: E402
from planner.physics import reuse  # noqa: E402
from planner.physics.track import SimSettings  # noqa: E402
from planner.tables.build import interstation_tables  # noqa: E402
from planner.tables.closed_loop import Scenario, closed_loop_batch  # noqa: E402
from planner.tables.ratios import leg_ratio_grid  # noqa: E402


def tables_step(line, job):
    """The nightly job's tables step on ``line`` in this one process: every leg, direction and train type, with
    ``job``'s [tables] settings (also :func:`bench_scaling.machine_cpu_s`'s work)."""
    tp = job.tables
    tasks = [(t.train_type, d, a.station_id, b.station_id) for t in line.train_types for d in DIRECTIONS
             for a, b in line.interstations(d)]
    return [interstation_tables(line, tt, o, d, leg_ratio_grid(tp.ratios, line, tt, o, d, tp.min_target_kmh * KMH),
                                after_departure_m=tp.eval_offset_m, eval_interval_m=tp.eval_interval_m or None,
                                settings=SimSettings(ds_m=tp.ds_m), eval_auto_s=tp.eval_auto_s or None)
            for tt, _, o, d in tasks]


def _closed_loop(line, job, tables):
    cl = job.closed_loop
    scs = [Scenario(s.name, s.load, s.traction) for s in cl.scenarios]
    return [closed_loop_batch(line, t.train_type, t.onboard(), scenarios=scs, modes=list(cl.modes),
                              extra_s=cl.horizon_s, step_s=cl.step_s, settings=SimSettings(ds_m=job.tables.ds_m))
            for t in tables]


def _parquet(results) -> dict:
    with tempfile.TemporaryDirectory() as d:
        return {Path(p).relative_to(d): Path(p).read_bytes() for p in write_tables(results, d)}


def _bits(x):
    if isinstance(x, np.ndarray):
        return [x.dtype.str, x.shape, x.tobytes()]
    if dataclasses.is_dataclass(x):
        return [_bits(getattr(x, f.name)) for f in dataclasses.fields(x)]
    if isinstance(x, (list, tuple)):
        return [_bits(y) for y in x]
    if isinstance(x, dict):
        return [(k, _bits(x[k])) for k in sorted(x, key=repr)]
    return repr(x)


def _timed(on: bool, fn, *args):
    reuse.ENABLED = on
    c0 = time.process_time()
    out = fn(*args)
    return time.process_time() - c0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3)
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    job = load_job(ROOT / "jobs" / "nightly.toml")
    tables_step(line, job)  # warm up: imports, kernels loaded
    cpu = {"tables": {False: [], True: []}, "closed loop": {False: [], True: []}}
    for i in range(args.pairs):
        for on in ((False, True) if i % 2 == 0 else (True, False)):
            c, tabs = _timed(on, tables_step, line, job)
            cpu["tables"][on].append(c)
            files = _parquet(tabs)
            c, loops = _timed(on, _closed_loop, line, job, tabs)
            cpu["closed loop"][on].append(c)
            if on:
                got = (files, _bits(loops))
            else:
                ref = (files, _bits(loops))
        if got[0] != ref[0]:
            raise SystemExit(f"bench_reuse: table Parquet files differ: "
                             f"{sorted(str(k) for k in ref[0] if got[0].get(k) != ref[0][k])[:5]}")
        if got[1] != ref[1]:
            raise SystemExit("bench_reuse: closed-loop results differ with reuse")
    print(f"bench_reuse: sample line, {len(tabs)} legs x directions x train types, one process, CPU time "
          f"(process_time), {args.pairs} alternating pairs; {len(ref[0])} table Parquet files byte-identical "
          "in every pair, closed-loop results bit-identical")
    for step, d in cpu.items():
        off, on = np.array(d[False]), np.array(d[True])
        print(f"  {step:12s} off {', '.join(f'{x:.2f}' for x in off)} s | on {', '.join(f'{x:.2f}' for x in on)} s"
              f" | median on/off {np.median(on) / np.median(off):.2f}")


if __name__ == "__main__":
    main()
