"""The package layout holds (ARCHITECTURE.md): floors import only downwards, the
algorithm floors are pure, and no module or algorithm function grows past its size.

Imports are read from the source (every ``import``/``from`` statement, also those
inside functions), so a lazy import cannot hide from the check.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "planner"

FLOORS = ["errors", "io", "line", "physics", "tables", "stopping", "network", "delay", "datasets", "bundle", "report", "pages",
          "job", "api", "cli"]
"""Ground floor first; a floor imports only from itself and the floors before it."""

ALGORITHMS = ("physics", "tables", "stopping", "network", "delay")
IMPURE = ("pandas", "pyarrow", "matplotlib", "planner.line.loader", "planner.api", "planner.io.parquet")
"""What an algorithm floor never imports: frames, Arrow, charts, and anything that reads a line or dataset."""
ROOT_LOADERS = {"load_line", "running_time", "timekeeping_run"}
"""``from planner import load_line`` climbs back up to the package root's loader."""

MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 120


def floor_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "planner"


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(source: str, module: str, is_package: bool) -> list[tuple[int, str]]:
    """Every module an import statement in ``source`` names, absolute, with its line number."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if is_package else module.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            out.append((node.lineno, target))
            if target == "planner":
                # `from planner import x`: x may be a sub-package or a root function
                out += [(node.lineno, "planner." + a.name) for a in node.names]
    return out


def modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path, module_name(path)


def impure_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    bad = []
    for lineno, target in imports(source, module, is_package):
        if any(target == p or target.startswith(p + ".") for p in IMPURE):
            bad.append(f"{module}:{lineno} imports {target}")
        elif target.startswith("planner.") and target.split(".")[1] in ROOT_LOADERS:
            bad.append(f"{module}:{lineno} imports {target} from the package root")
    return bad


def upward_imports(source: str, module: str, is_package: bool = False) -> list[str]:
    here = floor_of(module)
    if here not in FLOORS:
        return []
    bad = []
    for lineno, target in imports(source, module, is_package):
        if not target.startswith("planner."):
            continue
        there = target.split(".")[1]
        if there in ROOT_LOADERS:
            there = "api"
        if there in FLOORS and FLOORS.index(there) > FLOORS.index(here):
            bad.append(f"{module}:{lineno} imports {target} ({there} is above {here})")
    return bad


def test_the_checks_can_fail():
    """Planted imports are caught, also lazy ones and relative ones."""
    src = "def f():\n    import pandas as pd\n    from ..line.loader import load_line\n    from planner import load_line\n"
    assert len(impure_imports(src, "planner.tables.x")) == 3
    assert upward_imports("from planner.report import margins\n", "planner.physics.x")
    assert upward_imports("from ..job import config\n", "planner.tables.x")
    assert not upward_imports("from planner.physics import dynamics\n", "planner.tables.x")


def test_every_module_sits_on_a_floor():
    floors = {floor_of(m) for _, m in modules()} - {"planner", "__main__"}
    assert floors <= set(FLOORS), f"sub-packages not on a floor: {sorted(floors - set(FLOORS))}; add to FLOORS"


def test_algorithm_floors_are_pure():
    bad = []
    for path, mod in modules():
        if floor_of(mod) in ALGORITHMS:
            bad += impure_imports(path.read_text(), mod, path.name == "__init__.py")
    assert not bad, "algorithm floors import frames, Arrow, charts or a loader:\n" + "\n".join(bad)


def test_no_floor_imports_upward():
    bad = []
    for path, mod in modules():
        bad += upward_imports(path.read_text(), mod, path.name == "__init__.py")
    assert not bad, "imports running back up:\n" + "\n".join(bad)


def test_module_sizes():
    big = [f"{mod}: {n} lines" for path, mod in modules()
           if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES]
    assert not big, f"modules over {MAX_MODULE_LINES} lines:\n" + "\n".join(big)


def long_functions(source: str, module: str) -> list[str]:
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            n = node.end_lineno - node.lineno + 1
            if n > MAX_FUNCTION_LINES:
                out.append(f"{module}.{node.name} (line {node.lineno}): {n} lines")
    return out


def test_function_sizes_in_algorithm_floors():
    long = []
    for path, mod in modules():
        if floor_of(mod) in ALGORITHMS:
            long += long_functions(path.read_text(), mod)
    assert not long, f"functions over {MAX_FUNCTION_LINES} lines:\n" + "\n".join(long)


@pytest.mark.parametrize("floor", ALGORITHMS)
def test_algorithm_floors_import_without_frames(floor):
    """Importing a pure floor in a fresh interpreter loads neither pandas nor pyarrow nor matplotlib."""
    import subprocess
    import sys

    code = ("import importlib, pkgutil, sys, planner.{f} as p\n"
            "for m in pkgutil.walk_packages(p.__path__, 'planner.{f}.'): importlib.import_module(m.name)\n"
            "print(','.join(sorted(k for k in ('pandas', 'pyarrow', 'matplotlib') if k in sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code.format(f=floor)], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"importing planner.{floor} loads {out.stdout.strip()}"


def test_the_code_digest_covers_every_floor():
    """The cache key's code digest reads the whole package: a change on any floor recomputes."""
    from planner.job.units import code_files

    seen = {module_name(p) for p in code_files()}
    assert seen == {m for _, m in modules()}
    assert {floor_of(m) for m in seen} >= set(FLOORS) - {"api"} | {"planner"}


def test_the_code_digest_names_the_compilers(monkeypatch):
    """A new numba (or llvmlite, numpy) compiles different machine code: cached units must not be reused."""
    import importlib.metadata

    from planner.job import units

    monkeypatch.setattr(units, "_CODE_DIGEST", None)
    before = units.code_digest()
    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda d: "0.0-test" if d == "numba" else real(d))
    monkeypatch.setattr(units, "_CODE_DIGEST", None)
    assert units.code_digest() != before
