"""planner: nightly train-running planning for a whole railway line.

Public API (stable): ``load_line``, ``running_time``, ``timekeeping_run`` (see
:mod:`planner.api`) and the sub-packages named after the railway steps, in
pipeline order: ``line``, ``physics``, ``tables``, ``stopping``, ``network``,
``datasets``, ``bundle``, ``report``, ``job`` (ARCHITECTURE.md).
"""
from __future__ import annotations

__version__ = "0.1.0"


def load_line(path):
    """Load and validate a line database folder; return a :class:`planner.line.model.Line` in SI."""
    from planner.line.loader import load_line as _load

    return _load(path)


def running_time(line_or_path, train_type, origin, destination, *, ratio=1.0, load=0.0,
                 traction_factor=1.0, ratio_changes=(), settings=None):
    """Running time between two stations at a target-speed ratio; see :func:`planner.api.running_time`."""
    from planner.api import running_time as _rt

    return _rt(line_or_path, train_type, origin, destination, ratio=ratio, load=load,
               traction_factor=traction_factor, ratio_changes=ratio_changes, settings=settings)


def timekeeping_run(line_or_path, train_type, origin, destination, *, arrival_s, changes=(), load=0.0,
                    traction_factor=1.0, settings=None):
    """One interstation in time-keeping mode (docs/design.md §4); see :func:`planner.api.timekeeping_run`."""
    from planner.api import timekeeping_run as _tk

    return _tk(line_or_path, train_type, origin, destination, arrival_s=arrival_s, changes=changes,
               load=load, traction_factor=traction_factor, settings=settings)


def __getattr__(name):
    # lazy public classes (importing numpy/pandas only when used)
    if name == "RunResult":
        from planner.api import RunResult

        return RunResult
    raise AttributeError(f"module 'planner' has no attribute {name!r}")
