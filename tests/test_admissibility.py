"""Admissibility (issue 12 item 1): each rule on a constructed result, the datum-free correlation on a
fit, and the ranking that puts admissible candidates first."""
import numpy as np
import pytest
from conftest import stated_result

from structsearch.data.flightdata import FlightData
from structsearch.flight.synthetic import campaign
from structsearch.engine.stallmodel import StallModel
from structsearch.grid_search.admissibility import AdmissibilityRules, reasons
from structsearch.fitting.centred_correlation import centred_correlation
from structsearch.fitting.candidate_result import CandidateResult, R2Summary, SplitScores
from structsearch.fitting.candidates import Candidate
from structsearch.grid_search.ranking import passed_over, rank

LIFT = Candidate("L", "g", "CL", (("CL0", "1"), ("CL_KL", "K_L(X)"), ("CL_a", "alpha")), states=(("", "U"),))
PITCH = Candidate("P", "g", "Cm", (("Cm0", "1"), ("Cm_CL", "CL"), ("Cm_xcgCL", "x_cg/cbar*CL")))
RULES = AdmissibilityRules(alpha_range=(0.0, 0.30), cg_range=(7.01, 7.26), cbar=2.0)


def result(candidate=LIFT, mse=(1.0, 2.0, 3.0), **changes):
    names = ("tau1", "tau2", "a1", "a_star") + tuple(n for n, _ in candidate.regressors) \
        if candidate.states else tuple(n for n, _ in candidate.regressors)
    scores = SplitScores(float(np.mean(mse)), tuple(mse), (100,) * len(mse), R2Summary(0.9, 0.8, 1.0))
    params = {n: 0.2 for n in names}
    fields = dict(names=names, nonlinear_names=names[:4] if candidate.states else (), params=params,
                  stderr={n: 0.01 for n in names}, p_values={n: 1e-6 for n in names}, at_bound={},
                  correlation=tuple(tuple(float(i == j) for j in range(len(names))) for i in range(len(names))),
                  converged=True, not_identifiable={}, message="ok", train=scores, validation=scores)
    fields.update(changes)
    return stated_result(candidate.name, "g", candidate.coefficient, None, 0.0, **fields)


def test_a_clean_result_is_admissible():
    assert reasons(result(), LIFT, RULES) == ()


@pytest.mark.parametrize("changes,expected", [
    (dict(converged=False, message="max_nfev reached"), "did not converge (max_nfev reached)"),
    (dict(not_identifiable={"a1": "X stays at 1"}), "not identifiable: a1"),
    (dict(at_bound={"a_star": "lower"}), "a_star at its lower bound"),
    (dict(p_values={"tau1": 0.2, "tau2": float("nan")}), "t-test accepts 0 at 5%: tau1, tau2"),
])
def test_each_fit_rule_gives_its_reason(changes, expected):
    why = reasons(result(**changes), LIFT, RULES)
    assert len(why) == 1 and expected in why[0], why


def test_correlation_rule_and_its_threshold():
    corr = np.eye(7)
    corr[4, 5] = corr[5, 4] = -0.97
    r = result(correlation=tuple(map(tuple, corr)))
    assert reasons(r, LIFT, RULES) == ("|rho(CL0, CL_KL)| = 0.970 > 0.95",)
    assert reasons(r, LIFT, AdmissibilityRules(max_correlation=0.98)) == ()
    # judged on the datum-free matrix when there is one
    assert reasons(result(correlation=tuple(map(tuple, corr)), centred_correlation=tuple(map(tuple, np.eye(7)))),
                   LIFT, RULES) == ()


def test_alpha_star_outside_the_flown_range():
    why = reasons(result(params={**result().estimates.params, "a_star": 0.35}), LIFT, RULES)
    assert why == ("a_star = 20.1 deg outside the alpha range flown (0.0 to 17.2 deg)",)
    assert reasons(result(params={**result().estimates.params, "a_star": 0.35}), LIFT, AdmissibilityRules()) == ()


def test_negative_kirchhoff_and_lift_slope_terms():
    why = reasons(result(params={**result().estimates.params, "CL_KL": -1.0, "CL_a": -0.1}), LIFT, RULES)
    assert why == ("Kirchhoff term CL_KL = -1 is not positive", "lift-slope term CL_a = -0.1 is not positive")


