"""Benchmark: solve time of one minimum-time stopping pattern (docs/design.md §5, issues 5 and 20).

Prints the median (and 90th percentile) wall time per ``solve_stop`` call over a few
thousand seeded random station approaches with up to six event points (positions
where a deceleration or speed limit changes), split by the number of event points;
on position-independent approaches (the problem Ruckig solves), ``solve_stop`` against
Ruckig on the same problems in the same process, both ways fair (:func:`versus_ruckig`:
the whole call from Python on both sides, the compiled core alone on both sides, and the
whole call reading the duration on both sides; CPU time, alternated), against issue 38's
3x and issue 20's 5 µs target;
the solver before it was compiled (``planner/stopping/pattern.py`` at
:data:`BEFORE`, read from git) on the same approaches, with the largest duration
difference; and what compiling the kernel just in time costs a fresh process (what
every process paid before the build at install, and still pays without one: see
:mod:`planner.io.compiled`). Run: ``.venv/bin/python benchmarks/bench_stopping.py``.
"""
from __future__ import annotations

import importlib.util
import math
import random
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.stopping.pattern import decel_limit_profile, solve_stop  # noqa: E402

TARGET_US = 5.0
RATIO_TARGET = 3.0  # issue 38: solve_stop <= 3x Ruckig per call, same inputs, same process
REPEAT = 20  # calls per timed block: CPU time per call is the block's over REPEAT (the timer's cost spread)
N_CASES = 4000
BEFORE = "104b7df"  # the last commit with the pure-Python solver (planner/stopping/pattern.py)
ROOT = Path(__file__).resolve().parents[1]


def random_approach(rng: random.Random):
    """A station approach: 300-900 m from the TASC beacon, 40-110 km/h, gradients and restrictions."""
    X = rng.uniform(300.0, 900.0)
    v0 = rng.uniform(40.0, 110.0) / 3.6
    J = rng.uniform(0.4, 1.0)
    n_grad = rng.randint(0, 3)
    n_speed = rng.randint(0, 6 - n_grad)
    grads = [(0.0, rng.uniform(-10.0, 10.0))] + sorted(
        (rng.uniform(10.0, X - 10.0), rng.uniform(-15.0, 15.0)) for _ in range(n_grad)
    )
    adhesion = rng.uniform(2.5, 3.5) / 3.6
    dl = decel_limit_profile(3.6 / 3.6, adhesion, grads)
    sl = [(0.0, v0 * rng.uniform(1.0, 1.2))] + sorted(
        (rng.uniform(10.0, X - 10.0), rng.uniform(25.0, 100.0) / 3.6) for _ in range(n_speed)
    )
    return v0, X, J, dl, sl


def safe_side_cost(step_m: float = 0.25) -> dict:
    """Time the per-piece safe-side bound of the deceleration limit costs on the sample line.

    The train-averaged gradient is piecewise linear in the front's position;
    the patterns bound each linear piece by its least favourable value
    (:func:`planner.stopping.approach.gradient_steps`). The exact bound is approached
    from the safe side by cutting every piece into ``step_m`` slices, each at
    its own least favourable value (the duration converges to the exact
    bound's from above as the slices shrink); the optimistic slices (each at
    its most favourable value) bound it from below. Over every feasible
    pattern of the nightly sweep (2.5 … 3.5 km/h/s) prints the extra time of
    the per-piece bound against the fine one: sum, median, max.
    """
    import warnings

    import numpy as np

    from planner.stopping import approach
    from planner.physics import dynamics
    from planner.line.loader import load_line
    from planner.line.model import sign
    from planner.stopping.sweep import InfeasibleStopWarning, stop_sweep

    line = load_line(Path(__file__).resolve().parents[1] / "lines" / "sample")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InfeasibleStopWarning)
        results = stop_sweep(line, n_jobs=1)
    extra, bracket = [], []
    for r in results:
        tt = line.train_type(r.train_type)
        sg = sign(r.direction)
        X = r.approach_length_m
        knots, _ = approach._mean_gradient_knots(line, tt.length_m, r.direction, r.approach_start_m, X)
        xs = np.unique(np.concatenate([knots, np.arange(0.0, X, step_m)]))
        g = dynamics.running_gradient(line.gradients, r.approach_start_m + sg * xs, tt.length_m, sg) * 1000.0
        lo = [(float(x), float(v)) for x, v in zip(xs[:-1], np.minimum(g[:-1], g[1:]))]
        hi = [(float(x), float(v)) for x, v in zip(xs[:-1], np.maximum(g[:-1], g[1:]))]
        for a, p in zip(r.adhesion_ms2, r.patterns):
            if not p.feasible:
                continue
            fine = [approach.decel_limits(line, tt, r.direction, r.approach_start_m, X, a, gs)
                    for gs in (lo, hi)]
            q_lo, q_hi = (solve_stop(r.v_start_ms, X, jerk_max=r.jerk_max_ms3, decel_limits=dl,
                                     speed_limits=r.speed_limits) for dl in fine)
            if q_lo.feasible:
                extra.append(p.duration_s - q_lo.duration_s)
                bracket.append(q_lo.duration_s - q_hi.duration_s)
    ex = np.array(extra)
    print(f"  safe-side bound per piece vs {step_m:g} m slices (exact bound), {ex.size} patterns of the "
          f"sample sweep: extra time sum {ex.sum():.2f} s, median {np.median(ex):.4f} s, max {ex.max():.3f} s "
          f"(slices vs optimistic slices: max {max(bracket):.4f} s)")
    return {"n": int(ex.size), "sum_s": float(ex.sum()), "median_s": float(np.median(ex)), "max_s": float(ex.max())}



