"""The Dask backend: a pool of futures on a ``dask.distributed`` client, and the client of a whole run.

:func:`planner.io.parallel.backend` hands out a :class:`DaskPool` for ``name="dask"``: the run's
(:func:`dask_run`, made once by the nightly job) or a client of its own for the context.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Sequence

from planner.errors import JobError
from planner.io.parallel import ClusterLostError, Pool, quiet_loggers


WAITED_FOR = 1
"""The Dask priority of work the job process waits for next (:meth:`DaskPool.imap`); a step's units have 0."""
BATCH_MAX = 16
"""A step's units per task on Dask at most (:meth:`DaskPool.batch_size`): a table's unit takes 0.05-0.1 s of CPU
(100x line; sample), so a task of 16 about a second, against a few milliseconds of the cluster's own CPU per task."""
BATCHES_PER_WORKER = 8
"""A step's tasks on Dask for each of the cluster's workers at least (:meth:`DaskPool.batch_size`), so that its
last tasks still spread over the workers."""


class DaskPool(Pool):
    """Futures on a ``dask.distributed`` client, with a bounded wait when the cluster is lost."""

    n_jobs = -1

    def __init__(self, client, scheduler: str, lost_timeout_s: float):
        self.client = client
        self.scheduler = scheduler
        self.lost_timeout_s = float(lost_timeout_s)
        self.poll_s = min(1.0, self.lost_timeout_s / 4.0)
        self.ask_s = min(5.0, self.lost_timeout_s / 4.0)  # a busy scheduler may take a moment to answer

    def _workers(self) -> int | None:
        """Workers the scheduler has now, or None when it does not answer within ``ask_s``."""
        try:
            info = self.client.sync(self.client.scheduler.identity, n_workers=-1, callback_timeout=self.ask_s)
        except Exception:  # noqa: BLE001 - any failure to get an answer means: no scheduler right now
            return None
        return len(info.get("workers", {}))

    def _lost(self, done: int, total: int, why: str) -> ClusterLostError:
        resume = (f"the {done} finished unit(s) are cached, so the next run resumes from them"
                  if done else "no unit of this step finished; earlier steps' units are cached")
        return ClusterLostError(f"dask cluster {self.scheduler} lost: {why}; {done} of {total} unit(s) of this step "
                                f"done; {resume}; check the cluster, then run again")

    def batch_size(self, total: int) -> int:
        """Units per task for a step of ``total``: :data:`BATCH_MAX` at most, and at least
        :data:`BATCHES_PER_WORKER` tasks for each of the cluster's workers (so the step's last tasks still
        spread over them)."""
        workers = self._workers() or 1
        return max(1, min(BATCH_MAX, total // (BATCHES_PER_WORKER * workers)))

    def imap(self, fn: Callable, arglist: Sequence[tuple], waited_for: bool = False) -> Iterator[Any]:
        """Every task submitted now (before the first result is asked for: a started step or a background task
        runs while the job process goes on, as on local workers), results in order.

        A step's units go in batches (:meth:`batch_size`), as joblib batches the local workers' short tasks: the
        scheduler and each worker spend a few milliseconds of CPU on every task, and a step has thousands of
        units of a few tens of milliseconds. The scheduler runs what was submitted first first, so a step's
        queued units would hold back work the job process needs before them (a step's datasets written, the
        margin legs, a page); ``waited_for`` work is submitted with a higher priority, and runs as soon as a
        worker is free, as it does among the local workers' few queued tasks."""
        total = len(arglist)
        try:
            size = self.batch_size(total) if total > 1 else 1
            batches = [arglist[i:i + size] for i in range(0, total, size)]
            futures = [self.client.submit(run_batch, fn, list(b), pure=False,
                                          priority=WAITED_FOR if waited_for else 0) for b in batches]
        except Exception as e:  # noqa: BLE001 - the scheduler went away between connect and submit
            raise self._lost(0, total, f"cannot submit work ({type(e).__name__}: {e})") from None
        return self._taken(futures, total)

    def _taken(self, futures: list, total: int) -> Iterator[Any]:
        """The units' results of ``futures`` (batches of :meth:`imap`, submitted), in order, each batch waited for
        with a bounded wait when the cluster is lost."""
        from concurrent.futures import CancelledError

        from distributed import KilledWorker

        done = 0
        taken = 0  # batches whose results were taken
        try:
            for fut in futures:
                lost_since: float | None = None
                while True:
                    try:
                        res = fut.result(timeout=self.poll_s)
                        break
                    except TimeoutError:
                        pass
                    except CancelledError:  # includes distributed's FutureCancelledError
                        raise self._lost(done, total, "the scheduler cancelled the work (scheduler gone or "
                                                      "restarted)") from None
                    except KilledWorker as e:
                        raise self._lost(done, total, f"workers died running one task ({e}); its units may "
                                                      "need more memory than a worker has") from None
                    n = self._workers()
                    if n:
                        lost_since = None
                        continue
                    lost_since = time.monotonic() if lost_since is None else lost_since
                    if time.monotonic() - lost_since >= self.lost_timeout_s:
                        what = "no scheduler answer" if n is None else "no workers"
                        raise self._lost(done, total, f"{what} for {self.lost_timeout_s:g} s "
                                                      "([parallel] dask_lost_timeout_s)") from None
                taken += 1
                for r in res:
                    done += 1
                    yield r
        finally:
            if taken < len(futures):
                try:
                    self.client.cancel(futures[taken:], asynchronous=False)
                except Exception:  # noqa: BLE001 - best effort: the cluster may be gone
                    pass


def run_batch(fn: Callable, arglist: list[tuple]) -> list:
    """Worker: ``fn(*args)`` of each of a batch's units, in order (:meth:`DaskPool.imap`)."""
    return [fn(*a) for a in arglist]


RUN: dict[str, "DaskPool"] = {}
"""The Dask pool of the run in progress (:func:`dask_run`), while one is open in this process."""


@contextmanager
def dask_run(scheduler: str, lost_timeout_s: float = 60.0) -> Iterator["DaskPool"]:
    """One Dask client for a whole run: every step's units, the margin report's legs and the work started
    beside the steps (:func:`planner.io.parallel.background`) go to the cluster through it, and a step's
    units can still be running while the job process goes on (as with local workers). The cluster's workers
    share the job machine's file system at the same paths (the output root, its cache and staged run: units
    write their datasets where they are made)."""
    with dask_client(scheduler, lost_timeout_s) as pool:
        RUN["pool"] = pool
        try:
            yield pool
        finally:
            RUN.pop("pool", None)


@contextmanager
def dask_client(scheduler: str, lost_timeout_s: float) -> Iterator["DaskPool"]:
    try:
        from dask.distributed import Client
    except ImportError:
        raise JobError("backend dask needs the dask extra: pip install 'planner[dask]'") from None
    # from connect to close: a lost scheduler is the one line of ClusterLostError, not the client's log
    # of its failed reconnect and of the tasks its close cancels (each with a traceback)
    with quiet_loggers("distributed"):
        try:
            client = Client(scheduler, timeout=f"{float(lost_timeout_s)}s")
        except Exception as e:  # noqa: BLE001 - any connection failure is a user-facing setup problem
            raise JobError(f"cannot reach the dask scheduler {scheduler!r} within {lost_timeout_s:g} s: "
                           f"{e}") from None
        try:
            yield DaskPool(client, scheduler, lost_timeout_s)
        finally:
            try:
                client.close(timeout=min(5.0, float(lost_timeout_s)))
            except Exception:  # noqa: BLE001 - closing a client of a dead cluster must not mask the real error
                pass
