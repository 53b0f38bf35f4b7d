"""Tasks small enough to spread: a candidate's starts, stage starts, statistics and folds as tasks of their own, the
trace they leave, and what ``bench --trace`` reads from a trace."""
import json

import numpy as np
import pytest

from conftest import fitter_for, run_cli
from structsearch.data.errors import DataError
from structsearch.experiments.trace_bench import analyse, critical_path, list_schedule, read_trace
from structsearch.fitting.candidate_fit import fit_staged
from structsearch.fitting.options import FitOptions
from structsearch.fitting.specs import load_grid
from structsearch.fitting.staging import DonorEstimate, best_contained, warm_start
from structsearch.fitting.trace import Trace


def _event(name, ts, dur, parents=(), pid=1, cat="start"):
    return {"name": name, "cat": cat, "ph": "X", "ts": ts * 1e6, "dur": dur * 1e6, "pid": pid, "tid": pid,
            "args": {"parents": list(parents)}}


# A diamond A -> (B, C) -> D beside a lone E; durations in seconds. By hand: work 1+2+3+1+4 = 11; the longest chain
# is A, C, D = 5. On 2 workers a list schedule in recorded start order runs A and E at 0; at 1 (A done) B takes the
# free worker; at 3 (B done) C starts, D waits for it until 6: wall 7. On 64 workers the wall is the chain, 5.
DIAMOND = {"traceEvents": [_event("A", 0, 1), _event("E", 0, 4), _event("B", 1, 2, ["A"]),
                           _event("C", 1, 3, ["A"]), _event("D", 4, 1, ["B", "C"])]}


def test_a_hand_built_graph_gives_the_work_path_and_schedule_worked_out_by_hand(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(DIAMOND))
    events = read_trace(path)
    assert critical_path(events) == (5.0, ["A", "C", "D"])
    assert list_schedule(events, 1) == 11.0
    assert list_schedule(events, 2) == 7.0
    assert list_schedule(events, 64) == 5.0
    fig = analyse(events)
    assert fig["work_s"] == 11.0 and fig["parallelism"] == pytest.approx(11 / 5)
    assert fig["predicted_speedup_2_to_16"] == pytest.approx(7 / 5)


def test_bench_trace_writes_its_figures_beside_the_other_benchmarks(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(DIAMOND))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "bench.json").write_text(json.dumps({"one_start": {"kept": True}}))
    proc = run_cli("bench", "--trace", path, "--out", tmp_path / "out")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "out" / "bench.json").read_text())
    assert doc["one_start"] == {"kept": True}
    assert doc["trace"]["critical_path_s"] == 5.0 and doc["trace"]["predicted_wall_s"]["2"] == 7.0
    assert "critical path 5.0 s" in proc.stdout


@pytest.mark.parametrize("events, why", [
    ([_event("A", 0, 1), _event("A", 1, 1)], "a second task named 'A'"),
    ([_event("A", 0, 1, ["Z"])], "waits for 'Z', which is not in the trace"),
    ([_event("A", 0, -1)], "negative duration"),
    ([{**_event("A", 0, 1), "args": {"parents": "B"}}], "args.parents is not a list"),
])
def test_a_bad_trace_is_one_clear_error_naming_the_file(tmp_path, events, why):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps({"traceEvents": events}))
    with pytest.raises(DataError, match=why) as err:
        read_trace(path)
    assert "bad.json" in str(err.value)


def test_bench_trace_refuses_a_bench_json_it_cannot_extend(tmp_path):
    path = tmp_path / "t.json"
    path.write_text(json.dumps(DIAMOND))
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "bench.json").write_text("[1, 2")
    proc = run_cli("bench", "--trace", path, "--out", tmp_path / "out")
    errors = [line for line in proc.stderr.splitlines() if line.strip()]
    assert proc.returncode == 2 and len(errors) == 1 and "bench.json" in errors[0], proc.stderr
    assert (tmp_path / "out" / "bench.json").read_text() == "[1, 2"   # left as it was


