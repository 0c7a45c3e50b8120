"""The kernels' machine code, built once at install instead of in every process.

The compiled kernels (:mod:`planner.physics.kernel`, the integrator's inner loop,
and :mod:`planner.stopping.kernel`, the stopping solver) are numba functions.
Compiled just in time they cost about 5 s (integrator) and 8 s (solver) of CPU in
every process that uses them: the main process and each parallel worker, every
night. :func:`build` compiles them ahead of time with ``numba.pycc`` into an
ordinary CPython extension module under ``planner/_aot/`` (``make install`` runs
``planner kernels build``); :func:`load` imports that module instead of
compiling. It is the same source compiled by the same compiler for the same
CPU (tuned to the host, as the JIT is); the results are the same to the bit
(``tests/test_compiled.py`` runs both on the kernel battery and on random stops).

Why not numba's own ``cache=True``: its index is a pickle read back from disk,
and the project trusts no pickle on disk. An extension module is code installed
like any other in the environment (``planner/_aot/`` beside the package's
sources, git-ignored), and it is trusted only under two digests:

- its name carries the digest of its **sources** (the kernel modules' bytes, and
  the numba, llvmlite and numpy versions, Python ABI and host CPU model and
  features that compiled them), so an edited kernel, a new compiler or an
  environment copied to another CPU never loads a stale or foreign build:
  :func:`load` finds no module of that name and the kernel compiles just in
  time, as before;
- a sidecar ``<name>.json`` written with it records the SHA-256 of the module
  file, checked before the import, so a truncated or altered file is refused.

``PLANNER_JIT=1`` in the environment skips the built modules (to compare the two,
or to debug the kernels with numba's own tools).
"""
from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.metadata
import importlib.util
import json
import os
import sys
import tempfile
import warnings
from pathlib import Path
from types import ModuleType

AOT_DIR = Path(__file__).resolve().parents[1] / "_aot"
"""Where the built modules live: inside the installed package, never in the work tree's outputs."""

COMPILERS = ("numba", "llvmlite", "numpy")
"""Their versions go into every digest: machine code is theirs as much as the source's."""


def source_digest(kind: str, modules: tuple[str, ...]) -> str:
    """SHA-256 over what a build of ``kind`` is made from: the sources of ``modules``, the compilers, the ABI."""
    h = hashlib.sha256(f"planner-aot\0{kind}\0{sys.implementation.cache_tag}\0{host_cpu()}\0".encode())
    for dist in COMPILERS:
        h.update(f"{dist}={importlib.metadata.version(dist)}\0".encode())
    for name in modules:
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            raise ImportError(f"kernel source {name} not found")
        h.update(name.encode() + b"\0" + Path(spec.origin).read_bytes() + b"\0")
    return h.hexdigest()


def host_cpu() -> str:
    """This machine's CPU model and features as LLVM names them: a build is tuned for them (as the JIT
    is) and so runs only here; another CPU finds no build of its name and compiles just in time."""
    import llvmlite.binding as ll  # about 0.05 s, against 0.4 s for numba itself

    return f"{ll.get_host_cpu_name()}:{ll.get_host_cpu_features().flatten()}"


def module_name(kind: str, modules: tuple[str, ...]) -> str:
    """The extension module's name (and so its file's): ``_aot_<kind>_<first 16 hex of the source digest>``."""
    if not kind.isidentifier():
        raise ValueError(f"kernel kind {kind!r} is not an identifier")
    return f"_aot_{kind}_{source_digest(kind, modules)[:16]}"


def _paths(name: str) -> tuple[Path, Path]:
    suffix = importlib.machinery.EXTENSION_SUFFIXES[0]
    return AOT_DIR / f"{name}{suffix}", AOT_DIR / f"{name}.json"


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _jit_forced() -> bool:
    return os.environ.get("PLANNER_JIT", "") not in ("", "0")


