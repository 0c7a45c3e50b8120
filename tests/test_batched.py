"""Short calls sent to the workers in batches (planner.io.parallel.batched): the same results, in the same order,
one call at a time; a stored unit read back is such a call (an edit night of a large line reads tens of thousands)."""
from __future__ import annotations

import operator

import pytest

from planner.io.parallel import BATCH, LocalPool, _each, batched, unbatched
from planner.job.units import _call


def _tag(x):
    return ("tag", x)


def _calls():
    """Long and short calls, short ones of two functions, runs longer than a batch."""
    calls, short = [], []
    for i in range(3 * BATCH + 5):
        if i % 50 == 7:
            calls.append((operator.mul, (i, 3)))
            short.append(False)
        else:
            calls.append((_tag if 100 <= i < 120 else operator.neg, (i,)))
            short.append(True)
    return calls, short


def test_batches_hold_runs_of_one_function_up_to_the_size_and_give_every_result_in_order():
    calls, short = _calls()
    tasks, sizes = batched(calls, short)
    assert len(tasks) == len(sizes) < len(calls)
    for (fn, args), n in zip(tasks, sizes):
        if n is None:
            assert fn is not _each
        else:
            assert fn is _each and 1 <= n == len(args[1]) <= BATCH and args[0] in (_tag, operator.neg)
    # every call is in exactly one task, in order
    flat = [c for (fn, args), n in zip(tasks, sizes)
            for c in ([(fn, args)] if n is None else [(args[0], a) for a in args[1]])]
    assert flat == calls
    expected = [fn(*args) for fn, args in calls]
    assert list(unbatched((_call(fn, args) for fn, args in tasks), sizes)) == expected


@pytest.mark.parametrize("size", [1, 2, BATCH])
def test_batched_calls_on_local_workers_give_what_the_calls_give(size):
    calls, short = _calls()
    tasks, sizes = batched(calls, short, size)
    got = list(unbatched(LocalPool(2).imap(_call, tasks), sizes))
    assert got == [fn(*args) for fn, args in calls]


def test_closing_the_results_closes_the_workers_generator():
    closed = []

    def gen():
        try:
            yield [1, 2]
            yield 3
        finally:
            closed.append(True)

    it = unbatched(gen(), [2, None])
    assert next(it) == 1
    it.close()
    assert closed == [True]


def test_nothing_short_is_nothing_batched():
    calls = [(operator.neg, (i,)) for i in range(5)]
    tasks, sizes = batched(calls, [False] * 5)
    assert tasks == calls and sizes == [None] * 5
    assert batched([], []) == ([], [])
