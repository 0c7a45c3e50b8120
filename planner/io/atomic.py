"""Atomic file writes: a final name appears only when its content is complete.

Everything the planner publishes (datasets, reports, charts, bundles, cache
entries) is written through :func:`atomic_path`: the content goes to a hidden
temporary file in the same folder, is flushed to disk, made readable (0644:
outputs are for every analyst, not secrets) and renamed over the final name
with ``os.replace``, which is atomic on POSIX. A failure or interruption
leaves the previous file (or none), never a half-written one. Two writers
flush differently: a staged run's files are flushed all at once before the
run is published (:func:`deferred_fsync`), and cache entries not at all (a
torn entry fails its digest and is recomputed).

A folder that must appear whole (an opened bundle) is filled under a
temporary name beside it and renamed into place once (:func:`folder_in_place`).
"""
from __future__ import annotations

import contextvars
import functools
import os
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import Iterable, Iterator


def _fsync_file(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_dir(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass  # some filesystems cannot fsync a folder; the rename is still atomic
    finally:
        os.close(fd)


FSYNC_THREADS = 16
"""Flushes a tree's files with this many at once (:func:`fsync_tree`)."""


def fsync_tree(folder: str | os.PathLike) -> None:
    """Flush every file under ``folder`` and every folder (``folder`` included) to disk.

    Many at a time, on threads (a flush waits for the disk, not for the processor): the file
    system commits concurrent flushes together, so a run's few hundred files and partition
    folders take one or two journal commits instead of one each (1.2-1.7 s one by one on
    the sample run, 0.1 s this way). The first failure is raised once every flush has ended.
    """
    files, folders = [], []
    for dirpath, _dirs, names in os.walk(folder):
        files += [os.path.join(dirpath, f) for f in names]
        folders.append(Path(dirpath))
    with ThreadPoolExecutor(max_workers=FSYNC_THREADS, thread_name_prefix="planner-fsync") as pool:
        done = [pool.submit(_fsync_file, f) for f in files] + [pool.submit(_fsync_dir, d) for d in folders]
    for f in done:
        f.result()


_DEFERRED = contextvars.ContextVar("planner_fsync_deferred", default=False)


@contextmanager
def deferred_fsync() -> Iterator[None]:
    """Within this context, atomic writes are not flushed one by one: the caller flushes them all at once.

    For a tree that becomes visible only through one later rename (the nightly job's
    staged run: :func:`planner.job.publish.publish` fsyncs the whole tree before it
    renames it). Each write is still atomic (temporary file, ``os.replace``); only the
    flush to disk moves to the barrier, so a few hundred files pay for one flush.
    """
    token = _DEFERRED.set(True)
    try:
        yield
    finally:
        _DEFERRED.reset(token)


def deferring() -> bool:
    """Whether atomic writes here are deferred (inside :func:`deferred_fsync`, or work started from there)."""
    return _DEFERRED.get()


def in_worker_context(fn, args: tuple) -> tuple:
    """``(fn, args)`` made into a call for another process (:func:`planner.io.parallel.background`) that writes as
    this thread would: a worker does not share this thread's context, so without this its writes would be flushed
    one by one inside :func:`deferred_fsync` (7,400 chart pages a night at 100x, two flushes each)."""
    return _deferred_call, (deferring(), fn, args)


def _deferred_call(deferred: bool, fn, args: tuple):
    if not deferred:
        return fn(*args)
    with deferred_fsync():
        return fn(*args)


def in_this_context(fn):
    """``fn`` bound to a copy of the calling thread's context, to hand to another thread: a thread
    starts with an empty context, so without this its writes would not see :func:`deferred_fsync`."""
    return functools.partial(contextvars.copy_context().run, fn)


@contextmanager
def atomic_path(path: str | os.PathLike, *, mode: int = 0o644, fsync: bool | None = None) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path``, on error it is removed.

    ``fsync``: flush the file and its folder to disk before and after the rename; the
    default is to, except inside :func:`deferred_fsync`.

    The temporary name ends in ``.tmp`` (so ``*.png`` or ``*.pdb`` globs never see
    it): writers that infer a format from the name must be told it (``savefig(format="png")``).
    """
    path = Path(path)
    if fsync is None:
        fsync = not deferring()
    try:  # the folder is there (most writes): no mkdir, whose failing call costs more than the file's own creation
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except (FileNotFoundError, NotADirectoryError):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        if fsync:
            _fsync_file(tmp)
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(e, OSError) and not e.filename:
            e.filename = str(path)  # os.write and pyarrow name no file: say which one did not fit
        raise
    if fsync:
        _fsync_dir(path.parent)


_CHUNK = 1 << 20
"""Bytes per ``os.write`` call (tests shrink it to widen the window a kill can hit)."""


def write_bytes_atomic(path: str | os.PathLike, data: bytes, *, mode: int = 0o644,
                       fsync: bool | None = None) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_path`)."""
    write_chunks_atomic(path, [data], mode=mode, fsync=fsync)


def write_chunks_atomic(path: str | os.PathLike, chunks: Iterable[bytes | memoryview], *, mode: int = 0o644,
                        fsync: bool | None = None) -> None:
    """Write the concatenated ``chunks`` to ``path`` atomically (see :func:`atomic_path`), each as it is made:
    a large page need not be held whole. A chunk that fails to be made (an exception from the iterable) leaves
    no file, as a failed write does."""
    with atomic_path(path, mode=mode, fsync=fsync) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_TRUNC)
        try:
            buf, size = [], 0
            for chunk in chunks:  # small pieces gathered to about _CHUNK bytes a write (a page comes in many);
                n = memoryview(chunk).nbytes
                if n >= _CHUNK:  # a large one written as it is, not copied into a gathered one
                    if buf:
                        _write_all(fd, b"".join(buf))
                        buf, size = [], 0
                    _write_all(fd, chunk)
                    continue
                buf.append(chunk)
                size += n
                if size >= _CHUNK:
                    _write_all(fd, b"".join(buf))
                    buf, size = [], 0
            if buf:
                _write_all(fd, b"".join(buf))
        finally:
            os.close(fd)


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view[:_CHUNK]):]


