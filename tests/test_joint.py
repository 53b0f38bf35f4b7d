"""Joint fits (issue 29): the stacked separable problem (derivatives against finite differences, blocks that
share nothing fit as they fit alone), the joint fit of the final models on a small campaign, its fit.json,
and one clear error for every joint fit that cannot be."""
import json

import numpy as np
import pytest

from structsearch.data.errors import DeclarationError
from structsearch.engine.fit import fit_problem
from structsearch.engine.joint import JointProblem
from structsearch.engine.separable import SeparableModel
from structsearch.engine.snls import SeparableProblem, model_jacobian

from conftest import central_difference

X = np.linspace(0.0, 4.0, 120)


def _blocks(shared=True):
    a = SeparableModel({"a0": "1", "a1": "exp(-k*x)"}, variables=["x"]).bind({"x": X})
    b = SeparableModel({"b0": "1", "b1": "x*exp(-k*x)" if shared else "x*exp(-j*x)"}, variables=["x"]).bind({"x": X})
    return a, b


def test_the_joint_evaluation_is_the_blocks_weighted_and_interleaved_and_its_derivatives_are_exact():
    a, b = _blocks()
    problem = JointProblem((a, b), np.array([4.0, 0.25]), len(X))
    assert problem.nonlinear_names == ("k",) and problem.linear_names == ("a0", "a1", "b0", "b1")
    theta, coef = np.array([0.7]), np.array([0.3, 1.1, -0.4, 2.0])
    ev = problem.evaluate(theta)
    alone = a.evaluate(theta)
    np.testing.assert_allclose(ev.phi[0::2, :2], 2.0 * alone.phi)        # block a, weight 4: rows scaled by 2
    assert not np.any(ev.phi[0::2, 2:]) and not np.any(ev.phi[1::2, :2])  # block-diagonal
    np.testing.assert_allclose(ev.phi[1::2, 2:], 0.5 * b.evaluate(theta).phi)
    jac = model_jacobian(ev, coef, 1)[:, :1]
    fd = central_difference(lambda t: problem.evaluate(t).phi @ coef, theta)
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-9)
    np.testing.assert_array_equal(problem.boundaries(np.array([0, 60, 120])), [0, 120, 240])


class _Stacked(SeparableProblem):
    """The joint problem without its block reduction: the generic projection of the stacked matrix."""

    def __init__(self, problem):
        self.problem = problem
        self.nonlinear_names, self.linear_names = problem.nonlinear_names, problem.linear_names

    def evaluate(self, theta):
        return self.problem.evaluate(theta)


def test_the_block_reduction_equals_the_stacked_projection():
    rng = np.random.default_rng(5)
    a, b = _blocks()
    c = SeparableModel({"c0": "x", "c1": "exp(-j*x)*x**2"}, variables=["x"]).bind({"x": X})
    problem = JointProblem((a, b, c), np.array([4.0, 0.25, 1.7]), len(X))
    y = rng.standard_normal(3 * len(X))
    theta = np.array([0.7, 1.4])
    blockwise = problem.reduce(theta, y)
    stacked = _Stacked(problem).reduce(theta, y)
    np.testing.assert_allclose(blockwise.coef, stacked.coef, rtol=1e-10)
    # the block reduction's rows come block after block, the stacked problem's interleaved
    order = np.concatenate([np.arange(b, 3 * len(X), 3) for b in range(3)])
    np.testing.assert_allclose(blockwise.residual, stacked.residual[order], atol=1e-12)
    np.testing.assert_allclose(blockwise.jacobian, stacked.jacobian[order], atol=1e-10)
    # and both are the derivative of the projected residual
    fd = central_difference(lambda t: problem.reduce(t, y).residual, theta)
    np.testing.assert_allclose(blockwise.jacobian, fd, rtol=1e-5, atol=1e-8)


