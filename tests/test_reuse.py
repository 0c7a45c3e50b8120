"""Exact reuse of identical runs (planner.physics.reuse): the same bytes as stepping every run.

The reference is always the integrator with reuse switched off (every run stepped on its own),
or a run simulated alone; the comparisons are of bits (``_same``), never within a tolerance.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from linedb import default_tables, write_line_db

ROOT = Path(__file__).resolve().parents[1]


def _leaves(x, path=""):
    """Every array (and scalar, as its repr) of a result, with where it sits."""
    if isinstance(x, np.ndarray):
        yield path, x
    elif dataclasses.is_dataclass(x):
        for f in dataclasses.fields(x):
            yield from _leaves(getattr(x, f.name), f"{path}.{f.name}")
    elif isinstance(x, dict):
        for k in sorted(x):
            yield from _leaves(x[k], f"{path}[{k!r}]")
    elif isinstance(x, (tuple, list)):
        for i, y in enumerate(x):
            yield from _leaves(y, f"{path}[{i}]")
    else:
        yield path, np.asarray(repr(x))


def _same(a, b) -> list[str]:
    """Where two results differ in any bit (empty: they are the same bytes)."""
    la, lb = list(_leaves(a)), list(_leaves(b))
    assert [p for p, _ in la] == [p for p, _ in lb]
    return [p for (p, x), (_, y) in zip(la, lb)
            if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes()]


def _both(monkeypatch, fn, merges: bool | None = True):
    """``fn()`` with reuse off, then on; with ``merges``, runs did follow others (else the
    comparison would show nothing; None: not asked, the batch stops at a stall)."""
    from planner.physics import reuse

    followed = []
    expand = reuse.Reuse.expand
    monkeypatch.setattr(reuse.Reuse, "expand", lambda self: (followed.append(self.f_idx.size), expand(self))[1])
    out = []
    for on in (False, True):
        monkeypatch.setattr(reuse, "ENABLED", on)
        out.append(fn())
    assert merges is None or (sum(followed) > 0) == merges
    return out


def test_equal_groups_puts_together_only_equal_columns():
    from planner.physics import reuse

    keys = np.array([[1, 2], [3, 4], [1, 2], [5, 6], [3, 4], [1, 2], [1, 3]], np.uint64).T
    assert reuse.equal_groups(keys).tolist() == [0, 1, 0, 3, 1, 0, 6]
    # a hash that collides everywhere (multiplier 0: every hash is the last word's): still only equal
    # columns meet, each with the first of its kind
    keys = np.array([[1, 2], [3, 2], [1, 2], [4, 2], [3, 2], [4, 2]], np.uint64).T
    assert reuse.equal_groups(keys, mix=np.uint64(0)).tolist() == [0, 1, 0, 3, 1, 3]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    import planner

    return planner.load_line(write_line_db(tmp_path_factory.mktemp("tiny") / "tiny"))


def test_copies_of_a_run_end_as_the_run_alone(tiny, monkeypatch):
    """Ten copies of one run, started at different times: the batch steps one of them; each copy's
    time and energy are those of simulating it alone, to the bit."""
    from planner.physics import reuse
    from planner.physics.run_curve import RunState, simulate
    from planner.physics.track import make_track

    monkeypatch.setattr(reuse, "ENABLED", True)
    for tt in ("EMU10", "EMU6"):
        track = make_track(tiny, tt, "A", "B")
        train = tiny.train_type(tt)
        t0 = np.linspace(0.0, 1e4, 10) + np.pi

        def start(i):
            return RunState(np.full(i.size, 300.0), t0[i], np.full(i.size, 12.0),
                            np.zeros(i.size, np.int8), np.full(i.size, 0.9))

        batch = simulate(track, train, 0.8, start=start(np.arange(10)))
        for i in range(10):
            alone = simulate(track, train, 0.8, start=start(np.array([i])))
            assert batch.time_s[i] == alone.time_s[0] and batch.energy_kwh[i] == alone.energy_kwh[0]
            assert batch.stop_m[i] == alone.stop_m[0]
        assert len(set(batch.time_s - t0)) > 1  # the copies' sums differ in their last bits: not one copy shifted


def _random_line(root: Path, seed: int):
    """The tiny line with random gradients, speed limits and maximum speed (a different line per seed)."""
    import pandas as pd

    import planner

    rng = np.random.default_rng(seed)
    t = default_tables(f"rnd{seed}")
    t["line"].loc[0, "max_speed_kmh"] = float(rng.choice([80.0, 100.0, 120.0]))
    edges = np.sort(rng.choice(np.arange(100, 4900, 50), 6, replace=False)).astype(float)
    t["gradients"] = pd.DataFrame({"start_m": edges[:-1], "end_m": edges[1:],
                                   "gradient_permil": np.round(rng.uniform(-15, 15, 5), 1)})
    a, b = sorted(rng.choice(np.arange(500, 4500, 100), 2, replace=False).astype(float))
    t["speed_limits"].loc[0, ["start_m", "end_m", "limit_kmh"]] = [a, b, float(rng.choice([45.0, 60.0, 75.0]))]
    return planner.load_line(write_line_db(root / f"rnd{seed}", **t))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_tables_of_random_lines_are_the_same_bytes(tmp_path, monkeypatch, seed):
    """Tables (a)–(d) of every leg, both train types (constant and sawtooth cruise), with and
    without reuse, at 10 m and 1 m steps."""
    from planner.physics.track import SimSettings
    from planner.tables.build import build_tables

    line = _random_line(tmp_path, seed)
    ds = 10.0 if seed != 2 else 1.0
    grid = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4]
    off, on = _both(monkeypatch, lambda: build_tables(line, ratios=grid, n_jobs=1, settings=SimSettings(ds_m=ds),
                                                      eval_interval_m=400.0))
    assert any(r.approach is not None for r in on)  # table (d) is among them
    assert _same(off, on) == []


def test_closed_loop_and_changes_are_the_same_bytes(tiny, monkeypatch):
    """Batches with events: the closed loop's controller at every point, ratio changes, snapshots."""
    from planner.physics.run_curve import simulate
    from planner.physics.track import make_track
    from planner.tables.build import interstation_tables
    from planner.tables.closed_loop import closed_loop_interstation

    for tt in ("EMU10", "EMU6"):
        tab = interstation_tables(tiny, tt, "A", "B", [1.0, 0.9, 0.8, 0.7, 0.6, 0.5], eval_interval_m=300.0)
        for mode in ("nearest", "adaptive"):
            off, on = _both(monkeypatch, lambda: closed_loop_interstation(tiny, tt, tab.onboard(), mode=mode,
                                                                        scenario="perturbed"))
            assert _same(off, on) == []
        track = make_track(tiny, tt, "A", "B", nodes_m=[500.0, 900.0, 1300.0])
        r = np.repeat([1.0, 0.8, 0.6], 4)
        changes = [(500.0, np.tile([0.7, 0.9, 0.7, 1.0], 3)), (1300.0, np.full(12, 0.6))]
        off, on = _both(monkeypatch, lambda: simulate(track, tiny.train_type(tt), r, changes=changes,
                                                      snapshots_m=[500.0, 900.0, 1300.0]))
        assert _same(off, on) == []


