"""The bench's references: the search's critical path on a hand-made chain, and the independent
numpy/scipy script that the whole-process ``fit`` is timed against."""
import json
import subprocess
import sys

import numpy as np
import pytest

from structsearch.fitting.candidates import Candidate

LIFT_REGRESSORS = (("CL0", "1"), ("CL_KL_ss", "K_L(X_ss)"))


def _lift(name, grid, kind, extra_state=()):
    return Candidate(name, grid, "CL", LIFT_REGRESSORS, (("ss", kind),) + extra_state)


def test_the_critical_path_is_the_longest_chain_of_donors_twins_and_lift_models():
    from structsearch.experiments.bench import critical_path
    separation = [_lift("S", "separation", "S"), _lift("Q", "separation", "Q"), _lift("U", "separation", "U"),
                  Candidate("W", "separation", "CL", (("CL0", "1"), ("CL_KL_w", "K_L(X_w)")), (("w", "S"),))]
    # L is U under another name (served U's fit: U's chain, not U's plus its own); L2 waits for S, Q and U
    lift = [_lift("L", "lift", "U"), _lift("L2", "lift", "U", (("w", "S"),))]
    drag = [Candidate("D", "drag", "CD", (("CD0", "1"),), (("ss", "U"),), lift="L2"),
            Candidate("E", "drag", "CD", (("CD0", "1"),), (("ss", "U"),), lift="L")]
    path = critical_path([(separation, [1.0, 2.0, 4.0, 6.5]), (lift, [4.0, 10.0]), (drag, [3.0, 1.0])])
    assert path == {"seconds": 20.0, "chain": ["separation S", "separation Q", "separation U", "lift L2", "drag D"]}
    # without the lift models' grid, a drag candidate's chain is its own fit
    assert critical_path([(drag, [3.0, 1.0])]) == {"seconds": 3.0, "chain": ["drag D"]}
    # a longer independent candidate is the path by itself
    assert critical_path([(separation, [1.0, 2.0, 4.0, 7.5])])["chain"] == ["separation W"]


def test_the_reference_script_reaches_structsearchs_optimum_from_the_declared_start(campaign_on_disk):
    from structsearch.experiments.bench_process import SCRIPT
    from structsearch.fitting.models import build_model
    from structsearch.fitting.specs import resolve_candidate
    campaign = campaign_on_disk(seed=3, scale=0.05)
    out = subprocess.run([sys.executable, str(SCRIPT), str(campaign.directory)], capture_output=True, text=True,
                         check=True)
    script = json.loads(out.stdout)
    train = campaign.split("train")
    model = build_model(resolve_candidate("CL-VI"))
    fit = model.fit(train, n_starts=1)
    assert script["samples"] == train.n_samples
    assert script["rss"] == pytest.approx(float(np.sum(fit.residuals ** 2)), rel=1e-6)
    assert list(script["theta"]) == list(model.nonlinear_names)
    for name, value in script["theta"].items():
        assert value == pytest.approx(fit.params[name], rel=1e-3)
    # the script knows nothing of structsearch: it would measure nothing if it did
    assert "structsearch" not in SCRIPT.read_text().split('"""')[2]


def test_a_single_fit_may_trust_its_stage_with_fewer_optimizer_runs(simulated_campaign):
    from structsearch.fitting.candidate_fit import fit_staged
    from structsearch.fitting.options import FitOptions
    from structsearch.fitting.specs import resolve_candidate
    campaign = simulated_campaign(seed=1, scale=0.05)
    train, validation = campaign.split("train"), campaign.split("validation")
    options = FitOptions(n_starts=1, cv_folds=0)
    usual = fit_staged(resolve_candidate("CL-VI"), train, validation, None, options)
    lean = fit_staged(resolve_candidate("CL-VI"), train, validation, None, options, stage_starts=1, declared_too=False)
    # the stage's estimates, the stage's optimum with tau1 at 0 (never worse than the stage) and the declared start;
    # trusting the stage drops the declared one
    assert (usual.optimizer.n_starts, lean.optimizer.n_starts) == (3, 2)
    assert lean.mse_train == pytest.approx(usual.mse_train, rel=1e-6)