def test_blocks_that_share_nothing_fit_as_they_fit_alone():
    rng = np.random.default_rng(2)
    a, b = _blocks(shared=False)
    ya = 0.3 + 1.1 * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X))
    yb = -0.4 + 2.0 * X * np.exp(-1.3 * X) + 0.02 * rng.standard_normal(len(X))
    problem = JointProblem((a, b), np.array([3.0, 0.5]), len(X))
    bounds = np.array([[0.01, 5.0], [0.01, 5.0]])
    joint = fit_problem(problem, problem.interleave([ya, yb]), boundaries=np.array([0, 2 * len(X)]),
                        segment_names=("m",), start=[1.0, 1.0], lower=bounds[:, 0], upper=bounds[:, 1],
                        covariance="white")
    for block, y, names in ((a, ya, ("k", "a0", "a1")), (b, yb, ("j", "b0", "b1"))):
        alone = fit_problem(block, y, boundaries=np.array([0, len(X)]), segment_names=("m",), start=[1.0],
                            lower=[0.01], upper=[5.0], covariance="white")
        for n in names:
            assert joint.params[n] == pytest.approx(alone.params[n], rel=1e-7), n


def test_a_joint_problem_refuses_a_linear_coefficient_in_two_blocks():
    a, _ = _blocks()
    with pytest.raises(DeclarationError, match="a0"):
        JointProblem((a, a), np.array([1.0, 1.0]), len(X))
    with pytest.raises(DeclarationError, match="positive weight"):
        JointProblem(_blocks(), np.array([1.0, 0.0]), len(X))


def test_the_gauss_newton_step_predicts_what_a_solve_moves_and_vanishes_at_the_optimum():
    from structsearch.engine.snls import gauss_newton_step, solve
    rng = np.random.default_rng(8)
    a, b = _blocks()
    ya = 0.3 + 1.1 * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X))
    yb = -0.4 + 2.0 * X * np.exp(-0.7 * X) + 0.02 * rng.standard_normal(len(X))
    lower, upper = np.array([0.01]), np.array([5.0])
    first = JointProblem((a, b), np.array([1.0 / 0.01 ** 2, 1.0 / 0.02 ** 2]), len(X))
    y1 = first.interleave([ya, yb])
    optimum = solve(first, y1, [1.0], lower, upper, tol=1e-12)
    assert abs(gauss_newton_step(first, y1, optimum.theta, lower, upper)[0]) < 1e-8
    # other weights: the optimum moves, and the step from the old one says by how much (to second order)
    second = JointProblem((a, b), np.array([1.0 / 0.01 ** 2, 1.0 / 0.005 ** 2]), len(X))
    y2 = second.interleave([ya, yb])
    moved = solve(second, y2, optimum.theta, lower, upper, tol=1e-12).theta - optimum.theta
    step = gauss_newton_step(second, y2, optimum.theta, lower, upper)
    assert abs(moved[0]) > 1e-4 and step[0] == pytest.approx(moved[0], rel=0.05)
    # a step that would leave the box stops at its edge
    assert gauss_newton_step(second, y2, optimum.theta, lower, optimum.theta + 1e-6)[0] == pytest.approx(1e-6)


@pytest.fixture(scope="module")
def joint_and_sequential(simulated_campaign):
    from structsearch.fitting.candidate_fit import fit_staged
    from structsearch.fitting.joint import fit_joint
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.options import FitOptions
    from structsearch.fitting.specs import find_candidate
    campaign = simulated_campaign(seed=4, scale=0.1)
    train, val = campaign.split("train"), campaign.split("validation")
    options = FitOptions(n_starts=1)
    names = ("CL-VI", "CD-IXr", "Cm-XXXIIIr")
    joint = fit_joint([find_candidate(n) for n in names], train, val, options)
    lift = fit_staged(find_candidate("CL-VI"), train, val, None, options)
    seq = {"CL": lift}
    for n in names[1:]:
        c = find_candidate(n)
        seq[c.coefficient] = fit_staged(c, train, val, LiftFit(find_candidate("CL-VI"), lift), options)
    return joint, seq


