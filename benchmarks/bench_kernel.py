"""The integrator's compiled kernel against plain compiled loops of the same physics (issue 20).

Prints:
1. the kernel's cost of first use in a fresh process (import numba and compile), CPU and wall;
2. for batches of 1, 100 and 2,000 runs on the 3 km interstation of ``bench_run_curve.py`` (1 m
   steps, constant ratio from standstill, random load and traction factor): the CPU time of one
   ``simulate()`` call and of two plain compiled loops of the same physics written for this
   benchmark, a C loop (``kernel_ref.c``, gcc -O2, through ctypes) and a minimal numba loop
   (below); runs alternated, median of the repeats; the ratios against the C loop (targets of issue
   38: ≤ 1.2× at batch 1, ≤ 1.0× at 100 and at 2,000; issue 20's were 3×, 2× and 1.5×) and the largest
   difference in running time between planner and each loop;
3. the bit-identity battery: 4 interstations per direction of the sample line for every train type,
   6 runs each with a ratio change, a snapshot and a continuation from it, recorded; the SHA-256
   of every array against ``kernel_battery.json``, the digests of the numpy integrator the kernel
   replaced (computed on the sample line as committed with it; the file's ``about`` records the arrays
   recomputed on purpose since, when a physics fix moved them).

Run: ``python benchmarks/bench_kernel.py`` (from the repository root). Needs gcc for the C loop
(skipped with a note if there is none).
"""
from __future__ import annotations

import ctypes
import hashlib
import json
import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(HERE))

from bench_run_curve import interstation_3km  # noqa: E402
from planner.physics import dynamics  # noqa: E402
from planner.physics.run_curve import RunState, simulate  # noqa: E402
from planner.physics.track import make_track  # noqa: E402

TARGETS = {1: 1.2, 100: 1.0, 2000: 1.0}
SAMPLES = {1: 15, 100: 9, 2000: 5}
CALLS_PER_SAMPLE = {1: 50, 100: 2, 2000: 1}

FIRST_USE = """
import json, time
t0, c0 = time.perf_counter(), time.process_time()
from planner.line import testing
from planner.physics.track import make_track
from planner.physics.run_curve import simulate
t1, c1 = time.perf_counter(), time.process_time()
line = testing.line()
tr = make_track(line, "T", "S0", "S1")
t2, c2 = time.perf_counter(), time.process_time()
simulate(tr, line.train_type("T"), 1.0)
t3, c3 = time.perf_counter(), time.process_time()
simulate(tr, line.train_type("T"), 1.0)
t4, c4 = time.perf_counter(), time.process_time()
print(json.dumps({"import": [t1 - t0, c1 - c0], "first": [t3 - t2, c3 - c2], "second": [t4 - t3, c4 - c3]}))
"""


# --- the minimal numba loop: the same physics as kernel_ref.c, line by line ---------------------

@njit(nogil=True, error_model="numpy")
def _nb_interp(x, xp, fp):
    nt = xp.shape[0]
    if x < xp[0]:
        return fp[0]
    if x >= xp[nt - 1]:
        return fp[nt - 1]
    lo, hi = 0, nt - 1
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    return (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]) * (x - xp[lo]) + fp[lo]


@njit(nogil=True, error_model="numpy")
def _nb_run_batch(s, vn2, ag, b, bstop, tsp, tef, amax, ratio, ram, rbm, rcm, tfi, t_out, work_out):
    m, n = s.shape[0], ratio.shape[0]
    length = s[m - 1]
    c2 = np.empty(m)
    for i in range(n):
        r2 = ratio[i] * ratio[i]
        svc = r2 * vn2[m - 1]
        c2[m - 1] = 0.0
        for k in range(m - 2, -1, -1):
            up = svc + 2.0 * b * (s[k + 1] - s[k])
            svc = min(r2 * vn2[k], up)
            c2[k] = min(2.0 * bstop * (length - s[k]), svc)
        w = v = t = work = 0.0
        c0 = c2[0]
        for k in range(m - 1):
            ds = s[k + 1] - s[k]
            cs0 = ag[k] - (ram[i] + v * (rbm[i] + rcm[i] * v))
            a0 = min(cs0 + _nb_interp(v, tsp, tef) * tfi[i], max(amax, cs0))
            vp = math.sqrt(max(w + 2.0 * ds * a0, 0.0))
            cs1 = ag[k + 1] - (ram[i] + vp * (rbm[i] + rcm[i] * vp))
            a1 = min(cs1 + _nb_interp(vp, tsp, tef) * tfi[i], max(amax, cs1))
            slope = a0 + a1
            wend = w + slope * ds
            c1 = c2[k + 1]
            frac, w1 = 1.0, wend
            if wend > c1:
                frac, w1 = (w - c0) / ((w - c0) - (wend - c1)), c1
            xc = frac * ds
            wc = w + slope * xc
            vc, v1, rest = math.sqrt(wc), math.sqrt(w1), ds - xc
            cb = 0.5 * (cs0 + cs1)
            t += 2.0 * (xc / (v + vc) + rest / (vc + v1))
            work += xc * (0.5 * slope - cb) + max(0.5 * (w1 - wc) - rest * cb, 0.0)
            w, v, c0 = w1, v1, c1
        t_out[i], work_out[i] = t, work


