"""planner: nightly train-running planning for a whole railway line.

Public API (stable): ``load_line``, ``running_time``, ``timekeeping_run`` and
the modules named after railway steps (``speed_profile``, ``run_curve``,
``tables``, ``onboard``, ``stopping``, ``margins``, ``bundle``, ``network``).
"""
from __future__ import annotations

__version__ = "0.1.0"


def load_line(path):
    """Load and validate a line database folder; return a :class:`planner.model.Line` in SI."""
    from .loader import load_line as _load

    return _load(path)