def test_the_joint_fit_of_the_final_models(joint_and_sequential):
    joint, seq = joint_and_sequential
    r = joint.result
    assert r.converged and joint.weights_settled and not r.not_identifiable
    assert set(joint.shared) == {"tau1_ss", "tau2_ss", "a1_ss", "a_star_ss", "a1_w", "a_star_w"}
    for cf in joint.coefficients:
        # the target: every coefficient within 2 % of its sequential fit's validation MSE, or better
        assert cf.validation.mse <= 1.02 * seq[cf.coefficient].mse_validation, cf.coefficient
        assert set(cf.stderr) == set(cf.params) and all(v > 0 for v in cf.stderr.values())
    # the weights are the settled inverse residual variances of the coefficients
    for cf in joint.coefficients:
        assert cf.weight == pytest.approx(1.0 / cf.train.mse, rel=1e-2)
    # drag and pitch bring their information on the shared states: no shared parameter is known worse
    worse = [n for n in joint.shared if r.stderr[n] > 1.05 * seq["CL"].estimates.stderr[n]]
    assert not worse, {n: (r.stderr[n], seq["CL"].estimates.stderr[n]) for n in worse}


def test_the_joint_fit_document(joint_and_sequential):
    joint, _ = joint_and_sequential
    from structsearch.data.atomic import json_ready
    doc = json.loads(json.dumps(json_ready(joint.to_dict())))
    assert doc["joint"] is True and set(doc["params"]) == set(joint.shared) == set(doc["stderr"])
    assert set(doc["coefficients"]) == {"CL", "CD", "Cm"}
    for coef, entry in doc["coefficients"].items():
        assert {"model", "parameters", "stderr", "mse", "r2"} <= set(entry)
        assert set(entry["mse"]) == {"train", "validation"}
    assert doc["covariance"]["kind"] == "hac-maneuver" and doc["weights_settled"] is True
    assert "C_L drag and pitch read" in doc["covariance"]["accounts_for"]
    # bands for every coefficient on one alpha grid, with the joint covariance
    static = doc["bands"]["static"]
    for coef in ("CL", "CD", "Cm"):
        band = static[coef]
        assert len(band["estimate"]) == len(static["alpha"])
        assert all(lo <= e <= hi for lo, e, hi in zip(band["confidence_low"], band["estimate"],
                                                      band["confidence_high"]))
        assert len(band["dof"]) == len(static["alpha"]) and band["reasons"] == []


@pytest.mark.parametrize("spec, match", [
    ("CL-VI,CL-I", "coefficient CL twice"),
    ("CL-I,CD-IXr", "does not have"),
    ("CL-VI", "two or three structures"),
    ("CL-VI,CD-NOPE", "CD-NOPE"),
])
def test_a_joint_fit_that_cannot_be_is_one_clear_error(spec, match):
    from structsearch.fitting.joint import joint_structures
    with pytest.raises(DeclarationError, match=match):
        joint_structures(spec)


def test_a_joint_spec_file(tmp_path):
    from structsearch.fitting.joint import joint_structures
    good = tmp_path / "joint.toml"
    good.write_text('[joint]\nstructures = ["CL-VI", "Cm-XXXIIIr"]\n')
    assert [c.name for c in joint_structures(str(good))] == ["CL-VI", "Cm-XXXIIIr"]
    bad = tmp_path / "bad.toml"
    bad.write_text('[joint]\nstructures = "CL-VI"\n')
    with pytest.raises(DeclarationError, match=r"bad.toml: a joint spec needs"):
        joint_structures(str(bad))
    unknown = tmp_path / "unknown.toml"
    unknown.write_text('[joint]\nstructures = ["CL-VI", "CD-NOPE"]\n')
    with pytest.raises(DeclarationError, match=r"unknown.toml: structure 'CD-NOPE'"):
        joint_structures(str(unknown))


@pytest.mark.slow
def test_fit_joint_on_the_command_line(campaign_on_disk, tmp_path, run_cli):
    data = campaign_on_disk(seed=2, scale=0.05)
    proc = run_cli("fit", "--data", str(data.directory), "--joint", "CL-VI,CD-IXr", "--starts", "1",
                   "--out", str(tmp_path / "j"))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "j" / "fit.json").read_text())
    assert set(doc["coefficients"]) == {"CL", "CD"} and doc["joint"] is True
    assert "(joint fit)" in (tmp_path / "j" / "fit.md").read_text()
    # both --model and --joint, or a coefficient twice: one error line, nothing written
    proc = run_cli("fit", "--data", str(data.directory), "--joint", "CD-IXr,CD-I", "--out", str(tmp_path / "k"))
    assert proc.returncode != 0 and "twice" in proc.stderr and not (tmp_path / "k").exists()


