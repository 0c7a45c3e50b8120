"""Benchmark: the same planner work in a plain process, in a plain thread, and on a Dask worker's task thread.

The 10x line's cold night costs its Dask workers ~40 % more CPU than joblib's workers for the same units
(``bench_scaling.py --dask``). This isolates where: the run curves of the sample's down interstations
(``planner.network.arrivals.simulate_interstation``, the conflict check's unit of work), ``--passes`` times,
timed inside the task with ``time.thread_time`` (the task thread's own CPU) and ``time.process_time`` (the
whole worker process: its event loop and monitors too). On a cluster started as the README says
(``dask scheduler``; ``dask worker ADDR --nworkers 2 --nthreads 1``) with Dask's defaults, and with the
README's settings (the worker's profiler off, its event loop's monitors slowed: ``bench_scaling.QUIET``).
Part of ``make bench`` (about half a minute: two clusters started and ended).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(ROOT))



def work(passes: int) -> tuple[float, float]:
    """(task-thread CPU, process CPU) of ``passes`` passes over the sample's down interstations [s]."""
    from planner.line.loader import load_line
    from planner.network.arrivals import DEFAULT_RATIOS, simulate_interstation

    line = load_line(ROOT / "lines" / "sample")
    keys = [(t.train_type, a.station_id, b.station_id) for t in line.train_types for a, b in line.interstations("down")]
    simulate_interstation(line, *keys[0], DEFAULT_RATIOS, 10.0)  # imports and first call out of the timing
    p0, t0 = time.process_time(), time.thread_time()
    for _ in range(passes):
        for k in keys:
            simulate_interstation(line, *k, DEFAULT_RATIOS, 10.0)
    return time.thread_time() - t0, time.process_time() - p0


def on_dask(passes: int, quiet: bool) -> tuple[float, float]:
    from bench_scaling import DaskCluster
    from dask.distributed import Client

    cluster = DaskCluster(2, Path(tempfile.mkdtemp(prefix="bench_dask_worker.")), quiet=quiet)
    try:
        with Client(cluster.address) as c:
            return c.submit(work, passes, pure=False).result()
    finally:
        cluster.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--passes", type=int, default=60)
    args = ap.parse_args(argv)
    rows = [("plain process (main thread)", work(args.passes))]
    out: list = []
    th = threading.Thread(target=lambda: out.append(work(args.passes)))
    th.start()
    th.join()
    rows.append(("plain process, another thread", out[0]))
    rows.append(("Dask worker, Dask's defaults", on_dask(args.passes, False)))
    rows.append(("Dask worker, the README's settings", on_dask(args.passes, True)))
    base = rows[0][1][0]
    for name, (thread_s, proc_s) in rows:
        print(f"  {name:44s} task thread {thread_s:6.3f} s ({thread_s / base:4.2f}x)   process {proc_s:6.3f} s",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
