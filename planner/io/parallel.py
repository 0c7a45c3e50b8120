"""Where parallel work runs: local joblib (loky) processes, or a Dask cluster.

Workers are plain module-level functions with small picklable arguments, so
the same :meth:`Pool.imap` call runs on either backend, and results come back
in submission order: outputs do not depend on the backend.

Failure behaviour (issue 21):

* **Dask cluster lost.** joblib's dask backend waits for workers without end:
  with every worker killed a run hung for 900 s holding the job lock. The Dask
  pool therefore submits futures itself (``client.submit``) and, while it waits
  for a result, asks the scheduler how many workers it has. When the cluster
  has had no workers, or the scheduler has not answered, for
  ``lost_timeout_s`` (job file ``[parallel] dask_lost_timeout_s``), or the
  scheduler cancels the work, it raises a one-line :class:`ClusterLostError`
  saying how many units finished: each finished unit is already in the cache,
  so the next run resumes from them. The caller's ``with`` blocks (the job
  lock among them) unwind normally, so the lock is released.
* **Local worker killed** (mostly by the kernel's out-of-memory killer) under a
  task: one :class:`WorkerLostError` line with the worker's exit code and how many
  tasks were done, instead of loky's ``TerminatedWorkerError`` traceback.
* **Main process killed.** loky workers are separate processes that would
  idle for minutes (loky's idle timeout) after a SIGKILL of the main process.
  Each worker runs :func:`_exit_with_parent` at start (every pool is configured
  by :func:`_loky`, with the main process's id): a daemon thread that ends the
  worker within :data:`PARENT_POLL_S` once its parent is gone, the first of
  them removing the output root's staging folder on its way out
  (:func:`for_output_root`). The planner's promise: every worker ends within
  3 s of the main process (``tests/stress_kill.py`` measures it).

Quiet failures (issue 32): an environment fault ends a run with the planner's
one line on stderr and nothing else. While a Dask client is open
(:func:`backend`), the ``distributed`` loggers are raised above ``CRITICAL``
(:func:`quiet_loggers`): a lost scheduler otherwise logs the client's failed
reconnect and the tracebacks of its cancelled tasks. A joblib generator left
unfinished because the run failed (a full disk while a step's results are
stored) is closed at once, in the thread that started it, without joblib's
"tasks have been successfully executed but not used" warning
(:func:`_abandon_quietly`). loky renewing a grown worker (its guard against leaks) prints no warning
(:func:`_quiet_renewals`), nor does loky's resource tracker after a kill (:func:`_quiet_tracker`), nor loky's
manager thread racing the shutdown of its executor after a failure (:func:`_quiet_manager_thread`).
"""
from __future__ import annotations

import logging
import os
import sys
import threading
import time
import warnings
from contextlib import contextmanager
from typing import Any, Callable, Iterator, Sequence

import joblib

from planner.errors import JobError

PARENT_POLL_S = 0.5
"""How often a local worker checks that the main process is alive [s]."""


class ClusterLostError(JobError):
    """The Dask cluster went away (no workers, or no scheduler) for longer than the configured bound."""

    key = "job.cluster_lost"


class WorkerLostError(JobError):
    """A local worker process died under a task (killed, mostly by the kernel for want of memory, or crashed)."""

    key = "job.worker_lost"


def _worker_lost(e: Exception, done: int, total: int | None) -> WorkerLostError:
    """One line for loky's ``TerminatedWorkerError`` (whose text is four lines and a traceback)."""
    import re

    codes = re.search(r"exit codes of the workers are (\{[^}]*\})", str(e))
    of = f" of {total}" if total is not None else ""
    return WorkerLostError(f"a local worker process died under a task (exit code {codes.group(1) if codes else '?'}:"
                           f" killed, mostly by the system for want of memory, or crashed); {done}{of} task(s) "
                           "done; lower the number of worker processes ([parallel] n_jobs, or --jobs) or free "
                           "memory, then run again (the nightly job's finished units are cached)")


