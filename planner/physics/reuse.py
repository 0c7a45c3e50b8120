"""Exact reuse of identical runs: a batch steps each distinct state once.

Two runs of one batch that stand at the same grid node with the same bits in everything the
kernel's step reads of a run have the same future, bit for bit. What it reads
(:func:`planner.physics.kernel.advance`): of the state, speed², speed, the ceiling² at the node,
the stall marker (``st`` rows ``S_W``, ``S_V``, ``S_C0``, ``S_BAD``), the phase code and the coasting
flag (``lane``); every per-run constant (its ``par`` column: Davis terms, traction, ratio, cruise
cap, shedding rate) and its column of the ceiling's segment table ``e``; and what the whole batch
shares (the track, the train, the batch-wide switches). The step is a function of exactly these
(the tractive-effort piece it hunts from is found again from the speed), so two runs equal in
them at node k are equal in them at every later node. The batch-wide switches (above-ceiling
mode, stall checks) are the same for both, and the same with either one dropped: each is a
maximum, minimum or "any" over the runs' states, in which two equal runs count alike.

What two such runs do not share are their sums, time and traction work, each added up step by
step (``t ← t + Δt``): the kernel never reads them (a time that is not finite stops the batch as a
stall, and a finite time plus the same finite increment stays finite). So at a *check node*
(:func:`check_every`, counted from the grid's start) the batch keeps one run of each set of
equal ones in the kernel (the *leader*: the lowest index) and the others *follow* it: the kernel
records each followed leader's increments Δt and Δwork step by step (``inc`` rows ``I_DT``, ``I_DWORK``)
and a follower adds the same increments to its own sums in the same order, one at a time
(kernel ``follow``): the same additions of the same bits as stepping it would make. Its time
and energy are therefore those of stepping it, to the bit, and everything else of its state is
its leader's. At a node with an event (snapshot, ratio change, controller) and at the end every
run has its own columns again (:meth:`Reuse.expand`), so the events and the result see the batch
as if each run had been stepped. Equality is decided on the bits themselves (a hash only finds
candidates; a run follows only a run whose key words it equals), never by a tolerance.

A batch stepped with and without reuse gives byte-identical results (``tests/test_reuse.py``:
every table of the sample line and of random small lines). It pays where runs meet: the rows of
table (b) with the same ratio after a point, which hold the same target or brake on the same
curve; table (d)'s states at the last point (``benchmarks/bench_reuse.py`` measures it).
"""
from __future__ import annotations

import numpy as np

from planner.physics import kernel_abi as K

ENABLED = True
"""Reuse identical runs in :func:`planner.physics.run_curve.simulate` (off: every run is stepped;
the results are the same bytes, this is for the tests and the benchmark that show it)."""
CHECK_EVERY = 16
"""Nodes between two looks for runs that have met (counted from the grid's first node), in a batch of at
least :data:`BIG_BATCH` runs (:func:`check_every`)."""
BIG_BATCH = 1000
"""Runs in the kernel from which a batch looks every :data:`CHECK_EVERY` nodes, not every 4 × that."""
MERGE_SHARE = 16
"""Runs that have met leave the kernel's batch once they are at least 1/MERGE_SHARE of it (the batch's
arrays are copied without them); fewer stay in it, stepped, until then."""
MIN_RUNS = 8
"""Smaller batches are not searched for equal runs: looking costs more than it can save."""

_MIX = np.uint64(0x9E3779B97F4A7C15)
_DYN_ROWS = [K.S_W, K.S_V, K.S_C0, K.S_BAD]
"""The state rows a step reads (with ``lane`` and the constants); ``S_T``, ``S_WORK`` are sums it
never reads, ``S_WLAST`` is written on the last step before anything reads it."""


def check_every(n: int) -> int:
    """Nodes to the next look for runs that have met, in a batch of ``n`` runs in the kernel: a look
    costs a fixed part and a part per run, a step a part per run, so small batches look less often."""
    return CHECK_EVERY if n >= BIG_BATCH else 4 * CHECK_EVERY


def equal_groups(keys: np.ndarray, mix: np.uint64 = _MIX) -> np.ndarray:
    """For each column of ``keys`` (c, n) uint64, the lowest index of a column with the same bits
    (kernel ``groups``: a hash table finds candidates, equal words decide; ``mix`` is the hash's
    multiplier, which the tests set to 0 to make every hash collide)."""
    keys = np.ascontiguousarray(keys, dtype=np.uint64)
    n = keys.shape[1]
    rep = np.empty(n, np.int64)
    table = np.full(1 << max(int(2 * n - 1).bit_length(), 1), -1, np.int64)
    K.load().groups(keys, np.uint64(mix), table, rep)
    return rep


