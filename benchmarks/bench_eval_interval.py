"""Benchmark: arrival error and cost against the evaluation interval and the ratio grid (issue 22).

The study of the published method on the sample line (:mod:`planner.report.eval_study`): for every
ratio grid (the job's default — 10 % steps to 70 %, then 5 % — and 10 %, 5 %, 2.5 % steps all
the way) and every evaluation interval (beacons only, 1000, 500, 200 m), build the tables of
every interstation, direction and train type, run the closed loop (designated times minimum …
minimum + 60 s, modes nearest and adaptive, scenarios nominal and perturbed = load 1.0, traction
× 0.9 against the nominal tables), and print the median / p95 / max |arrival error| over
feasible runs with what the setting costs: evaluation points, table (b) rows, bytes of the
largest signed bundle (with the stopping patterns, as the nightly job builds it) and the
table build's CPU time (summed over tasks, each timed in its worker).

Then the issue's checks: the best setting of the nearest rule whose bundle stays under 2×
today's (default grid, beacons only) against max ≤ 2 s nominal and ≤ 3 s perturbed, with its
worst runs explained (last evaluation point with authority, gap between table entries there),
and the adaptive mode's max ≤ 1 s at every setting.

Slow: the whole study is 16 settings × 66 tasks (about 30-40 min CPU). Pass ``--grids`` and
``--intervals`` to run part of it, ``--types`` for some train types.

Run: ``.venv/bin/python benchmarks/bench_eval_interval.py [--grids default,5%] [--intervals 0,200]
[--types E10] [--jobs N] [--html study.html]``
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import planner  # noqa: E402
from planner.report.eval_study import (  # noqa: E402
    ADAPTIVE_MAX_S,
    BUNDLE_FACTOR,
    GRIDS,
    INTERVALS,
    NEAREST_BOUNDS_S,
    Setting,
    best_nearest,
    format_table,
    format_worst,
    run_setting,
)
from planner.pages.eval_study import write_html  # noqa: E402

NEAREST_BOUNDS = NEAREST_BOUNDS_S  # the bounds, one copy (planner.report.eval_study)


def _grids(text: str) -> list[str]:
    out = []
    for g in (x.strip() for x in text.split(",") if x.strip()):
        g = g.replace("%", " %") if g.endswith("%") and " %" not in g else g
        if g not in GRIDS:
            raise SystemExit(f"--grids: {g!r} is not one of {', '.join(GRIDS)}")
        out.append(g)
    return out


def _intervals(text: str) -> list[float | None]:
    return [None if float(x) == 0 else float(x) for x in text.split(",") if x.strip()]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grids", default=",".join(GRIDS), help="comma-separated: default,10%%,5%%,2.5%%")
    ap.add_argument("--intervals", default=",".join("0" if i is None else f"{i:g}" for i in INTERVALS),
                    help="comma-separated metres, 0 = beacons only")
    ap.add_argument("--types", default="", help="train types (default all)")
    ap.add_argument("--jobs", type=int, default=-1)
    ap.add_argument("--html", type=Path, default=None, help="also write the study page here")
    ap.add_argument("--stops", type=Path, default=None, help="reuse a `planner stops --out` folder")
    ap.add_argument("--order", choices=("grid", "cost"), default="grid",
                    help="grid: grids outer, intervals inner; cost: cheapest settings first")
    ap.add_argument("--settings", default="", help="explicit GRID:INTERVAL list instead of --grids x "
                    "--intervals, e.g. 'default:0,5%%:200' (today's setting is always run first)")
    ap.add_argument("--base-bundle-bytes", type=int, default=0,
                    help="today's largest bundle [bytes], measured before: today's setting is then not run")
    ap.add_argument("--interstations", default="", help="only these, e.g. 'TKD-OHS,OHS-TKD' (both "
                    "directions must be named; no bundle bytes then)")
    args = ap.parse_args()
    line = planner.load_line(ROOT / "lines" / "sample")
    types = [t for t in args.types.split(",") if t] or None
    grids, intervals = _grids(args.grids), _intervals(args.intervals)
    settings = [Setting("default", None)] + [Setting(g, i) for g in grids for i in intervals
                                             if (g, i) != ("default", None)]
    if args.settings:
        pairs = [x.rsplit(":", 1) for x in args.settings.split(",") if x.strip()]
        settings = [Setting("default", None)] + [
            Setting(_grids(g)[0], _intervals(i)[0]) for g, i in pairs if (_grids(g)[0], _intervals(i)[0])
            != ("default", None)]
    if args.base_bundle_bytes:
        settings = settings[1:]
    subset = [tuple(x.split("-", 1)) for x in args.interstations.split(",") if x.strip()] or None
    if args.order == "cost":  # cheap and likely candidates first, so a cut-short run says the most
        def cost(s):
            n_r = {"10 %": 9, "default": 14, "5 %": 17, "2.5 %": 33}[s.grid]
            return n_r ** 2 * (1 if s.interval_m is None else 7000 / s.interval_m)
        settings = settings[:1] + sorted(settings[1:], key=cost)
    print(f"bench_eval_interval: sample line{' (interstations ' + args.interstations + ')' if subset else ''}, "
          f"{len(settings)} settings "
          f"({', '.join(s.label for s in settings)}), types {', '.join(types or [t.train_type for t in line.train_types])}",
          flush=True)
    t_all = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        stops = args.stops
        if stops is None:
            from planner.stopping.sweep import stop_sweep
            from planner.datasets.stops import write_stops

            t0 = time.perf_counter()
            stops = Path(tmp) / "stops"
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                write_stops(stop_sweep(line, train_types=types, n_jobs=args.jobs), stops)
            print(f"  stopping patterns (for the bundle bytes) in {time.perf_counter() - t0:.0f} s", flush=True)
        results = []
        base_bytes = args.base_bundle_bytes or None
        for s in settings:
            t0 = time.perf_counter()
            r = run_setting(line, s, stops_dir=stops, train_types=types, n_jobs=args.jobs, interstations=subset)
            results.append(r)
            if base_bytes is None:
                base_bytes = r.bundle_max_bytes  # today's setting, run first
            st = r.stats
            print(f"  {s.label:24s} {time.perf_counter() - t0:6.0f} s wall, tables {r.tables_cpu_s:6.1f} s CPU; "
                  f"nearest max {st[('nearest', 'nominal')]['max_abs_error_s']:.2f} / "
                  f"{st[('nearest', 'perturbed')]['max_abs_error_s']:.2f} s, adaptive max "
                  f"{st[('adaptive', 'nominal')]['max_abs_error_s']:.2f} / "
                  f"{st[('adaptive', 'perturbed')]['max_abs_error_s']:.2f} s", flush=True)
            print("    " + format_table([r], base_bytes or r.bundle_max_bytes).splitlines()[-1], flush=True)
            for sc in NEAREST_BOUNDS:
                if ("nearest", sc) in r.worst:
                    print(f"    nearest {sc} worst: {format_worst(r.worst[('nearest', sc)])}", flush=True)
    print(f"\nstudy ({time.perf_counter() - t_all:.0f} s wall): |arrival error| over feasible runs [s]; bundle = the "
          f"largest signed bundle, x = relative to today's (default grid, beacons only)")
    print(format_table(results, base_bytes))

    if subset:
        print("\n(part of the line only: no bundle bytes, so no best setting under the bundle bound)")
        best = None
    else:
        best = best_nearest(results, base_bytes, BUNDLE_FACTOR, NEAREST_BOUNDS)
    print(f"\nnearest rule, best setting with the largest bundle under {BUNDLE_FACTOR:g}x today's "
          f"({base_bytes / 1024:.0f} kB):")
    if best is None:
        print("  none")
    else:
        ok = all(best.stats[("nearest", sc)]["max_abs_error_s"] <= b for sc, b in NEAREST_BOUNDS.items())
        print(f"  {best.setting.label}: bundle {best.bundle_max_bytes / 1024:.0f} kB "
              f"({best.bundle_max_bytes / base_bytes:.2f}x); max |error| "
              + ", ".join(f"{sc} {best.stats[('nearest', sc)]['max_abs_error_s']:.2f} s (bound {b:g})"
                          for sc, b in NEAREST_BOUNDS.items()) + f" -> {'met' if ok else 'NOT met'}")
        for sc in NEAREST_BOUNDS:
            w = best.worst.get(("nearest", sc))
            if w is not None:
                print(f"  worst {sc}: {format_worst(w)}")
    print(f"\nadaptive mode, max |error| <= {ADAPTIVE_MAX_S:g} s at every setting:")
    bad = [(r.setting.label, sc, r.stats[("adaptive", sc)]["max_abs_error_s"]) for r in results
           for sc in ("nominal", "perturbed") if r.stats[("adaptive", sc)]["max_abs_error_s"] > ADAPTIVE_MAX_S]
    worst = max(r.stats[("adaptive", sc)]["max_abs_error_s"] for r in results for sc in ("nominal", "perturbed"))
    print(f"  worst {worst:.2f} s -> {'met' if not bad else 'NOT met: ' + '; '.join(f'{a} {b} {c:.2f}' for a, b, c in bad)}")
    for r in results:
        for sc in ("nominal", "perturbed"):
            if r.stats[("adaptive", sc)]["max_abs_error_s"] > ADAPTIVE_MAX_S and ("adaptive", sc) in r.worst:
                print(f"  {r.setting.label} {sc}: {format_worst(r.worst[('adaptive', sc)])}")
    if args.html:
        write_html(results, args.html, line_name=line.name if line.line_id in line.name else f"{line.name} ({line.line_id})", base_bytes=base_bytes)
        print(f"\nwrote {args.html}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
