"""What each part of a cold night's content costs in CPU, and what leaving it out would give up.

Run ``.venv/bin/python benchmarks/bench_content.py [--copies N] [--rounds K]`` (``make bench`` runs it on
the sample). The 100x line's cold night does more computing than two cores can do in 300 s; this prints
how much of the night each optional part takes, so that a decision to leave one out is taken on figures.
It changes nothing in the product: every variant is the shipped job with one setting changed, except
"no table (d)", which makes table (d) unavailable on every leg the way a stall at the last evaluation
point does (the adaptive mode then uses table (c) there), and measures what that costs the closed loop's
arrival error.

Every night runs in one process (``[parallel] n_jobs = 1``), so its CPU is the night's computing without
the pool's overhead, and the disk is synced before each, so that no night pays for the last one's writes.
Each round runs the shipped job first and every variant after it, each round in another order, and the
shipped job once more at the end; the spread of the shipped nights is this machine's noise, and a
variant's figure is its median over the rounds. The sample (the default) has the daily feed's
restrictions and the fixed costs of a small line (the conflict check and the Monte-Carlo days weigh
more than on a big one); ``--copies 10`` runs the line ``bench_scaling.py`` builds (ten samples end to
end, no daily feed), whose shares are those of the 100x line (the night grows linearly), at about 100 s
a night.
"""
from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_nightly  # noqa: E402
import bench_scaling  # noqa: E402
import big_line  # noqa: E402

NO_TABLE_D = ("import planner.tables.build as b\n"
              "from planner.errors import InfeasibleError\n"
              "def _none(*a, **k):\n"
              "    raise InfeasibleError('table (d) left out (bench_content)')\n"
              "b.approach_table = _none\n")
"""Run before the command in the night's one process: every leg's table (d) is unavailable."""

VARIANTS: list[tuple[str, list[tuple[str, str]], str, str]] = [
    ("closed loop every 2 s", [(r"(?m)^step_s = 1\.0\b", "step_s = 2.0")], "",
     "the closed loop proves every second designated time"),
    ("closed loop: adaptive only", [(r'(?m)^modes = \["nearest", "adaptive"\]', 'modes = ["adaptive"]')], "",
     "the nearest mode is not proved"),
    ("no Monte-Carlo days", [(r"(?m)^days = 1000\b", "days = 0")], "",
     "the predicted day only: no punctuality under ordinary delays"),
    ("no conflict check", [(r"(?m)^(\[conflicts\]\n)enabled = true", r"\1enabled = false")], "",
     "no route conflicts, headways, nor the day as it runs (it needs them)"),
    ("adhesion every 0.2 km/h/s", [(r'(?m)^adhesion_kmh_s = "2\.5:3\.5:0\.1"', 'adhesion_kmh_s = "2.5:3.5:0.2"')],
     "", "6 stopping patterns per approach instead of 11"),
    ("no table (d)", [], NO_TABLE_D, "sawtooth trains at the last point: table (c) instead (closed loop below)"),
]
ONE_PROCESS = (r"(?m)^n_jobs = -1\b", "n_jobs = 1")


def _edit(text: str, pattern: str, repl: str) -> str:
    new, n = re.subn(pattern, repl, text)
    if n != 1:
        raise SystemExit(f"bench_content: jobs/nightly.toml has {n} matches of {pattern!r}, not 1: update the variant")
    return new


def _project(base: Path, copies: int) -> Path:
    """The sample's project in ``base`` (:func:`bench_nightly._project`); with ``copies`` > 1, its job on the big line
    instead (:func:`bench_scaling.job_folder`: no daily feed, whose trains and stations are the sample's)."""
    proj = bench_nightly._project(base)
    if copies > 1:
        bench_scaling.job_folder(proj, big_line.build(copies, base / "lines"))
    return proj


def _night(proj: Path, name: str, edits, prelude: str, keep: bool = False) -> tuple[float, Path | None]:
    """One cold night of the edited job in a fresh output root: its CPU [s] and, with ``keep``, its run folder
    (else the outputs are deleted). The disk is synced first, so no night pays for the last one's writes."""
    text = (proj / "jobs" / "nightly.toml").read_text()
    for pattern, repl in [ONE_PROCESS, *edits, (r"(?m)^output_root = .*$", f'output_root = "out-{name}"')]:
        text = _edit(text, pattern, repl)
    job = proj / "jobs" / f"{name}.toml"
    job.write_text(text)
    code = prelude + "import sys\nfrom planner.cli import main\nsys.argv = ['planner', *sys.argv[1:]]\nmain()\n"
    os.sync()
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run([sys.executable, "-c", code, "run", str(job.relative_to(proj)), "--no-progress"],
                       cwd=proj, capture_output=True, text=True)
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"bench_content: the night '{name}' failed:\n{r.stdout}{r.stderr}")
    cpu = (ru.ru_utime + ru.ru_stime) - (ru0.ru_utime + ru0.ru_stime)
    if not keep:
        shutil.rmtree(proj / f"out-{name}")
        return cpu, None
    return cpu, sorted((proj / f"out-{name}").glob("r0*"))[-1]


