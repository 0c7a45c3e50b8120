"""Benchmark: the nightly job on the sample line and on a line N times its size, cold and after one edit.

Builds the big line (:mod:`big_line`: N copies of the sample end to end, a proportionate
timetable) in a temporary folder and runs ``planner run`` on the nightly job
(``jobs/nightly.toml`` with ``lines`` and ``output_root`` changed, and no daily feed: the
feeds name the sample's own trains and stations) for

* the sample, cold (empty output root, so no cache);
* the big line, cold;
* the big line again after one speed restriction edit (``speed_limits.parquet``: the
  first limit of the middle copy lowered by 10 km/h), reusing the cold run's cache: the
  incremental night.

Each run is its own process tree (the planner and its workers), measured from outside:
wall time; CPU time of the whole tree (user + system, ``RUSAGE_CHILDREN``: the machine is
shared, CPU time is the figure to compare); peak memory, twice: the largest single
process (``ru_maxrss``) and the peak of the tree's summed resident memory, sampled every
0.2 s with psutil (shared pages counted once per process, so an upper bound). Per run it
prints the job's step times (its manifest's ``timings_s``: wall, beside-running steps
overlap) and the CPU time and peak memory of the main process and of the workers.

Targets (issue 38), cold, big line against sample: time ratio <= 0.8 x N, peak memory
ratio <= 2. Copies: ``--copies N`` or ``$PLANNER_BENCH_COPIES`` (default 10, what
``make bench`` runs); the network-sized night is ``PLANNER_BENCH_COPIES=100`` (opt-in:
about ten times as long). ``--no-sample`` skips the sample's run, ``--keep DIR`` keeps
lines, outputs and logs. ``--verify-edit`` also runs the edited line cold in a fresh output root and
compares the datasets and the bundles' members with the edit night's. ``--dask`` also runs the big line's cold
night on a Dask cluster started here as a
user starts one (``dask scheduler``; ``dask worker ADDRESS --nworkers 2 --nthreads 1``) and prints its wall
and CPU against joblib's, and whether the published datasets are the same (issue 48: within 15 %).

Each night also prints what its process tree read from and wrote to the disk (not the page cache: the rusage
block counts). An edit night reads back every entry it reuses and every file of the previous run it links, to
check their digests: on a machine that has dropped them from memory since the cold night (a host reclaiming idle
page cache) that is gigabytes from the disk. ``--page-cache dropped`` drops the page cache before the edit night
(root only), so that the figure does not depend on what the machine kept; ``both`` then runs a second edit with
the first one's reads still in memory.

Before the nights and after them it prints the machine's speed at the night's heaviest kind of work (the sample's
tables step in one process, :func:`machine_cpu_s`), and at the end each night's CPU in units of that figure: on a
shared machine CPU seconds move from day to day, and notes compare runs through it.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import big_line  # noqa: E402

TIME_RATIO_TARGET = 0.8  # x copies: 10 copies at most 8 times the sample's time
MEMORY_RATIO_TARGET = 2.0
SAMPLE_S = 0.2


def job_folder(base: Path, line_dir: Path, scheduler: str = "") -> Path:
    """A project folder holding ``jobs/nightly.toml`` for ``line_dir`` (no daily feed) with its own output root;
    with ``scheduler``, on that Dask cluster."""
    src = (ROOT / "jobs" / "nightly.toml").read_text()
    if scheduler:
        src = re.sub(r'(?m)^backend = .*$', 'backend = "dask"', src)
        src = re.sub(r'(?m)^scheduler = .*$', f"scheduler = {json.dumps(scheduler)}", src)
    src = re.sub(r'(?m)^lines = .*$', f"lines = [{json.dumps(str(line_dir))}]", src)
    src = re.sub(r'(?m)^output_root = .*$', f"output_root = {json.dumps(str(base / 'outputs'))}", src)
    src = re.sub(r'(?m)^feeds = .*$', "feeds = []", src)
    (base / "jobs").mkdir(parents=True, exist_ok=True)
    (base / "jobs" / "nightly.toml").write_text(src)
    return base


class _TreeSampler(threading.Thread):
    """Samples a process tree's resident memory and per-process CPU time every :data:`SAMPLE_S`; ``also``: the roots
    of other trees the run uses (a Dask cluster's scheduler and workers), counted in the tree's and a worker's peak
    (not in the CPU: :meth:`DaskCluster.cpu_s` counts theirs)."""

    def __init__(self, pid: int, also: tuple[int, ...] = ()):
        super().__init__(daemon=True)
        import psutil

        self.root = psutil.Process(pid)
        self.also = [psutil.Process(a) for a in also]
        self.peak_sum = 0
        self.peak_main = 0
        self.peak_worker = 0
        self.cpu: dict[int, float] = {}  # last seen user + system time per process
        self.stop = threading.Event()

    def run(self) -> None:
        import psutil

        while not self.stop.is_set():
            try:
                procs = [self.root] + self.root.children(recursive=True)
            except psutil.Error:
                return
            mine = len(procs)
            for a in self.also:
                try:
                    procs += [a] + a.children(recursive=True)
                except psutil.Error:
                    pass
            total = 0
            for n, p in enumerate(procs):
                try:
                    rss = p.memory_info().rss
                    t = p.cpu_times()
                except psutil.Error:
                    continue
                total += rss
                if n < mine:
                    self.cpu[p.pid] = t.user + t.system
                if p.pid == self.root.pid:
                    self.peak_main = max(self.peak_main, rss)
                else:
                    self.peak_worker = max(self.peak_worker, rss)
            self.peak_sum = max(self.peak_sum, total)
            self.stop.wait(SAMPLE_S)


def run_job(base: Path, label: str, also: tuple[int, ...] = ()) -> dict:
    """``planner run jobs/nightly.toml`` in ``base`` (log: ``base/<label>.log``), measured from here; ``also``: the
    process trees of the cluster it runs on, counted in its memory peaks (:class:`_TreeSampler`)."""
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    with open(base / f"{label}.log", "w") as log:
        p = subprocess.Popen([sys.executable, "-m", "planner.cli", "run", "jobs/nightly.toml", "--no-progress"],
                             cwd=base, stdout=log, stderr=subprocess.STDOUT)
        sampler = _TreeSampler(p.pid, also)
        sampler.start()
        rc = p.wait()
        sampler.stop.set()
        sampler.join()
    wall = time.perf_counter() - t0
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = {"rc": rc, "wall_s": wall, "cpu_s": (ru.ru_utime + ru.ru_stime) - (ru0.ru_utime + ru0.ru_stime),
           "maxrss_mb": ru.ru_maxrss / 1024, "tree_peak_mb": sampler.peak_sum / 2**20,
           "main_peak_mb": sampler.peak_main / 2**20, "worker_peak_mb": sampler.peak_worker / 2**20,
           "main_cpu_s": sampler.cpu.get(p.pid, 0.0),
           # from the storage device, not the page cache (512-byte blocks): what a night reads back of earlier ones
           "read_mb": (ru.ru_inblock - ru0.ru_inblock) * 512 / 2**20,
           "written_mb": (ru.ru_oublock - ru0.ru_oublock) * 512 / 2**20,
           "log": (base / f"{label}.log").read_text()[-3000:], "timings": {}}
    out["worker_cpu_s"] = max(0.0, out["cpu_s"] - out["main_cpu_s"])
    runs = sorted(d for d in (base / "outputs").glob("r0*") if (d / "manifest.json").is_file())
    if rc == 0 and runs:
        out["timings"] = json.loads((runs[-1] / "manifest.json").read_text()).get("timings_s", {})
    return out


def edit_restriction(line_dir: Path, copies: int) -> str:
    """Lower the first speed limit of the middle copy by 10 km/h (in place); what was edited."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = line_dir / "speed_limits.parquet"
    t = pq.read_table(path)
    rows = len(t) // copies
    i = (copies // 2) * rows
    lim = t.column("limit_kmh").to_pylist()
    new = max(1.0, float(lim[i]) - 10.0)
    lim[i] = type(lim[i])(new) if lim[i] is not None else new
    col = t.schema.get_field_index("limit_kmh")
    t = t.set_column(col, t.schema.field(col), pa.array(lim, type=t.schema.field(col).type))
    pq.write_table(t, path)
    return f"speed_limits row {i}: {lim[i] + 10:g} -> {lim[i]:g} km/h"


QUIET = {"DASK_DISTRIBUTED__WORKER__PROFILE__ENABLED": "False", "DASK_DISTRIBUTED__ADMIN__TICK__INTERVAL": "1s",
         "DASK_DISTRIBUTED__ADMIN__SYSTEM_MONITOR__INTERVAL": "5s",
         "DASK_DISTRIBUTED__NANNY__PRE_SPAWN_ENVIRON": "{'MALLOC_TRIM_THRESHOLD_': None}"}
"""The worker settings the README recommends: the worker's profiler off (it samples the task thread every
10 ms) and its event loop's monitors slowed; the planner's task thread then runs ~1.1x a plain process's
CPU instead of ~1.25x (``bench_dask_worker.py``). And glibc's own heap settings kept in the worker processes:
Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_`` in them, and any such setting fixes glibc's threshold for
allocating by ``mmap`` at 128 KiB, so every large array of a unit is mapped, faulted in page by page and unmapped
again (the 10x cold night on Dask: CPU 132.0 s with it, 118.4 s without; joblib's workers have glibc's default)."""


class DaskCluster:
    """A Dask cluster on this machine started the way a user starts one (README): ``dask scheduler`` and
    ``dask worker ADDRESS --nworkers N --nthreads 1`` with the README's settings (:data:`QUIET`, unless
    ``quiet`` is False), each its own process tree, ended on exit. ``cpu_s()``: the CPU time (user +
    system) its processes have used so far."""

    def __init__(self, workers: int, work: Path, quiet: bool = True):
        import socket

        with socket.socket() as sk:
            sk.bind(("127.0.0.1", 0))
            port = sk.getsockname()[1]
        self.address = f"tcp://127.0.0.1:{port}"
        dask = str(Path(sys.executable).with_name("dask"))
        env = dict(os.environ, PYTHONPATH=str(ROOT), **(QUIET if quiet else {}))
        self.log = open(work / "dask.log", "w")
        self.procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                        "--no-dashboard"], stdout=self.log, stderr=subprocess.STDOUT, env=env)]
        self.procs.append(subprocess.Popen([dask, "worker", self.address, "--nworkers", str(workers), "--nthreads",
                                            "1", "--no-dashboard", "--memory-limit", "0"], cwd=ROOT,
                                           stdout=self.log, stderr=subprocess.STDOUT, env=env))
        from dask.distributed import Client

        with Client(self.address, timeout=60) as c:
            c.wait_for_workers(workers, timeout=120)

    def cpu_s(self) -> float:
        import psutil

        total = 0.0
        for p in self.procs:
            try:
                for q in [psutil.Process(p.pid)] + psutil.Process(p.pid).children(recursive=True):
                    t = q.cpu_times()
                    total += t.user + t.system
            except psutil.Error:
                pass
        return total

    def close(self) -> None:
        for p in reversed(self.procs):
            p.terminate()
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()
        self.log.close()


