"""Benchmark: the cold nightly job on the sample line and on a line N times its size (issue 20).

Builds the big line (:mod:`big_line`, default 10 copies of the sample with a
proportionate timetable) in a temporary folder, then runs ``planner run`` on the
nightly job (``jobs/nightly.toml`` with only ``lines`` and ``output_root``
changed) for the sample and for the big line, each in its own subprocess with a
fresh output root (no cache). Prints for each the wall time and the peak
resident memory of the largest process of the run (``ru_maxrss`` of the
finished process tree, measured by a small parent process per run), and their
ratios against the targets of issue 20: time ratio <= N, peak memory ratio <= 3.
The per-step times are the job's own (its ``--json`` summary is not needed: the
log's step lines are printed as they are).

Run: ``.venv/bin/python benchmarks/bench_scaling.py [--copies N] [--keep DIR]``.
"""
from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import big_line  # noqa: E402

TIME_RATIO_TARGET = 10.0  # for 10 copies: linear
MEMORY_RATIO_TARGET = 3.0

_MEASURE = r"""
import json, resource, subprocess, sys, time
t0 = time.perf_counter()
with open(sys.argv[1] + "/run.log", "w") as log:
    p = subprocess.run(sys.argv[2:], cwd=sys.argv[1], stdout=log, stderr=subprocess.STDOUT)
wall = time.perf_counter() - t0
ru = resource.getrusage(resource.RUSAGE_CHILDREN)
with open(sys.argv[1] + "/run.log") as log:
    tail = log.read()[-4000:]
print(json.dumps({"rc": p.returncode, "wall_s": wall, "maxrss_kb": ru.ru_maxrss,
                  "cpu_s": ru.ru_utime + ru.ru_stime, "log": tail}))
"""


def job_folder(base: Path, line_dir: Path) -> Path:
    """A project folder holding ``jobs/nightly.toml`` for ``line_dir`` with a fresh output root."""
    src = (ROOT / "jobs" / "nightly.toml").read_text()
    src = re.sub(r'(?m)^lines = .*$', f"lines = [{json.dumps(str(line_dir))}]", src)
    src = re.sub(r'(?m)^output_root = .*$', f"output_root = {json.dumps(str(base / 'outputs'))}", src)
    (base / "jobs").mkdir(parents=True)
    (base / "jobs" / "nightly.toml").write_text(src)
    return base


def run_job(base: Path) -> dict:
    """``planner run jobs/nightly.toml`` in ``base``, measured by a parent process of its own (log: base/run.log)."""
    planner = Path(sys.executable).with_name("planner")
    out = subprocess.run([sys.executable, "-c", _MEASURE, str(base), str(planner), "run", "jobs/nightly.toml"],
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="cold nightly job: sample vs a line N times its size")
    ap.add_argument("--copies", type=int, default=10)
    ap.add_argument("--keep", type=Path, default=None, help="keep the lines and outputs in this folder")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="bench_scaling.")) if args.keep is None else args.keep
    try:
        big = big_line.build(args.copies, work / "lines")
        results = {}
        for name, line_dir in (("sample", ROOT / "lines" / "sample"), (big.name, big)):
            r = run_job(job_folder(work / f"job-{name}", line_dir))
            results[name] = r
            status = "ok" if r["rc"] == 0 else f"FAILED (exit {r['rc']}): {r['log'][-600:]}"
            print(f"  {name:12s} wall {r['wall_s']:7.1f} s   CPU {r['cpu_s']:7.1f} s   "
                  f"peak RSS {r['maxrss_kb'] / 1024:7.1f} MB   {status}", flush=True)
        s, b = results["sample"], results[big.name]
        tr = b["wall_s"] / s["wall_s"]
        cr = b["cpu_s"] / s["cpu_s"]
        mr = b["maxrss_kb"] / s["maxrss_kb"]
        target = TIME_RATIO_TARGET * args.copies / 10.0
        print(f"bench_scaling: {args.copies}x line vs sample, cold nightly: time ratio {tr:.1f} "
              f"(target <= {target:g}; CPU ratio {cr:.1f}), peak memory ratio {mr:.2f} "
              f"(target <= {MEMORY_RATIO_TARGET:g})")
        return 0 if s["rc"] == 0 and b["rc"] == 0 else 1
    finally:
        if args.keep is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
