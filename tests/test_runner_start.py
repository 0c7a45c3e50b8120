"""Runner.start: a step's units started on the workers and taken later (the job's speed–distance charts and
train graph trajectories), through the cache like Runner.run."""
from __future__ import annotations

import dataclasses
import functools
import operator

import pytest

from planner.job.cache import Cache
from planner.job.config import Job
from planner.job.units import Progress, Runner, Unit, kept_beside


def _runner(tmp_path, n_jobs: int) -> Runner:
    job = Job(str(tmp_path / "job.toml"), str(tmp_path))
    job = dataclasses.replace(job, parallel=dataclasses.replace(job.parallel, n_jobs=n_jobs))
    return Runner(job, Cache(tmp_path / "cache"), Progress(enabled=False))


def _units(n: int) -> list[Unit]:
    # operator.mul pickles by reference: the workers compute i * 7 exactly
    return [Unit("demo", f"{i:064x}", f"unit {i}", operator.mul, (i, 7)) for i in range(n)]


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_started_units_give_run_results_and_each_result_once(tmp_path, n_jobs):
    runner = _runner(tmp_path, n_jobs)
    units = _units(6)
    for u in units[::2]:  # every other unit cached by an earlier run, under a value a worker would not give
        runner.cache.put("demo", u.key, -1)
    seen = {}
    started = runner.start("demo", units)
    out = started.results(each=lambda g, i, r: seen.setdefault((g, i), []).append(r))
    want = [-1 if i % 2 == 0 else 7 * i for i in range(6)]
    assert out == [want]
    assert seen == {(0, i): [want[i]] for i in range(6)}  # each unit once, cached ones included
    assert (runner.computed, runner.reused) == ({"demo": 3}, {"demo": 3})
    assert [runner.cache.get("demo", u.key) for u in units] == want  # computed units stored as they came
    assert started.results() == [want]  # taken once; asking again gives the same lists


def test_a_discarded_start_keeps_the_finished_units_in_the_cache(tmp_path):
    runner = _runner(tmp_path, 2)
    units = _units(4)
    runner.start("demo", units).discard()  # the run failed before it needed them
    assert [runner.cache.get("demo", u.key) for u in units] == [0, 7, 14, 21]


def _report(i: int) -> dict:
    """A unit's result that is large beside what the job keeps of it (a line's conflict report and its table)."""
    import numpy as np

    return {"windows": np.arange(100_000, dtype=float) + i, "table": [i, "kept"]}


def _keep(res: dict) -> tuple:
    import os

    return res["table"], os.getpid()


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_unit_with_after_is_stored_whole_and_gives_what_is_kept(tmp_path, monkeypatch, n_jobs):
    """Unit.after: the cache holds the whole result (the next run's hit) and the caller gets after(result). On a
    local worker both happen there: the job process stores nothing of it and gets only what is kept; with one job
    here. A cached result is given through after too."""
    import os

    import numpy as np

    stored = []
    put = Cache.put
    monkeypatch.setattr(Cache, "put", lambda self, step, key, obj: (stored.append(key), put(self, step, key, obj)))
    runner = _runner(tmp_path, n_jobs)
    units = [Unit("demo", f"{i:064x}", f"unit {i}", _report, (i,), after=_keep) for i in range(3)]
    runner.cache.put("demo", units[0].key, _report(10))  # cached by an earlier run
    stored.clear()
    seen = {}
    out = runner.start("demo", units).results(each=lambda g, i, r: seen.setdefault(i, r))[0]
    assert [table for table, _ in out] == [[10, "kept"], [1, "kept"], [2, "kept"]] and seen == dict(enumerate(out))
    here = {pid == os.getpid() for _, pid in out[1:]}
    assert here == ({True} if n_jobs == 1 else {False})  # kept where the result was made
    assert stored == ([u.key for u in units[1:]] if n_jobs == 1 else [])  # else stored on the worker
    for i, u in enumerate(units):
        got = runner.cache.get("demo", u.key)
        assert np.array_equal(got["windows"], _report(10 if i == 0 else i)["windows"])


def _full_disk(res: dict):
    import errno
    import os

    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), f"/run/stage/occupation/part-{res['table'][0]}.parquet")


def test_a_failing_after_on_a_worker_fails_the_unit_and_keeps_its_entry(tmp_path):
    """What ``after`` raises on a worker (a full disk while it writes the datasets) comes to the caller as the
    unit's error, with the file it names; the whole result is stored before, so the next run loads it."""
    runner = _runner(tmp_path, 2)
    units = [Unit("demo", f"{i:064x}", f"unit {i}", _report, (i,), after=_full_disk) for i in range(2)]
    with pytest.raises(OSError) as e:
        runner.start("demo", units).results()
    # the first unit to fail (either: they run side by side) names its file
    failed = {f"/run/stage/occupation/part-{i}.parquet": i for i in range(2)}.get(e.value.filename)
    assert e.value.errno == 28 and failed is not None, e.value
    got = runner.cache.get("demo", units[failed].key)
    assert got is not None and got["table"] == [failed, "kept"]


@kept_beside
def _table(res: dict) -> list:
    return res["table"]


def _place(decode: bool, load):
    """A Placed unit's files: the result's first window when ``decode``, else nothing read (the previous run's)."""
    return float(load()["windows"][0]) if decode else "not decoded"


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_placed_unit_read_back_decodes_its_result_only_when_its_files_need_it(tmp_path, monkeypatch, n_jobs):
    """Placed: what the job keeps is stored beside the result and read back without decoding it; the placed part
    gets a loader that decodes the result only when called. With the kept entry gone, it is made again from the
    decoded result."""
    from planner.job.units import Placed

    runner = _runner(tmp_path, n_jobs)
    units = [Unit("demo", f"{i:064x}", f"unit {i}", _report, (i,), after=Placed(_table, functools.partial(_place, i == 1)))
             for i in range(3)]
    assert runner.start("demo", units).results()[0] == [([i, "kept"], float(i) if i == 1 else "not decoded")
                                                        for i in range(3)]
    read = []
    get = Cache.get
    monkeypatch.setattr(Cache, "get", lambda self, kind, key: (read.append((kind, int(key, 16))), get(self, kind, key))[1])
    again = _runner(tmp_path, 1)  # read back in this process: the reads counted here
    again.cache.path("demo_kept", units[2].key).unlink()
    assert again.start("demo", units).results()[0] == [([i, "kept"], float(i) if i == 1 else "not decoded")
                                                       for i in range(3)]
    assert again.computed.get("demo", 0) == 0 and again.reused == {"demo": 3}
    # unit 0: what is kept, read beside; unit 1: its files read the result; unit 2: what is kept made again from it
    assert sorted(k for kind, k in read if kind == "demo") == [1, 2]
    assert again.cache.get("demo_kept", units[2].key) == [2, "kept"]
