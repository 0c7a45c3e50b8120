"""Monte Carlo days: primary delays drawn, propagated, and only their statistics kept.

Takes the day's :class:`~planner.delay.network.DelayNetwork`, the primary-delay rules, a number of days
and a seed; gives :class:`Stats` (sums, histograms and per-activity totals over all days). The days run
in chunks (:func:`chunk_days`: :data:`CHUNK_DAYS`, fewer on a network so large that a chunk's delays
would pass :data:`CHUNK_BYTES`, never fewer than :data:`MIN_CHUNK_DAYS`), each with its primary delays
drawn from its own stream (:func:`planner.delay.primary.sample`), in parallel on the job's workers
(:func:`planner.io.parallel.iter_tasks`). The chunks' statistics are summed in chunk order as they
arrive, so the result is the same bytes whatever the number of workers, and memory is one chunk's
delays per worker (events × chunk days × 8 bytes, a few times) plus two chunks' statistics.

Per day, each event's delay is propagated twice with the same primary delays: on the whole network and
on each train alone (no headways, no connections). The difference is the **knock-on** (secondary)
delay: what the event would not have without the other trains.

Delay histogram per event (:data:`EDGES_S`): bin 0 is on time (delay 0), then 10 s bins to 10 min,
60 s bins to 1 h, and one bin beyond. A share "within 1, 3, 5 min" is exact (the minutes are edges);
a quantile is the upper edge of the bin in which it falls (at most 10 s high below 10 min).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.delay.network import CONNECTION, HEADWAY, DelayNetwork
from planner.delay.primary import Rule, sample
from planner.delay.propagate import histogram, propagate

CHUNK_DAYS = 250
"""Days per chunk, at most (:func:`chunk_days`)."""
CHUNK_BYTES = 32 * 2 ** 20
"""A chunk's delays [bytes] (events × days × 8), at most, unless that is fewer than :data:`MIN_CHUNK_DAYS`."""
MIN_CHUNK_DAYS = 64
"""Days per chunk, at least: each event's update runs over the chunk's days, and fewer days than this cost more
per day than the cache misses of a larger chunk. Measured in one process, ns per event and day: the 10× sample
line 74 / 47 / 55 / 101 with chunks of 250 / 62 / 16 / 4 days (1,000 days); the 100× line 100 / 53 / 70 / 109 with
chunks of 250 / 62 / 16 / 6 days (500 days). The sample (6,728 events) keeps :data:`CHUNK_DAYS`; the 10× line runs
64 days a chunk (34 MB of delays), the 100× line too (344 MB)."""

EDGES_S = np.concatenate([[0.0], np.arange(10.0, 600.0 + 1, 10.0), np.arange(660.0, 3600.0 + 1, 60.0)])
"""Upper edges of the delay bins [s]: (−∞, 0], (0, 10], …, (590, 600], (600, 660], …, (3540, 3600]; then (3600, ∞)."""


@dataclass(eq=False)
class Stats:
    """Statistics of simulated days, summed over days (so chunks add)."""

    days: int
    sum_s: np.ndarray          # per event: Σ delay
    sumsq_s: np.ndarray        # per event: Σ delay²
    alone_sum_s: np.ndarray    # per event: Σ delay of the train alone
    primary_sum_s: np.ndarray  # per event: Σ its own primary delay
    hist: np.ndarray           # (events, bins) days per delay bin
    push_s: np.ndarray         # per activity: Σ delay it transmitted
    binds: np.ndarray          # per activity: days it set its event's delay
    absorbed_s: np.ndarray     # per activity: Σ delay its slack absorbed

    def add(self, o: "Stats") -> "Stats":
        """Add ``o``'s days into these statistics (in place; the same sums as ``self + o``) and return them."""
        self.days += o.days
        for f in ("sum_s", "sumsq_s", "alone_sum_s", "primary_sum_s", "hist", "push_s", "binds", "absorbed_s"):
            getattr(self, f).__iadd__(getattr(o, f))
        return self

    def __add__(self, o: "Stats") -> "Stats":
        return Stats(self.days + o.days, *(getattr(self, f) + getattr(o, f) for f in
                                           ("sum_s", "sumsq_s", "alone_sum_s", "primary_sum_s", "hist", "push_s",
                                            "binds", "absorbed_s")))

    @property
    def mean_s(self) -> np.ndarray:
        return self.sum_s / self.days

    @property
    def sem_s(self) -> np.ndarray:
        """Standard error of each event's mean delay [s]."""
        var = np.maximum(self.sumsq_s / self.days - self.mean_s ** 2, 0.0) * self.days / max(self.days - 1, 1)
        return np.sqrt(var / self.days)

    @property
    def knock_on_s(self) -> np.ndarray:
        """Mean knock-on delay per event [s] (module doc)."""
        return (self.sum_s - self.alone_sum_s) / self.days

    def quantile_s(self, q: float) -> np.ndarray:
        """Upper bin edge of each event's ``q`` quantile [s] (+inf beyond the last edge)."""
        cum = np.cumsum(self.hist, axis=1)
        k = (cum >= q * self.days - 1e-9).argmax(axis=1)
        edges = np.r_[EDGES_S, np.inf]
        return edges[k]

    def within(self, seconds: float) -> np.ndarray:
        """Share of days each event is at most ``seconds`` late (``seconds`` an edge of the bins)."""
        return self.hist[:, :edge_index(seconds) + 1].sum(axis=1) / self.days