@pytest.mark.slow
def test_the_joint_bench_reports_cost_scores_and_shared_parameters():
    from structsearch.experiments.bench_joint import markdown, run_joint_bench
    fig = run_joint_bench(scale=0.05, seed=3, starts=1)
    assert set(fig["mse_validation"]) == {"CL", "CD", "Cm"} and fig["cost_ratio"] > 0
    assert set(fig["shared"]) == {"tau1_ss", "tau2_ss", "a1_ss", "a_star_ss", "a1_w", "a_star_w"}
    assert 0 < fig["bands_ratio"] < 1
    text = markdown(fig, "structsearch bench --joint --out x")
    assert "joint sd / lift-only sd" in text and "bench --joint" in text


def test_statistics_at_a_given_solution_equal_those_of_a_solve_that_ends_there():
    from structsearch.engine.snls import solve
    rng = np.random.default_rng(8)
    a, b = _blocks()
    problem = JointProblem((a, b), np.array([2.0, 0.5]), len(X))
    y = problem.interleave([0.3 + 1.1 * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X)),
                            -0.4 + 2.0 * X * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X))])
    outcome = solve(problem, y, [1.0], [0.01], [5.0])
    kw = dict(boundaries=np.array([0, 2 * len(X)]), segment_names=("m",), lower=[0.01], upper=[5.0],
              covariance="hac")
    given = fit_problem(problem, y, solution=outcome, **kw)
    solved = fit_problem(problem, y, start=outcome.theta, **kw)
    assert given.nfev == outcome.nfev and given.converged == outcome.success
    for n in problem.nonlinear_names + problem.linear_names:
        assert given.params[n] == pytest.approx(solved.params[n], rel=1e-8), n
        assert given.stderr[n] == pytest.approx(solved.stderr[n], rel=1e-6), n


def test_the_factor_of_a_joint_jacobian_block_by_block_is_that_of_the_whole_matrix():
    """The joint problem's Jacobian is factorised block by block on each block's columns (its Phi is
    block-diagonal): R^T R must be the whole column-scaled J^T J, and every statistic must be unchanged."""
    from structsearch.engine.sandwich import scaled_factor
    from structsearch.engine.snls import solve
    a, b = _blocks()
    problem = JointProblem((a, b), np.array([2.0, 0.5]), len(X))
    theta, coef = np.array([0.7]), np.array([0.3, 1.1, -0.4, 2.0])
    jac = model_jacobian(problem.evaluate(theta), coef, 1)
    whole, scale = scaled_factor(jac)
    blocked, scale_b = scaled_factor(jac, problem.jacobian_blocks())
    np.testing.assert_allclose(scale_b, scale)
    np.testing.assert_allclose(blocked.T @ blocked, whole.T @ whole, atol=1e-12)
    np.testing.assert_allclose(blocked.T @ blocked, (jac / scale).T @ (jac / scale), atol=1e-12)
    # a pattern that misses a non-zero column would be wrong: the pattern names every non-zero of the Jacobian
    for rows, columns in problem.jacobian_blocks():
        outside = np.delete(jac[rows], columns, axis=1)
        assert not np.any(outside)
    # the statistics with the blocked factor equal those of the same problem without its pattern
    rng = np.random.default_rng(3)
    y = problem.interleave([0.3 + 1.1 * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X)),
                            -0.4 + 2.0 * X * np.exp(-0.7 * X) + 0.01 * rng.standard_normal(len(X))])
    outcome = solve(problem, y, [1.0], [0.01], [5.0])

    class Plain(SeparableProblem):   # the same problem without its Jacobian's pattern (the protocol's default)
        nonlinear_names, linear_names = problem.nonlinear_names, problem.linear_names
        evaluate = staticmethod(problem.evaluate)
    kw = dict(boundaries=np.array([0, 2 * len(X)]), segment_names=("m",), lower=[0.01], upper=[5.0],
              covariance="hac-maneuver", solution=outcome)
    with_pattern, without = fit_problem(problem, y, **kw), fit_problem(Plain(), y, **kw)
    for n in problem.nonlinear_names + problem.linear_names:
        assert with_pattern.stderr[n] == pytest.approx(without.stderr[n], rel=1e-9), n
    assert with_pattern.condition_number == pytest.approx(without.condition_number, rel=1e-9)


