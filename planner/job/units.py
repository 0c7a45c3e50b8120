"""Units of work of the nightly job and the digests that key them in the cache.

A unit is one call of a step's library function (an interstation × direction ×
train type for tables and the closed loop, a station approach for stopping
patterns, a line for margins and conflicts) with the key of exactly the inputs
it depends on: the slice of the line it can see (:func:`interstation_inputs`),
its step's parameters and the planner's code (:func:`code_digest`). The
:class:`Runner` takes a step's units, reads the cached ones and computes the
rest in parallel; :class:`Progress` shows it.
"""
from __future__ import annotations

import dataclasses
import hashlib
import importlib.metadata
import os
import signal
import time
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Sequence

import planner
from planner import __version__
from planner.errors import PlannerError
from planner.io.compiled import COMPILERS  # their versions are part of the code digest
from planner.job.cache import Cache
from planner.job.config import Job
from planner.line.model import Line, per_line


# --- digests of exactly what a unit depends on -----------------------------------
_CODE_DIGEST: str | None = None


def kernel_backends() -> dict[str, str]:
    """Per compiled kernel, where its machine code comes from: ``aot`` (built at install) or ``jit``."""
    from planner.io import compiled
    from planner.physics import kernel_abi
    from planner.stopping import codes

    stop = compiled.status("stopping", codes.SOURCES)["state"] == "built"
    return {"integrator": kernel_abi.backend(), "stopping": "aot" if stop else "jit"}


def code_files() -> list[Path]:
    """Every source file of the planner package, every floor (sorted)."""
    return sorted(Path(planner.__file__).resolve().parent.rglob("*.py"))


def asset_files() -> list[Path]:
    """The package's data files that pages are made of (``assets/`` folders: scripts, styles), sorted."""
    return sorted(p for p in Path(planner.__file__).resolve().parent.rglob("assets/*") if p.is_file())


def code_digest() -> str:
    """SHA-256 over the planner package's source files (names and bytes), its version and its compilers'."""
    global _CODE_DIGEST
    if _CODE_DIGEST is None:
        h = hashlib.sha256(__version__.encode())
        for dist in COMPILERS:  # the kernels' machine code comes from these: a new compiler recomputes
            h.update(f"{dist}={importlib.metadata.version(dist)}".encode() + b"\0")
        for kind, backend in sorted(kernel_backends().items()):  # built at install or just in time: same
            h.update(f"{kind}={backend}".encode() + b"\0")  # bits (tests/test_compiled.py), kept apart anyway
        pkg = Path(planner.__file__).resolve().parent
        for p in code_files() + asset_files():  # a page's script is code too: a new one republishes the run
            h.update(p.relative_to(pkg).as_posix().encode() + b"\0")
            h.update(p.read_bytes())
        _CODE_DIGEST = h.hexdigest()
    return _CODE_DIGEST


def _segments(seg) -> list:
    return [(float(a), float(b), float(v)) for a, b, v in zip(seg.start_m, seg.end_m, seg.value)]


def interstation_inputs(line: Line, train_type: str, origin: str, destination: str) -> dict[str, Any]:
    """Everything of the line database that a run from ``origin`` to ``destination`` can see.

    Read from :meth:`planner.line.model.Line.window` (the stretch between the two
    stop markers widened by one train length on both sides), the same slice the
    unit is given to compute with, so the key digests exactly what the unit sees.
    """
    w = line.window(origin, destination, train_type)
    ext = w.run_between(origin, destination)
    direction = ext.direction
    return {
        "line_id": w.line_id,  # results carry it (partition line=): a copy under another id is not a hit
        "direction": direction,
        "origin": [origin, ext.start_m],
        "destination": [destination, ext.end_m],
        "line_max_ms": w.max_speed_ms,
        "train": dataclasses.asdict(w.train_type(train_type)),
        "gradients": _segments(w.gradients),
        "curves": _segments(w.curves),
        "limits": [dataclasses.astuple(s) for s in w.limits_for(direction, train_type)],
        "beacons": [dataclasses.astuple(x) for x in w.beacons_for(direction)],
        **({"approach_m": w.approach_m} if w.approach_m is not None else {}),  # the line's pattern start
    }


