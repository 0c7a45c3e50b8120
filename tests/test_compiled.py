"""The kernels built at install (planner.io.compiled): loaded, the same to the bit, and trusted only by digest.

``make test`` builds them first (``planner kernels build``), as ``make install`` does, so the
in-process kernels here are the built ones. Their results are checked against independent
references: the integrator against the digests of the numpy integrator it replaced
(``benchmarks/kernel_battery.json``, committed with that integrator; 8 of its 192 arrays recomputed on purpose
when a physics fix moved them, as its ``about`` records), and the stopping solver
against the same source compiled just in time, on random requests.
"""
from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from planner.io import compiled
from planner.physics import kernel_abi as K
from planner.stopping import codes

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "benchmarks"


def _bench_kernel():
    spec = importlib.util.spec_from_file_location("bench_kernel", BENCH / "bench_kernel.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_both_kernels_are_built_for_these_sources():
    """`make install` / `make test` build them; a process then compiles nothing (`planner kernels status`)."""
    from planner.stopping import pattern

    for kind, sources in (("integrator", K.SOURCES), ("stopping", codes.SOURCES)):
        st = compiled.status(kind, sources)
        assert st["state"] == "built", f"{kind}: {st['state']}; run `planner kernels build` (make test does)"
    assert K.backend() == "aot"
    assert type(K.load().advance).__name__ == "builtin_function_or_method"  # not a numba dispatcher
    pattern.solve_stop(20.0, 400.0, jerk_max=0.8, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 25.0)])
    assert pattern._k.__name__.startswith("_aot_stopping_")
    code = ("import sys, planner.api, planner.stopping.pattern as p; "
            "p.solve_stop(20.0, 400.0, jerk_max=0.8, decel_limits=[(0.0, 1.0)], speed_limits=[(0.0, 25.0)]); "
            "from planner.physics import run_curve; "
            "print(sorted(m for m in ('numba', 'planner.physics.kernel', 'planner.stopping.kernel') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={k: v for k, v in os.environ.items() if k != "PLANNER_JIT"})
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr[-1500:]  # no compiler loaded


def test_the_built_integrator_reproduces_the_numpy_integrator_to_the_bit():
    """The 192-array battery (runs with ratio changes, snapshots, continuations) against the digests of the
    numpy integrator the kernel replaced; then the same in a process that compiles just in time."""
    bench = _bench_kernel()
    want = json.loads((BENCH / "kernel_battery.json").read_text())["digests"]
    got = bench.battery()
    assert len(got) == len(want) == 192
    differ = sorted(k for k in want if bench.digest(got[k]) != want[k])
    assert differ == [], f"{len(differ)} arrays differ, first {differ[:3]}"

    code = ("import json, sys; sys.path.insert(0, {b!r}); import bench_kernel as b; "
            "from planner.physics import kernel_abi as K; assert K.backend() == 'jit', K.backend(); "
            "print(json.dumps({{k: b.digest(v) for k, v in b.battery().items()}}))").format(b=str(BENCH))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                         env={**os.environ, "PLANNER_JIT": "1"})
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout) == want


def _random_requests(n: int, seed: int):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        v0, X, J = rng.uniform(1, 35), rng.uniform(20, 1500), rng.uniform(0.3, 1.2)
        dl = [(0.0, rng.uniform(0.3, 1.3))] + [(float(x), rng.uniform(0.3, 1.3))
                                               for x in np.sort(rng.uniform(1, X, rng.integers(0, 3)))]
        sl = [(0.0, v0 + rng.uniform(0, 5))] + [(float(x), rng.uniform(3, 30))
                                                for x in np.sort(rng.uniform(1, X, rng.integers(0, 3)))]
        yield v0, X, J, np.array(dl + sl, dtype=np.float64), len(dl), bool(rng.integers(0, 2))


def test_the_built_stopping_solver_equals_the_jit_one_to_the_bit():
    """1,500 random requests (feasible, infeasible and refused alike): every output word identical."""
    from planner.stopping import kernel as jit_kernel  # the source, compiled just in time here
    from planner.stopping import pattern

    pattern._k = None
    built = pattern._compiled()
    assert built is not jit_kernel and built.__name__.startswith("_aot_stopping_")
    verdicts = set()
    for v0, X, J, steps, n_dl, opt in _random_requests(1500, seed=7):
        n = len(steps)
        a, b = np.zeros(codes.work_size(n)), np.zeros(codes.work_size(n))
        a[:2 * n] = b[:2 * n] = steps.ravel()
        na = built.kernel(v0, X, J, n_dl, n, opt, a)
        nb = jit_kernel.kernel(v0, X, J, n_dl, n, opt, b)
        assert na == nb and a.tobytes() == b.tobytes(), (v0, X, J, steps.tolist(), n_dl, opt)
        verdicts.add(min(na, 1))
    # an array too small for the request's work is refused before anything is written (no bounds checks)
    small = np.zeros(codes.work_size(2) - 1)
    small[:4] = 0.0, 1.0, 0.0, 25.0
    for k in (built, jit_kernel):
        assert k.kernel(20.0, 400.0, 0.8, 1, 2, True, small) == -codes.INTERNAL
        assert small[:4].tolist() == [0.0, 1.0, 0.0, 25.0] and not small[4:].any()
    bad = np.array([[0.0, 1.0], [5.0, 1.0], [4.0, 2.0]])
    assert built.check_steps(bad, 0, 3, 1) == jit_kernel.check_steps(bad, 0, 3, 1) == (codes.NOT_SORTED, 2)
    assert 1 in verdicts and min(verdicts) < 0  # both solved and refused requests were compared