def test_the_gauss_newton_relaxation_settles_where_the_solves_do(joint_and_sequential, simulated_campaign,
                                                                 monkeypatch):
    """The weight iteration takes one Gauss-Newton step per iteration; when the steps stop contracting it
    solves each iteration's problem instead. Forced onto the solves after its first step (no step can
    contract by a factor 0), the fit must settle where the steps settled: the same fixed point."""
    import structsearch.fitting.joint as joint_module
    from structsearch.fitting.options import FitOptions
    from structsearch.fitting.specs import find_candidate
    joint, _ = joint_and_sequential
    assert joint.weights_settled and "Gauss-Newton" in joint.result.message
    campaign = simulated_campaign(seed=4, scale=0.1)
    monkeypatch.setattr(joint_module, "CONTRACTION", 0.0)
    solved = joint_module.fit_joint([find_candidate(n) for n in ("CL-VI", "CD-IXr", "Cm-XXXIIIr")],
                                    campaign.split("train"), campaign.split("validation"), FitOptions(n_starts=1))
    assert solved.weights_settled and solved.result.converged and "Gauss-Newton" not in solved.result.message
    r, s = joint.result, solved.result
    for n in r.names:
        # both stop within 1e-3 of the box of the fixed point: far inside the standard deviation
        assert abs(r.params[n] - s.params[n]) < 0.25 * s.stderr[n], (n, r.params[n], s.params[n], s.stderr[n])
        assert r.stderr[n] == pytest.approx(s.stderr[n], rel=0.05), n


@pytest.mark.parametrize("lift_parameter", ["CL_KL_ss", "tau1_ss", "a_star_w"])
def test_the_path_through_the_lift_output_is_its_finite_difference(joint_and_sequential, simulated_campaign,
                                                                     lift_parameter):
    """J + K, the joint model's derivative with the C_L that drag and pitch read moving with the lift parameters,
    against a central difference of the drag and pitch predictions with C_L recomputed from the moved lift model."""
    from structsearch.fitting.joint import lift_output_jacobian
    from structsearch.fitting.models import build_model, model_with_lift, with_lift_prediction
    joint, _ = joint_and_sequential
    train = simulated_campaign(seed=4, scale=0.1).split("train")
    problem, order, params = joint.problem, joint.candidates, dict(joint.result.params)
    models = [build_model(c) if c.coefficient == "CL" else model_with_lift(c, {}) for c in order]
    names = tuple(problem.nonlinear_names) + tuple(problem.linear_names)
    k = len(problem.nonlinear_names)
    theta = np.array([params[n] for n in problem.nonlinear_names])
    coef = np.array([params[n] for n in problem.linear_names])
    jac = model_jacobian(problem.evaluate(theta), coef, k)
    total = jac + lift_output_jacobian(problem, order, models, train, joint.lift, params, jac)
    lift_names = build_model(joint.lift).nonlinear_names + build_model(joint.lift).linear_names
    column = names.index(lift_parameter)
    h = 1e-5 * max(abs(params[lift_parameter]), 1e-2)

    def drag_and_pitch(shift):
        moved = {**params, lift_parameter: params[lift_parameter] + shift}
        seen = with_lift_prediction(train, {n: moved[n] for n in lift_names}, joint.lift)
        return [np.sqrt(problem.weights[b]) * m.predict(seen, {n: moved[n] for n in m.nonlinear_names + m.linear_names})
                for b, m in enumerate(models) if order[b].coefficient != "CL"]

    up, down = drag_and_pitch(h), drag_and_pitch(-h)
    blocks = [b for b, c in enumerate(order) if c.coefficient != "CL"]
    for b, u, d in zip(blocks, up, down):
        numeric = (u - d) / (2 * h)
        analytic = total[b::problem.n_blocks, column]
        assert np.max(np.abs(numeric)) > 0
        np.testing.assert_allclose(analytic, numeric, rtol=1e-4, atol=1e-6 * np.max(np.abs(numeric)))
    # without the C_L path (J alone) the drag and pitch rows would miss it
    assert not np.allclose(jac[blocks[0]::problem.n_blocks, column], (up[0] - down[0]) / (2 * h), rtol=1e-3)