@per_line
def interstation_digest(line: Line, train_type: str, origin: str, destination: str) -> str:
    """The digest of :func:`interstation_inputs`, made once per line object and interstation
    (:func:`~planner.line.model.per_line`): the tables', stops', margins' and charts' keys each digest the same
    slice of the line, and making it again for each was 4 s of the job process on the 100x line."""
    from planner.job.publish import digest

    return digest(interstation_inputs(line, train_type, origin, destination))


def stops_key(job: Job, line: Line, train_type: str, origin: str, destination: str) -> str:
    """The cache key of the stops step's unit of the approach from ``origin`` to ``destination``: its slice of the
    line, the job's stopping-pattern parameters and step, and the code. The step's units are keyed by it, and a
    leg's chart finds its arrival's patterns by it."""
    from planner.job.publish import digest

    return digest(["stops", code_digest(), interstation_digest(line, train_type, origin, destination),
                   dataclasses.asdict(job.stops), job.tables.ds_m])


# --- units of work -----------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Unit:
    """One cacheable piece of work: ``fn(*args)`` whose result is keyed by ``key``."""

    step: str
    key: str
    label: str
    fn: Callable
    args: tuple
    after: Callable | None = None
    """What the job keeps of the result, ``after(result)`` (module level, or a partial of one): made where the
    result is, once it is stored in the cache there, when that is a local worker (the whole result then never
    travels to this process), else here (a cached result, one job, Dask). For a result much larger than what the
    job needs of it: a line's conflict report, whose occupation windows the job only writes as datasets."""


def _tables_unit(line, tt, o, d, ratios, eval_offset_m, ds_m, eval_interval_m=0.0, eval_auto_s=0.0):
    """``ratios``: (grid spec, its floor's minimum target [m/s]): the leg's grid is made here, from its slice."""
    from planner.physics.track import SimSettings
    from planner.tables.build import interstation_tables
    from planner.tables.ratios import leg_ratio_grid

    return interstation_tables(line, tt, o, d, leg_ratio_grid(ratios[0], line, tt, o, d, ratios[1]),
                               after_departure_m=eval_offset_m, eval_interval_m=eval_interval_m or None,
                               settings=SimSettings(ds_m=ds_m), eval_auto_s=eval_auto_s or None)


def _stops_unit(line, tt, o, d, adhesions_ms2, approach_m, ds_m):
    from planner.physics.track import SimSettings
    from planner.stopping.sweep import approach_patterns

    return approach_patterns(line, tt, o, d, adhesions_ms2, approach_m, settings=SimSettings(ds_m=ds_m))


@dataclasses.dataclass(frozen=True)
class Stored:
    """A unit's result by its entry in the work cache (``root``, ``step``, ``key``): what a unit that needs another's
    result is given instead of the result, so that it never passes through the job process. :meth:`load` reads it
    where it is used (checked by its digest like every read); this run stored it (with ``--no-cache`` too)."""

    root: str
    step: str
    key: str

    def load(self):
        from planner.errors import JobError

        cache = Cache(Path(self.root))
        obj = cache.get(self.step, self.key)
        if obj is None:
            raise JobError(f"{cache.path(self.step, self.key)}: a result this run stored is {cache.why_missed()}; "
                           "check the disk and run the job again")
        return obj


def _closed_loop_unit(line, tt, tables, scenarios, modes, horizon_s, step_s, ds_m):
    """``tables``: the leg's on-board tables, or the tables unit's :class:`Stored` result (read here)."""
    from planner.tables.closed_loop import Scenario, closed_loop_batch
    from planner.physics.track import SimSettings

    if isinstance(tables, Stored):
        tables = tables.load().onboard()
    return closed_loop_batch(line, tt, tables, scenarios=[Scenario(s.name, s.load, s.traction) for s in scenarios],
                             modes=modes, extra_s=horizon_s, step_s=step_s, settings=SimSettings(ds_m=ds_m))


def warm_worker() -> None:
    """What a worker imports for the job's units and background work, done first
    (:func:`planner.io.parallel.started_workers`), while the main process reads the lines. Here, not in
    :mod:`planner.job.pipeline`: a worker unpickling it imports this module, not the whole job (~35 ms
    of each worker's start, while the main process and both workers share the two cores)."""
    import planner.stopping.sweep  # noqa: F401
    import planner.tables.build  # noqa: F401
    import planner.tables.closed_loop  # noqa: F401


