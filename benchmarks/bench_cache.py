"""Benchmark: the work cache's entries read and written, per kind of unit, on the sample night's own results.

A cold night of the sample line (``planner run``, in a temporary output root) fills a cache; then every entry
of each kind is read back as the job reads it (:meth:`planner.job.cache.Cache.get`: the file, its digest,
:func:`planner.job.codec.decode`) and packed again (:func:`planner.job.cache.pack`). Printed per kind: entries,
mean size, read and pack time per entry in CPU milliseconds of this process (``time.process_time``: the machine
is shared, wall time says little). An edit night of a large line reads every entry of its unchanged units
(about 36,000 at 100x), so the read figure, times that, is what it pays to learn that nothing changed.

Run: ``.venv/bin/python benchmarks/bench_cache.py [--repeat N]``
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_scaling import job_folder  # noqa: E402
from planner.job.cache import Cache, pack  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="reads and packs of each entry (the best is kept)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench_cache.") as tmp:
        base = job_folder(Path(tmp), ROOT / "lines" / "sample")
        rc = subprocess.call([sys.executable, "-m", "planner.cli", "run", "jobs/nightly.toml", "--no-progress"],
                             cwd=base, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if rc != 0:
            print(f"bench_cache: the sample night failed (exit {rc})")
            return 1
        cache = Cache(base / "outputs" / ".cache")
        kinds = sorted(p.name for p in cache.root.iterdir() if p.is_dir())
        print(f"  {'kind':12s} {'entries':>7s} {'mean kB':>8s} {'read ms':>8s} {'pack ms':>8s}")
        for kind in kinds:
            files = sorted((cache.root / kind).rglob("*.pce"))
            read = packed = float("inf")
            size = sum(f.stat().st_size for f in files)
            for _ in range(args.repeat):
                t0 = time.process_time()
                objs = [cache.get(kind, f.stem) for f in files]
                t1 = time.process_time()
                for f, obj in zip(files, objs):
                    pack(kind, f.stem, obj)
                t2 = time.process_time()
                read, packed = min(read, t1 - t0), min(packed, t2 - t1)
            if any(o is None for o in objs):
                print(f"bench_cache: an entry of {kind} did not read back")
                return 1
            n = len(files)
            print(f"  {kind:12s} {n:7d} {size / n / 1e3:8.1f} {1e3 * read / n:8.3f} {1e3 * packed / n:8.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