def same_datasets(a: Path, b: Path, ignore: tuple[str, ...] = ()) -> tuple[int, list[str]]:
    """How many Parquet files two published runs have (those of the datasets ``ignore`` aside), and those whose
    bytes differ or that only one has (paired by their paths without the run's ``run_id=``/``run_date=`` folders:
    a file does not name its run)."""
    from planner.io.parquet import without_run

    def files(run: Path) -> dict[str, Path]:
        return {without_run(p.relative_to(run).as_posix()): p for p in run.rglob("*.parquet")
                if p.relative_to(run).parts[0] not in ignore}

    fa, fb = files(a), files(b)
    bad = sorted(set(fa) ^ set(fb))
    bad += [f for f in sorted(set(fa) & set(fb)) if fa[f].read_bytes() != fb[f].read_bytes()]
    return len(fa), bad


def same_bundles(a: Path, b: Path) -> tuple[int, list[str]]:
    """How many bundle members two published runs have, the manifest and its signature aside (each run signs its
    own release), and those whose bytes differ or that only one has: the tables a vehicle loads. A bundle of each
    run is held at a time."""
    from planner.bundle.archive import read_members

    def members(bundle: Path) -> dict[str, bytes]:
        got = read_members(bundle)[0] if bundle.is_file() else {}
        return {f"{bundle.name}/{m}": data for m, data in got.items() if m not in ("manifest.json", "manifest.sig")}

    n, bad = 0, []
    for name in sorted({p.name for run in (a, b) for p in (run / "bundles").glob("*.pdb")}):
        ma, mb = members(a / "bundles" / name), members(b / "bundles" / name)
        n += len(ma)
        bad += sorted(set(ma) ^ set(mb)) + [m for m in sorted(set(ma) & set(mb)) if ma[m] != mb[m]]
    return n, bad


