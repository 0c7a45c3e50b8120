"""Station stops: the minimum-time jerk-limited stopping-pattern solver
(``pattern``, pure: limits in, a pattern out, the ``StopPattern`` of ``result``;
its construction compiled with numba in ``kernel``, ``construct`` and
``pieces``), the one definition of a station approach (``approach``) and the
sweep over every approach and adhesion level (``sweep``).

Takes a ``Line``; gives patterns and sweep results. Pure: no pandas, pyarrow or
file access.
"""
