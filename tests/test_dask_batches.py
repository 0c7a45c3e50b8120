"""A step's units go to a Dask cluster in batches, results in order; work the job waits for goes first.

The cluster is a LocalCluster of threads (``processes=False``): its tasks share this process, so a unit can
wait on an event the test sets, and the order in which the tasks ran is known without timing anything.
"""
from __future__ import annotations

import threading

import pytest

distributed = pytest.importorskip("dask.distributed")

from planner.io.dask_pool import BATCH_MAX, BATCHES_PER_WORKER, DaskPool  # noqa: E402
from planner.io.parallel import backend  # noqa: E402

GO = threading.Event()
RAN: list = []  # (kind, value) in the order the cluster's one thread ran them


def square(x: int) -> int:
    return x * x


def fails_at(x: int, bad: int) -> int:
    if x == bad:
        raise ValueError(f"unit {x} failed")
    return x


def held(x: int) -> int:
    GO.wait(60)
    RAN.append(("unit", x))
    return x


STARTED = threading.Event()


def starts(x: int) -> int:
    STARTED.set()
    return x


def waited(x: int) -> int:
    RAN.append(("waited", x))
    return x


@pytest.fixture
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as lc:
        yield lc


def test_the_batch_size_spreads_a_step_over_the_workers_and_is_bounded():
    pool = DaskPool.__new__(DaskPool)
    for workers, total, expected in [(2, 7194, BATCH_MAX), (2, 100, 100 // (2 * BATCHES_PER_WORKER)),
                                     (64, 7194, 7194 // (64 * BATCHES_PER_WORKER)), (2, 3, 1), (None, 5, 1)]:
        pool._workers = lambda w=workers: w
        assert pool.batch_size(total) == expected, (workers, total)


def test_units_in_batches_give_their_results_in_order_in_fewer_tasks(cluster):
    with backend("dask", scheduler=cluster.scheduler_address) as pool:
        with distributed.get_task_stream(client=pool.client) as ts:
            got = list(pool.imap(square, [(i,) for i in range(100)]))
    assert got == [i * i for i in range(100)]
    size = 100 // (2 * BATCHES_PER_WORKER)  # 6 units a task on two workers
    assert len(ts.data) == -(-100 // size) == 17


def test_a_step_runs_on_the_cluster_before_its_first_result_is_asked_for(cluster):
    """As on local workers: the job starts a step or a background task, goes on with its own work, and takes the
    results later (a lazily submitted task would run only then, in line with the job instead of beside it)."""
    STARTED.clear()
    with backend("dask", scheduler=cluster.scheduler_address) as pool:
        it = pool.imap(starts, [(7,)])
        assert STARTED.wait(60), "nothing ran before a result was asked for"
        assert list(it) == [7]


def test_a_failing_unit_in_a_batch_raises_its_own_error_after_the_units_before_its_batch(cluster):
    with backend("dask", scheduler=cluster.scheduler_address) as pool:
        it = pool.imap(fails_at, [(i, 40) for i in range(100)])  # batches of 6: unit 40 is in the 7th
        got = []
        with pytest.raises(ValueError, match="unit 40 failed"):
            for r in it:
                got.append(r)
    assert got == list(range(36))  # the six batches before it


def test_work_the_job_waits_for_runs_before_the_units_queued_earlier():
    """Every unit waits until the waited-for task is submitted too, so all are queued when the first ends:
    the cluster's one thread takes the waited-for task before the batches still queued."""
    GO.clear()
    RAN.clear()
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as one:
        with backend("dask", scheduler=one.scheduler_address) as pool:
            units = pool.imap(held, [(i,) for i in range(64)])  # 8 batches of 8, submitted before any is taken
            job = pool.imap(waited, [(0,)], waited_for=True)
            GO.set()
            assert next(job) == 0
            assert list(units) == list(range(64))
    at = RAN.index(("waited", 0))
    assert at < 64 - 8, f"the waited-for task ran after {at} units: it was queued behind the step"
