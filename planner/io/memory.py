"""Freed memory given back to the system between the steps of a long run.

Memory a step frees is not always returned: glibc's ``malloc`` keeps freed heap pages for later
allocations, and Arrow's allocator (mimalloc) keeps freed pages of its own. A process that held a
whole line's results for one step (the main process, or a worker after a line's conflict check,
train graph or bundles) then stays that large for the rest of the run, and on a line ten times the
sample that was a few hundred megabytes per process. :func:`give_back` returns them after such a
step: Arrow's unused pages, then glibc's free heap pages (``malloc_trim``, where the C library has
it). It changes no result; it costs about a millisecond when little is free (tens when much is).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import functools


@functools.lru_cache(maxsize=1)
def _malloc_trim():
    """glibc's ``malloc_trim``, or None (another C library: nothing to call)."""
    name = ctypes.util.find_library("c")
    try:
        return getattr(ctypes.CDLL(name), "malloc_trim", None) if name else None
    except OSError:
        return None


def give_back() -> None:
    """Return the freed pages of Arrow's memory pool and of the C heap to the system."""
    import pyarrow as pa

    pa.default_memory_pool().release_unused()
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


def then_give_back(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, then :func:`give_back` (also when it raises)."""
    try:
        return fn(*args, **kwargs)
    finally:
        give_back()


__all__ = ["give_back", "then_give_back"]