def edge_index(seconds: float) -> int:
    """The bin whose upper edge is ``seconds`` (an edge of :data:`EDGES_S`: the minutes the shares are read at)."""
    return int(np.flatnonzero(np.isclose(EDGES_S, seconds))[0])


def bins(z: np.ndarray) -> np.ndarray:
    """Bin of each delay (:data:`EDGES_S`)."""
    return np.searchsorted(EDGES_S, z, side="left")


def chunk_stats(net: DelayNetwork, alone: DelayNetwork, rules: list[Rule], days: int, seed: int,
                chunk: int, stream: tuple[int, ...] = ()) -> Stats:
    """Statistics of one chunk of ``days`` days (chunk index ``chunk``: its own random stream; ``stream``:
    :func:`planner.delay.primary.sample`)."""
    p = sample(net, rules, days, seed, chunk, stream)
    z, push, binds, absorbed = propagate(net, p, attribution=True)
    za = propagate(alone, p)
    alone_sum = za.sum(axis=1)
    del za
    hist = histogram(z, EDGES_S)
    return Stats(days, z.sum(axis=1), _sum_squares(z), alone_sum, p.sum(axis=1), hist, push, binds, absorbed)


def _sum_squares(z: np.ndarray, rows: int = 4096) -> np.ndarray:
    """``(z * z).sum(axis=1)``, the same bytes, a block of rows at a time (no square of the whole chunk held)."""
    out = np.empty(z.shape[0])
    for i in range(0, z.shape[0], rows):
        b = z[i:i + rows]
        out[i:i + rows] = (b * b).sum(axis=1)
    return out


def chunk_days(n_events: int) -> int:
    """Days per chunk for a network of ``n_events`` events: as many as keep a chunk's delays within
    :data:`CHUNK_BYTES`, from :data:`MIN_CHUNK_DAYS` to :data:`CHUNK_DAYS`."""
    return int(max(MIN_CHUNK_DAYS, min(CHUNK_DAYS, CHUNK_BYTES // (8 * max(int(n_events), 1)))))


def plan_chunks(days: int, chunk_days: int = CHUNK_DAYS) -> list[int]:
    """Days of each chunk: full chunks, then the rest."""
    full, rest = divmod(int(days), int(chunk_days))
    return [int(chunk_days)] * full + ([rest] if rest else [])


def simulate(net: DelayNetwork, rules: list[Rule], days: int, seed: int, *, n_jobs: int = 1,
             progress=None, chunk: int | None = None, stream: tuple[int, ...] = ()) -> Stats:
    """``days`` simulated days of the network, their statistics (module doc); ``chunk`` days per chunk
    (default :func:`chunk_days`); ``stream``: the draws' own stream (a section of a line,
    :func:`planner.delay.primary.sample`)."""
    from planner.io.parallel import iter_tasks

    if days < 1:
        raise ValueError("days must be ≥ 1")
    alone = net.without((HEADWAY, CONNECTION))
    sizes = plan_chunks(days, chunk_days(net.n_events) if chunk is None else chunk)
    total = None
    for part in iter_tasks(chunk_stats, [(net, alone, rules, n, seed, i, stream) for i, n in enumerate(sizes)], n_jobs,
                           progress):
        total = part if total is None else total.add(part)
    return total
