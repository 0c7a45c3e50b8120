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
import os


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


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]


@functools.lru_cache(maxsize=1)
def _mallinfo2():
    """glibc's ``mallinfo2`` (2.33 on), or None."""
    name = ctypes.util.find_library("c")
    try:
        fn = getattr(ctypes.CDLL(name), "mallinfo2", None) if name else None
    except OSError:
        return None
    if fn is not None:
        fn.restype = _Mallinfo2
    return fn


def slack_bytes() -> int | None:
    """Resident memory the C heap does not use [bytes]: the process's resident size less the heap's
    chunks in use and its mapped blocks (glibc's ``mallinfo2``), or None where either is unknown. It
    grows when freed chunks stay resident, and :func:`give_back` shrinks it; the rest of it (code,
    Arrow's pool, the interpreter's own arenas) changes slowly."""
    info = _mallinfo2()
    try:
        with open("/proc/self/statm", "rb") as f:
            resident = int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return None
    if info is None:
        return None
    heap = info()
    return resident - int(heap.uordblks) - int(heap.hblkhd)


LARGE_SLACK_BYTES = 64 << 20
"""What :func:`give_back_large` waits for: less, and the pages given back would mostly be taken again."""
_slack_after = 0
""":func:`slack_bytes` after the last give-back of :func:`give_back_large` (lowered when it is seen lower)."""


def give_back_large(min_bytes: int = LARGE_SLACK_BYTES) -> bool:
    """:func:`give_back` when the process holds at least ``min_bytes`` more resident memory it does not
    use (:func:`slack_bytes`) than after the last time it did; whether it did.

    For a worker between units: after most of them little is freed, and giving back a few pages
    each time costs more than it saves (the next unit faults them in again: on the 10× line,
    3–4 s of system time a night); after a large result was sent back, hundreds of megabytes are.
    Where the C library or the system cannot tell, nothing is given back here."""
    global _slack_after
    slack = slack_bytes()
    if slack is None:
        return False
    if slack - _slack_after < min_bytes:
        _slack_after = min(_slack_after, slack)
        return False
    give_back()
    _slack_after = slack_bytes() or 0
    return True


def then_give_back(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, then :func:`give_back` (also when it raises)."""
    try:
        return fn(*args, **kwargs)
    finally:
        give_back()


__all__ = ["give_back", "give_back_large", "slack_bytes", "then_give_back"]
