"""The splits a grid's fits share, sent to worker processes once.

A search sends about a hundred tasks to its workers. Pickling the training and validation maneuvers
(~50 MB) into each task costs the parent process about 0.1 s of hashing and copying per task and
gives every worker a private copy. Instead the parent writes the two splits once to a temporary
folder (``joblib.dump``) and each task carries only the file's path; a worker loads it once,
memory-mapped read-only, so the pages are shared between the processes.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

from ..data.atomic import remove_orphans
from ..data.flightdata import FlightData
from .lift_context import forget_lift_contexts

# Backends whose workers are processes on this machine (a dask cluster's may not see this disk).
LOCAL_PROCESS_BACKENDS = ("loky", "multiprocessing")

_LOADED: dict[str, tuple[FlightData, FlightData]] = {}


@contextmanager
def shared_splits(train: FlightData, validation: FlightData, backend: str, n_jobs: int):
    """A handle to (train, validation) for tasks: a file path for local worker processes, else the
    objects themselves (one process: nothing is pickled), or a dask future of them (scattered to the workers)."""
    if backend == "dask":   # scattered to every worker once; a task carries the future, which dask resolves
        from dask.distributed import get_client
        yield get_client().scatter([(train, validation)], broadcast=True)[0]
        return
    if backend not in LOCAL_PROCESS_BACKENDS or n_jobs == 1:
        yield train, validation
        return
    import joblib
    remove_orphans(Path(tempfile.gettempdir()), "structsearch-")
    with tempfile.TemporaryDirectory(prefix=f"structsearch-{os.getpid()}-") as folder:
        path = Path(folder) / "splits.pkl"
        joblib.dump((train, validation), path)
        yield str(path)


def resolve_splits(handle) -> tuple[FlightData, FlightData]:
    """(train, validation) from a handle of :func:`shared_splits`; a path is loaded once per process."""
    if not isinstance(handle, str):
        return handle
    if handle not in _LOADED:
        import joblib
        _LOADED.clear()   # a worker serves one search at a time
        forget_lift_contexts()
        _LOADED[handle] = joblib.load(handle, mmap_mode="r")
    return _LOADED[handle]
