"""The day as it will run: Monte Carlo days on the sample's day and the 10× line's, against mc_dagprop.

Prints, for the sample's operating day (jobs/nightly.toml, 2026-11-30) and the same day of a line ten times
the sample (benchmarks/big_line.py): the network's size, the predicted day's time, the wall time of 10,000
simulated days on all cores (the job's parallel map) and on one, the peak memory of the chunk the
propagation holds, and, when mc_dagprop is installed (`make test` installs it), the same network and
primary delays simulated by mc_dagprop in this process: its time for the same days, and planner / mc_dagprop.

    .venv/bin/python benchmarks/bench_robustness.py [--days 10000] [--no-big]
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from planner import load_line  # noqa: E402
from planner.delay.montecarlo import chunk_days, simulate  # noqa: E402
from planner.delay.predicted import predict_day  # noqa: E402
from planner.job.config import load_job  # noqa: E402
from planner.job.robustness import connections, dwell_rule, rules  # noqa: E402
from planner.network.arrivals import train_curves  # noqa: E402
from planner.network.check import check_timetable  # noqa: E402


def day_network(line_dir: Path, job):
    from planner.job.day import line_on_day

    line = load_line(line_dir)
    try:
        on, _said, lifted = line_on_day(job, line)
    except Exception:  # noqa: BLE001 - a line the job does not plan: its static timetable
        on, lifted = line, {}
    check = check_timetable(on, {}, curves=train_curves(on, lifted, n_jobs=-1))
    t0 = time.perf_counter()
    day = predict_day(check, min_dwell_s=dwell_rule(job), connections=connections(job))
    return day, time.perf_counter() - t0


def measure(name: str, day, rs, days: int) -> None:
    net = day.net
    print(f"{name}: {len(net.train_ids)} trains, {net.n_events} events, {net.n_activities} activities "
          f"({int((net.act_kind == 2).sum())} headways, {net.dropped} left out)")
    cd = chunk_days(net.n_events)
    simulate(net, rs, cd, 1, n_jobs=1)  # the kernel compiled in this process
    for n_jobs in (-1, 1):
        t0 = time.perf_counter()
        st = simulate(net, rs, days, 1, n_jobs=n_jobs)
        wall = time.perf_counter() - t0
        print(f"  {days} days, n_jobs={n_jobs:>2}: {wall:6.2f} s wall "
              f"({wall / days * 1e3:.3f} ms per day); mean arrival delay {st.mean_s[net.ev_kind == 0].mean():.2f} s")
    one = 2 * net.n_events * cd * 8 / 1e6
    print(f"  delays held per chunk of {cd} days: {one:.0f} MB (whole network and each train alone)")
    try:
        from dagprop_peer import dagprop_delays, peer_primary
    except ImportError as e:
        print(f"  mc_dagprop: not available ({e}); `make test` installs it")
        return
    t0 = time.perf_counter()
    simulate(net, rs, days, 1, n_jobs=1)
    ours = time.perf_counter() - t0
    prim = peer_primary(net, rs)
    t0 = time.perf_counter()
    dagprop_delays(net.sched_s, net.act_src, net.act_dst, net.min_s, prim, days, 1)
    theirs = time.perf_counter() - t0
    print(f"  one process, {days} days: planner {ours:.2f} s (with the statistics and each train alone), "
          f"mc_dagprop {theirs:.2f} s; planner / mc_dagprop = {ours / theirs:.2f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--days", type=int, default=10_000)
    ap.add_argument("--no-big", action="store_true", help="the sample only")
    args = ap.parse_args()
    job = load_job(ROOT / "jobs" / "nightly.toml")
    rs = rules(job)
    day, t = day_network(ROOT / "lines" / "sample", job)
    print(f"predicted day of the sample: {t:.2f} s")
    measure("sample 2026-11-30", day, rs, args.days)
    if not args.no_big:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from big_line import build

        with tempfile.TemporaryDirectory() as tmp:
            big = build(10, Path(tmp))
            day, t = day_network(big, job)
            print(f"predicted day of the 10x line: {t:.2f} s")
            measure("10x line", day, rs, args.days)
    return 0


if __name__ == "__main__":
    sys.exit(main())
