"""Where parallel work runs: local joblib processes, or a Dask cluster through joblib.

Workers are plain module-level functions with small picklable arguments, so
the same ``Parallel(...)(delayed(f)(...) ...)`` call runs on either backend,
and results come back in submission order: outputs do not depend on the backend.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator

import joblib

from .errors import JobError


@contextmanager
def backend(name: str = "local", *, n_jobs: int = -1, scheduler: str = "") -> Iterator[int]:
    """Context in which ``joblib.Parallel`` runs on the chosen backend; yields n_jobs to use.

    Parameters
    ----------
    name : {"local", "dask"}
    n_jobs : int
        Local worker processes (-1 = all cores).
    scheduler : str
        Dask scheduler address for ``name="dask"``.
    """
    if name == "local":
        with joblib.parallel_config(backend="loky", n_jobs=n_jobs):
            yield n_jobs
        return
    if name != "dask":
        raise JobError(f"unknown parallel backend {name!r}; use local or dask")
    try:
        from dask.distributed import Client
    except ImportError:
        raise JobError("backend dask needs the dask extra: pip install 'planner[dask]'") from None
    try:
        client = Client(scheduler, timeout="10s")
    except Exception as e:  # noqa: BLE001 - any connection failure is a user-facing setup problem
        raise JobError(f"cannot reach the dask scheduler {scheduler!r}: {e}") from None
    try:
        with joblib.parallel_config(backend="dask", wait_for_workers_timeout=60):
            yield -1
    finally:
        client.close()