def dask_against_joblib(work: Path, big: Path, joblib_run: dict, workers: int = 2) -> bool:
    """The cold night of ``big`` on a local Dask cluster (``workers`` workers, one thread each) against the
    joblib run ``joblib_run`` of the same line: wall, CPU (the job's process tree and the cluster's), and
    whether the published datasets are the same."""
    cluster = DaskCluster(workers, work)
    try:
        base = job_folder(work / f"job-{big.name}-dask", big, cluster.address)
        c0 = cluster.cpu_s()
        r = run_job(base, "cold", also=tuple(p.pid for p in cluster.procs))
        r["cpu_s"] += cluster.cpu_s() - c0  # the workers are the cluster's processes, not the job's children
        r["worker_cpu_s"] = max(0.0, r["cpu_s"] - r["main_cpu_s"])
    finally:
        cluster.close()
    _show(f"{big.name}, cold, Dask ({workers} workers x 1 thread)", r)
    if r["rc"]:
        return False
    # `changes` is each run's difference from the run before it: the joblib run's may follow an edit night
    n, bad = same_datasets(work / f"job-{big.name}" / "outputs" / "latest", base / "outputs" / "latest",
                           ignore=("changes",))
    ratio = r["wall_s"] / joblib_run["wall_s"]
    print(f"bench_scaling: Dask vs joblib, cold: wall {r['wall_s']:.1f} / {joblib_run['wall_s']:.1f} s = {ratio:.2f} "
          f"(target within 15 %: 0.87-1.15); datasets: {n - len(bad)} of {n} the same"
          + (f", differ: {', '.join(bad[:5])}" if bad else ""), flush=True)
    return not bad