def test_the_integrator_refuses_arrays_the_built_code_would_misread():
    """The built functions do not check their arguments: check_layout does, before any call."""
    good = np.zeros((2, 3))
    K.check_layout(par=good, flags=np.zeros(5, dtype=np.int64))
    with pytest.raises(TypeError, match="par: expected C-contiguous float64 of rank 2"):
        K.check_layout(par=good.astype(np.float32))
    with pytest.raises(TypeError, match="par"):
        K.check_layout(par=np.zeros((3, 2)).T)  # Fortran order
    with pytest.raises(TypeError, match="flags"):
        K.check_layout(flags=np.zeros(5))


@pytest.fixture()
def aot_dir(tmp_path, monkeypatch):
    monkeypatch.setattr(compiled, "AOT_DIR", tmp_path)
    monkeypatch.delenv("PLANNER_JIT", raising=False)
    return tmp_path


def _plant(aot_dir: Path, kind: str, sources, payload: bytes, record: dict | None):
    name = compiled.module_name(kind, sources)
    so = aot_dir / f"{name}{importlib.machinery.EXTENSION_SUFFIXES[0]}"
    so.write_bytes(payload)
    if record is not None:
        (aot_dir / f"{name}.json").write_text(json.dumps(record))
    return name, so


def test_a_build_that_does_not_match_its_digest_is_never_loaded(aot_dir):
    """An altered file, a missing record and a record of another module all fall back to just in time
    (kind "probe": the real integrator's module is already loaded in this process)."""
    real = b"\x7fELF not really a module"
    name, so = _plant(aot_dir, "probe", K.SOURCES, real, {"module": "x", "sha256": "0" * 64})
    with pytest.warns(RuntimeWarning, match="does not match its digest record"):
        assert compiled.load("probe", K.SOURCES) is None
    (aot_dir / f"{name}.json").unlink()
    with pytest.warns(RuntimeWarning, match="does not match"):
        assert compiled.load("probe", K.SOURCES) is None
    assert compiled.status("probe", K.SOURCES)["state"].startswith("jit")
    (aot_dir / f"{name}.json").write_text(json.dumps({"module": name, "sha256": hashlib.sha256(real).hexdigest()}))
    with pytest.warns(RuntimeWarning, match="does not import"):  # intact by its digest, but no module: refused
        assert compiled.load("probe", K.SOURCES) is None


def test_an_edited_kernel_source_names_another_module(tmp_path, monkeypatch):
    """The module's name carries the digest of its sources, compilers and CPU: a stale or foreign build is
    never found."""
    pkg = tmp_path / "aotprobe"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    src = pkg / "k.py"
    src.write_text("X = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = compiled.module_name("probe", ("aotprobe.k",))
    src.write_text("X = 2\n")
    after = compiled.module_name("probe", ("aotprobe.k",))
    assert before != after and before.startswith("_aot_probe_")
    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda d: "0.0-test" if d == "llvmlite" else real(d))
    foreign = compiled.module_name("probe", ("aotprobe.k",))
    assert foreign != after
    monkeypatch.setattr(importlib.metadata, "version", real)
    monkeypatch.setattr(compiled, "host_cpu", lambda: "othercpu:+sse2")  # an environment copied elsewhere
    assert compiled.module_name("probe", ("aotprobe.k",)) not in (after, foreign)
    with pytest.raises(ValueError):
        compiled.module_name("../x", ("aotprobe.k",))


def test_planner_jit_skips_the_builds(monkeypatch):
    monkeypatch.setenv("PLANNER_JIT", "1")
    assert compiled.load("stopping", codes.SOURCES) is None
    assert compiled.status("stopping", codes.SOURCES)["state"] == "jit (PLANNER_JIT set)"
    assert compiled.status("stopping", codes.SOURCES, env=False)["state"] == "built"


def test_kernels_status_command_reports_both():
    from typer.testing import CliRunner

    from planner.cli import app

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = CliRunner().invoke(app, ["kernels", "status"])
    assert res.exit_code == 0, res.output
    assert "integrator: built:" in res.output and "stopping: built:" in res.output and "delay: built:" in res.output
