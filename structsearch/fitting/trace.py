"""A record of the tasks a command ran, for ``--trace FILE``: each task's name, kind, start, end, worker and the
tasks it waited for, written as Chrome trace-event JSON (it opens in Perfetto or chrome://tracing).

A command fits in calls (a grid, then the next grid once the first is ranked; a discovery step, then the next
once the first is judged): the first tasks of a call wait for the end of the call before it, which the trace
states with a zero-length ``call N done`` event whose parents are the tasks that call ended with. So the
recorded graph holds the dependencies the command really had, and a schedule of it (``structsearch bench --trace``)
predicts what more workers would gain without assuming more freedom than the command has.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass


@dataclass(frozen=True)
class Span:
    """One task: ``start`` and ``end`` in seconds (the wall clock of the machine, ``time.time()``), the ``worker``
    (process id) that ran it and the names of the tasks it waited for."""

    name: str
    kind: str
    start: float
    end: float
    worker: int
    parents: tuple[str, ...]


class Trace:
    """The spans of one command, in the order they ended (thread-safe: a dask client calls back from its own)."""

    def __init__(self):
        self._spans: list[Span] = []
        self._names: dict[str, int] = {}
        self._calls = 0
        self._lock = threading.Lock()

    def unique(self, name: str) -> str:
        """``name``, or ``name #k`` when a task of that name ran already (a candidate fitted in two calls)."""
        with self._lock:
            k = self._names.get(name, 0) + 1
            self._names[name] = k
            return name if k == 1 else f"{name} #{k}"

    def add(self, span: Span) -> None:
        with self._lock:
            self._spans.append(span)

    @property
    def spans(self) -> tuple[Span, ...]:
        with self._lock:
            return tuple(self._spans)

    def call_boundary(self, since: int) -> tuple[str, ...]:
        """Close the call whose spans start at index ``since``: a zero-length ``call N done`` span after its last
        task, whose parents are its tasks no other task of it waited for; the next call's first tasks wait for it.
        Returns the parents the next call's first tasks take (none when the call ran no task)."""
        with self._lock:
            mine = self._spans[since:]
            if not mine:
                return self._last_boundary()
            named = {p for s in mine for p in s.parents}
            sinks = tuple(s.name for s in mine if s.name not in named)
            self._calls += 1
            end = max(s.end for s in mine)
            self._spans.append(Span(f"call {self._calls} done", "call", end, end, 0, sinks))
            return (f"call {self._calls} done",)

    def _last_boundary(self) -> tuple[str, ...]:
        return (f"call {self._calls} done",) if self._calls else ()

    def roots(self) -> tuple[str, ...]:
        """What a new call's first tasks wait for: the end of the call before it (none for the first call)."""
        with self._lock:
            return self._last_boundary()

    def __len__(self) -> int:
        with self._lock:
            return len(self._spans)

    def to_chrome(self) -> dict:
        """Chrome trace-event JSON: complete events (``"ph": "X"``), ``ts`` and ``dur`` in microseconds from the
        first task's start, ``pid``/``tid`` the worker, ``args.parents`` the names of the tasks it waited for."""
        spans = self.spans
        t0 = min((s.start for s in spans), default=0.0)
        events = [{"name": s.name, "cat": s.kind, "ph": "X", "ts": round((s.start - t0) * 1e6, 1),
                   "dur": round((s.end - s.start) * 1e6, 1), "pid": s.worker, "tid": s.worker,
                   "args": {"parents": list(s.parents)}} for s in sorted(spans, key=lambda s: (s.start, s.name))]
        return {"traceEvents": events, "displayTimeUnit": "ms",
                "otherData": {"producer": "structsearch", "clock": "wall (time.time), microseconds"}}
