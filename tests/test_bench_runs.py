"""The benchmarks that drive the structure search and the diagnosis through their own entry points (``bench
--discovery``, ``diagnose --benchmark``) run end to end on a small campaign: each builds its fitters itself."""
import math

import pytest


@pytest.mark.slow
def test_the_discovery_bench_runs_the_story_twice_and_discover_once():
    from structsearch.experiments.bench_discovery import run_discovery_bench
    fig = run_discovery_bench(n_jobs=1, scale=0.05, coefficients=("CL",))
    assert set(fig["story_structure_search"]["final_model"]) == {"CL", "CD", "Cm"}
    assert math.isfinite(fig["story_ratio"]) and fig["story_ratio"] > 0
    found = fig["discover"]["CL"]   # 5 % of the maneuvers: too few for a move to pass from the intercept alone
    assert found["structures_fitted"] > found["moves"] == len(found["path"]) and found["final"]["name"]
    assert found["thesis_final"]["role"] == "thesis final"


@pytest.mark.slow
def test_the_withheld_benchmark_runs_one_effect_and_one_null_case():
    from structsearch.diagnosis.withheld import run
    res = run(scale=0.05, null_seeds=(0,), effects=("elevator",), anomalies=())
    assert [r.effect for r in res.rows] == ["elevator"] and res.outside == ()
    assert len(res.null) == 3 and all(n.seed == 0 for n in res.null)
    assert set(res.to_dict()) >= {"seed", "scale", "rows", "null"}
