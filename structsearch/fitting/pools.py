"""Where a command's tasks run: this process (one job), local worker processes (joblib's reusable executor,
whose workers survive between the calls of a command) or threads, or the dask cluster of the client the caller
opened. Every pool hands the task graph (:mod:`.task_graph`) the same futures interface."""
from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

from .task_graph import DaskPool, ExecutorPool, InlinePool, timed

# Thread pools of numerical libraries a worker process must not multiply by the number of workers.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS", "NUMEXPR_NUM_THREADS")
# A dask cluster gets this many tasks per worker ahead: its scheduler places them, and a worker that finishes
# finds its next task there rather than waiting for the driver's round trip.
DASK_TASKS_PER_WORKER = 2

_WATCHED: list[int] = []


def watch_parent(poll_seconds: float = 1.0) -> None:
    """In a worker process: end it when the process that started it is gone (killed with -9, it cannot stop
    its workers; an orphan would go on fitting for minutes). Started once per process, a daemon thread."""
    if _WATCHED:
        return
    parent = os.getppid()
    _WATCHED.append(parent)

    def watch():
        import time
        while True:
            time.sleep(poll_seconds)
            if os.getppid() != parent:
                os._exit(70)

    import threading
    threading.Thread(target=watch, name="structsearch-parent-watch", daemon=True).start()


def in_worker(fn, args):
    """A task in a local worker process, which ends itself if the command's process dies."""
    watch_parent()
    return timed(fn, args)


def worker_environment(n_jobs: int) -> dict[str, str]:
    """The workers' thread pools share the cores, as joblib's Parallel arranges, unless the caller said."""
    from joblib import cpu_count
    threads = str(max(cpu_count() // n_jobs, 1))
    env = {var: os.environ.get(var, threads) for var in THREAD_VARIABLES}
    if "ENABLE_IPC" not in os.environ:  # TBB's schedulers coordinate across processes, as joblib sets it
        env["ENABLE_IPC"] = "1"
    return env


@contextmanager
def task_pool(backend: str, n_jobs: int) -> Iterator[object]:
    """The pool of ``n_jobs`` workers of ``backend`` ("loky" or "multiprocessing": local processes; "threading";
    "dask": the cluster of the client the caller opened)."""
    if backend == "dask":
        from dask.distributed import get_client
        client = get_client()
        workers = len(client.scheduler_info().get("workers", {})) or n_jobs
        yield DaskPool(client, DASK_TASKS_PER_WORKER * workers)
        return
    if n_jobs <= 1:
        yield InlinePool()
        return
    if backend == "threading":
        from concurrent.futures import ThreadPoolExecutor
        with ThreadPoolExecutor(n_jobs) as executor:
            yield ExecutorPool(executor, n_jobs)
        return
    from joblib.executor import get_memmapping_executor
    yield ExecutorPool(get_memmapping_executor(n_jobs, timeout=300, env=worker_environment(n_jobs)), n_jobs,
                       wrap=in_worker)


def _ready() -> int:
    """A worker's first task: import what every fitting task runs on."""
    from . import candidate_job  # noqa: F401
    return os.getpid()


def warm_workers(backend: str, n_jobs: int) -> None:
    """Start the local worker processes now, without waiting for them: their interpreters import the package while
    the command reads its campaign, instead of after (the pool the command's first fit asks for is this one)."""
    if backend not in ("loky", "multiprocessing") or n_jobs <= 1:
        return
    from joblib.executor import get_memmapping_executor
    executor = get_memmapping_executor(n_jobs, timeout=300, env=worker_environment(n_jobs))
    for _ in range(n_jobs):
        executor.submit(_ready)
