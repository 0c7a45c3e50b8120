"""The whole nightly job on the sample line, cold (empty cache) and warm (nothing changed).

Targets (issue 8): cold at most 120 s, warm at most 5 s on the 2-core machine; issue 20: cold at most 15 s;
issue 38: cold at most 6 s. Prints wall and CPU time (user + system of the run's whole process tree).
Runs in a temporary copy of the project so the real outputs/ is untouched.

Also prints the wall time of a fixed reference load (pure Python and numpy, no planner code) on both
cores before and after the runs: this machine's speed drifts (about 20 % within an hour was seen),
so a figure near its target is only comparable at the same reference time.
"""
from __future__ import annotations

import shutil
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _reference_load() -> None:
    """A fixed amount of CPU work, the same on every run (no planner code: a planner change does not move it)."""
    import numpy as np

    x = 0
    for i in range(4_000_000):
        x += i * i
    a = np.arange(2_000_000, dtype=np.float64)[::-1].copy()
    for _ in range(8):
        np.sort(np.sin(a))


def reference_s() -> float:
    """Wall time of :func:`_reference_load` on two processes at once (both cores, as the job uses them) [s]."""
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
                               "import bench_nightly; bench_nightly._reference_load()"]) for _ in range(2)]
    for p in procs:
        if p.wait() != 0:
            raise SystemExit("reference load failed")
    return time.perf_counter() - t0


def main() -> None:
    before = reference_s()
    with tempfile.TemporaryDirectory() as tmp:
        proj = Path(tmp)
        shutil.copytree(ROOT / "lines" / "sample", proj / "lines" / "sample")
        shutil.copytree(ROOT / "feeds" / "sample", proj / "feeds" / "sample")  # the job's [day] feeds
        shutil.copytree(ROOT / "jobs", proj / "jobs")
        for label in ("cold", "warm"):
            t0 = time.perf_counter()
            ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            r = subprocess.run([sys.executable, "-m", "planner.cli", "run", "jobs/nightly.toml", "--no-progress"],
                               cwd=proj, capture_output=True, text=True)
            wall = time.perf_counter() - t0
            ru = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (ru.ru_utime + ru.ru_stime) - (ru0.ru_utime + ru0.ru_stime)
            if r.returncode != 0:
                print(r.stdout, r.stderr)
                raise SystemExit(f"{label} run failed")
            target = " (target <= 6 s)" if label == "cold" else ""
            print(f"nightly job on the sample line, {label}: {wall:.1f} s wall{target}, {cpu:.1f} s CPU")
            if label == "cold":
                print("\n".join("  " + ln for ln in r.stdout.splitlines()[1:12]))
    print(f"machine speed: reference load {before:.2f} s before, {reference_s():.2f} s after (two processes; "
          "lower is faster; compare nightly times only at similar reference times)")


if __name__ == "__main__":
    main()
