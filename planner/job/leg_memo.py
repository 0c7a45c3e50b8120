"""The margin report's legs as units of their own in the work cache: an edit recomputes the legs it touches.

The margin report is one unit of the nightly job, keyed by the whole line: one lowered speed limit changes
that key, and every leg of the line was computed again (on the 100x line, 59 s of an edit night for what
touched a handful of legs). Inside it, each leg group (direction, train type, origin, destination, lifted
restrictions) is now a unit of its own, keyed by exactly what its computation reads:

- the slice of the line the leg can see (:func:`planner.job.units.interstation_inputs` of the day's line
  without the group's lifted restrictions: the leg's stop markers, gradients, curves, the limits and
  beacons of its direction and train type, the train type, the line's maximum and approach);
- its trains' scheduled running times;
- the closed loop's errors at those times, and the train type's adhesion levels (from the stops step);
- the job's parameters and the planner's code.

The tables a leg uses come from the tables step's units, keyed by the same slice and parameters, so they
are what the key already says. A group whose key is stored is read back (the pickle-free codec, checked by
its digest like every cache entry) instead of computed; one whose key is new is computed and stored.
"""
from __future__ import annotations

from pathlib import Path

from planner.job.cache import Cache
from planner.job.publish import digest
from planner.job.units import code_digest, interstation_inputs

KIND = "margin_leg"


class LegMemo:
    """A leg group's result in the work cache at ``root`` (a plain path: it travels to the worker that computes
    the margins), for the job parameters whose digest is ``params``. ``enabled=False`` (``--no-cache``)
    reads nothing and still stores. ``hits`` and ``computed`` count the groups of the last report made here."""

    def __init__(self, root: str | Path, params: str, enabled: bool = True):
        self.root, self.params, self.enabled = str(root), params, enabled
        self.hits = self.computed = 0
        self._cache: Cache | None = None

    def __getstate__(self) -> dict:
        return {"root": self.root, "params": self.params, "enabled": self.enabled}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["root"], state["params"], state["enabled"])

    @property
    def cache(self) -> Cache:
        if self._cache is None:
            self._cache = Cache(Path(self.root), enabled=self.enabled)
        return self._cache

    def key(self, line, group: tuple, times, closed_loop_errors: dict, adhesion) -> str:
        from planner.line.operating_day import without_temporary

        direction, train_type, origin, destination, lifted = group
        seen = interstation_inputs(without_temporary(line, lifted), train_type, origin, destination)
        errors = sorted((repr(k), repr(v)) for k, v in closed_loop_errors.items())
        return digest([KIND, code_digest(), self.params, seen, [direction, train_type, origin, destination,
                                                                 list(lifted)],
                       [float(t) for t in times], errors, [float(a) for a in adhesion]])

    def get(self, key: str):
        r = self.cache.get(KIND, key)
        self.hits += r is not None
        return r

    def rejected_why(self) -> list[tuple[str, str, str]]:
        """The entries read here that failed verification (each then computed and stored again)."""
        return list(self._cache.rejected_why) if self._cache is not None else []

    def put(self, key: str, result) -> None:
        self.computed += 1
        self.cache.put(KIND, key, result)