def _call(fn, args):
    """joblib worker: module level, so it pickles to local processes and Dask workers alike."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args)


def nothing_kept(_result) -> None:
    """:attr:`Unit.after` of a unit whose result the job never needs: nothing comes back; a worker that does need it
    reads it from the cache by its key (:class:`Stored`)."""
    return None


def kept_beside(fn: Callable) -> Callable:
    """Mark a module-level :attr:`Unit.after` whose result is small beside the unit's: what it keeps is stored
    too, as its own entry beside the result's (kind ``<step>_kept``, the same key), so that a read of the stored
    unit (:func:`_read_kept`) checks the result's digest and decodes only that. For a function of the result
    alone (the code is in every key)."""
    fn.kept_beside = True
    return fn


@dataclasses.dataclass(frozen=True)
class Placed:
    """A :attr:`Unit.after` in two parts: what the job keeps of the result (``kept``: a :func:`kept_beside` function of
    the result alone, stored beside it) and what this run makes of it in its own folder (``place(load)``, module
    level or a partial of one: its files, given ``load``, which decodes the result when called; a run whose files
    are the previous run's does not call it, :mod:`planner.job.made`). What the job gets: ``(kept, placed)``."""

    kept: Callable
    place: Callable

    def __call__(self, res):
        return self.kept(res), self.place(lambda: res)


def _beside(after: Callable | None) -> bool:
    if isinstance(after, Placed):
        after = after.kept
    return getattr(after, "kept_beside", False) is True


def _kept(after: Callable | None, res):
    """What the job keeps of a unit's result (:attr:`Unit.after`), wherever it is made."""
    return res if after is None else after(res)


def _beside_part(after: Callable | None, kept):
    """What of ``kept`` is stored beside the result: all of it, or a :class:`Placed` after's ``kept`` part (the
    placed part names this run's files)."""
    return kept[0] if isinstance(after, Placed) else kept


def _stored(cache: Cache, step: str, key: str, after: Callable | None, res):
    """A unit's result stored in the cache (it survives a later failure), then what the job keeps of it (stored
    beside it too when :func:`kept_beside`: after the result, so that it never stands for a result not stored)."""
    cache.put(step, key, res)
    kept = _kept(after, res)
    if _beside(after):
        cache.put(f"{step}_kept", key, _beside_part(after, kept))
    return kept


def _loader(cache: Cache, step: str, key: str) -> Callable:
    """A function that decodes the stored unit (checked just before) when a :class:`Placed` after needs it."""
    def load():
        obj = cache.get(step, key)
        if obj is None:
            raise PlannerError(f"the stored {step} unit {key[:12]} could not be read back ({cache.why_missed()}); "
                               "run the job again: it is computed then")
        return obj
    return load


def _call_kept(fn, args, cache: Cache, step: str, key: str, after: Callable | None):
    """Local worker (run by :func:`_call`): a unit's result stored in the cache here, then what the job keeps
    (:attr:`Unit.after`; the whole result without one)."""
    return _stored(cache, step, key, after, fn(*args))


def _read_kept(cache: Cache, step: str, key: str, after: Callable, own: bool = True):
    """Worker: a stored unit with :attr:`Unit.after` read back here, where what the job keeps of it is made (the
    whole result never comes to the job process); ``(kept, None)``, or ``(None, why)`` when the entry was not
    trusted: the job then has it computed again (:meth:`Runner.recompute`). The unit's inputs are not sent for a
    read, only its key: on a night that changed little they are most of what would travel, for nothing. Its own
    :class:`Cache` on the same root, so that the job's counts the rejection once (:meth:`Cache.rejected_elsewhere`)
    wherever this runs (``own=False``: read in the job process, with its cache).

    The entry is always checked (its name, kind, key and digest); it is decoded only when what the job keeps
    needs it: not for :func:`nothing_kept` (whoever needs the result reads it by its key), nor when what is kept
    is stored beside it (:func:`kept_beside`; an entry beside that is missing or not trusted is made again from
    the decoded result, and the unit is not recomputed)."""
    mine = Cache(cache.root, enabled=cache.enabled) if own else cache
    if after is nothing_kept or _beside(after):
        if not mine.check(step, key):
            return None, mine.why_missed()
        if after is nothing_kept:
            return None, None
        # beside it: a damaged one is made again below, not a rejected unit (the job's counts do not see it)
        kept = Cache(cache.root, enabled=cache.enabled).get(f"{step}_kept", key)
        if kept is not None:
            if isinstance(after, Placed):  # this run's files: the result is decoded only if they are not reused
                return (kept, after.place(_loader(mine, step, key))), None
            return kept, None
    obj = mine.get(step, key)
    if obj is None:
        return None, mine.why_missed()
    kept = _kept(after, obj)
    if _beside(after):
        mine.put(f"{step}_kept", key, _beside_part(after, kept))
    return kept, None


class Runner:
    """Runs units through the cache and the parallel backend, counting what it computed."""

    def __init__(self, job: Job, cache: Cache, progress: "Progress"):
        self.job = job
        self.cache = cache
        self.progress = progress
        self.computed: dict[str, int] = {}
        self.reused: dict[str, int] = {}

    def recompute(self, u: Unit):
        """A stored unit that was not trusted where it was read (:func:`_read_kept`) started again on a worker (here,
        later, with one job), where it is stored; :meth:`planner.io.parallel.Background.result` is what the job
        keeps of it. Started as each is found, so that a damaged cache is computed again in parallel."""
        from planner.io.parallel import background

        p = self.job.parallel
        return background(_call, (_call_kept, (u.fn, u.args, self.cache, u.step, u.key, u.after)),
                          name=p.backend, n_jobs=p.n_jobs)

    def run(self, step: str, units: Sequence[Unit]) -> list:
        """Results of ``units`` in order; cached ones loaded, the rest computed in parallel.

        Each result is cached as soon as it arrives, so a run that fails part
        way (e.g. :class:`planner.io.parallel.ClusterLostError`) leaves the
        finished units for the next run.
        """
        return self.run_steps([(step, units)])[0]

    def run_steps(self, groups: Sequence[tuple[str, Sequence[Unit]]]) -> list[list]:
        """:meth:`run` for several steps' units in one pass of the workers; a result list per step.

        For units that do not depend on each other: a step of one long unit (a
        line's conflicts or train graph) then runs on one worker while the
        other works through a step of many, instead of alone on a core after
        it. Each step's progress bar and timing run from the common start to
        its own last unit.
        """
        return self.start_steps(groups, wait=True).results()

    def start(self, step: str, units: Sequence[Unit]) -> "Started":
        """:meth:`run` without waiting: the units start on the local workers now and this process goes on
        with work of its own; :meth:`Started.results` takes them (stored in the cache as they are taken).
        For a step whose results nothing needs until later (the speed–distance charts, drawn while the
        pages are written). On the run's Dask cluster (:func:`planner.io.parallel.dask_run`) likewise; with
        one job, or a Dask client of its own, the units are computed before it returns, as by :meth:`run`."""
        return self.start_steps([(step, units)], wait=False)

    def start_steps(self, groups: Sequence[tuple[str, Sequence[Unit]]], wait: bool) -> "Started":
        """The units of ``groups`` looked up in the cache and the rest started (:meth:`run_steps`, :meth:`start`)."""
        from planner.io.parallel import LocalPool, backend, batched, run_pool, unbatched

        started = Started(self, groups)
        p = self.job.parallel
        run = run_pool()
        # a stored unit with Unit.after is read where it is used, on a worker, when there are workers: the job
        # process looks at the entry's name only, not at its contents
        elsewhere = (p.backend == "local" and p.n_jobs != 1) or (
            p.backend == "dask" and run is not None and run.scheduler == p.scheduler)
        for g, (step, units) in enumerate(groups):
            missing = 0
            reads = 0
            for i, u in enumerate(units):
                if elsewhere and u.after is not None and self.cache.present(step, u.key):
                    started.todo.append((g, i))
                    started.reads.add((g, i))
                    reads += 1
                    continue
                if u.after is None:
                    obj = self.cache.get(step, u.key)
                    kept, found = obj, obj is not None
                else:  # what the job keeps of it (Unit.after), here: it was made before
                    kept, why = _read_kept(self.cache, step, u.key, u.after, own=False)
                    found = why is None
                if not found:
                    started.todo.append((g, i))
                    missing += 1
                else:
                    started.out[g][i] = kept
            self.reused[step] = self.reused.get(step, 0) + len(units) - missing
            self.computed[step] = self.computed.get(step, 0) + missing
            self.progress.start(step, len(units), done=len(units) - missing - reads)
        started.left = [sum(1 for t in started.todo if t[0] == g) for g in range(len(groups))]
        for g, (step, _) in enumerate(groups):
            if not started.left[g]:
                self.progress.finish(step)
        if not started.todo:
            return started
        with backend(p.backend, n_jobs=p.n_jobs, scheduler=p.scheduler,
                     lost_timeout_s=p.dask_lost_timeout_s) as pool:
            unit = started.unit
            on_run = pool is run_pool()  # the run's Dask cluster: its futures outlive this context too

            def task(t):
                u = unit(t)
                if t in started.reads:
                    return _read_kept, (self.cache, u.step, u.key, u.after)
                if t in started.kept:
                    return _call_kept, (u.fn, u.args, self.cache, u.step, u.key, u.after)
                return u.fn, u.args

            started.kept = set(started.reads)  # read and kept where they are used
            if pool.n_jobs == 1 or (len(started.todo) == 1 and wait):  # one unit waited for: here
                started.gen = (_call(*task(t)) for t in started.todo)
            else:  # a local pool's tasks start now and go on after the context (joblib's generator)
                # results stored, and what the job keeps made, where they are made; with the kill-point hook, here
                if (isinstance(pool, LocalPool) or on_run) and not os.environ.get(KILL_ENV):
                    started.kept |= set(started.todo)
                tasks, sizes = batched([task(t) for t in started.todo], [t in started.reads for t in started.todo])
                started.gen = unbatched(pool.imap(_call, tasks), sizes)  # reads in batches: 37,000 a 100x edit
            if wait or not (isinstance(pool, LocalPool) or on_run):
                started.results()
        return started


class Started:
    """Units started by :meth:`Runner.start_steps`: the cached results, the rest coming from the workers."""

    def __init__(self, runner: Runner, groups: Sequence[tuple[str, Sequence[Unit]]]):
        self.runner, self.groups = runner, groups
        self.out: list[list] = [[None] * len(units) for _, units in groups]
        self.todo: list[tuple[int, int]] = []
        self.kept: set[tuple[int, int]] = set()  # units stored on their worker, and kept there (Unit.after)
        self.reads: set[tuple[int, int]] = set()  # stored units read back on a worker (of kept: see _read_kept)
        self.left: list[int] = []
        self.gen = None

    def unit(self, t: tuple[int, int]) -> Unit:
        return self.groups[t[0]][1][t[1]]

    def results(self, each: Callable[[int, int, Any], None] | None = None) -> list[list]:
        """A result list per step, waiting for the workers; each result is stored in the cache as it
        arrives, then ``each(group, index, result)`` is called (first for the results found in the cache,
        then for the others as they arrive: a page per result written while the workers draw the next)."""
        gen, self.gen = self.gen, None
        if each is not None:
            waiting = set(self.todo) if gen is not None else set()
            for g, res in enumerate(self.out):
                for i, r in enumerate(res):
                    if (g, i) not in waiting:
                        each(g, i, r)
        if gen is None:
            return self.out
        r = self.runner
        redo = []  # (unit, started again): stored units not trusted where they were read

        def take(g: int, i: int, res) -> None:
            self.out[g][i] = res
            r.progress.advance(self.groups[g][0])
            self.left[g] -= 1
            if not self.left[g]:
                r.progress.finish(self.groups[g][0])
            if each is not None:
                each(g, i, res)

        try:
            for (g, i), res in zip(self.todo, gen):
                step, u = self.groups[g][0], self.unit((g, i))
                if (g, i) in self.reads:
                    res, why = res
                    if why is not None:  # not trusted where it was read: computed again, and counted here
                        r.cache.rejected_elsewhere(step, u.key, why)
                        r.reused[step] -= 1
                        r.computed[step] = r.computed.get(step, 0) + 1
                        redo.append(((g, i), r.recompute(u)))
                        continue
                elif (g, i) not in self.kept:  # else stored on its worker already, and kept there
                    res = _stored(r.cache, step, u.key, u.after, res)
                if (g, i) not in self.reads:  # a unit just stored (test hook), not one read back
                    _kill_point()
                take(g, i, res)
            while redo:
                t, h = redo[0]
                res = h.result()
                redo.pop(0)
                take(*t, res)
        finally:
            gen.close()  # a failed run (a full disk): stop the workers' tasks now, in this thread
            for _, h in redo:
                h.discard()
        return self.out

    def discard(self) -> None:
        """The run failed before it needed the results: wait for the workers (waiting, not aborting: see
        :meth:`planner.io.parallel.Background.discard`) and keep what they finished in the cache, as far as it
        can be stored; errors are dropped (the run's own error is the one reported)."""
        gen, self.gen = self.gen, None
        if gen is None:
            return
        try:
            for t, res in zip(self.todo, gen):
                if t in self.kept:  # stored on its worker
                    continue
                try:
                    self.runner.cache.put(self.groups[t[0]][0], self.unit(t).key, res)
                except Exception:  # noqa: BLE001 - e.g. the full disk the run failed on
                    pass
        except Exception:  # noqa: BLE001 - a unit that failed: the run is failing already
            pass
        finally:
            gen.close()


# --- test hook -----------------------------------------------------------------------
KILL_ENV = "PLANNER_TEST_KILL_AT"
"""Tests only: with ``N`` in this environment variable a run SIGKILLs its own process at its N-th
kill point (each unit just stored in the cache, then the staged run just before publishing), so
tests kill runs at deterministic moments instead of after a wall-clock delay. With it set, the job
process stores each computed result as it takes it (normally the worker that made it does), so that
the N-th kill point is the N-th unit stored whatever the workers have finished meanwhile; a stored unit
read back on a worker is not a kill point. Unset normally."""


_kill_points = 0


def _kill_point() -> None:
    global _kill_points
    _kill_points += 1
    if os.environ.get(KILL_ENV) == str(_kill_points):
        os.kill(os.getpid(), signal.SIGKILL)


# --- progress ------------------------------------------------------------------------
class Progress:
    """A rich progress bar per step (counts and time left) plus the per-step timings."""

    def __init__(self, enabled: bool = True):
        self.timings: dict[str, float] = {}
        self._t0: dict[str, float] = {}
        self._ids: dict[str, Any] = {}
        self._bar = None
        if enabled:
            from rich.progress import (
                BarColumn, MofNCompleteColumn, Progress as RichProgress, TextColumn, TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = RichProgress(
                TextColumn("{task.description:<12}"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(), transient=False,
            )

    def __enter__(self):
        if self._bar:
            self._bar.start()
        return self

    def __exit__(self, *exc):
        if self._bar:
            self._bar.stop()

    def start(self, step: str, total: int, done: int = 0) -> None:
        self._t0[step] = time.perf_counter()
        if self._bar is not None:
            if step in self._ids:
                self._bar.update(self._ids[step], total=total, completed=done)
            else:
                self._ids[step] = self._bar.add_task(step, total=total, completed=done)

    def advance(self, step: str, n: int = 1) -> None:
        if self._bar is not None and step in self._ids:
            self._bar.advance(self._ids[step], n)

    def finish(self, step: str) -> None:
        """End the step's current interval; a step's timing is the sum of its intervals (a step may
        compute its units in one and write its page in another)."""
        t0 = self._t0.pop(step, None)
        if t0 is not None:
            self.timings[step] = round(self.timings.get(step, 0.0) + time.perf_counter() - t0, 3)
        if self._bar is not None and step in self._ids:
            t = self._bar.tasks[[x.id for x in self._bar.tasks].index(self._ids[step])]
            self._bar.update(self._ids[step], completed=t.total)

    @contextmanager
    def step(self, name: str, total: int = 1):
        self.start(name, total)
        yield
        self.finish(name)