class References:
    """The two plain loops on one track, fed the same per-run constants as the planner."""

    def __init__(self, track, train, tmp: Path):
        self.train = train
        self.s = track.s_m
        self.vn2 = track.vmax_ms ** 2
        self.ag = dynamics.track_accel_ms2(track.gradient, track.curve_specific, train.rotating_mass_factor)
        self.tsp = np.ascontiguousarray(train.traction_speed_ms, dtype=float)
        self.tef = np.ascontiguousarray(train.traction_effort_N, dtype=float)
        self.lib = None
        gcc = shutil.which("gcc")
        if gcc:
            so = tmp / "kernel_ref.so"
            subprocess.run([gcc, "-O2", "-shared", "-fPIC", "-o", str(so), str(HERE / "kernel_ref.c"), "-lm"],
                           check=True)
            self.lib = ctypes.CDLL(str(so))

    def _per_run(self, ratio, load, tf):
        tr = self.train
        inv = 1.0 / dynamics.effective_mass_kg(dynamics.mass_kg(tr.empty_mass_kg, tr.full_load_mass_kg, load),
                                               tr.rotating_mass_factor)
        return ratio, tr.davis_a_N * inv, tr.davis_b_N_per_ms * inv, tr.davis_c_N_per_ms2 * inv, tf * inv

    def c(self, ratio, load, tf, walk: bool = False):
        tr, n = self.train, ratio.size
        p = [np.ascontiguousarray(a, dtype=float) for a in self._per_run(ratio, load, tf)]
        t, work, c2 = np.empty(n), np.empty(n), np.empty(len(self.s))
        ptr = ctypes.POINTER(ctypes.c_double)
        d, i = ctypes.c_double, ctypes.c_int
        (self.lib.run_batch_walk if walk else self.lib.run_batch)(i(len(self.s)), *(a.ctypes.data_as(ptr) for a in (self.s, self.vn2, self.ag)),
                           d(tr.service_brake_ms2), d(tr.stop_brake_ms2), i(len(self.tsp)),
                           self.tsp.ctypes.data_as(ptr), self.tef.ctypes.data_as(ptr), d(tr.max_accel_ms2), i(n),
                           *(a.ctypes.data_as(ptr) for a in p + [c2, t, work]))
        return t

    def numba(self, ratio, load, tf):
        tr, n = self.train, ratio.size
        t, work = np.empty(n), np.empty(n)
        _nb_run_batch(self.s, self.vn2, self.ag, tr.service_brake_ms2, tr.stop_brake_ms2, self.tsp, self.tef,
                      tr.max_accel_ms2, *self._per_run(ratio, load, tf), t, work)
        return t


def first_use() -> None:
    out = subprocess.run([sys.executable, "-c", FIRST_USE], cwd=ROOT, capture_output=True, text=True, check=True)
    f = json.loads(out.stdout)
    print("kernel first use in a fresh process (wall / CPU s): "
          f"import planner physics incl. numba {f['import'][0]:.2f} / {f['import'][1]:.2f}; "
          f"first simulate() incl. compile {f['first'][0]:.2f} / {f['first'][1]:.2f}; "
          f"second {f['second'][0] * 1e3:.2f} / {f['second'][1] * 1e3:.2f} ms")


def cpu_per_call(fn, calls: int) -> float:
    c0 = time.process_time()
    for _ in range(calls):
        fn()
    return (time.process_time() - c0) / calls