def test_the_joint_covariance_counts_the_lift_output(joint_and_sequential, simulated_campaign):
    """The reported joint covariance is T C T^T, C the one conditional on the C_L drag and pitch read (the stacked
    problem's own statistics at the same solution) and T = (J^T (J + K))^-1 J^T J; it says so, and it is wider
    than the conditional one on the shared states."""
    from structsearch.engine.snls import Outcome
    from structsearch.fitting.joint import lift_output_jacobian
    from structsearch.fitting.models import build_model, model_with_lift, with_lift_prediction
    joint, _ = joint_and_sequential
    train = simulated_campaign(seed=4, scale=0.1).split("train")
    problem, order, r = joint.problem, joint.candidates, joint.result
    params = dict(r.params)
    models = [build_model(c) if c.coefficient == "CL" else model_with_lift(c, {}) for c in order]
    lift_names = build_model(joint.lift).nonlinear_names + build_model(joint.lift).linear_names
    seen = with_lift_prediction(train, {n: params[n] for n in lift_names}, joint.lift)
    y = problem.interleave([(train if c.coefficient == "CL" else seen)[c.coefficient] for c in order])
    k = len(problem.nonlinear_names)
    theta = np.array([params[n] for n in problem.nonlinear_names])
    coef = np.array([params[n] for n in problem.linear_names])
    solution = Outcome(theta, theta, coef, 0.0, 1, 1, 1, "given", True)
    conditional = fit_problem(problem, y, boundaries=problem.boundaries(train.bounds), segment_names=train.names,
                              lower=np.full(k, -1e9), upper=np.full(k, 1e9), covariance="hac-maneuver",
                              solution=solution)
    jac = model_jacobian(problem.evaluate(theta), coef, k)
    extra = lift_output_jacobian(problem, order, models, train, joint.lift, params, jac)
    a = jac.T @ jac
    t = np.linalg.solve(a + jac.T @ extra, a)
    expected = t @ conditional.covariance @ t.T
    np.testing.assert_allclose(r.covariance, expected, rtol=1e-6, atol=1e-14)
    assert "C_L drag and pitch read" in r.estimates.generated_regressors
    wider = [n for n in joint.shared if r.stderr[n] > conditional.stderr[n]]
    assert len(wider) >= len(joint.shared) // 2, {n: (r.stderr[n], conditional.stderr[n]) for n in joint.shared}


def test_drag_and_pitch_under_the_joint_lift_model(joint_and_sequential, simulated_campaign):
    """A drag or pitch candidate fitted on the joint lift (search --joint-lift) reproduces the joint fit's own
    block (given the lift estimate, both are the same least-squares problem), and its two-step covariance has
    the joint fit as first step."""
    from structsearch.fitting.candidate_fit import fit_candidate
    from structsearch.fitting.joint import joint_lift
    from structsearch.fitting.options import FitOptions
    from structsearch.fitting.specs import find_candidate
    joint, seq = joint_and_sequential
    campaign = simulated_campaign(seed=4, scale=0.1)
    train, val = campaign.split("train"), campaign.split("validation")
    read = joint_lift(joint)
    assert read.name == "CL-VI" and read.partners == ("CD-IXr", "Cm-XXXIIIr")
    assert read.influence.shape == (train.n_samples, len(read.influence_names))
    assert read.cache_key != dict(read.params)      # never served a sequential lift's cached fits
    for name in ("CD-IXr", "Cm-XXXIIIr"):
        c = find_candidate(name)
        r = fit_candidate(c, train, val, read, FitOptions(n_starts=1))
        block = next(cf for cf in joint.coefficients if cf.model == name)
        for n in r.estimates.params:
            assert r.estimates.params[n] == pytest.approx(block.params[n], rel=2e-2, abs=1e-3 * abs(block.params[n]) + 1e-6), n
        assert "joint fit" in r.estimates.generated_regressors
        assert all(np.isfinite(v) and v > 0 for v in r.estimates.stderr.values())
        # the lift model's error enters: the two-step standard deviations exceed the conditional (white) ones
        conditional = fit_candidate(c, train, val, read, FitOptions(n_starts=1, covariance="hac-maneuver",
                                                                    scores_only=True))
        assert any(r.estimates.stderr[n] > conditional.estimates.stderr[n] for n in r.estimates.stderr)