def _bits(a: np.ndarray) -> np.ndarray:
    """A float64 array's bits as uint64 (a view where it can be)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


class Reuse:
    """The leaders and followers of one :class:`planner.physics.run_curve._Integrator` batch
    between two event nodes (module doc)."""

    def __init__(self, integ):
        self.it = integ

    def advance(self, k: int, k_to: int) -> None:
        """Every run from node ``k`` to ``k_to`` (no event strictly between), each distinct state
        stepped once; the batch's arrays hold every run's own state again afterwards, or the
        stall flags name the batch's run (as the kernel would have named it)."""
        it = self.it
        prep = it.prep
        if k >= k_to:
            return
        n = it.n
        # the constants' class of each run: par and e columns, bit for bit
        self.cls = equal_groups(np.concatenate([_bits(it.par), _bits(it.e)]))
        if (self.cls == np.arange(n)).all():  # no two runs share their constants: none can meet
            it.kernel.advance(k, k_to, it.k0, prep.trk, prep.seg, it.par, it.st, it.lane, it.e, it.cst, it.tab,
                              it.flags, it.rec, it.rec_p, False, K.NO_INC, K.NO_SLOT)
            return
        self.cls = self.cls.astype(np.uint64)
        self.act = np.arange(n)
        self.par, self.st, self.lane, self.e = it.par, it.st.copy(), it.lane.copy(), it.e
        self.f_idx = np.empty(0, np.int64)
        self.f_lead = np.empty(0, np.int64)
        self.f_t, self.f_w = np.empty(0), np.empty(0)
        self.slot, self.f_slot = K.NO_SLOT, np.empty(0, np.int64)
        self._merge()
        while k < k_to:
            every = check_every(self.act.size)
            kn = min(k_to, (k // every + 1) * every)
            followed = self.f_idx.size > 0
            # the increments of the runs others follow only (their slots), not of every run in the kernel
            inc = np.empty((2, int(self.slot.max()) + 1, kn - k + 1)) if followed else K.NO_INC
            it.kernel.advance(k, kn, k, prep.trk, prep.seg, self.par, self.st, self.lane, self.e, it.cst,
                              it.tab, it.flags, K.NO_REC, K.NO_REC_P, False, inc, self.slot)
            if it.flags[K.F_STALL_TO] >= 0:  # the lowest index stalled is a leader (followers' indices are higher)
                it.flags[K.F_STALL_RUN] = self.act[it.flags[K.F_STALL_RUN]]
                return
            if followed:
                self._follow(inc)
            k = kn
            if k < k_to:
                self._merge()
        self.expand()

    def _follow(self, inc: np.ndarray) -> None:
        """Each follower adds its leader's increments of the last stretch to its sums (kernel ``follow``)."""
        K.check_layout(inc=inc, lead=self.f_slot, sums=self.f_t)
        K.check_layout(sums=self.f_w)
        self.it.kernel.follow(inc, self.f_slot, self.f_t, self.f_w)

    def _merge(self) -> None:
        """Drop from the kernel's batch every run equal to a lower one (module doc); it follows that one."""
        st, lane = self.st, self.lane
        na = self.act.size
        keys = np.empty((7, na), np.uint64)
        keys[:4] = _bits(st)[_DYN_ROWS]
        keys[4:6] = lane.view(np.uint8)
        keys[6] = self.cls[self.act]
        rep = equal_groups(keys)
        keep = rep == np.arange(na)
        if (na - np.count_nonzero(keep)) * MERGE_SHARE < na:
            return  # too few to be worth copying the batch without them: they are found again at the next look
        gone = np.flatnonzero(~keep)
        # the runs that meet a leader here follow it from here, with their own sums so far
        self.f_idx = np.concatenate([self.f_idx, self.act[gone]])
        self.f_lead = np.concatenate([rep[self.f_lead], rep[gone]])
        self.f_t = np.concatenate([self.f_t, st[K.S_T, gone]])
        self.f_w = np.concatenate([self.f_w, st[K.S_WORK, gone]])
        new_pos = np.cumsum(keep) - 1
        self.f_lead = new_pos[self.f_lead]
        self.act = self.act[keep]
        self.par = np.ascontiguousarray(self.par[:, keep])
        self.st = np.ascontiguousarray(st[:, keep])
        self.lane = np.ascontiguousarray(lane[:, keep])
        self.e = np.ascontiguousarray(self.e[:, keep])
        # the runs others follow get a slot in the kernel's increments, in batch order; -1: no follower
        followed = np.zeros(self.act.size, bool)
        followed[self.f_lead] = True
        leaders = np.flatnonzero(followed)  # np.unique's answer without its sort (which took 1 % of a cold night's CPU)
        self.slot = np.full(self.act.size, -1, np.int64)
        self.slot[leaders] = np.arange(leaders.size)
        self.f_slot = self.slot[self.f_lead]

    def expand(self) -> None:
        """Every run's own state in the batch's arrays: a follower's is its leader's with its own sums."""
        it = self.it
        it.st[:, self.act] = self.st
        it.lane[:, self.act] = self.lane
        if self.f_idx.size:
            it.st[:, self.f_idx] = self.st[:, self.f_lead]
            it.st[K.S_T, self.f_idx] = self.f_t
            it.st[K.S_WORK, self.f_idx] = self.f_w
            it.lane[:, self.f_idx] = self.lane[:, self.f_lead]
