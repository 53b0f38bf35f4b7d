"""The task graph's pools: what an abandoned run prints, and the order tasks run in."""
import threading

from structsearch.fitting.task_graph import ExecutorPool, InlinePool, Task, run_tasks


class _ExecutorThread(threading.Thread):
    """Stands for loky's manager thread: a thread class of the executor's own module."""


_ExecutorThread.__module__ = "joblib.externals.loky.process_executor"


class _OtherThread(threading.Thread):
    pass


class _DyingExecutor:
    """An executor whose shutdown ends one of its threads with an exception, as loky's can on Ctrl-C, and one
    thread that is not the executor's."""

    def __init__(self, thread_class):
        self.thread_class = thread_class

    def shutdown(self, wait=True, kill_workers=False):
        def fail():
            raise KeyError(13)
        t = self.thread_class(target=fail)
        t.start()
        t.join()


def _reaching_the_hook(monkeypatch, thread_class) -> list:
    reached = []
    monkeypatch.setattr(threading, "excepthook", lambda args: reached.append(args.exc_type))
    ExecutorPool(_DyingExecutor(thread_class), capacity=2).abandon([], interrupted=True)
    return reached


def test_an_interrupted_run_prints_no_traceback_from_the_executors_own_threads(monkeypatch):
    assert _reaching_the_hook(monkeypatch, _ExecutorThread) == []


def test_an_exception_in_any_other_thread_is_still_printed_and_the_hook_is_restored(monkeypatch):
    assert _reaching_the_hook(monkeypatch, _OtherThread) == [KeyError]
    assert threading.excepthook.__name__ == "<lambda>"


def test_tasks_made_ready_by_a_result_run_and_priority_orders_the_ready():
    order = []

    def leaf(name):
        order.append(name)
        return name

    def chain(out):
        return [Task("b", "fit", leaf, ("b",), lambda _: [], priority=1.0),
                Task("c", "fit", leaf, ("c",), lambda _: [], priority=0.0)]

    run_tasks([Task("a", "fit", leaf, ("a",), chain)], InlinePool())
    assert order == ["a", "c", "b"]