def test_a_trace_that_is_not_json_is_refused(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    with pytest.raises(DataError, match="not a readable trace"):
        read_trace(path)


SOME = ("X_ss/X_w S/S", "X_ss/X_w Q/S", "X_ss/X_w U/S", "X U")


@pytest.fixture(scope="module")
def traced(simulated_campaign, tmp_path_factory):
    """Four separation candidates (a chain S/S -> Q/S -> U/S that warm starts, and X U, which climbs its stage)
    on a campaign with cross-validation folds, fitted as tasks on one and on two workers."""
    campaign = simulated_campaign(seed=4, scale=0.15)
    grid = load_grid("separation")
    candidates = [grid[n] for n in SOME]
    out = {}
    for jobs in (1, 2):
        trace = Trace()
        fitter = fitter_for(campaign, tmp_path_factory.mktemp(f"cache{jobs}"), FitOptions(), n_jobs=jobs, trace=trace)
        out[jobs] = (fitter.fit(candidates), trace)
    return campaign, candidates, out


def _same(a, b, rtol=1e-9):
    """Two results of one fit: the same optimum up to the rounding a BLAS kernel or thread count brings (costs
    converge to 1e-10 relative; a kernel moves them by 1e-13)."""
    assert a.estimates.names == b.estimates.names
    np.testing.assert_allclose(a.estimates.values, b.estimates.values, rtol=1e-6, atol=1e-9)
    assert a.mse_train == pytest.approx(b.mse_train, rel=rtol)
    assert (a.cv is None) == (b.cv is None)
    if a.cv is not None:
        assert a.cv.mse == pytest.approx(b.cv.mse, rel=1e-7)
    assert a.optimizer.n_starts == b.optimizer.n_starts


def test_the_tasks_fit_what_a_serial_staged_fit_does(traced):
    """Start for start: a candidate without a donor (X U: its quasi-steady stage first) and one warm started from
    its donors (U/S from Q/S) give what :func:`fit_staged` gives with the same starts."""
    campaign, candidates, out = traced
    results = out[2][0]
    train, validation = campaign.split("train"), campaign.split("validation")
    _same(results[3], fit_staged(candidates[3], train, validation, None, FitOptions()))
    fitted = [(c, DonorEstimate.of(r)) for c, r in zip(candidates[:2], results[:2])]
    warm, nested = warm_start(candidates[2], fitted), best_contained(candidates[2], fitted)
    assert warm is not None
    _same(results[2], fit_staged(candidates[2], train, validation, None, FitOptions(), start=warm, nested=nested))
    assert all(r.cv is not None and r.cv_folds == 2 for r in results)


def test_the_results_do_not_depend_on_the_number_of_workers(traced):
    _, _, out = traced
    for a, b in zip(out[1][0], out[2][0]):
        _same(a, b)


def test_the_trace_holds_every_task_after_the_tasks_it_waited_for(traced):
    _, _, out = traced
    trace = out[2][1]
    doc = trace.to_chrome()
    events = {e["name"]: e for e in doc["traceEvents"]}
    kinds = {e["cat"] for e in events.values()}
    assert {"start", "stage start", "fit", "fold", "call"} <= kinds
    assert len({e["pid"] for e in events.values() if e["cat"] != "call"}) == 2   # both workers worked
    for e in events.values():
        assert e["ph"] == "X" and e["dur"] >= 0
        for p in e["args"]["parents"]:
            # a parent ended before its child started (one wall clock; 1 ms for its resolution)
            assert events[p]["ts"] + events[p]["dur"] <= e["ts"] + 1e3, (p, e["name"])
    # the chain waits for estimates, not for folds: Q/S's starts follow S/S's starts, never its folds
    q_starts = [e for n, e in events.items() if n.startswith("separation/X_ss/X_w Q/S: start")]
    assert any(p.startswith("separation/X_ss/X_w S/S: start") for e in q_starts for p in e["args"]["parents"])
    assert not any("fold" in p for e in q_starts for p in e["args"]["parents"])
    fig = analyse(read_trace_from(doc))
    assert fig["tasks"] == sum(1 for e in events.values() if e["cat"] != "call")
    assert fig["critical_path_s"] <= fig["work_s"]


def read_trace_from(doc):
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "t.json"
        path.write_text(json.dumps(doc))
        return read_trace(path)