def test_centre_of_pressure_aft_of_the_cg_envelope():
    # dCm/dCL = Cm_CL + Cm_xcgCL x_cg/cbar: -0.05 and -0.175 over the envelope (stable)
    stable = {"Cm0": 0.05, "Cm_CL": 3.455, "Cm_xcgCL": -1.0}
    assert reasons(result(PITCH, params=stable), PITCH, RULES) == ()
    # forward limit stable, aft limit not: one reason, naming the aft cg
    # (dCm/dCL = -0.5 + 0.14 x_cg/cbar: -0.0093 forward, +0.0082 aft)
    unstable = {"Cm0": 0.05, "Cm_CL": -0.5, "Cm_xcgCL": 0.14}
    why = reasons(result(PITCH, params=unstable), PITCH, RULES)
    assert len(why) == 1 and "not aft of the cg at 7.260 m" in why[0] and "dCm/dCL = 0.0082" in why[0], why
    # no envelope in the campaign: the rule is not applied
    assert reasons(result(PITCH, params=unstable), PITCH, AdmissibilityRules()) == ()


def test_centred_correlation_removes_the_datum_of_x_cg():
    """C_m,K0 and C_m,cg correlate at -1.00 in the thesis because x_cg/cbar ~ 3.5 varies by 1 %; with x_cg
    centred the same model shows what the data can separate, and the fit itself is unchanged."""
    rng = np.random.default_rng(2)
    base = campaign({"quasi-steady": 4}, duration=20.0, seed=3)
    n = base.n_samples
    cl = 0.3 + 0.6 * rng.random(n)
    x_cg = np.repeat(rng.uniform(7.05, 7.12, len(base.starts)), np.diff(np.append(base.starts, n)))
    cm = 0.05 + 3.0 * cl - 0.9 * x_cg / base.constants["cbar"] * cl + 0.002 * rng.standard_normal(n)
    data = FlightData({**base.columns, "CL": cl, "x_cg": x_cg, "Cm": cm}, base.starts, base.names, base.source,
                      base.constants)
    model = StallModel.declare("P", "Cm", dict(PITCH.regressors))
    fit = model.fit(data, covariance="white")
    raw = fit.correlation[1, 2]
    centred = centred_correlation(PITCH, model, data, fit)
    assert abs(raw) > 0.99 and abs(centred[1, 2]) < 0.5, (raw, centred[1, 2])
    # a column whose centring would change the model (CL alone is not a regressor of this one) stays
    lone = Candidate("Q", "g", "Cm", (("Cm_xcgCL", "x_cg/cbar*CL"),))
    lone_model = StallModel.declare("Q", "Cm", dict(lone.regressors))
    assert centred_correlation(lone, lone_model, data, lone_model.fit(data, covariance="white")) is None


def test_ranking_puts_admissible_candidates_first_and_names_the_passed_over():
    better = result(mse=(0.9, 1.8, 2.7), p_values={"tau1": 0.3})
    better = stated_result(**{**better.__dict__, "name": "better"})
    ok = stated_result(**{**result().__dict__, "name": "ok"})
    broken = CandidateResult.failure(name="broken", grid="g", coefficient="CL", lift=None, error="boom", seconds=0)
    ranked = rank([better, ok, broken], lambda s: reasons(s, LIFT, RULES))
    assert [r.name for r in ranked] == ["ok", "better", "broken"]
    assert ranked[0].placement.admissible and not ranked[1].placement.admissible and ranked[1].placement.rank == 2
    assert ranked[1].placement.reasons == ("t-test accepts 0 at 5%: tau1",)
    assert ranked[2].placement.reasons == ("fit failed: boom",) and ranked[2].placement.rank is None
    assert [r.name for r in passed_over(ranked)] == ["better"]
    # JSON round trip keeps the verdict
    again = CandidateResult.from_json(ranked[1].to_json())
    assert again.placement.admissible is False and again.placement.reasons == ranked[1].placement.reasons


# ----- refinement (issue 12 item 3) ---------------------------------------------------------------
from structsearch.grid_search.refinement import refine, structure_key  # noqa: E402


def _fitted(candidate, p_values, corr=None, mse=(1.0, 2.0, 3.0)):
    base = result(candidate, mse=mse)
    names = base.estimates.names
    corr = np.eye(len(names)) if corr is None else corr
    return stated_result(**{**base.__dict__, "name": candidate.name,
                              "p_values": {n: p_values.get(n, 1e-6) for n in names},
                              "correlation": tuple(map(tuple, corr))})


DRAG = Candidate("D-IX", "g", "CD", (("CD0", "1"), ("CD_q", "qstar"), ("CD_CL", "CL"), ("CD_CL2", "CL**2"),
                                     ("CD_1mX", "1 - X")), states=(("", "U"),))