@pytest.mark.slow
def test_search_under_a_joint_lift_on_the_command_line(campaign_on_disk, tmp_path, run_cli):
    data = campaign_on_disk(seed=2, scale=0.05)
    out = tmp_path / "s"
    proc = run_cli("search", "--data", str(data.directory), "--grid", "drag", "--joint-lift", "CL-VI,CD-IXr",
                   "--starts", "1", "--out", str(out), "--jobs", "1")
    assert proc.returncode == 0, proc.stderr
    assert "joint lift model: CL-VI + CD-IXr" in proc.stdout
    doc = json.loads((out / "joint_lift.json").read_text())
    assert doc["joint"] is True and set(doc["coefficients"]) == {"CL", "CD"}
    assert (out / "ranking.csv").exists()
    proc = run_cli("search", "--data", str(data.directory), "--grid", "drag", "--joint-lift", "CL-VI,CD-IXr",
                   "--covariance", "white", "--out", str(tmp_path / "w"))
    assert proc.returncode != 0 and "--joint-lift with --covariance white" in proc.stderr
    assert not (tmp_path / "w").exists()


def test_a_joint_fits_forward_replay_with_its_sampled_band(joint_and_sequential, simulated_campaign):
    from structsearch.flight.replay import replay
    from structsearch.flight.replay_bands import deepest_maneuver, joint_aero, replay_band
    joint, _ = joint_and_sequential
    val = simulated_campaign(seed=4, scale=0.1).split("validation")
    rb = replay_band(joint, val, samples=8, seed=1)
    index = deepest_maneuver(val)
    assert rb.maneuver == val.names[index]
    direct = replay(val.select([index]), joint_aero(joint, joint.result.params), rb.window_s)[0]
    for s in ("alpha", "q", "theta", "V"):
        np.testing.assert_array_equal(rb.estimate[s], direct.simulated[s])
        assert len(rb.low[s]) == len(rb.t) and np.all(rb.low[s] <= rb.high[s])
        # the band is the spread the parameters cause around the replay at the estimate: it holds it nearly always
        inside = (rb.estimate[s] >= rb.low[s] - 1e-12) & (rb.estimate[s] <= rb.high[s] + 1e-12)
        assert inside.mean() > 0.8, s
    assert rb.diverged == 0 and rb.draws == 8
    doc = rb.to_dict()
    assert set(doc["states"]["alpha"]) == {"measured", "estimate", "confidence_low", "confidence_high"}
    again = replay_band(joint, val, samples=8, seed=1)
    np.testing.assert_array_equal(again.low["alpha"], rb.low["alpha"])
    with pytest.raises(DeclarationError, match="no such maneuver"):
        replay_band(joint, val, maneuver="nope", samples=4)


@pytest.mark.slow
def test_fit_joint_with_sampled_bands_on_the_command_line(campaign_on_disk, tmp_path, run_cli):
    data = campaign_on_disk(seed=2, scale=0.05)
    out = tmp_path / "j"
    proc = run_cli("fit", "--data", str(data.directory), "--joint", "CL-VI,CD-IXr,Cm-XXXIIIr", "--starts", "1",
                   "--band-samples", "8", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    bands = json.loads((out / "fit.json").read_text())["bands"]
    assert bands["replay"]["draws"] == 8 and "alpha" in bands["replay"]["states"]
    assert bands["static"]["CL"]["sampled"]["draws"] == 8
    text = (out / "fit.md").read_text()
    assert "Forward replay of" in text and "Cross-check by parameter sampling (8 draws" in text
    proc = run_cli("fit", "--data", str(data.directory), "--model", "CL-VI", "--replay-maneuver", "x",
                   "--out", str(tmp_path / "k"))
    assert proc.returncode != 0 and "--replay-maneuver goes with --joint" in proc.stderr
    assert not (tmp_path / "k").exists()
