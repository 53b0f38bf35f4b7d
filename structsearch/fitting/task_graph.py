"""Tasks on workers: a graph that grows as its tasks finish, run on this process, on local worker processes
(joblib's reusable executor) or on a dask cluster, each task's start, end, worker and parents recorded.

A task is a function and its arguments, the names of the tasks whose results it was made from, and what comes
of its result (``then``: the tasks it makes ready, which may be none until a sibling finishes too). The driver
keeps at most ``capacity`` tasks on the workers and hands a free worker the ready task of lowest ``priority``
(ties: the one made ready first), so a chain that later tasks wait for is not queued behind a wave of leaves.
The results do not depend on the order tasks finish in: a task's arguments are fixed when it is made, and the
callers join siblings by name, never by arrival.
"""
from __future__ import annotations

import heapq
import itertools
import os
import threading
import time
from contextlib import contextmanager
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from .trace import Span, Trace


@dataclass(frozen=True)
class Task:
    """``fn(*args)`` on a worker; ``then(result)`` (on the driver) returns the tasks it makes ready."""

    name: str
    kind: str
    fn: Callable
    args: tuple
    then: Callable[[Any], Iterable["Task"]]
    parents: tuple[str, ...] = ()
    priority: float = 0.0


def timed(fn: Callable, args: tuple) -> tuple[Any, float, float, int]:
    """``fn(*args)`` with its wall-clock start and end and the worker's process id."""
    t0 = time.time()
    out = fn(*args)
    return out, t0, time.time(), os.getpid()


class InlinePool:
    """Every task on this process, when it is submitted (one worker: the order of a serial run)."""

    capacity = 1

    def submit(self, fn: Callable, args: tuple) -> Future:
        future: Future = Future()
        try:
            future.set_result(timed(fn, args))
        except Exception as exc:   # raised by the driver, as a worker's would be
            future.set_exception(exc)
        return future

    def wait_first(self, futures) -> set:
        return set(futures)

    def abandon(self, futures, interrupted: bool) -> None:
        """Nothing runs elsewhere."""


class ExecutorPool:
    """Tasks on a ``concurrent.futures`` executor (joblib's reusable process executor, or threads)."""

    def __init__(self, executor, capacity: int, wrap: Callable | None = None):
        self.executor, self.capacity, self.wrap = executor, capacity, wrap

    def submit(self, fn: Callable, args: tuple) -> Future:
        if self.wrap is not None:
            return self.executor.submit(self.wrap, fn, args)
        return self.executor.submit(timed, fn, args)

    def wait_first(self, futures) -> set:
        return wait(futures, return_when=FIRST_COMPLETED)[0]

    def abandon(self, futures, interrupted: bool) -> None:
        if interrupted and hasattr(self.executor, "shutdown"):
            # Ctrl-C or SIGTERM: the tasks still running are lost anyway (the finished fits are cached); the workers
            # end now, before the caller removes the shared splits they read
            with _executor_threads_quiet():
                try:
                    self.executor.shutdown(wait=True, kill_workers=True)
                except TypeError:
                    self.executor.shutdown(wait=True)
            return
        # a failed task: nothing more starts; the caller then removes the shared splits, so wait for the tasks
        # already running rather than pull their data from under them
        for future in futures:
            future.cancel()
        wait(futures)


@contextmanager
def _executor_threads_quiet():
    """Within the block, an exception that ends one of the executor's own threads is not printed. Killing the
    workers of joblib's (loky's) executor while its manager thread queues the next task can end that thread
    with a KeyError on the task it was about to hand out: the run is being abandoned on purpose, so that
    traceback would be noise under the one-line 'interrupted' message. Any other thread's exception is printed
    as usual."""
    previous = threading.excepthook

    def hook(args):
        if args.thread is not None and type(args.thread).__module__.startswith(_EXECUTOR_THREAD_MODULES):
            return
        previous(args)

    threading.excepthook = hook
    try:
        yield
    finally:
        threading.excepthook = previous


_EXECUTOR_THREAD_MODULES = ("joblib.externals.loky", "loky", "concurrent.futures")


class DaskPool:
    """Tasks on the dask cluster of the client the caller opened (``distributed.get_client()``)."""

    def __init__(self, client, capacity: int):
        self.client, self.capacity = client, capacity

    def submit(self, fn: Callable, args: tuple):
        return self.client.submit(timed, fn, args, pure=False)

    def wait_first(self, futures) -> set:
        from dask.distributed import wait as dask_wait
        return set(dask_wait(list(futures), return_when="FIRST_COMPLETED").done)

    def abandon(self, futures, interrupted: bool) -> None:
        self.client.cancel(list(futures))


@dataclass
class _Ready:
    heap: list = field(default_factory=list)
    order: Iterable[int] = field(default_factory=itertools.count)

    def push(self, tasks: Iterable[Task]) -> None:
        for t in tasks:
            heapq.heappush(self.heap, (t.priority, next(self.order), t))

    def pop(self) -> Task:
        return heapq.heappop(self.heap)[2]


def run_tasks(first: Iterable[Task], pool, trace: Trace | None = None) -> None:
    """Run ``first`` and every task their results make ready, until none is left. A task that raises stops the
    run: the tasks already on the workers finish (their results are kept, as every finished one is), then the
    first exception is raised."""
    ready, running = _Ready(), {}
    ready.push(first)
    failure: BaseException | None = None
    try:
        while ready.heap or running:
            while ready.heap and len(running) < pool.capacity and failure is None:
                task = ready.pop()
                running[pool.submit(task.fn, task.args)] = task
            if not running:
                break
            for future in pool.wait_first(running):
                task = running.pop(future)
                try:
                    out, t0, t1, worker = future.result()
                except Exception as exc:
                    failure = failure or exc
                    continue
                if trace is not None:
                    trace.add(Span(task.name, task.kind, t0, t1, worker, task.parents))
                ready.push(task.then(out))   # kept (a finished fit is cached) even after a failure
        if failure is not None:
            raise failure
    except KeyboardInterrupt:
        pool.abandon(list(running), interrupted=True)
        raise
    except BaseException:
        pool.abandon(list(running), interrupted=False)
        raise