def _exit_with_parent(parent: int | None = None) -> None:
    """loky worker initializer: exit as soon as the process that started this worker is gone.

    ``parent``: the main process's id, as it was when the pool was configured (:func:`_loky`). Polls
    ``os.getppid()``: when the parent dies the worker is re-parented (to init or a subreaper) and the id
    changes. The id is given, not read here: a worker whose main process was killed while the worker was
    still starting (its imports take ~0.5 s) would read init's id as its parent's and live on. Polling is
    used rather than ``PR_SET_PDEATHSIG`` because that signal fires when the *thread* that forked the
    worker ends, which in loky may be a manager thread, not the process.
    """
    parent = os.getppid() if parent is None else parent

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        _clean_after_parent()
        os._exit(1)

    threading.Thread(target=watch, name="planner-exit-with-parent", daemon=True).start()


def _loky(n_jobs: int):
    """The one configuration of the planner's local workers (a ``joblib.parallel_config``): loky processes
    that end with this process (:func:`_exit_with_parent`). Every pool, background task and map uses it, so
    they share loky's one reusable executor instead of restarting it for a different configuration."""
    return joblib.parallel_config(backend="loky", n_jobs=n_jobs, initializer=_exit_with_parent,
                                  initargs=(os.getpid(),))


OUTPUT_ROOT_ENV = "PLANNER_WORKERS_OUTPUT_ROOT"
"""The output root of the job that started the local workers, as their environment has it (:func:`for_output_root`)."""


@contextmanager
def for_output_root(root: str | os.PathLike) -> Iterator[None]:
    """Local workers started inside this context clean the output root's staging folder if the main process is
    killed: a SIGKILL leaves no one else to do it before the next run (:func:`_clean_after_parent`). The
    workers read it from their environment, which they inherit when loky starts them."""
    before = os.environ.get(OUTPUT_ROOT_ENV)
    os.environ[OUTPUT_ROOT_ENV] = os.fspath(os.path.abspath(root))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(OUTPUT_ROOT_ENV, None)
        else:
            os.environ[OUTPUT_ROOT_ENV] = before


def _clean_after_parent() -> None:
    """A worker whose main process died: remove the staging folders of its output root, if no job holds the
    root's lock (a dead process's lock is released by the kernel; a job that has started since holds it and
    cleans them itself). Errors are ignored: the next run cleans them too.

    Another worker may still be writing a dataset into the staged run until its own watch sees the main process
    gone (up to :data:`PARENT_POLL_S` later), so a worker removes them again until twice that has passed. It
    holds the lock only while it removes (a few milliseconds): a job restarted at once after the kill finds the
    root free, takes the lock and cleans the rest itself; from then on the worker's try fails and it stops."""
    import fcntl

    from planner.io.atomic import remove_staging

    root = os.environ.get(OUTPUT_ROOT_ENV)
    if not root:
        return
    try:
        fd = os.open(os.path.join(root, ".lock"), os.O_RDWR)
    except OSError:
        return
    try:
        until = time.monotonic() + 2 * PARENT_POLL_S
        while True:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # OSError when a job holds it: that job cleans
            try:
                remove_staging(root)
            finally:
                fcntl.flock(fd, fcntl.LOCK_UN)
            if time.monotonic() >= until:
                break
            time.sleep(PARENT_POLL_S / 4)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def quiet_loggers(name: str) -> Iterator[None]:
    """Drop every record of the logger ``name`` and of its children while the context lasts, then put
    their levels back. Levels, not handlers: a record dropped by its logger's level reaches no handler,
    neither the library's own nor logging's last-resort handler on stderr; children created meanwhile
    inherit the level of ``name``."""
    known = list(logging.Logger.manager.loggerDict.items())
    names = [name] + [n for n, lg in known if n.startswith(name + ".") and isinstance(lg, logging.Logger)]
    saved = [(lg, lg.level) for lg in map(logging.getLogger, names)]
    for lg, _ in saved:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in saved:
            lg.setLevel(level)


