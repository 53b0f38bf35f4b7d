"""Where a command's tasks run: this process (one job), local worker processes (joblib's reusable executor,
whose workers survive between the calls of a command) or threads, or the dask cluster of the client the caller
opened. Every pool hands the task graph (:mod:`.task_graph`) the same futures interface."""
from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from ..data.atomic import remove_dead_runs
from .task_graph import DaskPool, ExecutorPool, InlinePool, timed

# Thread pools of numerical libraries a worker process must not multiply by the number of workers.
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                    "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS", "NUMEXPR_NUM_THREADS")
# A dask cluster gets this many tasks per worker ahead: its scheduler places them, and a worker that finishes
# finds its next task there rather than waiting for the driver's round trip.
DASK_TASKS_PER_WORKER = 2

_WATCHED: list[int] = []


def watch_parent(parent: int | None = None, poll_seconds: float = 1.0) -> None:
    """In a worker process: end it when the process that started it (``parent``, else its parent now) is gone
    (killed with -9, it cannot stop its workers; an orphan would go on fitting for minutes). Started once per
    process, a daemon thread. The pool passes its pid: a worker whose parent died while the worker started up
    has been adopted already, and must not take its new parent for the one to watch."""
    if _WATCHED:
        return
    parent = os.getppid() if parent is None else parent
    _WATCHED.append(parent)
    if os.getppid() != parent:
        os._exit(70)

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
    yield ExecutorPool(local_executor(n_jobs), n_jobs, wrap=in_worker)


def local_executor(n_jobs: int):
    """joblib's reusable executor of ``n_jobs`` local worker processes: each watches its parent from its start
    (a command killed the moment its workers exist leaves none behind), and joblib's memory-mapping folder is in a
    folder of this run (:func:`run_folder`), not in /dev/shm where a killed run would leave it."""
    from joblib.executor import get_memmapping_executor
    return get_memmapping_executor(n_jobs, timeout=300, env=worker_environment(n_jobs), initializer=watch_parent,
                                   initargs=(os.getpid(),), temp_folder=str(run_folder()))


_RUN_FOLDER: list[Path] = []


def run_folder() -> Path:
    """``<tmp>/structsearch-<pid>-workers-*``: the temporary folder of this process's workers, removed at exit;
    what runs killed with -9 left is removed first (:func:`~structsearch.data.atomic.remove_dead_runs`)."""
    if not _RUN_FOLDER:
        base = Path(tempfile.gettempdir())
        remove_dead_runs(base)
        folder = Path(tempfile.mkdtemp(prefix=f"structsearch-{os.getpid()}-workers-", dir=base))
        _RUN_FOLDER.append(folder)
        atexit.register(shutil.rmtree, folder, True)
    return _RUN_FOLDER[0]


def _ready() -> int:
    """A worker's first task: import what every fitting task runs on."""
    from . import candidate_job  # noqa: F401
    return os.getpid()


def warm_workers(backend: str, n_jobs: int) -> None:
    """Start the local worker processes now, without waiting for them: their interpreters import the package while
    the command reads its campaign, instead of after (the pool the command's first fit asks for is this one)."""
    if backend not in ("loky", "multiprocessing") or n_jobs <= 1:
        return
    executor = local_executor(n_jobs)
    for _ in range(n_jobs):
        executor.submit(_ready)