def machine_cpu_s(repeats: int = 3) -> list[float]:
    """The machine's speed at the night's heaviest kind of work, printed before and after the nights: the CPU
    seconds of the sample's tables step in this one process (:func:`bench_reuse.tables_step`, the nightly job's
    settings), ``repeats`` times after a warm-up. The work is the same on every machine and day, so two runs'
    figures compare through it: on a shared machine the same night's CPU has varied by 1.4x from one day to the
    next, and this figure from 4.9 to 7.4 s within an hour (hence before and after)."""
    import planner
    from bench_reuse import tables_step
    from planner.job.config import load_job

    line, job = planner.load_line(ROOT / "lines" / "sample"), load_job(ROOT / "jobs" / "nightly.toml")
    tables_step(line, job)  # warm up: imports, kernels loaded
    out = []
    for _ in range(repeats):
        c0 = time.process_time()
        tables_step(line, job)
        out.append(time.process_time() - c0)
    return out


def _show_machine(when: str) -> float:
    runs = machine_cpu_s()
    mid = sorted(runs)[len(runs) // 2]
    print(f"  machine, {when}: the sample's tables in one process take {mid:.2f} s of CPU (median of "
          f"{', '.join(f'{x:.2f}' for x in runs)} s)", flush=True)
    return mid


def _show(name: str, r: dict) -> None:
    status = "ok" if r["rc"] == 0 else f"FAILED (exit {r['rc']}): {r['log'][-600:]}"
    print(f"  {name:22s} wall {r['wall_s']:7.1f} s   CPU {r['cpu_s']:7.1f} s (main {r['main_cpu_s']:.1f}, workers "
          f"{r['worker_cpu_s']:.1f})   peak: tree {r['tree_peak_mb']:7.0f} MB, main {r['main_peak_mb']:.0f} MB, "
          f"a worker {r['worker_peak_mb']:.0f} MB   {status}", flush=True)
    print(f"      disk (not the page cache): read {r['read_mb']:.0f} MB, written {r['written_mb']:.0f} MB", flush=True)
    if r["cpu_s"] > 0:  # the job process's share bounds what any number of workers can gain (Amdahl)
        f = r["main_cpu_s"] / r["cpu_s"]
        print(f"      serial fraction (job-process CPU / all CPU) {f:.1%}: no cluster makes this night more than "
              f"{1 / f if f > 0 else float('inf'):.1f}x faster", flush=True)
    if r["timings"]:
        print("      steps [s wall]: " + ", ".join(f"{k} {v:.1f}" for k, v in r["timings"].items()), flush=True)


def drop_page_cache() -> str | None:
    """Write the dirty pages out and drop the clean ones (Linux, root only): every byte the next night reads of the
    earlier nights (the cache's entries, the previous run's files it checks and links) then comes from the disk.
    None when done, else why not."""
    try:
        os.sync()
        with open("/proc/sys/vm/drop_caches", "w") as f:
            f.write("1")
    except OSError as e:
        return f"cannot drop the page cache ({e.strerror or e}; it needs root on Linux)"
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="nightly job: sample vs a line N times its size, cold and incremental")
    ap.add_argument("--copies", type=int, default=int(os.environ.get("PLANNER_BENCH_COPIES", "10")))
    ap.add_argument("--no-sample", action="store_true", help="skip the sample's run (no ratios)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the lines, outputs and logs in this folder")
    ap.add_argument("--verify-edit", action="store_true",
                    help="also a cold night of the edited line in a fresh output root: the edit night's datasets and "
                         "bundle members must be the same (run id and date aside)")
    ap.add_argument("--dask", action="store_true",
                    help="also the big line's cold night on a local Dask cluster (dask scheduler, dask worker "
                         "--nworkers 2 --nthreads 1), against joblib: wall, CPU and the same datasets")
    ap.add_argument("--page-cache", choices=("as-left", "dropped", "both"), default="as-left",
                    help="the edit night with the page cache as the nights before left it (default), after dropping "
                         "it (every entry the night reads back comes from the disk: root only), or both: dropped, "
                         "then a second edit with the first's reads still in memory. A machine that reclaims idle "
                         "page cache (e.g. a DAMON pageout scheme) is somewhere between the two")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="bench_scaling.")) if args.keep is None else args.keep
    try:
        t0 = time.perf_counter()
        big = big_line.build(args.copies, work / "lines")
        n_trains = sum(1 for _ in __import__("pyarrow.parquet", fromlist=["x"]).read_table(
            big / "timetable.parquet", columns=["train_id"]).column(0).unique())
        print(f"  built {big.name} ({n_trains} trains) in {time.perf_counter() - t0:.1f} s", flush=True)
        machine = [_show_machine("before")]
        results = {}
        if not args.no_sample:
            results["sample"] = run_job(job_folder(work / "job-sample", ROOT / "lines" / "sample"), "cold")
            _show("sample, cold", results["sample"])
        base = job_folder(work / f"job-{big.name}", big)
        results["cold"] = r = run_job(base, "cold")
        _show(f"{big.name}, cold", r)
        ok = r["rc"] == 0
        if ok and args.dask:
            ok = dask_against_joblib(work, big, r)
        if ok:
            what = edit_restriction(big, args.copies)
            why = drop_page_cache() if args.page_cache != "as-left" else None
            if why:
                print(f"bench_scaling: {why}", flush=True)
                return 1
            results["edit"] = r = run_job(base, "edit")
            cache = "" if args.page_cache == "as-left" else ", page cache dropped"
            _show(f"{big.name}, one edit{cache}", r)
            print(f"      (edit: {what})")
            ok = r["rc"] == 0
            if ok:
                c = results["cold"]
                print(f"      edit night against the cold night: CPU {r['cpu_s'] / c['cpu_s']:.0%} (target <= 10 %), "
                      f"wall {r['wall_s'] / c['wall_s']:.0%}", flush=True)
            if ok and args.page_cache == "both":  # the same again, the first edit's reads still in memory
                what2 = edit_restriction(big, args.copies)
                results["edit, warm"] = r2 = run_job(base, "edit2")
                _show(f"{big.name}, a second edit, page cache warm", r2)
                print(f"      (edit: {what2})")
                ok = r2["rc"] == 0
                if ok:
                    print(f"      against the cold night: CPU {r2['cpu_s'] / c['cpu_s']:.0%}, "
                          f"wall {r2['wall_s'] / c['wall_s']:.0%}", flush=True)
            if ok and args.verify_edit:  # what the edit night published is what a cold night of the edited line does
                fresh = job_folder(work / f"job-{big.name}-edited-cold", big)
                r2 = run_job(fresh, "cold")
                _show(f"{big.name} edited, cold", r2)
                # `changes` is what changed since the run before: the fresh root has none
                n, bad = same_datasets(base / "outputs" / "latest", fresh / "outputs" / "latest", ("changes",))
                print(f"bench_scaling: edit night vs a cold night of the edited line: {n - len(bad)} of {n} dataset "
                      "files the same (run id and date aside; `changes`, the difference from the run before, left "
                      "out)" + (f", differ: {', '.join(bad[:5])}" if bad else ""), flush=True)
                nb, bad_b = same_bundles(base / "outputs" / "latest", fresh / "outputs" / "latest")
                print(f"bench_scaling: edit night vs a cold night of the edited line: {nb - len(bad_b)} of {nb} bundle "
                      "members the same (each run's signed manifest aside)"
                      + (f", differ: {', '.join(bad_b[:5])}" if bad_b else ""), flush=True)
                ok = r2["rc"] == 0 and not bad and not bad_b
        machine.append(_show_machine("after"))
        if ok:  # the nights' CPU in the machine's own unit, comparable across days (machine_cpu_s)
            unit = sum(machine) / 2
            print("bench_scaling: CPU in units of the machine figure (the mean of before and after, "
                  f"{unit:.2f} s): " + ", ".join(f"{k} {r['cpu_s'] / unit:.1f}" for k, r in results.items()
                                                 if r["rc"] == 0), flush=True)
        if "sample" in results and ok and results["sample"]["rc"] == 0:
            s, b = results["sample"], results["cold"]
            tr, cr = b["wall_s"] / s["wall_s"], b["cpu_s"] / s["cpu_s"]
            mr, mm = b["tree_peak_mb"] / s["tree_peak_mb"], b["maxrss_mb"] / s["maxrss_mb"]
            print(f"bench_scaling: {args.copies}x line vs sample, cold nightly: CPU ratio {cr:.1f}, wall ratio "
                  f"{tr:.1f} (target <= {TIME_RATIO_TARGET * args.copies:g}); peak memory ratio {mr:.2f} "
                  f"(tree; largest process {mm:.2f}; target <= {MEMORY_RATIO_TARGET:g})")
        return 0 if ok and all(x["rc"] == 0 for x in results.values()) else 1
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
