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

    def imap(self, fn: Callable, arglist: Sequence[tuple]) -> Iterator[Any]:
        from concurrent.futures import CancelledError

        from distributed import KilledWorker

        total = len(arglist)
        try:
            futures = [self.client.submit(fn, *a, pure=False) for a in arglist]
        except Exception as e:  # noqa: BLE001 - the scheduler went away between connect and submit
            raise self._lost(0, total, f"cannot submit work ({type(e).__name__}: {e})") from None
        done = 0
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
                        raise self._lost(done, total, f"workers died running one unit ({e}); the unit may "
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
                done += 1
                yield res
        finally:
            if done < total:
                try:
                    self.client.cancel(futures[done:], asynchronous=False)
                except Exception:  # noqa: BLE001 - best effort: the cluster may be gone
                    pass


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
