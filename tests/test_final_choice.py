"""The structure a search ends with: the best admissible structure it fitted (the ranking's one-standard-error rule),
or the better ones it set aside with the reason; and a stop reason that agrees with the numbers beside it."""
import dataclasses

import pytest
from conftest import stated_result
from test_discovery import _scores

from structsearch.discovery.adoption import DEFAULT_ALPHA, move_test
from structsearch.discovery.final_choice import lower, select_final, set_aside, stopped_text
from structsearch.discovery.moves import Move, structure_key
from structsearch.discovery.search_nodes import Exploration, Node, Status, Step, Stop
from structsearch.fitting.specs import find_candidate


def _result(name, per, n):
    return stated_result(name, "g", "CL", None, 0.0, names=tuple(f"p{i}" for i in range(n)), train=_scores(per),
                         validation=_scores(per), cv=_scores(per), cv_folds=3)


def _node(name, level, n, status, parent=None, reasons=(), screened=False, passed=True):
    """A structure of held-out MSE ``level`` on five maneuvers (a little spread: a standard error to judge by)."""
    per = [level * f for f in (1.0, 1.02, 0.98, 1.01, 0.99)]
    base = find_candidate("CL-VI")   # a structure of its own (what the final choice tells structures apart by)
    candidate = dataclasses.replace(base, name=name, regressors=base.regressors + (("CL_x", f"de*{name!r}"),))
    node = Node(candidate, _result(name, per, n), Move("add", f"add {name}", (name,)) if parent else None,
                parent, parent, None, status, tuple(reasons), 1 if parent else 0, screened)
    if parent is not None:
        test = move_test(parent.result, node.result, DEFAULT_ALPHA, 5)
        if not passed:
            test = type(test)(**{**test.__dict__, "p_value": 0.5})
        node = Node(node.candidate, node.result, node.move, parent, parent, test, status, node.reasons, 1, screened)
    return node


def _search():
    """The reported search: from the intercept, a state is adopted whose fit the t-test and a correlation speak
    against; the elevator alone is admissible and far worse; two states (a child the step did not adopt) are
    admissible and best; one structure was only screened."""
    start = _node("minimal", 1.0, 1, Status.START)
    state = _node("state", 0.10, 4, Status.IMPROVES, start, ("t-test accepts 0 at 5%: CL0", "|rho(a1, a_star)| > 0.95"))
    elevator = _node("elevator", 0.70, 2, Status.REJECTED, start)
    two = _node("two states", 0.05, 7, Status.REJECTED, state, passed=False)
    screened = _node("screened", 0.04, 8, Status.REJECTED, state, screened=True)
    steps = (Step(1, ("minimal",), (state, elevator), (state,), 0.0), Step(2, ("state",), (two, screened), (), 0.0))
    return Exploration(start, start, steps, "", 5, 0.0, Stop.NO_MOVE), [start, state]


def assert_final_choice(ex: Exploration, admissible_first: bool = True, alpha: float = DEFAULT_ALPHA):
    """The property: the final structure is within one standard error of the best admissible structure fitted in
    full (the ranking's rule), and every structure of lower held-out MSE is set aside with a reason and its cost."""
    final = ex.final
    admissible = [n for n in ex.fitted(full=True) if n.admissible]
    if admissible_first and admissible:
        best = min(admissible, key=lambda n: n.mse)
        assert final.admissible
        assert move_test(best.result, final.result, alpha, 1).within_one_se, (final.candidate.name, best.candidate.name)
    better = {structure_key(n.candidate) for n in ex.fitted(full=False) if lower(n.mse, final.mse)}
    listed = [structure_key(a.node.candidate) for a in ex.set_aside]
    assert len(set(listed)) == len(listed) and set(listed) == better - {structure_key(final.candidate)}
    for a in ex.set_aside:
        assert a.reason and a.mse_cost > 0 and a.to_dict()["reason"] == a.reason
    assert [a.node.mse for a in ex.set_aside] == sorted(a.node.mse for a in ex.set_aside)


def assert_stop_agrees(found, max_steps: int):
    """The stop reason says "at the floor" only where the final structure is; a budget only where it was spent; a
    step that kept nothing otherwise."""
    ex = found.exploration
    if "floor" in found.stopped and "above the floor" not in found.stopped:
        assert found.explained, found.stopped
    if ex.stop == Stop.MAX_STEPS:
        assert len(ex.steps) >= max_steps
    elif ex.stop in (Stop.NO_MOVE, Stop.LOOK_AHEAD_LED_NOWHERE, Stop.OWN_FLOOR):
        assert any(not s.beam and s.expanded == ex.stopped_at for s in ex.steps)