@contextmanager
def folder_in_place(dest: str | os.PathLike, *, mode: int = 0o755) -> Iterator[Path]:
    """Yield a fresh, empty temporary folder beside ``dest`` (the same file system) to fill; when the block
    succeeds, its files and the folder are flushed and it becomes ``dest`` by one rename. When the block
    or the rename fails, the temporary folder is removed, and so are the parent folders this call made:
    ``dest`` is never seen half-filled, and a failure leaves everything as it was.

    ``dest`` must be missing or an empty folder (the rename replaces an empty folder atomically); else
    the rename raises ``OSError`` (``ENOTEMPTY`` or ``EEXIST`` for a folder with entries, ``ENOTDIR``
    for a file or a symbolic link), after the clean-up. The temporary name is ``.<name>.*.tmp``.
    """
    dest = Path(dest)
    made = [p for p in reversed(dest.parents) if not p.exists()]  # removed again on failure
    tmp: Path | None = None
    done = False
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{dest.name}.", suffix=".tmp", dir=dest.parent))
        yield tmp
        fsync_tree(tmp)
        os.chmod(tmp, mode)
        os.rename(tmp, dest)
        done = True
        _fsync_dir(dest.parent)
    finally:
        if not done:
            if tmp is not None:
                shutil.rmtree(tmp, ignore_errors=True)
            for p in reversed(made):
                try:
                    p.rmdir()
                except OSError:
                    break


STAGING_PREFIX = ".staging-"
"""A run being written: ``<output root>/.staging-<run id>/``, renamed to the run's name when published."""


def remove_staging(root: str | os.PathLike) -> list[str]:
    """Remove the staging folders under ``root`` (the caller holds the output root's job lock, so none is a
    live run's); returns their names, sorted."""
    removed = []
    root = Path(root)
    if root.is_dir():
        for p in root.iterdir():
            if p.name.startswith(STAGING_PREFIX) and p.is_dir():
                shutil.rmtree(p, ignore_errors=True)
                removed.append(p.name)
    return sorted(removed)