_UNUSED_TASKS = r"\d+ tasks (have been successfully executed|which were still being processed)"
"""The start of joblib's warning when a ``return_as="generator"`` Parallel is closed before its end."""
_WORKER_RENEWED = r"A worker stopped while some jobs were given to the executor"
"""The start of loky's warning when it replaced a worker while tasks were queued (:func:`_quiet_renewals`)."""


def _quiet_renewals() -> None:
    """No loky warning on stderr when it renews a grown worker.

    Where psutil is installed (dask's ``distributed`` brings it), loky ends a worker whose resident memory
    has grown 300 MB past its size after its first task and starts a fresh one, warning "A worker stopped
    while some jobs were given to the executor ... or by a memory leak" from its manager thread. On a large
    line the planner's whole-line units (conflict check, train graph, bundles) grow a worker that much, and
    the renewal is what keeps the night's largest process small (a worker kept all night ran the line's last
    whole-line units from a baseline grown by all the units before them: on the line ten times the sample,
    569 MB instead of ~550 MB). It is expected, costs a worker's start, and is not a leak: the run says
    nothing about it. Only that message of loky's module is filtered; a worker that dies under a task is
    still the one line of :class:`WorkerLostError`."""
    warnings.filterwarnings("ignore", message=_WORKER_RENEWED, category=UserWarning,
                            module=r"joblib\.externals\.loky\.")


_quiet_renewals()


_TRACKER = "ignore:resource_tracker:UserWarning:joblib.externals.loky.backend.resource_tracker"
"""The ``-W`` option that silences loky's resource tracker (:func:`_quiet_tracker`)."""


def _quiet_tracker() -> None:
    """No warning on stderr from loky's resource tracker after the main process was killed.

    The tracker is a process of its own, started by loky with the interpreter's ``-W`` options
    (``sys.warnoptions``) and the main process's stderr. When the main process dies without releasing
    joblib's shared-memory folders (a SIGKILL, or one night in 77 a worker ended at exit), the tracker
    removes them, which is its job, and warns "resource_tracker: There appear to be N leaked folder
    objects to clean up at shutdown" on that stderr, after the run's own lines. Its cleaning is kept;
    only its warnings, all of which begin "resource_tracker", are filtered, in the tracker only."""
    if _TRACKER not in sys.warnoptions:
        sys.warnoptions.append(_TRACKER)


_quiet_tracker()


def _quiet_manager_thread(args) -> bool:
    """Whether an exception that ended a thread is loky's manager thread failing while its executor shuts down.

    joblib shuts the shared loky executor down (killing its workers) when a generator of results is closed
    before its end, which the planner does only when the run has already failed (:func:`_abandon_quietly`).
    loky's manager thread can then look up a task that the shutdown has just removed (``KeyError`` in
    ``add_call_item_to_queue``): a race inside loky, after the run's own error, with nothing left to lose.
    Its traceback would follow the run's one line on stderr; it is logged at debug level instead. Any other
    exception of that thread (its executor not shutting down) still reaches Python's usual hook."""
    try:
        from joblib.externals.loky.process_executor import _ExecutorManagerThread
    except ImportError:  # pragma: no cover - joblib without loky
        return False
    flags = getattr(args.thread, "executor_flags", None)
    if isinstance(args.thread, _ExecutorManagerThread) and flags is not None and flags.shutdown:
        logging.getLogger(__name__).debug("loky's manager thread ended while its executor shut down: %r",
                                          args.exc_value)
        return True
    return False


def _install_thread_hook() -> None:
    previous = threading.excepthook

    def hook(args) -> None:
        if not _quiet_manager_thread(args):
            previous(args)

    hook.planner = True  # installed once, whatever reloads the module
    if not getattr(previous, "planner", False):
        threading.excepthook = hook


_install_thread_hook()


_END = object()