def position_independent(rng: random.Random):
    """One deceleration limit, the start speed the only speed limit: the problem Ruckig solves too."""
    v0 = rng.uniform(40.0, 110.0) / 3.6
    return v0, rng.uniform(300.0, 900.0), rng.uniform(0.4, 1.0), [(0.0, rng.uniform(0.6, 1.0))], [(0.0, v0)]


def versus_ruckig(cases) -> None:
    """solve_stop against Ruckig on the position-independent ``cases``, both ways fair, against issue 38's 3x.

    (a) the whole call from Python on both sides: ``solve_stop`` (checks, writing the rows, the kernel, the
    StopPattern) against setting Ruckig's inputs from Python and ``calculate``; (b) the core on both
    sides: Ruckig's ``calculate(inp, traj)`` alone, its inputs set beforehand, against the compiled
    stopping kernel alone (``pattern._k.kernel``), its array filled beforehand; (c) as (a), then reading
    the duration on both sides (``p.duration_s``, ``traj.duration``): a StopPattern reads each field from
    its copy of the kernel's output when first read (:mod:`planner.stopping.result`), so (a) alone would
    leave that out. And every field of ours read once after (a) (the five breakpoint tuples built), to
    say what a caller who reads everything pays. Per case each of the seven runs ``REPEAT`` times in a
    block timed in CPU time (``time.process_time``) and wall time, the blocks alternated (order reversed
    every other case) so all see the same machine load; medians over the cases of the time per call.
    """
    import numpy as np

    from planner.stopping import codes, pattern

    try:
        import ruckig
    except ImportError:
        print("  versus Ruckig: ruckig not installed")
        return
    otg, inp, traj = ruckig.Ruckig(1), ruckig.InputParameter(1), ruckig.Trajectory(1)
    inp.current_position, inp.current_acceleration = [0.0], [0.0]
    inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
    calc, kern = otg.calculate, pattern._k.kernel
    work = np.zeros(codes.work_size(2))
    cpu, wall = time.process_time, time.perf_counter
    keys = ("whole ours", "whole ruckig", "core ours", "core ruckig", "read ours", "read ruckig", "all ours")
    t = {key: ([], []) for key in keys}
    worst = 0.0
    for i, (v0, X, J, dl, sl) in enumerate(cases):
        A, C = dl[0][1], sl[0][1]

        def whole_ours():
            for _ in range(REPEAT):
                solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)

        def whole_ruckig():
            for _ in range(REPEAT):
                inp.current_velocity, inp.target_position = [v0], [X]
                inp.max_velocity, inp.max_acceleration, inp.min_acceleration = [C], [A], [-A]
                inp.max_jerk = [J]
                calc(inp, traj)

        def core_ours():
            for _ in range(REPEAT):
                kern(v0, X, J, 1, 2, True, work)

        def core_ruckig():
            for _ in range(REPEAT):
                calc(inp, traj)

        def read_ours():
            for _ in range(REPEAT):
                solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl).duration_s

        def read_ruckig():
            for _ in range(REPEAT):
                inp.current_velocity, inp.target_position = [v0], [X]
                inp.max_velocity, inp.max_acceleration, inp.min_acceleration = [C], [A], [-A]
                inp.max_jerk = [J]
                calc(inp, traj)
                traj.duration

        def all_ours():
            for _ in range(REPEAT):
                p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
                p.feasible, p.reason, p.v_start_ms, p.x_stop_m, p.jerk_max_ms3, p.duration_s, p.brake_start_m
                p.braking_distance_m, p.t_s, p.x_m, p.v_ms, p.a_ms2, p.j_ms3

        inp.current_velocity, inp.target_position = [v0], [X]
        inp.max_velocity, inp.max_acceleration, inp.min_acceleration = [C], [A], [-A]
        inp.max_jerk = [J]
        work[:4] = (0.0, A, 0.0, C)
        runs = [("whole ours", whole_ours), ("whole ruckig", whole_ruckig), ("core ours", core_ours),
                ("core ruckig", core_ruckig), ("read ours", read_ours), ("read ruckig", read_ruckig),
                ("all ours", all_ours)]
        for key, f in runs[::-1] if i % 2 else runs:
            w0, c0 = wall(), cpu()
            f()
            c1, w1 = cpu(), wall()
            t[key][0].append((c1 - c0) / REPEAT)
            t[key][1].append((w1 - w0) / REPEAT)
        p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
        if p.feasible and kern(v0, X, J, 1, 2, True, work) == p.n_pieces:
            worst = max(worst, abs(p.duration_s - traj.duration), abs(p.duration_s - work[6]))
    med = {key: (statistics.median(c) * 1e6, statistics.median(w) * 1e6) for key, (c, w) in t.items()}
    print(f"  versus Ruckig, {len(cases)} position-independent cases (one deceleration limit, the start speed "
          f"the only speed limit), blocks of {REPEAT} calls alternated, medians per call, CPU (wall) µs:")
    for what, ours, theirs, how in (
            ("a", "whole ours", "whole ruckig", "whole call from Python: solve_stop vs setting Ruckig's "
                                                "inputs + calculate"),
            ("b", "core ours", "core ruckig", "core: the compiled stopping kernel, its array filled "
                                              "beforehand, vs calculate, its inputs set beforehand"),
            ("c", "read ours", "read ruckig", "(a) and reading the duration: solve_stop(...).duration_s vs "
                                              "Ruckig's + traj.duration")):
        r = med[ours][0] / med[theirs][0]
        print(f"  ({what}) {how}: {med[ours][0]:.2f} ({med[ours][1]:.2f}) vs {med[theirs][0]:.2f} "
              f"({med[theirs][1]:.2f}): ratio {r:.2f} (CPU), issue 38's target <= {RATIO_TARGET:g}x "
              f"{'met' if r <= RATIO_TARGET else 'NOT met'}")
    print(f"  where (a)'s time goes (medians, CPU): around the compiled core, solve_stop spends "
          f"{med['whole ours'][0] - med['core ours'][0]:.2f} µs in Python (the call, checks, writing the rows, "
          f"the StopPattern holding a copy of the kernel's output), Ruckig "
          f"{med['whole ruckig'][0] - med['core ruckig'][0]:.2f} µs (setting 7 inputs; its result stays in the "
          f"Trajectory it fills); reading every field of ours once after (a) costs "
          f"{med['all ours'][0] - med['whole ours'][0]:.2f} µs more (the 13 fields, the five breakpoint tuples)")
    mo = med["whole ours"][0]
    print(f"  issue 20's target <= {TARGET_US:g} µs per solve_stop here: {'met' if mo <= TARGET_US else 'NOT met'}; "
          f"largest |duration - Ruckig's| {worst:.1e} s")