def test_a_discovery_ends_on_the_best_admissible_structure_fitted_whatever_its_verdict_in_the_steps():
    ex, confirmed = _search()
    fitted = ex.fitted(full=True)
    final, rule = select_final(fitted, confirmed, admissible_first=True)
    assert final.candidate.name == "two states" and final.result.validation.mse == pytest.approx(0.05)
    assert "every admissible structure fitted" in rule
    aside = set_aside(final, ex.fitted(full=False), confirmed, DEFAULT_ALPHA, True)
    assert [a.node.screened for a in aside] == [True] and "screened only" in aside[0].reason
    assert_final_choice(Exploration(ex.start, final, ex.steps, "", 5, 0.0, Stop.NO_MOVE, aside, rule))


def test_a_better_structure_that_is_not_admissible_is_set_aside_with_its_reasons_and_cost():
    ex, confirmed = _search()
    steps = (ex.steps[0],)   # the two states never fitted: the elevator is the best admissible structure
    fitted = [ex.start, *steps[0].tried]
    final, _ = select_final(fitted, confirmed, admissible_first=True)
    assert final.result.validation.mse == pytest.approx(0.70)
    aside = set_aside(final, fitted, confirmed, DEFAULT_ALPHA, True)
    assert len(aside) == 1 and aside[0].reason.startswith("not admissible: t-test accepts 0 at 5%: CL0")
    assert aside[0].mse_cost == pytest.approx(0.60) and aside[0].excess > 5
    doc = aside[0].to_dict()
    assert doc["admissible"] is False and doc["reasons"] == list(aside[0].node.reasons) and doc["status"] == "improves"


def test_a_diagnosis_ends_on_an_adopted_structure_and_says_why_a_better_one_was_not():
    ex, confirmed = _search()
    fitted = ex.fitted(full=True)
    final, rule = select_final(fitted, confirmed, admissible_first=False)
    assert final is confirmed[1] and "adopted" in rule     # the state: adopted, though not admissible
    aside = set_aside(final, ex.fitted(full=False), confirmed, DEFAULT_ALPHA, False)
    reasons = {round(a.node.result.validation.mse, 6): a.reason for a in aside}
    assert reasons[0.05].startswith("not adopted: its test did not pass (p 0.5")
    assert reasons[0.04].startswith("screened only")
    assert_final_choice(Exploration(ex.start, final, ex.steps, "", 5, 0.0, Stop.NO_MOVE, aside, rule),
                        admissible_first=False)


@pytest.mark.parametrize("stop", list(Stop))
def test_the_stop_reason_names_the_floor_only_where_the_final_structure_is_at_it(stop):
    above = stopped_text(stop, False, "CL-minimal + X_ss", 20)
    at = stopped_text(stop, True, "CL-minimal + X_ss", 20)
    assert "at the floor of its own residual" not in above
    if stop == Stop.OWN_FLOOR:
        assert "at the floor of its own residual" in at and "above the floor" in above and "CL-minimal + X_ss" in above
    if stop == Stop.MAX_STEPS:
        assert "20 steps" in above and above == at


# ----- on searches run on campaigns other than the default one ----------------------------------------------

# other seeds, a truth with an effect withheld, the transport, few maneuvers: name -> build_campaign's options
CAMPAIGNS = {
    "seed 3": dict(seed=3, scale=0.1),
    "few maneuvers": dict(seed=11, scale=0.05),
    "one lift state withheld": dict(seed=1, scale=0.1, withhold=("second_separation_state",)),
    "transport": dict(seed=5, scale=0.1, aircraft="transport"),
    "seed 3, 15 maneuvers": dict(seed=3, scale=0.3),   # one that reaches the floor: the stop reason says so
}
MAX_STEPS = 8


@pytest.mark.slow
@pytest.mark.parametrize("name", list(CAMPAIGNS))
def test_discover_from_the_intercept_ends_on_the_best_admissible_structure_it_fitted(name, simulated_campaign,
                                                                                     tmp_path):
    from structsearch.api import Settings, discover
    found = discover(simulated_campaign(**CAMPAIGNS[name]), "CL", settings=Settings(jobs=1, cache=tmp_path),
                     max_steps=MAX_STEPS)
    assert_final_choice(found.exploration)
    assert_stop_agrees(found, MAX_STEPS)
    doc = found.to_dict()
    assert [a["name"] for a in doc["set_aside"]] == [a.node.candidate.name for a in found.exploration.set_aside]
    assert doc["final"]["name"] == found.exploration.final.candidate.name
    # the truth (the thesis' final lift model on the Citation's full truth), where the data make it admissible:
    # the discovered structure is not worse than it beyond one standard error
    truth = next(c for c in found.comparison if c.role == "thesis final")
    if name in ("seed 3", "few maneuvers", "seed 3, 15 maneuvers") and truth.admissible:
        assert truth.within_noise, (found.final.name, truth.excess, truth.excess_se)