def _abandon_quietly(gen: Iterator[Any], total: int) -> Iterator[Any]:
    """Yield from a joblib generator of ``total`` results; when the consumer stops early (the run failed),
    close it without joblib's warning that the remaining tasks were cancelled: the run's error says what
    happened. A worker process that died under a task is one :class:`WorkerLostError` line.

    joblib's generator is run to its end *before* its last result is handed on, so a consumer that takes
    the ``total`` results it asked for and then stops (``zip`` over its units, or one ``next``) never closes
    it early. Closing joblib's generator while it is still inside its retrieval loop aborts the whole loky
    executor, killing the tasks of every other ``Parallel`` on the shared workers (a background read of the
    tables, a train graph) with ``ShutdownExecutorError``. The last result may be handed out from inside that
    loop: when the consumer looks between the worker's result being registered and joblib counting the task
    done (its callback thread, slow on a loaded machine). A nightly run failed that way in CI.

    Not ``yield from``: that would close ``gen`` before the ``finally`` has set the filter.
    Close the returned generator in the thread that iterates it (joblib aborts from another
    thread with a warning of its own); :class:`planner.job.units.Runner` does.
    """
    from joblib.externals.loky.process_executor import TerminatedWorkerError

    done = 0
    try:
        while True:
            try:
                item = next(gen)
            except StopIteration:
                return
            except TerminatedWorkerError as e:
                raise _worker_lost(e, done, total) from None
            done += 1
            if done == total and next(gen, _END) is not _END:  # the end now, where closing it aborts nothing
                raise RuntimeError(f"joblib gave more than the {total} result(s) of its tasks")
            yield item
    finally:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_UNUSED_TASKS, category=UserWarning, module=r"joblib\.")
            gen.close()


class Pool:
    """Runs ``fn(*args)`` for each args tuple, results in submission order."""

    n_jobs: int = 1

    def imap(self, fn: Callable, arglist: Sequence[tuple], waited_for: bool = False) -> Iterator[Any]:
        """``waited_for``: work the job process waits for next (:func:`background`, :func:`iter_tasks`): a pool
        that queues all its tasks at once runs it before the units queued earlier (:class:`planner.io.dask_pool.
        DaskPool`). Local workers take a step's tasks a few at a time, so later work gets its turn there anyway."""
        raise NotImplementedError


class LocalPool(Pool):
    def __init__(self, n_jobs: int):
        self.n_jobs = n_jobs

    def imap(self, fn: Callable, arglist: Sequence[tuple], waited_for: bool = False) -> Iterator[Any]:
        from joblib import Parallel, delayed

        return _abandon_quietly(Parallel(n_jobs=self.n_jobs, return_as="generator")(delayed(fn)(*a) for a in arglist),
                                len(arglist))


class Background:
    """``fn(*args)`` started on a local worker now, its result taken later with :meth:`result`.

    Made by :func:`background`. On the run's Dask cluster (:func:`planner.io.dask_pool.dask_run`) it is
    a future there; without a local worker pool or a run's cluster (one job) the call runs in this
    process, in :meth:`result`. Either way the result is the same: the worker runs the same function.
    """

    _UNSET = object()

    def __init__(self, fn: Callable, args: tuple, n_jobs: int, pool: Pool | None = None):
        self._fn, self._args, self._gen, self._value = fn, args, None, self._UNSET
        if pool is not None:  # the run's Dask cluster
            self._gen = pool.imap(fn, [args], waited_for=True)
        elif n_jobs != 1:
            # the same loky configuration as LocalPool's steps, so its workers are reused
            with _loky(n_jobs):
                self._gen = _abandon_quietly(joblib.Parallel(return_as="generator")([joblib.delayed(fn)(*args)]), 1)

    def result(self) -> Any:
        """The result (waits for the worker; raises what the call raised)."""
        if self._value is self._UNSET:
            gen, self._gen = self._gen, None
            self._value = self._fn(*self._args) if gen is None else next(gen)
            self._fn = self._args = None  # what it was given (a line's results, to write) is not held after
        return self._value

    def discard(self) -> None:
        """Wait for the result and drop it, errors included (a run that failed before it needed it).

        Waiting, not aborting: closing joblib's generator while its task runs races loky's
        manager thread (a KeyError there), which would leave the workers' executor broken
        for the next step of this process. The work is a few seconds at most.
        """
        if self._gen is not None:
            try:
                next(self._gen)
            except Exception:  # noqa: BLE001 - the run is failing already; this result is not wanted
                pass
            self._gen = None
        self._fn = self._args = None


