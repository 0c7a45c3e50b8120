"""Local workers keep running when a whole-line unit grows them, and give large freed memory back between units.

loky (with psutil installed, as dask's ``distributed`` brings it) ends a worker that has grown 300 MB past
its size after its first task; on a line ten times the sample that restarted a worker twice a night (a
worker's imports again, a core idle meanwhile, and loky's warning on stderr). The planner's workers lift that
limit (:func:`planner.io.parallel._keep_grown_workers`) and give back what a large result left freed before
their next unit (:func:`planner.io.memory.give_back_large`).
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from planner.io import memory
from planner.io.parallel import LEAK_LIMIT_BYTES, backend


def _leak_limit_here(i: int):
    """Runs on a worker: its pid and loky's memory-leak limit as its worker loop reads it."""
    from joblib.externals.loky import process_executor

    return os.getpid(), getattr(process_executor, "_MAX_MEMORY_LEAK_SIZE", None)


def test_local_workers_run_with_lokys_leak_restart_lifted():
    with backend("local", n_jobs=2) as pool:
        got = list(pool.imap(_leak_limit_here, [(i,) for i in range(6)]))
    pids = {pid for pid, _ in got}
    assert os.getpid() not in pids  # the tasks ran on workers, not here
    # the installed joblib still has the constant its worker loop reads (an upgrade that renames it fails here)
    assert all(limit == LEAK_LIMIT_BYTES for _, limit in got), got
    from joblib.externals.loky import process_executor

    assert process_executor._MAX_MEMORY_LEAK_SIZE == int(3e8)  # this process is not a worker: loky's own


@pytest.mark.skipif(memory.slack_bytes() is None, reason="needs glibc's mallinfo2 and /proc")
def test_give_back_large_returns_freed_heap_pages_once_and_not_a_few():
    memory.give_back_large(0)  # whatever this process freed before: from here, the slack is measured
    base = memory.slack_bytes()
    chunks = [np.ones(1000) for _ in range(40_000)]  # 8 kB each: heap chunks, not mapped blocks (~320 MB)
    pins = chunks[99::100]  # kept: the heap's top cannot shrink by itself past them as the rest is freed
    del chunks
    freed = memory.slack_bytes()
    assert freed - base > 200 << 20  # freed, still resident: what a worker held after a large result was sent
    assert not memory.give_back_large(1 << 40)  # less than asked for: nothing given back
    assert memory.give_back_large()
    assert memory.slack_bytes() < freed - (200 << 20)  # the pages went back to the system
    assert not memory.give_back_large()  # nothing new freed since: no second give-back
    small = [np.ones(1000) for _ in range(2_000)]  # ~16 MB freed: below the threshold
    del small
    assert not memory.give_back_large()
    del pins
