"""``structsearch bench --trace FILE``: what a recorded run's task graph allows.

From the trace of a command (``--trace``: every task's start, duration, worker and the tasks it waited for):

* total work: the sum of the tasks' durations;
* critical path: the longest chain of tasks, each waiting for the one before (what no number of workers shortens);
* available parallelism: work / critical path (the most workers the graph keeps busy on average);
* the wall a list schedule of the recorded graph predicts for 2, 4, 8, 16 and 64 workers: tasks keep their
  recorded durations and dependencies, a free worker takes the ready task the run started first (Graham's list
  scheduling, within 2x of the best schedule). It leaves out what the trace does not hold: the driver's own work
  between calls (ranking, writing) and the cost of moving data to more workers, so it is an upper bound on the gain;
  the prediction at the run's own worker count, beside the wall it measured, says how far the model is off.
"""
from __future__ import annotations

import heapq
import json
from collections import defaultdict
from pathlib import Path

from ..data.errors import DataError

WORKER_COUNTS = (2, 4, 8, 16, 64)


def read_trace(path: str | Path) -> list[dict]:
    """The complete events of a trace file, checked: unique names, parents that are events of the file."""
    source = str(path)
    try:
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DataError(f"not a readable trace ({type(exc).__name__}: {exc})", source=source) from None
    events = doc.get("traceEvents") if isinstance(doc, dict) else None
    if not isinstance(events, list):
        raise DataError("no traceEvents list (Chrome trace-event JSON, written by --trace)", source=source)
    out, names = [], set()
    for k, e in enumerate(events):
        if not isinstance(e, dict) or e.get("ph") != "X":
            continue
        try:
            name, ts, dur = str(e["name"]), float(e["ts"]), float(e["dur"])
            args = e.get("args") or {}
            listed = args.get("parents", []) if isinstance(args, dict) else None
            if not isinstance(listed, list):
                raise TypeError("parents")
            parents = [str(p) for p in listed]
        except (KeyError, TypeError, ValueError):
            raise DataError(f"event {k} lacks a name, ts or dur, or its args.parents is not a list of names",
                            source=source) from None
        if name in names:
            raise DataError(f"event {k}: a second task named {name!r}", source=source)
        if dur < 0:
            raise DataError(f"event {k} ({name!r}): negative duration {dur}", source=source)
        names.add(name)
        out.append({"name": name, "kind": str(e.get("cat", "")), "ts": ts / 1e6, "dur": dur / 1e6,
                    "worker": e.get("pid"), "parents": parents})
    for e in out:
        missing = [p for p in e["parents"] if p not in names]
        if missing:
            raise DataError(f"task {e['name']!r} waits for {missing[0]!r}, which is not in the trace", source=source)
    return out


def _graph(events: list[dict]):
    """The events by name, how many parents each waits for, each one's children, and the ready heap of those that
    wait for none (keyed by recorded start: the order the run started them)."""
    by_name = {e["name"]: e for e in events}
    waiting = {e["name"]: len(e["parents"]) for e in events}
    children = defaultdict(list)
    for e in events:
        for p in e["parents"]:
            children[p].append(e["name"])
    ready = [(e["ts"], e["name"]) for e in events if not e["parents"]]
    heapq.heapify(ready)
    return by_name, waiting, children, ready


def _topological(events: list[dict]) -> list[dict]:
    """The events, every one after the tasks it waited for (Kahn; ties in recorded start order)."""
    by_name, waiting, children, ready = _graph(events)
    out = []
    while ready:
        _, name = heapq.heappop(ready)
        out.append(by_name[name])
        for c in children[name]:
            waiting[c] -= 1
            if waiting[c] == 0:
                heapq.heappush(ready, (by_name[c]["ts"], c))
    if len(out) != len(events):
        raise DataError("the trace's tasks wait for each other in a cycle")
    return out