def _rows(run: Path, dataset: str) -> int:
    d = run / dataset
    return len(pd.read_parquet(d)) if d.is_dir() else 0


def _closed_loop_cost(shipped: Path, without: Path) -> list[str]:
    """Adaptive-mode arrival error with and without table (d), per train type whose errors moved."""
    keys = ["line", "direction", "train_type", "origin", "destination", "scenario", "mode", "designated_s"]
    m = pd.read_parquet(shipped / "closed_loop").merge(pd.read_parquet(without / "closed_loop"), on=keys,
                                                       suffixes=("", "_without"))
    m = m[(m["mode"] == "adaptive") & m["feasible"] & m["feasible_without"]]
    out = []
    for (tt, sc), g in m.groupby(["train_type", "scenario"], observed=True):
        a, b = g["error_s"].abs().to_numpy(), g["error_s_without"].abs().to_numpy()
        if np.array_equal(a, b):
            continue
        out.append(f"  {tt} {sc:9s} ({len(g):,} runs): |error| p95 {np.quantile(a, .95):.3f} -> "
                   f"{np.quantile(b, .95):.3f} s, largest {a.max():.3f} -> {b.max():.3f} s, "
                   f"over 0.1 s {np.mean(a > 0.1):.1%} -> {np.mean(b > 0.1):.1%}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--copies", type=int, default=1, help="1: the sample (default); N: N samples end to end")
    ap.add_argument("--rounds", type=int, default=3, help="rounds of every night (default 3); medians are shown")
    args = ap.parse_args()
    if args.copies < 1 or args.rounds < 1:
        raise SystemExit("bench_content: --copies and --rounds must be at least 1")
    with tempfile.TemporaryDirectory() as tmp:
        proj = _project(Path(tmp) / "project", args.copies)
        shipped: list[tuple[float, Path | None]] = []
        cpu: dict[str, list[float]] = {name: [] for name, *_ in VARIANTS}
        runs: dict[str, Path | None] = {}
        for k in range(args.rounds):  # each round takes the variants in another order (no one always goes first)
            shipped.append(_night(proj, f"shipped{k}", [], "", keep=k == 0))
            j = k % len(VARIANTS)
            for i in [*range(j, len(VARIANTS)), *range(j)]:
                name, edits, prelude, _ = VARIANTS[i]
                last = k == args.rounds - 1 and name == "no table (d)"  # the one compared below
                c, runs[name] = _night(proj, f"r{k}v{i}", edits, prelude, keep=last)
                cpu[name].append(c)
        shipped.append(_night(proj, "shipped-last", [], ""))
        if _rows(shipped[0][1], "table_d") == 0:
            raise SystemExit("bench_content: the shipped night has no table (d): the line has no sawtooth train?")
        if _rows(runs["no table (d)"], "table_d") != 0:
            raise SystemExit("bench_content: 'no table (d)' still wrote table (d): the variant did not take")
        base = float(np.median([c for c, _ in shipped]))
        line = "the sample" if args.copies == 1 else f"{args.copies} samples end to end (no daily feed)"
        print(f"bench_content: {line}, cold nights in one process; the shipped job "
              f"{', '.join(f'{c:.1f}' for c, _ in shipped)} s of CPU (median {base:.1f} s; the spread is the "
              f"noise), {args.rounds} round(s)")
        print(f"  {'left out':28s} {'CPU [s]':>8s} {'saved':>7s}  what it gives up")
        for name, *_, gives_up in VARIANTS:
            c = float(np.median(cpu[name]))
            print(f"  {name:28s} {c:8.1f} {1 - c / base:7.1%}  {gives_up}")
        print("no table (d), the adaptive mode's closed loop (shipped -> without):")
        print("\n".join(_closed_loop_cost(shipped[0][1], runs["no table (d)"])) or "  no arrival error moved")


if __name__ == "__main__":
    main()