def solver_before():
    """``solve_stop`` as it was at :data:`BEFORE` (pure Python), loaded from git; None without git."""
    try:
        src = subprocess.run(["git", "show", f"{BEFORE}:planner/stopping/pattern.py"], cwd=ROOT,
                             capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    spec = importlib.util.spec_from_loader("_stopping_before", loader=None)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up
    exec(compile(src, f"{BEFORE}:planner/stopping/pattern.py", "exec"), mod.__dict__)
    return mod.solve_stop


def timed(solve, cases, **kw) -> list[float]:
    """Wall time of every call [s]."""
    out = []
    for v0, X, J, dl, sl in cases:
        t0 = time.perf_counter()
        solve(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, **kw)
        out.append(time.perf_counter() - t0)
    return out


def compile_time() -> tuple[float, float, float]:
    """(numba import, kernel compile) CPU seconds and the wall seconds of both, in a fresh process."""
    code = ("import time; w = time.perf_counter(); t = time.process_time(); import numba; "
            "t1 = time.process_time(); import planner.stopping.kernel; "
            "print(t1 - t, time.process_time() - t1, time.perf_counter() - w)")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    a, b, c = (float(x) for x in out.stdout.split())
    return a, b, c


def kernel_split(cases, solve_times: list[float]) -> None:
    """Where a solve's time goes: the compiled kernel alone (called as solve_stop calls it, on the
    same approaches, its array filled beforehand) against the whole call, median per approach."""
    import numpy as np

    from planner.stopping import codes, pattern

    k = pattern._k
    work = np.zeros(codes.work_size(max(len(c[3]) + len(c[4]) for c in cases)))
    kern = []
    for v0, X, J, dl, sl in cases:
        n = len(dl) + len(sl)
        work[:2 * n] = np.array(dl + sl, dtype=np.float64).ravel()
        t0 = time.perf_counter()
        k.kernel(v0, X, J, len(dl), n, True, work)
        kern.append(time.perf_counter() - t0)
    t0 = time.perf_counter()
    empty = time.perf_counter() - t0
    mk = statistics.median(kern) * 1e6
    rest = statistics.median(a - b for a, b in zip(solve_times, kern)) * 1e6
    print(f"  of which the compiled kernel median {mk:.2f} µs (paper rule and no step-down: ~1 µs; a speed "
          f"step-down adds ~10 trial constructions of the entry choice), the Python around it (checks, "
          f"writing the rows, the StopPattern) median {rest:.2f} µs; each figure includes "
          f"~{empty * 1e6:.2f} µs of timer")


def compare_before(cases) -> None:
    """Median per solve before and after, and the largest difference of the results."""
    before = solver_before()
    if before is None:
        print(f"  before ({BEFORE}): not available (no git history)")
        return
    worst, n, differ = 0.0, 0, 0
    t_old, t_new = [], []
    for rule in ("min-time", "paper"):
        for case in cases:
            v0, X, J, dl, sl = case
            t0 = time.perf_counter()
            a = before(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, rule=rule)
            t1 = time.perf_counter()
            b = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, rule=rule)
            t2 = time.perf_counter()
            if rule == "min-time":
                t_old.append(t1 - t0)
                t_new.append(t2 - t1)
            if a.feasible != b.feasible or a.reason != b.reason or a.n_pieces != b.n_pieces:
                differ += 1
                continue
            if a.feasible:
                n += 1
                worst = max(worst, abs(a.duration_s - b.duration_s),
                            max(abs(p - q) for p, q in zip(a.t_s, b.t_s)))
            elif not (a.braking_distance_m == b.braking_distance_m
                      or math.isnan(a.braking_distance_m) and math.isnan(b.braking_distance_m)):
                differ += 1
    print(f"  before ({BEFORE}, pure Python) median {statistics.median(t_old) * 1e6:.1f} µs, "
          f"after {statistics.median(t_new) * 1e6:.2f} µs per solve (same approaches, alternated): "
          f"{statistics.median(t_old) / statistics.median(t_new):.0f}x")
    print(f"  same results: {n} feasible patterns x both rules, max |dT| {worst:.1e} s over durations and "
          f"breakpoint times; {differ} verdicts or piece counts differ")