def ratios_table(refs: References, track, train) -> None:
    steps = len(track.s_m) - 1
    grid = np.array([1.0, 0.9, 0.8, 0.7, 0.65, 0.6, 0.55, 0.5, 0.45, 0.4, 0.35, 0.3, 0.25, 0.2])
    names = ["planner", "numba loop"] + (["C -O2", "C walk"] if refs.lib else [])
    print(f"\n3 km interstation, {steps} steps of ≤ {track.settings.ds_m:g} m; CPU time per call, median of "
          "alternated samples")
    print("C: the plain loop bisecting the traction table (as the kernel); C walk: the same loop walking from the "
          "last interval")
    print(f"{'batch':>6} {'planner ms':>11} {'C ms':>9} {'numba ms':>9} {'× C':>6} {'× C walk':>9} {'× numba':>8} "
          f"{'target':>7} {'ns/run-step':>12} {'max |Δt| s':>11}")
    for n in (1, 100, 2000):
        rng = np.random.default_rng(n)
        ratio, load, tf = np.resize(grid, n), rng.uniform(0.0, 1.0, n), rng.uniform(0.9, 1.0, n)
        fns = {"planner": lambda: simulate(track, train, ratio, load=load, traction_factor=tf).time_s,
               "numba loop": lambda: refs.numba(ratio, load, tf), "C -O2": lambda: refs.c(ratio, load, tf),
               "C walk": lambda: refs.c(ratio, load, tf, walk=True)}
        times = {k: [] for k in names}
        for j in range(SAMPLES[n]):
            for name in names[j % len(names):] + names[:j % len(names)]:  # alternate the order
                times[name].append(cpu_per_call(fns[name], CALLS_PER_SAMPLE[n]))
        med = {k: statistics.median(v) for k, v in times.items()}
        got = fns["planner"]()
        dev = max(float(np.max(np.abs(got - fns[k]()))) for k in names[1:])
        c_ms = f"{med['C -O2'] * 1e3:>9.3f}" if refs.lib else f"{'-':>9}"
        x_c = f"{med['planner'] / med['C -O2']:>6.2f}" if refs.lib else f"{'-':>6}"
        x_w = f"{med['planner'] / med['C walk']:>9.2f}" if refs.lib else f"{'-':>9}"
        print(f"{n:>6} {med['planner'] * 1e3:>11.3f} {c_ms} {med['numba loop'] * 1e3:>9.3f} {x_c} {x_w} "
              f"{med['planner'] / med['numba loop']:>8.2f} {TARGETS[n]:>6.1f}× "
              f"{med['planner'] / (n * steps) * 1e9:>12.1f} {dev:>11.1e}")


def battery() -> dict[str, np.ndarray]:
    """Every array of the battery (the same calls as the lead's reference run of the numpy integrator)."""
    import planner

    line = planner.load_line(ROOT / "lines" / "sample")
    out, i = {}, 0
    for tt in [t.train_type for t in line.train_types]:
        for d in ("down", "up"):
            for a, b in line.interstations(d)[:4]:
                tr = make_track(line, tt, a.station_id, b.station_id, nodes_m=[200.0, 700.0])
                train = line.train_type(tt)
                r = np.array([1.0, 0.9, 0.8, 0.65, 0.5, 0.35])
                res = simulate(tr, train, r, load=np.array([0, 0.5, 1, 0, 1, 0.3]),
                               traction_factor=np.array([1, 0.9, 1, 0.95, 0.9, 1]),
                               changes=[(700.0, np.array([0.7, 1.0, 0.5, 0.9, 0.6, 0.4]))],
                               snapshots_m=[200.0], record=True)
                for k in ("time_s", "energy_kwh", "t_s", "v_ms", "a_ms2", "phase", "ratio"):
                    out[f"{i}_{k}"] = getattr(res, k)
                sn = res.snapshots[200.0]
                st = RunState(sn.s_m, sn.t_s, sn.v_ms, sn.phase, sn.ratio)
                out[f"{i}_cont"] = simulate(tr, train, r[::-1].copy(), start=st).time_s
                i += 1
    return out


def digest(x: np.ndarray) -> str:
    h = hashlib.sha256(f"{x.dtype.str}{x.shape}".encode())
    h.update(np.ascontiguousarray(x).tobytes())
    return h.hexdigest()


def bit_identity() -> None:
    want = json.loads((HERE / "kernel_battery.json").read_text())["digests"]
    t0 = time.process_time()
    got = battery()
    cpu = time.process_time() - t0
    differ = sorted(k for k in want if k not in got or digest(got[k]) != want[k])
    print(f"\nbit-identity battery: {len(got)} arrays, {len(differ)} differ from the numpy integrator's digests "
          f"({cpu:.2f} s CPU)" + (f"; first: {', '.join(differ[:5])}" if differ else ": byte-identical"))


def main() -> None:
    first_use()
    line, tt = interstation_3km()
    track = make_track(line, "B", "S0", "S1")
    simulate(track, tt, 1.0)
    with tempfile.TemporaryDirectory() as tmp:
        refs = References(track, tt, Path(tmp))
        if refs.lib is None:
            print("no gcc: the C loop is skipped")
        one = np.ones(1)
        refs.numba(one, one * 0, one)  # compile the numba loop outside the timings
        ratios_table(refs, track, tt)
    bit_identity()


if __name__ == "__main__":
    main()