def _record_state(name: str, so: Path, meta: Path) -> str:
    """``"built"`` when the record beside module file ``so`` names it and holds its SHA-256, else why not."""
    try:
        record = json.loads(meta.read_text(encoding="utf-8"))
        ok = record.get("module") == name and record.get("sha256") == _file_digest(so)
    except (OSError, ValueError, AttributeError):
        return "jit (no readable digest record)"
    return "built" if ok else "jit (file does not match its digest)"


def load(kind: str, modules: tuple[str, ...]) -> ModuleType | None:
    """The built module of ``kind`` if there is one for exactly these sources and its file is intact, else None."""
    if _jit_forced():
        return None
    try:
        name = module_name(kind, modules)
    except (ImportError, OSError):
        return None
    if name in sys.modules:
        return sys.modules[name]
    so, meta = _paths(name)
    if not so.is_file():
        return None
    if _record_state(name, so, meta) != "built":
        warnings.warn(f"compiled kernel {so} does not match its digest record {meta.name}; ignoring it and "
                      f"compiling just in time (rebuild with: planner kernels build)", RuntimeWarning, stacklevel=2)
        return None
    loader = importlib.machinery.ExtensionFileLoader(name, str(so))
    spec = importlib.util.spec_from_file_location(name, so, loader=loader)
    try:
        module = importlib.util.module_from_spec(spec)
        loader.exec_module(module)
    except ImportError as e:
        warnings.warn(f"compiled kernel {so} does not import ({e}); compiling just in time (rebuild with: "
                      f"planner kernels build)", RuntimeWarning, stacklevel=2)
        return None
    sys.modules[name] = module
    return module


def status(kind: str, modules: tuple[str, ...], *, env: bool = True) -> dict[str, str]:
    """What :func:`load` would do for ``kind``: ``{"kind", "module", "state", "path"}`` (for ``planner kernels``);
    ``env=False``: whether the build is there and intact, whatever ``PLANNER_JIT`` says."""
    name = module_name(kind, modules)
    so, meta = _paths(name)
    if env and _jit_forced():
        state = "jit (PLANNER_JIT set)"
    elif not so.is_file():
        state = "jit (not built for these sources)"
    else:
        state = _record_state(name, so, meta)
    return {"kind": kind, "module": name, "state": state, "path": str(so)}


def build(kind: str, modules: tuple[str, ...], exports: dict) -> Path:
    """Compile ``exports`` (``{name: (numba dispatcher, signature)}``) into ``kind``'s module; its path.

    Written beside a temporary name and renamed into place with its digest record, so a
    failed or interrupted build leaves the previous state (JIT or the older build);
    builds of ``kind`` for other sources are removed.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # numba.pycc is "pending deprecation"; it is numba's AOT path today
        from numba.pycc import CC

    name = module_name(kind, modules)
    so, meta = _paths(name)
    AOT_DIR.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=AOT_DIR, prefix=".build-") as tmp:
        cc = CC(name)
        cc.output_dir = tmp
        cc.verbose = False
        cc.target_cpu = "host"  # as numba's JIT does; the CPU is part of the module's name (host_cpu)
        for export, (dispatcher, signature) in exports.items():
            cc.export(export, signature)(dispatcher.py_func)
        cc.compile()
        built = Path(tmp) / so.name
        if not built.is_file():
            raise RuntimeError(f"numba.pycc wrote no {so.name}")
        record = {"module": name, "sha256": _file_digest(built), "sources": list(modules),
                  "compilers": {d: importlib.metadata.version(d) for d in COMPILERS}}
        tmp_meta = Path(tmp) / meta.name
        tmp_meta.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(tmp_meta, meta)  # the record first: a module without its record is never loaded
        os.replace(built, so)
    for old in AOT_DIR.glob(f"_aot_{kind}_*"):
        if not old.name.startswith(name + ".") and old.name != name:
            old.unlink(missing_ok=True)
    return so