def test_refinement_drops_the_insignificant_then_one_of_a_pair_above_0_8():
    """The thesis' CD-IX -> CD-IXr: an insignificant q*, then the less significant of a pair correlated
    between 0.8 and 0.9 (a pair the 0.9 flag never shows), and the structure reached is the declared one."""
    corr = np.eye(9)
    i, j = 4 + 2, 4 + 3                      # CD_CL, CD_CL2 after the four nonlinear parameters
    corr[i, j] = corr[j, i] = 0.85
    # on the simulated campaign q*, C_L and C_L^2 all accept zero (C_L and C_L^2 correlate at -0.98): q*,
    # which has no correlated partner, goes first although C_L's p-value is larger
    start = _fitted(DRAG, {"CD_q": 0.13, "CD_CL": 0.43, "CD_CL2": 0.49}, corr)
    declared = Candidate("D-IXr", "g", "CD", (("CD0", "1"), ("CD_CL2", "CL**2"), ("CD_1mX", "1 - X")),
                         states=(("", "U"),))
    declared_result = _fitted(declared, {})
    fitted = []
    after_q = np.eye(8)
    after_q[5, 6] = after_q[6, 5] = 0.85     # CD_CL, CD_CL2 once q* is gone

    def fit(c):
        fitted.append(c.name)
        return _fitted(c, {"CD_CL": 0.56, "CD_CL2": 0.30}, after_q)
    done = refine(DRAG, start, fit, {structure_key(declared): (declared, declared_result)})
    assert [c.name for c, _ in done.steps] == ["D-IXr-auto", "D-IXr"] and fitted == ["D-IXr-auto"]
    assert done.reached == ("D-IXr",)


def test_refinement_drops_a_state_with_its_last_regressor():
    """Issue 30: the state the dropped term leaves without a regressor goes with it (before: the refinement
    stopped there)."""
    start = _fitted(DRAG, {"CD_1mX": 0.5})
    fitted = []

    def fit(c):
        fitted.append(c)
        base = result(c)
        return stated_result(**{**base.__dict__, "name": c.name})
    done = refine(DRAG, start, fit)
    ((step, _),) = done.steps[:1]
    assert step.states == () and "CD_1mX" not in dict(step.regressors) and "state(s) X" in step.note


def test_every_kind_of_reason_is_told_from_its_words():
    """The rules about kinds of reasons (hard ones reject a move, fixable ones start a refinement) read the kind
    from the words ``reasons`` writes; a reason of another judge has no kind."""
    from structsearch.grid_search.admissibility import FIXABLE_REASONS, HARD_REASONS, Reason
    words = {"fit failed: singular": Reason.FIT_FAILED,
             "optimizer did not converge (max nfev)": Reason.NOT_CONVERGED,
             "not identifiable: tau1, tau2": Reason.NOT_IDENTIFIABLE,
             "tau2_ss at its upper bound": Reason.AT_BOUND,
             "t-test accepts 0 at 5%: CL_q": Reason.INSIGNIFICANT,
             "|rho(CL0, CL_alpha)| = 0.972 > 0.95": Reason.CORRELATED,
             "a_star = 31.0 deg outside the alpha range flown (-2.0 to 20.0 deg)": Reason.ALPHA_STAR_OUTSIDE,
             "lift-curve term CL_alpha = -0.3 is not positive": Reason.NOT_POSITIVE,
             "centre of pressure at 0.412 m is not aft of the cg at 0.300 m": Reason.CENTRE_OF_PRESSURE}
    assert {Reason.of(w) for w in words} == set(Reason)
    assert all(Reason.of(w) is kind for w, kind in words.items())
    assert Reason.of("a judge's own words") is None
    assert not HARD_REASONS & FIXABLE_REASONS


def test_a_term_without_a_standard_deviation_is_named_so_never_given_a_p_value_above_one():
    from types import SimpleNamespace
    from structsearch.grid_search.refinement import _insignificant_why
    summary = SimpleNamespace(estimates=SimpleNamespace(p_values={"CL_vortex": float("nan"), "CL0": 0.82}))
    assert _insignificant_why(summary, "CL_vortex") == "no standard deviation (p-value not estimable)"
    assert _insignificant_why(summary, "CL0") == "t-test accepts 0, p = 0.82"


def test_a_vortex_lift_below_zero_is_not_admissible():
    """The dynamic-stall vortex adds lift while it lies over the section: a negative vortex lift is a state
    mimicking something else, named as such."""
    from types import SimpleNamespace
    from structsearch.grid_search.admissibility import _physics_reasons
    from structsearch.fitting.candidates import Candidate
    c = Candidate("A-V", "airfoil", "CL", (("CL_KL", "K_L(X)"), ("CL_vortex", "X_vortex")),
                  (("", "L"), ("vortex", "V")))
    rules = SimpleNamespace(cg_range=None, cbar=None)

    def reasons(value):
        return _physics_reasons(SimpleNamespace(estimates=SimpleNamespace(params={"CL_KL": 6.0, "CL_vortex": value})),
                                c, rules)
    assert reasons(0.8) == []
    assert reasons(-2.5) == ["vortex lift term CL_vortex = -2.5 is not positive"]
