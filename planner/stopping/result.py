"""The stopping solver's result: :class:`StopPattern` and its samples (docs/design.md §5).

:func:`planner.stopping.pattern.solve_stop` makes the patterns; this module is what they are.

A solved pattern is made without its constructor: it holds one copy of the solver's output and
builds its fields from it when they are first read, in two groups, the eight numbers and words
(feasibility, reason, request, duration, brake start, braking distance) and the five breakpoint
tuples. Building all thirteen fields and five tuples took as long as the solve itself, and most
callers read only the numbers (the margins) or nothing but the verdict. What is read is the same,
bit for bit, as what the constructor would have been given; equality, hashing, ``repr``,
``dataclasses.asdict``/``replace``, copying and pickling all go through the fields.

A solved pattern's ``_raw`` slot: ``(True, "", v_start_ms, x_stop_m, jerk_max_ms3, out)``, ``out``
the solver's output from ``out[2]`` as native doubles (``bytes``; the layout is
:mod:`planner.stopping.codes`'): the duration, brake start and braking distance, ``HEAD - 5``
floats not read, then the breakpoints t, x, v, a (``n + 1`` each) and the jerks (``n``) of its
``n`` pieces. A pattern made by the constructor has no ``_raw`` and all its fields.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from planner.errors import InfeasibleError, InputError
from planner.stopping.codes import HEAD

__all__ = ["PatternSamples", "StopPattern"]


class PatternSamples(NamedTuple):
    """A stopping pattern sampled in time (exact evaluation of the cubic pieces).

    Attributes
    ----------
    t_s, x_m, v_ms, a_ms2, j_ms3 : ndarray
        Time [s], position from the pattern start [m], speed [m/s], acceleration
        [m/s²] (negative when braking) and jerk [m/s³] (of the piece the sample
        lies in; the end point takes the last piece's jerk).
    """

    t_s: np.ndarray
    x_m: np.ndarray
    v_ms: np.ndarray
    a_ms2: np.ndarray
    j_ms3: np.ndarray


_NO_DEFAULT = object()


class _Solved:
    """A StopPattern field, a non-data descriptor: where the instance holds the field it is a plain
    attribute. A pattern made by the constructor holds all its fields and never comes here; one from
    :func:`~planner.stopping.pattern.solve_stop` holds only its ``_raw`` (module docstring) until a field is
    first read: then that field's group (the eight numbers and words, or the five breakpoint tuples) is
    set from it, as the constructor would have set it, and the field returned. Read on the class, the
    field's default (none: AttributeError, as for a plain field)."""

    __slots__ = ("name", "group", "default")

    def __init__(self, group: int, default=_NO_DEFAULT) -> None:
        self.group, self.default = group, default

    def __set_name__(self, owner, name: str) -> None:
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            if self.default is _NO_DEFAULT:
                raise AttributeError(self.name)
            return self.default
        raw = obj._raw
        if self.group:
            u, t, x, v, a, j = _UNPACK.get(len(raw[5])) or _unpacker(len(raw[5]))
            f = u(raw[5])
            got = {"t_s": f[t], "x_m": f[x], "v_ms": f[v], "a_ms2": f[a], "j_ms3": f[j]}
        else:
            T, s0, y = _SCALARS(raw[5])
            got = {"feasible": raw[0], "reason": raw[1], "v_start_ms": raw[2], "x_stop_m": raw[3],
                   "jerk_max_ms3": raw[4], "duration_s": T, "brake_start_m": s0, "braking_distance_m": y}
        obj.__dict__.update(got)  # frozen: the fields go into __dict__, not through setattr
        return got[self.name]


def _unpacker(size: int) -> tuple:
    """Reads the breakpoints from a solved pattern's ``out`` of ``size`` bytes (module docstring): the unpack
    and the slices of t, x, v, a (``n + 1`` each) and j (``n``) in what it returns (kept per size)."""
    n = (size // 8 - HEAD - 2) // 5
    q = n + 1
    u = struct.Struct(f"={8 * (HEAD - 2)}x{5 * n + 4}d").unpack
    return _UNPACK.setdefault(size, (u, *(slice(i * q, (i + 1) * q) for i in range(4)), slice(4 * q, 5 * q - 1)))


_SCALARS = struct.Struct("=3d").unpack_from
_UNPACK: dict[int, tuple] = {}


@dataclass(frozen=True)
class StopPattern:
    """A minimum-time jerk-limited stopping pattern, or why there is none.

    Attributes
    ----------
    feasible : bool
        True when a pattern meeting every limit exists.
    reason : str
        ``""`` when feasible; otherwise one line saying why (distance needed, ...).
    v_start_ms, x_stop_m, jerk_max_ms3 : float
        The request: start speed [m/s], stop position [m], jerk limit [m/s³].
    duration_s : float
        Pattern duration [s] (NaN when infeasible).
    brake_start_m : float
        Position where deceleration first begins, from the pattern start [m]
        (NaN when infeasible).
    braking_distance_m : float
        Distance from the brake start to the stop that the limits need [m]; also
        set when infeasible: then an upper bound on the distance needed, larger than
        ``x_stop_m`` (the construction's figure plus 10 µm and 1e-8 of it for its
        round-off, :func:`planner.stopping.pattern.needed_bound`: an approach that long
        is feasible), NaN when unknown (start speed above the first limit).
    t_s, x_m, v_ms, a_ms2 : tuple of float
        Breakpoints: state at the start of every piece, plus the end state
        (length ``n_pieces + 1``).
    j_ms3 : tuple of float
        Jerk of every piece [m/s³] (length ``n_pieces``).

    Notes
    -----
    A pattern from :func:`~planner.stopping.pattern.solve_stop` builds its fields from the solver's
    output when they are first read (:mod:`planner.stopping.result`); until then they are not in
    ``vars(pattern)``. Everything else reads them as attributes and sees what the constructor would
    have been given.
    """

    __slots__ = ("__dict__", "__weakref__", "_raw")  # _raw: a solved pattern's output (not a field)

    # each field a _Solved of its group (0: the numbers and words, 1: the breakpoints) and default, if any
    feasible: bool = _Solved(0)
    reason: str = _Solved(0)
    v_start_ms: float = _Solved(0)
    x_stop_m: float = _Solved(0)
    jerk_max_ms3: float = _Solved(0)
    duration_s: float = _Solved(0, math.nan)
    brake_start_m: float = _Solved(0, math.nan)
    braking_distance_m: float = _Solved(0, math.nan)
    t_s: tuple[float, ...] = _Solved(1, ())
    x_m: tuple[float, ...] = _Solved(1, ())
    v_ms: tuple[float, ...] = _Solved(1, ())
    a_ms2: tuple[float, ...] = _Solved(1, ())
    j_ms3: tuple[float, ...] = _Solved(1, ())

    def __getstate__(self) -> dict:
        """Pickled and copied as its fields (a solved pattern's read first), never its ``_raw``."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @property
    def n_pieces(self) -> int:
        """Number of constant-jerk pieces."""
        return len(self.j_ms3)

    def sample(self, dt_s: float) -> PatternSamples:
        """Sample the pattern every ``dt_s`` seconds, always including the end point.

        Parameters
        ----------
        dt_s : float
            Sampling interval [s], > 0.

        Returns
        -------
        PatternSamples
            Exact values of the cubic pieces at ``t = 0, dt, 2 dt, ..., T``.

        Raises
        ------
        InfeasibleError
            When the pattern is infeasible (there is nothing to sample).
        InputError
            When ``dt_s`` is not a positive number.
        """
        if not self.feasible:
            raise InfeasibleError(f"no stopping pattern to sample: {self.reason}")
        if not (dt_s > 0.0) or not math.isfinite(dt_s):
            raise InputError(f"sample: dt_s must be a positive number of seconds, got {dt_s!r}")
        T = self.duration_s
        t = np.arange(0.0, T, dt_s) if T > 0.0 else np.zeros(0)
        if t.size and T - t[-1] < 1e-9 * max(1.0, T):
            t = t[:-1]
        t = np.append(t, T)
        starts = np.asarray(self.t_s[:-1])
        if starts.size == 0:  # zero-length pattern (already standing at the stop)
            z = np.zeros_like(t)
            return PatternSamples(t, z + self.x_m[-1], z, z, z)
        idx = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, starts.size - 1)
        tau = t - starts[idx]
        x0 = np.asarray(self.x_m[:-1])[idx]
        v0 = np.asarray(self.v_ms[:-1])[idx]
        a0 = np.asarray(self.a_ms2[:-1])[idx]
        j = np.asarray(self.j_ms3)[idx]
        a = a0 + j * tau
        v = v0 + tau * (a0 + j * tau / 2.0)
        x = x0 + tau * (v0 + tau * (a0 / 2.0 + j * tau / 6.0))
        return PatternSamples(t, x, v, a, j)


set_raw = StopPattern._raw.__set__
"""Sets a solved pattern's ``_raw`` slot (module docstring; the class is frozen: no setattr)."""
