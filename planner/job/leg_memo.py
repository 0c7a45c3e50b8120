"""The margin report's legs as units of their own in the work cache: an edit recomputes the legs it touches.

The margin report is one unit of the nightly job, keyed by the whole line: one lowered speed limit changes
that key, and every leg of the line was computed again (on the 100x line, 59 s of an edit night for what
touched a handful of legs). Inside it, each leg group (direction, train type, origin, destination, lifted
restrictions) is now a unit of its own, keyed by exactly what its computation reads:

- the slice of the line the leg can see (:func:`planner.job.units.interstation_inputs` of the day's line
  without the group's lifted restrictions, by its digest: the leg's stop markers, gradients, curves, the limits and
  beacons of its direction and train type, the train type, the line's maximum and approach);
- its trains' scheduled running times;
- the options its computation is given: the closed loop's errors at those times, the train type's
  adhesion levels (from the stops step), the margin rule, the ratio grid, the approach, the evaluation
  points, the integration step;
- the planner's code.

The tables a leg uses come from the tables step's units, keyed by the same slice and parameters, so they
are what the key already says. A group whose key is stored is read back (the pickle-free codec, checked by
its digest like every cache entry) instead of computed; one whose key is new is computed and stored. In the
nightly job each group is a unit of the run's runner (:class:`LegUnits`), so both happen on the workers.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from planner.job.cache import Cache
from planner.job.publish import digest
from planner.job.units import code_digest, interstation_digest

KIND = "margin_leg"


def plain(v):
    """``v`` as JSON can hold it, exactly (a float's repr is exact; dataclasses and arrays as their values): what a
    unit's key digests of plain data (a leg group's options; a section's line,
    :func:`planner.job.steps.section_digest`)."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, dict):
        return sorted((repr(k), plain(x)) for k, x in v.items())
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return [plain(x) for x in v.tolist()]
    if isinstance(v, (np.floating, float)):
        return repr(float(v))
    if isinstance(v, (np.integer, int, bool, str)) or v is None:
        return v if not isinstance(v, np.integer) else int(v)
    raise TypeError(f"a unit's key cannot hold {type(v).__name__}")


class LegMemo:
    """A leg group's result in the work cache at ``root`` (a plain path: it travels to the worker that computes
    the margins). ``enabled=False`` (``--no-cache``)
    reads nothing and still stores. ``hits`` and ``computed`` count the groups of the last report made here."""

    def __init__(self, root: str | Path, enabled: bool = True):
        self.root, self.enabled = str(root), enabled
        self.hits = self.computed = 0
        self._cache: Cache | None = None

    def __getstate__(self) -> dict:
        return {"root": self.root, "enabled": self.enabled}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["root"], state["enabled"])

    @property
    def cache(self) -> Cache:
        if self._cache is None:
            self._cache = Cache(Path(self.root), enabled=self.enabled)
        return self._cache

    def key(self, line, group: tuple, times, options: dict) -> str:
        """The key of leg group ``group`` (direction, train type, origin, destination, lifted restrictions) with
        its trains' scheduled running ``times`` and the keyword arguments its computation is given
        (``options``: the rule, grid, adhesion levels, approach, evaluation points, the closed loop's errors
        at those times)."""
        from planner.line.operating_day import without_temporary

        direction, train_type, origin, destination, lifted = group
        seen = interstation_digest(without_temporary(line, lifted), train_type, origin, destination)
        return digest([KIND, code_digest(), seen, [direction, train_type, origin, destination,
                                                                 list(lifted)],
                       [float(t) for t in times], {k: plain(v) for k, v in sorted(options.items())}])

    def get(self, key: str):
        r = self.cache.get(KIND, key)
        self.hits += r is not None
        return r

    def stats(self) -> dict:
        """The groups read back (``hits``) and computed (``computed``) here, and the entries that failed
        verification (``rejected``: ``[kind, key, why]`` each; then computed and stored again)."""
        why = self._cache.rejected_why if self._cache is not None else []
        return {"hits": self.hits, "computed": self.computed, "rejected": [list(r) for r in why]}

    def put(self, key: str, result) -> None:
        self.computed += 1
        self.cache.put(KIND, key, result)


def leg_kept(result):
    """What the job keeps of a leg group's result (:attr:`planner.job.units.Unit.after`): all of it (a row's
    figures, without tables); declared so that a stored group is read back on a worker, not in the job process."""
    return result


class LegUnits(LegMemo):
    """The nightly job's leg groups, each a unit of the run's runner (:class:`planner.job.units.Runner`, step
    :data:`KIND`): a computed group is stored by the worker that computed it and a stored one read back on a worker
    (checked by its digest there), counted with the run's other units; the job process neither encodes nor decodes
    them. Keys as :class:`LegMemo`'s."""

    def __init__(self, runner):
        super().__init__(runner.cache.root, enabled=runner.cache.enabled)
        self.runner = runner

    def run(self, keys: list[str], tasks: list) -> list:
        """The groups' results: :func:`planner.report.margins.leg_task` of each task, each keyed by ``keys``."""
        from planner.job.units import Unit
        from planner.report.margins import leg_task

        return self.runner.run(KIND, [Unit(KIND, k, f"{t[1]} {t[2]}->{t[3]}", leg_task, tuple(t), after=leg_kept)
                                      for k, t in zip(keys, tasks)])

    def stats(self) -> dict:
        """Nothing: the runner counts the groups with the run's units."""
        return {}
