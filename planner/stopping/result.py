"""The stopping solver's result: :class:`StopPattern` and its samples (docs/design.md §5).

:func:`planner.stopping.pattern.solve_stop` makes the patterns; this module is what they are.
A solved pattern keeps its breakpoints as the solver wrote them, one copy of its output
(``bytes``), and turns them into the five tuples the first time one of them is read: most
patterns of a sweep are only timed, and building five tuples of floats per solve was as
long as the solve itself. What is read is the same either way, bit for bit.
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
BREAKPOINTS = ("t_s", "x_m", "v_ms", "a_ms2", "j_ms3")


class _Solved:
    """A StopPattern field, a non-data descriptor: where the instance holds the field it is a plain
    attribute. A pattern made by the constructor holds all its fields and never comes here; one from
    :func:`~planner.stopping.pattern.solve_stop` holds only its ``_raw`` (:data:`RAW`) until a field is
    first read: then that field (the five breakpoint tuples: all five) is set from it, as the constructor
    would have set it, and returned. Read on the class, the field's default (none: AttributeError, as for
    a plain field)."""

    __slots__ = ("name", "at", "default")

    def __init__(self, at: int, default=_NO_DEFAULT) -> None:
        self.at, self.default = at, default

    def __set_name__(self, owner, name: str) -> None:
        self.name = name

    def __get__(self, obj, owner=None):
        if obj is None:
            if self.default is _NO_DEFAULT:
                raise AttributeError(self.name)
            return self.default
        raw, at, d = obj._raw, self.at, obj.__dict__  # frozen: the fields go into __dict__, not setattr
        if at < 5:
            v = raw[at]
        elif at < 8:
            v = _DOUBLE(raw[5], 8 * (at - 5))[0]
        else:
            d.update(zip(BREAKPOINTS, breakpoints(raw[5])))
            return d[self.name]
        d[self.name] = v
        return v


RAW = "(True, '', v_start_ms, x_stop_m, jerk_max_ms3, out)"
"""A solved pattern's ``_raw``: ``out`` the solver's output from ``out[2]`` as native doubles (bytes,
:mod:`planner.stopping.codes`): the duration, brake start and braking distance, ``HEAD - 5`` floats
skipped, then the breakpoints t, x, v, a (``n + 1`` each) and the jerks (``n``) of its ``n`` pieces."""


def breakpoints(out: bytes) -> tuple[tuple[float, ...], ...]:
    """The five breakpoint tuples (t, x, v, a, j) in a solved pattern's output ``out`` (:data:`RAW`)."""
    n = (len(out) // 8 - HEAD - 2) // 5
    u = _UNPACK.get(n)
    if u is None:
        u = _UNPACK.setdefault(n, struct.Struct(f"={8 * (HEAD - 2)}x{5 * n + 4}d"))
    f = u.unpack(out)
    q = n + 1
    return f[:q], f[q:2 * q], f[2 * q:3 * q], f[3 * q:4 * q], f[4 * q:]


_DOUBLE = struct.Struct("=d").unpack_from
_UNPACK: dict[int, struct.Struct] = {}


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
        set when infeasible (it is then larger than ``x_stop_m``), NaN when
        unknown (start speed above the first limit).
    t_s, x_m, v_ms, a_ms2 : tuple of float
        Breakpoints: state at the start of every piece, plus the end state
        (length ``n_pieces + 1``).
    j_ms3 : tuple of float
        Jerk of every piece [m/s³] (length ``n_pieces``).

    Notes
    -----
    A pattern from :func:`~planner.stopping.pattern.solve_stop` reads its five breakpoint tuples from
    the solver's output the first time one is read (module docstring); until then they are not in
    ``vars(pattern)``. Equality, hashing, ``dataclasses.asdict`` and ``replace`` read them as
    attributes, so they see the same values as for a pattern made by the constructor.
    """

    __slots__ = ("__dict__", "__weakref__", "_raw")  # _raw: a solved pattern's output (not a field)

    feasible: bool = _Solved(0)
    reason: str = _Solved(1)
    v_start_ms: float = _Solved(2)
    x_stop_m: float = _Solved(3)
    jerk_max_ms3: float = _Solved(4)
    duration_s: float = _Solved(5, math.nan)
    brake_start_m: float = _Solved(6, math.nan)
    braking_distance_m: float = _Solved(7, math.nan)
    t_s: tuple[float, ...] = _Solved(8, ())
    x_m: tuple[float, ...] = _Solved(8, ())
    v_ms: tuple[float, ...] = _Solved(8, ())
    a_ms2: tuple[float, ...] = _Solved(8, ())
    j_ms3: tuple[float, ...] = _Solved(8, ())

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
"""Stores a solved pattern's output in its ``_raw`` slot (the class is frozen: no setattr)."""
