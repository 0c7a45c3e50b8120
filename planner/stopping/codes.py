"""The compiled stopping solver's interface, importable without compiling it.

The codes :func:`planner.stopping.kernel.kernel` returns and writes, the layout
of the one array it works in, and the modules a build of it is made of. The solver is
either the module built at install (:mod:`planner.io.compiled`) or, where
there is none for these sources, :mod:`planner.stopping.kernel` compiled just
in time; :func:`planner.stopping.pattern.solve_stop` picks on its first call and
reads both through the names here.
"""
from __future__ import annotations

# codes of kernel(); the caller turns them into a StopPattern or an error message
OK = 0
START_ABOVE_LIMIT, ZERO_LIMIT, STANDING, NEEDS_MORE, INTERNAL, INCONSISTENT = 1, 2, 3, 4, 5, 6
BAD_V_START, BAD_X_STOP, BAD_JERK = 10, 11, 12
BAD_DECEL, BAD_SPEED = 20, 30  # + a step-function code below
EMPTY, FIRST_NOT_ZERO, NOT_FINITE, NOT_SORTED, NOT_POSITIVE, NEGATIVE = 1, 2, 3, 4, 5, 6
HEAD = 8  # out[:HEAD]: code, index/value, T, brake start, braking distance, number of pieces

SOURCES = ("planner.stopping.pieces", "planner.stopping.construct", "planner.stopping.kernel", __name__,
           "planner.io.compiled")
"""What a build of the solver is made of: its digest names the built module (``planner kernels build``)."""


N_SLOTS = 5  # saved constructions in the node store (planner.stopping.construct names them)


def out_size(n_steps: int) -> int:
    """Length of the result part of the kernel's array for ``n_steps`` step rows in all."""
    return HEAD + 5 * (8 * (n_steps + 1) + 64 + 2)


def work_size(n_steps: int) -> int:
    """Length of the one array the kernel works in for ``n_steps`` step rows in all: the rows
    (``2 n_steps``, from 0), the result (:func:`out_size`, from ``2 n_steps``), then its scratch:
    the regions and their temporaries, the entry choices, the node counts and the node store."""
    n = n_steps
    out = HEAD + 5 * (8 * (n + 1) + 64 + 2)  # out_size(n), written out: the kernel compiles this function
    return (2 * n + out + (4 * n + 3) + (3 * n + 5) + 2 * (n + 1) + 3 + (N_SLOTS + 1)
            + N_SLOTS * 6 * (8 * (n + 1) + 64))
