"""Benchmark: `planner runtime ... --json` for one interstation, as a user runs it (issue 20).

Runs the installed command in fresh processes (cold interpreter each time) and
prints the median wall time of the whole command, and how much of it is imports
(``python -X importtime``: the cumulative time of the top-level imports the
command makes, before any line is loaded). Figures only; nothing is asserted.
"""
from __future__ import annotations

import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ARGS = ["runtime", str(ROOT / "lines" / "sample"), "--train-type", "E10", "--from", "TKD", "--to", "OHS", "--json"]
RUNS = 5


def wall_s() -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "planner.cli", *ARGS], check=True, capture_output=True)
    return time.perf_counter() - t0


def import_s() -> float:
    """Seconds spent importing (sum of the top-level entries of -X importtime)."""
    out = subprocess.run([sys.executable, "-X", "importtime", "-m", "planner.cli", *ARGS], check=True,
                         capture_output=True, text=True).stderr
    total = 0
    for line in out.splitlines():
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \| (\s*)(\S+)", line)
        if m and m.group(2) == "":  # top level: the name right after the bar
            total += int(m.group(1))
    return total / 1e6


def main() -> None:
    walls = [wall_s() for _ in range(RUNS)]
    imports = [import_s() for _ in range(RUNS)]
    w, i = statistics.median(walls), statistics.median(imports)
    print(f"bench_cli_runtime: `planner {' '.join(ARGS[:1])} sample E10 TKD->OHS --json`, {RUNS} cold runs")
    print(f"  wall {w:.2f} s median (min {min(walls):.2f}), of which imports {i:.2f} s ({100 * i / w:.0f} %)")


if __name__ == "__main__":
    main()