def background(fn: Callable, args: tuple, *, name: str = "local", n_jobs: int = -1) -> Background:
    """Start ``fn(*args)`` beside the main process (:class:`Background`): on a local worker with the
    ``local`` backend and ``n_jobs != 1``, on the run's Dask cluster with the ``dask`` backend inside
    :func:`planner.io.dask_pool.dask_run`, else later, in this process. For work of the main process that
    nothing needs until a later step (the nightly job's bundles). Its writes are flushed as the caller's would be
    (:func:`planner.io.atomic.in_worker_context`): inside the staged run's deferred flush, with the run."""
    from planner.io.atomic import in_worker_context

    pool = run_pool() if name == "dask" else None
    return Background(*in_worker_context(fn, args), n_jobs if name == "local" else 1, pool)


@contextmanager
def started_workers(warm: Callable[[], Any], *, name: str = "local", n_jobs: int = -1) -> Iterator[list[Background]]:
    """Start the local workers now, each running ``warm()`` (a module-level function importing what the
    work will need), while the main process does its own start (reads the line, checks the key): the
    first step then finds them ready instead of waiting for their start and imports (its units queue
    behind them). Nothing with one job or the Dask backend. Yields the handles; leaving the context
    waits for them (never abandoned mid-task: see :meth:`Background.discard`)."""
    handles: list[Background] = []
    if name == "local" and n_jobs != 1:
        n = joblib.cpu_count() if n_jobs < 0 else n_jobs
        handles = [Background(warm, (), n_jobs) for _ in range(n)]
    try:
        yield handles
    finally:
        for h in handles:
            h.discard()


def stop_workers() -> None:
    """End the idle local workers now (a command that is about to exit: otherwise the interpreter's exit
    waits ~0.3 s for each to wind down on its own). Nothing when there are none."""
    try:
        from joblib.externals.loky import reusable_executor
    except ImportError:  # pragma: no cover - joblib without loky
        return
    executor = getattr(reusable_executor, "_executor", None)  # loky's one reusable executor, if made
    if executor is not None:
        executor.shutdown(wait=True, kill_workers=True)


def map_tasks(fn: Callable, tasks: Sequence[tuple], n_jobs: int = -1,
              progress: Callable[[int, int], None] | None = None) -> list:
    """``[fn(*t) for t in tasks]``, in parallel: the one parallel map of the planner
    (:func:`iter_tasks`, its results kept).

    Parameters
    ----------
    fn : callable
        A module-level function (it is pickled to the workers).
    tasks : sequence of tuple
        The positional arguments of each call; keep them small (a task's
        arguments are pickled to its worker).
    n_jobs : int
        Worker processes; 1 runs in this process (no pickling), -1 all cores.
        Inside :func:`backend` the backend's workers are used.
    progress : callable ``(done, total)``, optional
        Called with ``(0, total)`` first and after every finished task.

    Returns
    -------
    list
        The results in task order, whatever the order the workers finish in, so
        outputs never depend on ``n_jobs`` or scheduling.
    """
    return list(iter_tasks(fn, tasks, n_jobs, progress))


BATCH = 64
"""Short calls sent to a worker as one task (:func:`batched`): a task costs the sender and the worker a fixed part
(sending it, taking its result back) that a call of a few tenths of a millisecond does not pay for."""