def critical_path(events: list[dict]) -> tuple[float, list[str]]:
    """The longest chain's seconds and its tasks, first first."""
    finish, via = {}, {}
    for e in _topological(events):
        before = max(e["parents"], key=lambda p: finish[p], default=None)
        finish[e["name"]] = (finish[before] if before else 0.0) + e["dur"]
        via[e["name"]] = before
    if not finish:
        return 0.0, []
    name = max(finish, key=finish.get)
    chain = []
    while name is not None:
        chain.append(name)
        name = via[name]
    return finish[chain[0]], chain[::-1]


def list_schedule(events: list[dict], workers: int) -> float:
    """The wall of a list schedule of the recorded graph on ``workers`` workers (module docstring)."""
    by_name, waiting, children, ready = _graph(events)
    running: list[tuple[float, str]] = []
    now = 0.0
    while ready or running:
        while ready and len(running) < workers:
            _, name = heapq.heappop(ready)
            heapq.heappush(running, (now + by_name[name]["dur"], name))
        now, name = heapq.heappop(running)
        for c in children[name]:
            waiting[c] -= 1
            if waiting[c] == 0:
                heapq.heappush(ready, (by_name[c]["ts"], c))
    return now


def analyse(events: list[dict], worker_counts=WORKER_COUNTS) -> dict:
    """Work, critical path, parallelism and predicted walls of a trace's events (``bench.json``: ``trace``)."""
    tasks = [e for e in events if e["kind"] != "call"]
    work = sum(e["dur"] for e in tasks)
    path, chain = critical_path(events)
    recorded = len({e["worker"] for e in tasks})
    wall = (max(e["ts"] + e["dur"] for e in tasks) - min(e["ts"] for e in tasks)) if tasks else 0.0
    predicted = {str(p): list_schedule(events, p) for p in sorted(set(worker_counts) | {max(recorded, 1)})}
    kinds: dict[str, dict] = defaultdict(lambda: {"tasks": 0, "work_s": 0.0})
    for e in tasks:
        kinds[e["kind"]]["tasks"] += 1
        kinds[e["kind"]]["work_s"] += e["dur"]
    return {"tasks": len(tasks), "calls": len(events) - len(tasks), "workers_recorded": recorded,
            "wall_s": wall, "work_s": work, "critical_path_s": path, "parallelism": work / path if path else None,
            "critical_path": [n for n in chain if not n.startswith("call ")],
            "predicted_wall_s": predicted,
            "predicted_speedup_2_to_16": predicted["2"] / predicted["16"] if predicted.get("16") else None,
            "predicted_at_recorded_workers_s": predicted[str(max(recorded, 1))],
            "by_kind": dict(kinds)}


def markdown(fig: dict, command: str) -> str:
    """The trace analysis as a page (``results/trace_bench.md``)."""
    p = fig["predicted_wall_s"]
    rows = "\n".join(f"| {w} | {s:.1f} | {p['2'] / s:.2f}x |" for w, s in p.items())
    kinds = "\n".join(f"| {k} | {v['tasks']} | {v['work_s']:.1f} |" for k, v in sorted(fig["by_kind"].items()))
    chain = " -> ".join(fig["critical_path"][:12]) + (" -> ..." if len(fig["critical_path"]) > 12 else "")
    return f"""# What the recorded task graph allows

Measured by `{command}` from the trace of one run ({fig['tasks']} tasks in {fig['calls']} calls, on
{fig['workers_recorded']} workers, {fig['wall_s']:.1f} s from the first task's start to the last one's end).

| total work | critical path | available parallelism (work / critical path) |
|---|---|---|
| {fig['work_s']:.1f} s | {fig['critical_path_s']:.1f} s | {fig['parallelism'] or float('nan'):.1f} |

Predicted wall of a list schedule of the recorded graph (tasks keep their durations and dependencies; the
driver's work between calls and the cost of more workers are left out, so this bounds the gain from above):

| workers | predicted wall (s) | speed-up over 2 workers |
|---|---|---|
{rows}

The prediction at the run's own {fig['workers_recorded']} workers is {fig['predicted_at_recorded_workers_s']:.1f} s
against the {fig['wall_s']:.1f} s measured.

| task kind | tasks | work (s) |
|---|---|---|
{kinds}

Critical path: {chain}
"""