def test_a_stall_names_the_same_run(tmp_path, monkeypatch):
    """A batch that stalls raises the same error (place, run, load, traction) with reuse as without."""
    from planner.errors import StallError
    from planner.physics.run_curve import simulate
    from planner.physics.track import make_track
    from steep_line import write_steep_line

    import planner

    line = planner.load_line(write_steep_line(tmp_path / "steep"))
    track = make_track(line, "FRT", "A", "B")
    load = np.array([0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0])

    def stall():
        with pytest.raises(StallError) as e:
            simulate(track, line.train_type("FRT"), 1.0, load=load, traction_factor=0.9)
        return str(e.value), e.value.position_m

    off, on = _both(monkeypatch, stall, merges=None)
    assert off == on and "run 2" in on[0]


def test_sample_tables_are_the_same_parquet_bytes(tmp_path, monkeypatch):
    """Every table dataset of a few legs of the sample (each train type, both directions), written
    with and without reuse: the same files, byte for byte."""
    import planner
    from planner.datasets.tables import write_tables
    from planner.tables.build import interstation_tables, table_tasks

    line = planner.load_line(ROOT / "lines" / "sample")
    tasks = table_tasks(line)
    picked = {}
    for t in tasks:
        picked.setdefault((t[0], t[1]), t)
    grid = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.45, 0.4, 0.35, 0.3]

    def tables():
        return [interstation_tables(line, t[0], t[2], t[3], grid, eval_auto_s=30.0) for t in picked.values()]

    off, on = _both(monkeypatch, tables)
    files = {}
    for name, res in (("off", off), ("on", on)):
        out = tmp_path / name
        files[name] = {p.relative_to(out): p.read_bytes() for p in map(Path, write_tables(res, out))}
    assert files["off"].keys() == files["on"].keys() and len(files["on"]) >= 5
    assert [k for k in files["on"] if files["on"][k] != files["off"][k]] == []
