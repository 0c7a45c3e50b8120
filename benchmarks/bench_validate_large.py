"""Benchmark: validating and loading a line database whose gradient table has 10 million rows.

Writes the tiny test line (tests/linedb.py) stretched to 10,000 km with a 1 m gradient segment
every metre (10 M rows, alternating ±5 ‰; ~80 MB of Parquet), then times, each in a fresh
process so that the peak memory is its own:

* ``check_line`` (what ``planner validate`` runs: read + every rule), and
* ``load_line`` (validation, then the SI model),

printing wall time, CPU time and the peak resident memory (``ru_maxrss``). Pass ``--rows N``
to change the size and ``--bad`` to put an overlap in the last row (the rules must find it).

Run: ``.venv/bin/python benchmarks/bench_validate_large.py``
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

CHILD = r"""
import json, resource, sys, time
from planner.line.loader import check_line, load_line
path, what = sys.argv[1], sys.argv[2]
t0, c0 = time.perf_counter(), time.process_time()
if what == "check_line":
    out = check_line(path)
    result = {"violations": len(out), "first": str(out[0]) if out else ""}
else:
    line = load_line(path)
    result = {"segments": int(len(line.gradients.start_m))}
result.update(wall_s=round(time.perf_counter() - t0, 2), cpu_s=round(time.process_time() - c0, 2),
              peak_rss_mb=round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1))
print(json.dumps(result))
"""


def write_line(folder: Path, rows: int, bad: bool) -> Path:
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    from linedb import default_tables, write_line_db

    t = default_tables(folder.name)
    t["line"].loc[0, "end_m"] = float(rows)
    write_line_db(folder, **t)
    start = np.arange(rows, dtype=np.float64)
    end = start + 1.0
    if bad:
        start[-1] -= 0.5  # overlaps the previous segment
    grad = np.where(np.arange(rows) % 2 == 0, 5.0, -5.0)
    pq.write_table(pa.table({"start_m": start, "end_m": end, "gradient_permil": grad}),
                   folder / "gradients.parquet")
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--bad", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        folder = write_line(Path(tmp) / "big", args.rows, args.bad)
        size = (folder / "gradients.parquet").stat().st_size / 1e6
        print(f"gradients.parquet: {args.rows:,} rows, {size:.1f} MB, written in {time.perf_counter() - t0:.1f} s")
        for what in ("check_line", "load_line"):
            if what == "load_line" and args.bad:
                continue
            r = subprocess.run([sys.executable, "-c", CHILD, str(folder), what], capture_output=True, text=True,
                               cwd=ROOT)
            if r.returncode:
                print(f"{what}: failed\n{r.stderr}")
                continue
            res = json.loads(r.stdout)
            print(f"{what:<11} wall {res.pop('wall_s'):6.2f} s  cpu {res.pop('cpu_s'):6.2f} s  "
                  f"peak RSS {res.pop('peak_rss_mb'):7.1f} MB  {res}")


if __name__ == "__main__":
    main()
