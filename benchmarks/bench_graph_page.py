"""Size and load time of the interactive train graph page: the sample day, and scaled to 2,000 trains.

Builds the sample line's graph (trajectories from the network module's run
curves; windows, conflicts and margins from ``outputs/latest`` when that run
planned the current sample line, else computed), writes the page, and opens it
in headless Chromium (``tests/browser.py``) several times: the figure is the
median time from navigation start to the end of the load event, which includes
parsing the inline data and building every SVG path (the script runs before
the load event), and the renderer main thread's CPU time for it (Chromium's
``TaskDuration`` in thread ticks), which does not grow when other work shares
the machine. Then the same for a day of N trains, made by repeating the
sample trains shifted in time (every train's path, windows and calls; 2,000 by
default), to show how the page scales.

    python benchmarks/bench_graph_page.py [--trains 2000] [--repeat 5] [--shots DIR]

``--shots DIR`` also saves screenshots of the opening view (the morning peak), the whole day, the
08:00 hour and a selected train's stairway.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))


def sample_graph():
    from planner import load_line
    from planner.report.published_run import read_line_dataset, read_manifest
    from planner.report.train_graph import graph_data

    line = load_line(ROOT / "lines" / "sample")
    run = ROOT / "outputs" / "latest"
    kw = {}
    try:
        m = read_manifest(run)
        if any(x.get("source_digest") == line.source_digest for x in m.get("lines", [])):
            kw = {name: read_line_dataset(run, ds, "sample") for name, ds in
                  (("windows", "occupation"), ("conflicts", "conflicts"), ("margin_totals", "margin_totals"))}
            print(f"windows, conflicts, margins from {run.resolve().name}")
    except Exception:  # noqa: BLE001 - no run: compute the conflicts, no margins
        print("no matching outputs/latest: conflicts computed here, margins not shown")
    t = time.perf_counter()
    g = graph_data(line, **kw)
    print(f"graph data of {len(g.trains)} trains: {time.perf_counter() - t:.1f} s "
          f"({sum(len(p.t_s) for p in g.trains)} path points after thinning)")
    return g


def scaled(g, n: int):
    """A day of n trains: the sample's trains repeated, each copy shifted by a few minutes."""
    import pandas as pd

    reps = int(np.ceil(n / len(g.trains)))
    trains, wins, cons, margins = [], [], [], {}
    for k in range(reps):
        dt = 97.0 * k  # s; copies interleave with the originals
        for tp in g.trains:
            if len(trains) == n:
                break
            tid = tp.train_id if k == 0 else f"{tp.train_id}.{k}"
            calls = tuple((s, a + dt, d + dt, st) for s, a, d, st in tp.calls)
            trains.append(dataclasses.replace(tp, train_id=tid, t_s=tp.t_s + dt, calls=calls))
            if tp.train_id in g.margins:
                margins[tid] = g.margins[tp.train_id]
        if g.windows is not None and len(g.windows):
            w = g.windows.copy()
            w["train_id"] = w["train_id"] if k == 0 else w["train_id"] + f".{k}"
            w[["start_s", "end_s"]] += dt
            wins.append(w)
        if g.conflicts is not None and len(g.conflicts):
            c = g.conflicts.copy()
            if k:
                c["train_a"] += f".{k}"
                c["train_b"] += f".{k}"
            c[["overlap_start_s", "overlap_end_s"]] += dt
            c["conflict_id"] += k * 1000
            cons.append(c)
    keep = {t.train_id for t in trains}
    w = pd.concat(wins) if wins else None
    if w is not None:
        w = w[w.train_id.isin(keep)]
    c = pd.concat(cons) if cons else None
    if c is not None:
        c = c[c.train_a.isin(keep) & c.train_b.isin(keep)]
    return dataclasses.replace(g, trains=trains, windows=w, conflicts=c, margins=margins)


def measure(path: Path, repeat: int) -> tuple[float, list[str]]:
    from browser import Browser

    times, cpu, errors = [], [], []
    with Browser(1500, 900) as b:
        for _ in range(repeat):
            p = b.open(path)
            assert p.eval("document.body.dataset.ready") == "1"
            times.append(p.load_ms)
            cpu.append(1000 * p.metrics.get("TaskDuration", float("nan")))
            errors += p.errors
    return statistics.median(times), statistics.median(cpu), errors


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trains", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--shots", type=Path, default=None)
    a = ap.parse_args()
    from browser import find_chromium

    from planner.pages.train_graph import write_page

    if find_chromium() is None:
        print("chromium not found: install Debian's chromium package")
        return
    g = sample_graph()
    with tempfile.TemporaryDirectory() as tmp:
        for label, data in (("sample day", g), (f"{a.trains} trains", scaled(g, a.trains))):
            path = write_page(data, Path(tmp) / "graph.html")
            size = path.stat().st_size
            ms, cpu, errors = measure(path, a.repeat)
            print(f"{label}: {len(data.trains)} trains, page {size / 1e6:.2f} MB "
                  f"({size / len(data.trains) / 1e3:.1f} kB per train), load {ms:.0f} ms wall "
                  f"(navigation start to load end), {cpu:.0f} ms main-thread CPU (medians of {a.repeat}, "
                  f"headless Chromium; load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)"
                  + (f"; console errors: {errors}" if errors else ""))
            if a.shots and label == "sample day":
                shots(path, a.shots)


def shots(path: Path, folder: Path) -> None:
    from browser import Browser

    folder.mkdir(parents=True, exist_ok=True)
    with Browser(1500, 900) as b:
        p = b.open(path)
        p.screenshot(folder / "graph_peak.png")  # the page opens on the morning peak
        p.eval("document.querySelector('#hours button.day').click()")
        p.screenshot(folder / "graph_day.png")
        p.eval("document.querySelector('button.hour[data-t0=\"28800\"]').click()")
        p.screenshot(folder / "graph_0800.png")
        x, y = p.eval("(() => { const tr = D.trains.find(t => t.t0 < 30000 && t.t1 > 30600 && t.svc === 'rapid'"
                      " && t.dir === 'down'); const r = svg.getBoundingClientRect();"
                      " return [r.left + sx(30300), r.top + sy(xAt(tr, 30300))]; })()")
        p.mouse(x, y)
        p.mouse(x, y, "click")
        p.mouse(x + 4, y + 2)
        p.screenshot(folder / "graph_0800_selected.png")
    print(f"screenshots in {folder}")


if __name__ == "__main__":
    main()
