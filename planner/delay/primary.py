"""Primary delays: what goes wrong on its own on an ordinary day, per train type and kind, drawn per day.

Takes the job's ``[robustness]`` rules (:class:`Rule`) and the network's events; gives each event's
primary delay on each simulated day (:func:`sample`), from a seed, the same bytes on every run.

Kinds of primary delay, and the event that carries one:

* ``origin``: a late departure from the train's origin (its first departure);
* ``dwell``: a longer dwell (the departure from an intermediate stop);
* ``running``: a slower run (the arrival at the end of each leg).

Distributions: ``none``; ``exponential`` (with probability ``probability`` a delay drawn from the
exponential distribution of mean ``mean_s``, else 0); ``empirical`` (a value drawn with equal weight from
observed delays, ``values`` in seconds: the job reads them from a Parquet file, see the docs). A rule
applies to one train type (``*``: every type); the last rule naming an event's type and kind wins.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planner.delay.network import ARRIVAL, DelayNetwork

KINDS = ("origin", "dwell", "running")
DISTRIBUTIONS = ("none", "exponential", "empirical")


@dataclass(frozen=True)
class Rule:
    """One primary-delay rule (module doc)."""

    kind: str
    distribution: str
    train_type: str = "*"
    probability: float = 1.0
    mean_s: float = 0.0
    values: tuple[float, ...] = field(default=(), repr=False)
    source: str = ""
    """Where ``values`` came from (a file), for the page."""

    def text(self) -> str:
        who = "every train type" if self.train_type == "*" else self.train_type
        if self.distribution == "exponential":
            return (f"{self.kind}, {who}: {self.probability:.0%} of events late by an exponential delay of mean "
                    f"{self.mean_s:.0f} s")
        if self.distribution == "empirical":
            v = np.asarray(self.values)
            return (f"{self.kind}, {who}: drawn from {len(v)} observed delays{' in ' + self.source if self.source else ''}"
                    f" (mean {v.mean():.1f} s, {np.mean(v > 0):.0%} late)")
        return f"{self.kind}, {who}: none"


def event_kinds(net: DelayNetwork) -> np.ndarray:
    """Each event's kind of primary delay, as an index into :data:`KINDS`."""
    return np.where(net.ev_kind == ARRIVAL, 2, np.where(net.ev_origin, 0, 1)).astype(np.int8)


def groups(net: DelayNetwork, rules: list[Rule]) -> list[tuple[Rule, np.ndarray]]:
    """Each rule that applies to some event, with the events it gives their delay (the last rule wins)."""
    kinds = event_kinds(net)
    types = np.asarray(net.train_types, dtype=object)[net.ev_train] if net.n_events else np.zeros(0, dtype=object)
    which = np.full(net.n_events, -1, dtype=np.int64)
    for i, r in enumerate(rules):
        m = kinds == KINDS.index(r.kind)
        if r.train_type != "*":
            m &= types == r.train_type
        which[m] = i
    return [(rules[i], np.flatnonzero(which == i)) for i in range(len(rules))
            if rules[i].distribution != "none" and (which == i).any()]


def sample(net: DelayNetwork, rules: list[Rule], days: int, seed: int, chunk: int, stream: tuple[int, ...] = ()
           ) -> np.ndarray:
    """Primary delays ``(n_events, days)`` [s] of chunk ``chunk`` of a run seeded ``seed``.

    Each chunk has its own stream (``SeedSequence(seed, spawn_key=(chunk, *stream))``), so a chunk's days are the
    same whichever worker draws them and however many there are; ``stream``: a section's own numbers
    (:func:`planner.network.sections.stream_of`; none for a whole line), so that sections draw apart.
    """
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(int(chunk), *map(int, stream))))
    out = np.zeros((net.n_events, int(days)))
    for r, idx in groups(net, rules):
        shape = (len(idx), int(days))
        if r.distribution == "exponential":
            late = rng.random(shape) < r.probability
            out[idx] = np.where(late, rng.exponential(r.mean_s, shape), 0.0)
        elif r.distribution == "empirical":
            v = np.asarray(r.values, dtype=float)
            out[idx] = v[rng.integers(0, len(v), shape)]
    return out
