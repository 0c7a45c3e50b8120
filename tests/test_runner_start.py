"""Runner.start: a step's units started on the workers and taken later (the job's speed–distance charts and
train graph trajectories), through the cache like Runner.run."""
from __future__ import annotations

import dataclasses
import operator

import pytest

from planner.job.cache import Cache
from planner.job.config import Job
from planner.job.units import Progress, Runner, Unit


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
