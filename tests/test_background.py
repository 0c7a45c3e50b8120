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


def _until(path, timeout_s):
    """A long task: runs until the test creates ``path`` (bounded)."""
    import time

    deadline = time.monotonic() + timeout_s
    while not os.path.exists(path):
        if time.monotonic() > deadline:
            return "timed out"
        time.sleep(0.01)
    return "done"


@pytest.fixture
def counted_late(monkeypatch):
    """joblib's callback thread counts each task done only after the consumer has taken its result.

    That is the ordering a loaded machine gives now and then (the callback thread preempted between
    registering a result and counting its task), made every time: joblib then hands the last result out
    from inside its retrieval loop, where closing its generator aborts the shared loky executor. Yields
    a list with, for each result held so, whether the consumer took it first (the ordering was forced)."""
    import threading
    import time

    from joblib import parallel as jp

    call, count = jp.Parallel.__call__, jp.BatchCompletionCallBack._dispatch_new
    mine, seen = [], []

    def called(self, iterable):  # this test's calls only: a task left by an earlier test is not waited for
        mine.append(self)
        return call(self, iterable)

    def head(self):
        jobs = self.parallel._jobs
        return bool(jobs) and jobs[0] is self

    def late(self):
        # held while the consumer can take it (the first result it waits for): a result finished before
        # the one ahead of it goes on, or it would hold this thread from the one the consumer waits for;
        # so does one finished before it was submitted (its callback runs in the consumer's own thread)
        if (any(p is self.parallel for p in mine) and head(self)
                and threading.current_thread() is not threading.main_thread()):
            deadline = time.monotonic() + 10.0
            while head(self) and time.monotonic() < deadline:
                time.sleep(0.001)
            seen.append(not head(self))
        return count(self)

    monkeypatch.setattr(jp.Parallel, "__call__", called)
    monkeypatch.setattr(jp.BatchCompletionCallBack, "_dispatch_new", late)
    return seen


def test_taking_every_result_then_stopping_leaves_the_other_workers_tasks_running(tmp_path, counted_late):
    """A step that takes its units' results and stops (the runner zips its units with the results), and
    a background result taken with one ``next``, must not cancel a task of another ``Parallel`` running
    beside them: a nightly run in CI lost its background read of the tables that way
    (``ShutdownExecutorError``: "The Executor was shutdown with kill_workers=True")."""
    from planner.io.parallel import backend

    go = tmp_path / "go"
    other = background(_until, (str(go), 60.0), n_jobs=2)  # the tables read back, say
    with backend("local", n_jobs=2) as pool:
        gen = pool.imap(_pid_and, [(1,), (2,)])
        assert [r[1] for _, r in zip(range(2), gen)] == [2, 4]
        gen.close()
    assert background(_pid_and, (3,), n_jobs=2).result()[1] == 6
    go.touch()
    assert other.result() == "done"
    assert len(counted_late) >= 2 and all(counted_late)