def main() -> None:
    cpu_import, cpu_compile, wall = compile_time()
    from planner.io import compiled
    from planner.stopping import codes

    built = compiled.status("stopping", codes.SOURCES)["state"]
    print(f"bench_stopping: kernel {built}; compiling it just in time would cost a fresh process: numba import "
          f"{cpu_import:.2f} s CPU, compile {cpu_compile:.2f} s CPU ({wall:.2f} s wall for both)")
    rng = random.Random(12345)
    cases = [random_approach(rng) for _ in range(N_CASES)]
    by_events: dict[int, list[float]] = {}
    for c in cases[:50]:  # warm-up (the compile, caches)
        solve_stop(c[0], c[1], jerk_max=c[2], decel_limits=c[3], speed_limits=c[4])
    all_t = timed(solve_stop, cases)
    n_feasible = 0
    for (v0, X, J, dl, sl), dt in zip(cases, all_t):
        by_events.setdefault(len({x for x, _ in dl[1:] + sl[1:] if x < X}), []).append(dt)
    paper_t = timed(solve_stop, cases, rule="paper")
    gain: list[float] = []
    for v0, X, J, dl, sl in cases:
        q = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl, rule="paper")
        p = solve_stop(v0, X, jerk_max=J, decel_limits=dl, speed_limits=sl)
        n_feasible += p.feasible
        if q.feasible:
            gain.append(q.duration_s - p.duration_s)
    med = statistics.median(all_t) * 1e6
    p90 = statistics.quantiles(all_t, n=10)[-1] * 1e6
    print(f"  {N_CASES} random approaches ({n_feasible} feasible), up to 6 event points")
    print(f"  solve_stop median {med:.2f} µs, p90 {p90:.2f} µs per pattern (over {TARGET_US:g} µs: "
          f"{sum(t * 1e6 > TARGET_US for t in all_t) / len(all_t):.0%}); "
          f"rule='paper' median {statistics.median(paper_t) * 1e6:.2f} µs")
    g = sorted(gain)
    print(f"  true minimum vs the paper's rule: faster on {sum(x > 1e-9 for x in g)} of {len(g)} patterns, "
          f"by up to {g[-1]:.3f} s (never slower: min {g[0]:+.2e} s)")
    kernel_split(cases, all_t)
    for k in sorted(by_events):
        ts = by_events[k]
        print(f"    {k} event points: n={len(ts):4d}  median {statistics.median(ts) * 1e6:.2f} µs")
    pi = [position_independent(rng) for _ in range(N_CASES)]
    versus_ruckig(pi)
    compare_before(cases[:1000])
    safe_side_cost()


if __name__ == "__main__":
    main()