def _each(fn: Callable, arglist: list) -> list:
    """Worker: ``fn(*args)`` of each call of a batch (:func:`batched`), in order."""
    return [fn(*args) for args in arglist]


def batched(calls: list[tuple[Callable, tuple]], short: list[bool], size: int = BATCH) -> tuple[list, list]:
    """``calls`` (function, arguments) for a pool's ``imap(_call, …)``, with each run of up to ``size`` consecutive
    short ones of one function made one call of :func:`_each`; and the count of results of each (None: a call's
    own result, not a list). :func:`unbatched` gives the results a call at a time again."""
    out, sizes, run = [], [], []

    def flush():
        if run:
            out.append((_each, (run[0][0], [args for _, args in run])))
            sizes.append(len(run))
            run.clear()

    for call, is_short in zip(calls, short):
        if not is_short or (run and run[0][0] is not call[0]):
            flush()
        if is_short:
            run.append(call)
            if len(run) == size:
                flush()
        else:
            out.append(call)
            sizes.append(None)
    flush()
    return out, sizes


def unbatched(results: Iterator, sizes: list) -> Iterator:
    """The results of :func:`batched`'s calls a call at a time, in order; closing it closes ``results``."""
    try:
        for n, res in zip(sizes, results):
            if n is None:
                yield res
            else:
                yield from res
    finally:
        results.close()


def iter_tasks(fn: Callable, tasks: Sequence[tuple], n_jobs: int = -1,
               progress: Callable[[int, int], None] | None = None) -> Iterator:
    """:func:`map_tasks`'s results one at a time, in task order, each as soon as it and those before it are in:
    a caller that folds them (sums a Monte Carlo's chunks) holds one result, not all of them."""
    total = len(tasks)
    if progress:
        progress(0, total)
    if n_jobs == 1 or total <= 1:
        results = (fn(*t) for t in tasks)
    elif run_pool() is not None:  # the job process of a run on a Dask cluster: its workers
        results = run_pool().imap(fn, list(tasks), waited_for=True)
    else:
        with _loky(n_jobs):  # its tasks are handed to the workers here, in the configuration's pool
            results = _abandon_quietly(joblib.Parallel(n_jobs=n_jobs, return_as="generator")(
                joblib.delayed(fn)(*t) for t in tasks), total)
    done = 0
    try:
        for r in results:
            done += 1
            if progress:
                progress(done, total)
            yield r
    finally:
        results.close()


@contextmanager
def backend(name: str = "local", *, n_jobs: int = -1, scheduler: str = "",
            lost_timeout_s: float = 60.0) -> Iterator[Pool]:
    """Context in which work runs on the chosen backend; yields a :class:`Pool`.

    Parameters
    ----------
    name : {"local", "dask"}
    n_jobs : int
        Local worker processes (-1 = all cores).
    scheduler : str
        Dask scheduler address for ``name="dask"``.
    lost_timeout_s : float
        Dask: how long the cluster may have no workers or no scheduler before
        the run fails with :class:`ClusterLostError` [s]; also the connect timeout.

    Notes
    -----
    Inside the context, every ``joblib.Parallel`` of the local backend (also
    those deeper in the planner, e.g. the margin report's) uses loky workers
    that end with the main process (:func:`_exit_with_parent`).
    """
    if name == "local":
        with _loky(n_jobs):
            yield LocalPool(n_jobs)
        return
    if name != "dask":
        raise JobError(f"unknown parallel backend {name!r}; use local or dask")
    from planner.io.dask_pool import dask_client

    run = run_pool()
    if run is not None and run.scheduler == scheduler:  # the run's client: its futures outlive this step
        yield run
        return
    with dask_client(scheduler, lost_timeout_s) as pool:
        yield pool


def run_pool():
    """The Dask pool of the run in progress in this process (:func:`planner.io.dask_pool.dask_run`), or None
    (the local backend; a worker)."""
    from planner.io.dask_pool import RUN

    return RUN.get("pool")
