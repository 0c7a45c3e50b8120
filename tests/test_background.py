"""planner.io.parallel.background: work started beside the main process, its result taken later."""
import os

import pytest

from planner.errors import InputError
from planner.io.parallel import background


def _pid_and(x):
    return os.getpid(), x * 2


def _fails(msg):
    raise InputError(msg)


def test_a_local_worker_computes_it_and_one_job_computes_it_here():
    away = background(_pid_and, (21,), n_jobs=2)
    here = background(_pid_and, (21,), n_jobs=1)
    dask = background(_pid_and, (21,), name="dask", n_jobs=2)  # dask's workers are for the units
    pid, value = away.result()
    assert value == 42 and pid != os.getpid()
    assert away.result() == (pid, 42)  # taken once, kept
    assert here.result() == (os.getpid(), 42) and dask.result() == (os.getpid(), 42)


def test_its_error_reaches_result_and_discard_drops_it_quietly():
    with pytest.raises(InputError, match="on purpose"):
        background(_fails, ("on purpose",), n_jobs=2).result()
    b = background(_fails, ("dropped",), n_jobs=2)
    b.discard()  # a failing run drops it: waits for the worker, raises nothing


def _warm():
    import planner.tables.build  # noqa: F401

    return os.getpid()


def test_started_workers_warm_beside_and_an_error_inside_waits_for_them():
    from planner.io.parallel import started_workers

    with started_workers(_warm, name="dask", n_jobs=2) as none, started_workers(_warm, n_jobs=1) as one:
        assert none == [] and one == []
    with started_workers(_warm, n_jobs=2) as warm:
        assert len(warm) == 2
        assert os.getpid() not in [w.result() for w in warm]
    with pytest.raises(InputError, match="bad line"):
        with started_workers(_warm, n_jobs=2):
            raise InputError("bad line")  # the handles are waited for on the way out, quietly
