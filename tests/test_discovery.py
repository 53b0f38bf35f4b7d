"""The structure search of issue 28: term library, moves, adoption test, spec files, the beam search."""
import dataclasses

import numpy as np
import pytest
from conftest import fitter_for, stated_result
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from structsearch.data.errors import DeclarationError
from structsearch.discovery.adoption import DEFAULT_ALPHA, move_test
from structsearch.discovery.moves import MOVE_KINDS, generate, structure_key
from structsearch.discovery.spec_file import spec_text
from structsearch.discovery.terms import (TermLibrary, library_for, normalise, read_terms, shipped_terms,
                                          uses_state)
from structsearch.engine.scores import R2Summary
from structsearch.fitting.candidate_result import CandidateResult, SplitScores
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.specs import find_candidate, resolve_candidate

FINALS = {"CL": "CL-VI", "CD": "CD-IXr", "Cm": "Cm-XXXIIIr"}
LIFTS = ("CL-I", "CL-VI")


def _library(coefficient: str) -> TermLibrary:
    return TermLibrary(coefficient, tuple(shipped_terms(coefficient)))


# ----- terms ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("coefficient", sorted(FINALS))
def test_shipped_terms_hold_every_regressor_of_the_final_models(coefficient):
    final = find_candidate(FINALS[coefficient])
    library = _library(coefficient)
    # instantiated on the final model's own states, the templates give back each of its regressors
    offered = {normalise(e) for _, e in library.instances(tuple(s for s, _ in final.states))}
    missing = [e for _, e in final.regressors if normalise(e) not in offered]
    assert not missing, missing
    # a template per expression: no duplicate templates, and no two templates share a name
    assert len({normalise(t.expression) for t in library.terms}) == len(library.terms)
    assert len({t.name for t in library.terms}) == len(library.terms)


def test_shipped_terms_of_an_unknown_coefficient():
    with pytest.raises(DeclarationError, match="no term library for coefficient 'CZ'"):
        shipped_terms("CZ")


def test_the_lateral_coefficients_have_a_term_library_from_their_grids():
    """The rolling moment's library holds its grid's terms: the classical derivatives, the rate made
    dimensionless with the half span, and the roll damping lost with separation."""
    expressions = {t.expression for t in shipped_terms("Cl")}
    assert {"beta", "pstar", "rstar", "da", "dr", "CL"} <= expressions
    assert any("pstar" in e and "X" in e for e in expressions)


def _write(tmp_path, text, name="terms.toml"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_read_terms_templates_a_user_file(tmp_path):
    path = _write(tmp_path, 'coefficient = "CD"\n[terms]\nCD_alpha3 = "alpha**3"\nCD_KD = "K_D(X)"\n'
                            'CD_Xde_w = "X_w*de"\n')
    terms = read_terms(path, "CD")
    assert [(t.name, t.expression, t.per_state) for t in terms] == [
        ("CD_alpha3", "alpha**3", False), ("CD_KD{s}", "K_D({X})", True), ("CD_Xde{s}", "{X}*de", True)]
    assert all(t.source == str(path) for t in terms)
    # X stands for each state of the candidate in turn
    assert terms[1].instances(("ss", "w")) == [("CD_KD_ss", "K_D(X_ss)"), ("CD_KD_w", "K_D(X_w)")]
    assert terms[1].instances(("",)) == [("CD_KD", "K_D(X)")]


@pytest.mark.parametrize("text,term,match", [
    ("[terms\nCD_a = 'alpha'\n", None, "not valid TOML"),
    ('coefficient = "CD"\n', None, r"no \[terms\] table"),
    ("[terms]\n", None, r"no \[terms\] table"),
    ('[terms]\nCD_empty = "  "\n', "CD_empty", "non-empty string"),
    ("[terms]\nCD_number = 3\n", "CD_number", "non-empty string"),
    ('[terms]\n"CD bad name" = "alpha"\n', "CD bad name", "letters, digits and underscores"),
    ('[terms]\nCD_broken = "alpha +* (de"\n', "CD_broken", "cannot parse"),
    ('[terms]\nCD_two = "X_ss*X_w"\n', "CD_two", "one separation state per term"),
])
def test_read_terms_errors_name_the_file_and_the_term(tmp_path, text, term, match):
    path = _write(tmp_path, text)
    with pytest.raises(DeclarationError, match=match) as caught:
        read_terms(path, "CD")
    message = str(caught.value)
    assert str(path) in message
    if term is not None:
        assert repr(term) in message


def test_read_terms_of_another_coefficient(tmp_path):
    path = _write(tmp_path, 'coefficient = "CL"\n[terms]\nCL_alpha3 = "alpha**3"\n')
    with pytest.raises(DeclarationError, match="the terms are for CL, not CD") as caught:
        read_terms(path, "CD")
    assert str(path) in str(caught.value)
    assert [t.name for t in read_terms(path, "CL")] == ["CL_alpha3"]


def test_read_terms_missing_file(tmp_path):
    with pytest.raises(DeclarationError, match="not found"):
        read_terms(tmp_path / "absent.toml", "CD")


_NAMES = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,10}", fullmatch=True).filter(lambda n: n != "coefficient")
_ATOMS = st.sampled_from(["alpha", "de", "CT", "qstar", "V", "CL", "1", "2.5", "X", "K_L(X)", "max_half(X)"])


@st.composite
def _expressions(draw):
    """A valid expression over campaign columns, helpers and at most one separation state."""
    parts = draw(st.lists(_ATOMS, min_size=1, max_size=4))
    ops = draw(st.lists(st.sampled_from([" + ", " - ", "*", "/"]), min_size=len(parts) - 1,
                        max_size=len(parts) - 1))
    text = parts[0] + "".join(o + p for o, p in zip(ops, parts[1:]))
    return text.replace("/0", "/2")


@settings(derandomize=True, max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=st.dictionaries(_NAMES, _expressions(), min_size=1, max_size=5),
       state=st.sampled_from(["", "ss", "w"]))
def test_read_terms_round_trips_random_tables(tmp_path, table, state):
    import json
    symbol = f"X_{state}" if state else "X"
    table = {n: e.replace("X", symbol) for n, e in table.items()}
    path = _write(tmp_path, "[terms]\n" + "".join(f"{json.dumps(n)} = {json.dumps(e)}\n" for n, e in table.items()))
    terms = read_terms(path, "CD")
    assert len(terms) == len(table)
    for t, (name, expr) in zip(terms, table.items()):
        assert t.per_state == ("X" in expr)
        # the template instantiated on the term's own state gives back what the user wrote (the name too,
        # unless a state's name had to be appended to it)
        ((got_name, got_expr),) = t.instances((state,))
        assert got_expr == expr
        if not t.per_state or not state or f"_{state}" in name:
            assert got_name == name


_GARBAGE = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=60)
_GARBAGE_EXPRESSION = st.text(alphabet="aXde_LK()[]{}+-/,.'\"0123456789 =:#\\", max_size=20)


@settings(derandomize=True, max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=_GARBAGE, expression=_GARBAGE_EXPRESSION, name=st.text(max_size=8), raw=st.binary(max_size=40))
def test_read_terms_on_garbage_raises_only_declaration_errors(tmp_path, text, expression, name, raw):
    import json
    path = tmp_path / "raw.toml"
    path.write_bytes(b"[terms]\nCD_x = \"" + raw + b"\"\n")
    try:
        read_terms(path, "CD")
    except DeclarationError as exc:
        assert str(path) in str(exc)
    for doc in (text, f"[terms]\n{json.dumps(name)} = {json.dumps(expression)}\n",
                f"coefficient = {json.dumps(name)}\n[terms]\nCD_x = {json.dumps(expression)}\n"):
        path = _write(tmp_path, doc)
        try:
            terms = read_terms(path, "CD")
        except DeclarationError as exc:
            assert str(path) in str(exc)
        else:
            assert terms and all(t.name for t in terms)


def test_library_for_sets_aside_shipped_terms_and_refuses_a_users_term_on_a_missing_column(tmp_path,
                                                                                          small_campaign):
    # the campaign without its centre-of-gravity column (a campaign that never logged it)
    data = dataclasses.replace(small_campaign, columns={k: v for k, v in small_campaign.columns.items()
                                                        if k != "x_cg"})
    assert "x_cg" not in data and "x_cg" not in data.constants
    assert not library_for("Cm", small_campaign).set_aside
    # C_L in a drag or pitch term is the lift model's output: kept on a campaign that does not log it
    assert "CL" not in small_campaign and "CL**2" in {t.expression for t in library_for("CD", data).terms}
    pitch = library_for("Cm", data)
    # the shipped centre-of-gravity term needs x_cg: set aside with the reason, the rest kept
    assert dict(pitch.set_aside) == {"Cm_xcgCL": "the campaign has no column x_cg"}
    assert "x_cg/cbar*CL" not in {t.expression for t in pitch.terms} and len(pitch.terms) > 5
    # a user's term on a column the campaign lacks is an error naming the file and the term
    path = _write(tmp_path, '[terms]\nCD_ok = "alpha**3"\nCD_flap = "flap_angle*alpha"\n')
    with pytest.raises(DeclarationError, match="'CD_flap' reads flap_angle") as caught:
        library_for("CD", data, path)
    assert str(path) in str(caught.value)
    # the user's terms join the shipped ones, a known expression only once
    path = _write(tmp_path, '[terms]\nCD_alpha3 = "alpha**3"\nCD_mine = "CL**2"\n')
    library = library_for("CD", data, path)
    assert [t.name for t in library.terms if t.source == str(path)] == ["CD_alpha3"]
    assert library.to_dict()["terms"]["CD_alpha3"] == "alpha**3"


# ----- moves ------------------------------------------------------------------------------------------

def _lifts():
    return {n: find_candidate(n) for n in LIFTS}


@pytest.mark.parametrize("name", ["CL-I", "CD-I", "Cm-I", "CL-VI"])
def test_every_generated_child_is_a_valid_new_structure(name):
    parent = find_candidate(name)
    moves = generate(parent, _library(parent.coefficient), _lifts())
    assert moves and {m.kind for m, _ in moves} <= set(MOVE_KINDS)
    keys = [structure_key(c) for _, c in moves]
    assert len(set(keys)) == len(keys)           # one move per child structure
    assert structure_key(parent) not in keys     # every move changes the structure
    for move, child in moves:
        assert child.coefficient == parent.coefficient and child.regressors, move
        names = [n for n, _ in child.regressors]
        exprs = [normalise(e) for _, e in child.regressors]
        assert len(set(names)) == len(names) and len(set(exprs)) == len(exprs), move
        if child.lift is None:
            # a candidate's own state without a regressor is never generated
            for s, _ in child.states:
                assert uses_state(child, f"X_{s}" if s else "X"), (move, child)
        else:
            assert child.states == _lifts()[child.lift].states, move
        # the parameters a nested move names are the child's
        child_params = set(names) | set(child.state_parameters)
        assert set(move.new_parameters) <= child_params, move


def test_generated_kinds_per_structure():
    kinds = {n: {m.kind for m, _ in generate(find_candidate(n), _library(find_candidate(n).coefficient), _lifts())}
             for n in ("CL-I", "CD-I", "CL-VI")}
    # drag is fed its lift model's states: no state moves, but another lift model
    assert "lift" in kinds["CD-I"] and not kinds["CD-I"] & {"state kind", "add state", "remove state"}
    assert {"state kind", "remove state", "add state"} <= kinds["CL-VI"] and "lift" not in kinds["CL-VI"]
    only = generate(find_candidate("CD-I"), _library("CD"), _lifts(), kinds=("drop",))
    assert only and {m.kind for m, _ in only} == {"drop"}
    with pytest.raises(DeclarationError, match="term library is for CL"):
        generate(find_candidate("CD-I"), _library("CL"), _lifts())


def _move_to(parent, expression, **kw):
    moves = generate(parent, _library(parent.coefficient), _lifts(), **kw)
    return [(m, c) for m, c in moves if expression in {e for _, e in c.regressors} - {e for _, e in parent.regressors}]


def test_a_term_is_replaced_by_a_modulated_pair_of_library_terms():
    """The centre-of-pressure model replaces Cm_alpha by C_L and x_cg C_L together (either alone fits worse than
    alpha): a replacement by two terms A and A*s, s a signal. Two unrelated signals are not such a pair."""
    from structsearch.discovery.moves import modulated_pairs
    cm = find_candidate("Cm-I")
    moves = {m.label: c for m, c in generate(cm, _library("Cm"), _lifts())}
    child = moves["replace Cm_alpha by Cm_CL = CL and Cm_xcgCL = x_cg/cbar*CL"]
    assert "Cm_alpha" not in dict(child.regressors)
    assert dict(child.regressors)["Cm_CL"] == "CL" and dict(child.regressors)["Cm_xcgCL"] == "x_cg/cbar*CL"
    pairs = {(a[1], b[1]) for a, b in modulated_pairs(tuple(_library("Cm").instances(("ss", "w"))))}
    assert ("CL", "x_cg/cbar*CL") in pairs and ("1 - X_w", "(1 - X_w)*CL") in pairs
    assert ("qstar", "de") not in pairs and ("de", "Xde") not in pairs        # two signals; a state's ratio
    assert not any(b == "max_half(X_ss)*de" for _, b in pairs)              # de * a state is not a modulation
    assert ("CL", "CL**2") in {(a[1], b[1]) for a, b in modulated_pairs(tuple(_library("CD").instances(("ss",))))}


def test_an_add_that_equals_a_library_effect_carries_its_name():
    cd = find_candidate("CD-I")
    ((move, child),) = [(m, c) for m, c in _move_to(cd, "CL**2") if m.kind == "add"]
    assert move.effect == "induced_drag" and move.name == "induced_drag"
    assert move.new_parameters == ("CD_CL2",)
    assert dict(child.regressors) == dict(cd.regressors) | {"CD_CL2": "CL**2"}
    # a term the library does not know as an effect carries none
    ((alpha2, _),) = [(m, c) for m, c in _move_to(cd, "alpha**2") if m.kind == "add"]
    assert alpha2.effect is None and alpha2.name == alpha2.label


def test_the_lift_move_rewrites_terms_on_a_state_for_every_state_of_the_new_lift_model():
    cd = find_candidate("CD-I")
    ((move, child),) = [(m, c) for m, c in generate(cd, _library("CD"), _lifts()) if m.kind == "lift"]
    assert move.label == "lift CL-I -> CL-VI" and child.lift == "CL-VI"
    exprs = [e for _, e in child.regressors]
    assert "1 - X_ss" in exprs and "1 - X_w" in exprs and "1 - X" not in exprs
    # the terms without a state are kept as they were
    assert [r for r in child.regressors if "X" not in r[1]] == [r for r in cd.regressors if "X" not in r[1]]
    assert child.states == find_candidate("CL-VI").states and child.bounds == find_candidate("CL-VI").bounds
    # pitch: max_half(X)*de becomes one term per state
    cm = find_candidate("Cm-I")
    ((_, child),) = [(m, c) for m, c in generate(cm, _library("Cm"), _lifts()) if m.kind == "lift"]
    assert {"max_half(X_ss)*de", "max_half(X_w)*de"} <= {e for _, e in child.regressors}


def test_a_state_kind_move_names_the_time_constant_it_adds():
    cl = find_candidate("CL-VI")   # X_ss unsteady, X_w steady
    by_label = {m.label: (m, c) for m, c in generate(cl, _library("CL")) if m.kind == "state kind"}
    assert set(by_label) == {"X_ss: U -> Q", "X_w: S -> Q"}
    move, child = by_label["X_w: S -> Q"]
    assert move.new_parameters == ("tau2_w",) and dict(child.states) == {"ss": "U", "w": "Q"}
    assert move.effect == "separation_delay"   # the effect library's name for it
    # without the effect library among the kinds the move keeps the effect's name (the benchmark scores on it)
    ((alone, _),) = [(m, c) for m, c in generate(cl, _library("CL"), kinds=("state kind",))
                     if m.label == "X_w: S -> Q"]
    assert alone.effect == "separation_delay" and alone.new_parameters == ("tau2_w",)
    # and the effect moves themselves are not generated then
    assert not [m for m, _ in generate(cl, _library("CL"), kinds=("state kind",)) if m.kind == "effect"]
    # to a simpler kind: nothing is added, the move is not nested
    move, child = by_label["X_ss: U -> Q"]
    assert move.new_parameters == () and dict(child.states) == {"ss": "Q", "w": "S"}


def test_removing_a_state_drops_its_terms_and_box():
    cl = find_candidate("CL-VI")
    moves = {m.label: c for m, c in generate(cl, _library("CL"), kinds=("remove state",))}
    child = moves["remove state X_w"]
    assert dict(child.states) == {"ss": "U"} and "K_L(X_w)" not in {e for _, e in child.regressors}
    assert dict(child.bounds) == {"a_star_ss": (0.05, 0.27)}
    # the only state of CL-I carries the term on it: removing it leaves no state, and the child stays valid
    (one,) = [c for m, c in generate(find_candidate("CL-I"), _library("CL"), kinds=("remove state",))]
    assert one.states == () and all("X" not in e for _, e in one.regressors)


# ----- adoption ---------------------------------------------------------------------------------------

def _scores(per, counts=None):
    per = tuple(float(x) for x in per)
    counts = tuple(counts or (100,) * len(per))
    return SplitScores(float(np.average(per, weights=counts)), per, counts, R2Summary(0.9, 0.8, 1.0))


def _result(name, validation, cv=None, n=3):
    return stated_result(name, "g", "CD", None, 0.0, names=tuple(f"p{i}" for i in range(n)),
                           train=_scores(validation if cv is None else cv), validation=_scores(validation),
                           cv=_scores(cv) if cv is not None else None, cv_folds=3 if cv is not None else 0)


PARENT_VAL = [1.0, 2.0, 1.5, 3.0, 2.5]
PARENT_CV = [1.2, 0.8, 2.2, 1.7, 2.9]


def test_identical_structures_never_improve():
    parent = _result("parent", PARENT_VAL, PARENT_CV)
    same = _result("child", PARENT_VAL, PARENT_CV, n=4)
    t = move_test(parent, same, DEFAULT_ALPHA, 5)
    assert t.gain == 0.0 and not t.improves and t.within_one_se
    assert np.isnan(t.p_value) and t.reason    # no spread: no p-value, and why
    # a child a little worse on some maneuvers and the same elsewhere: p >= 0.5, never an improvement
    worse = _result("child", [x * 1.01 for x in PARENT_VAL], [x * (1.02 if i % 2 else 1.0) for i, x in
                                                                 enumerate(PARENT_CV)])
    t = move_test(parent, worse, DEFAULT_ALPHA, 1)
    assert t.gain < 0 and t.p_value >= 0.5 and not t.improves
    assert t.basis == "cv+validation" and t.n_maneuvers == 10


def test_a_uniform_gain_improves():
    rng = np.random.default_rng(3)
    parent_val = rng.uniform(1, 3, 5)
    parent_cv = rng.uniform(1, 3, 5)
    ratio = 0.8 + rng.normal(0, 0.01, 10)    # 20 % better on every maneuver, small spread
    child = _result("child", parent_val * ratio[5:], parent_cv * ratio[:5], n=4)
    t = move_test(_result("parent", parent_val, parent_cv), child, DEFAULT_ALPHA, 30)
    assert t.improves and t.p_value < 1e-8 and t.threshold == pytest.approx(DEFAULT_ALPHA / 30)
    assert t.gain == pytest.approx(0.2, abs=0.01) and 0 < t.gain_se < 0.01
    assert t.to_dict()["kind"] == "paired" and t.to_dict()["p_value"] == t.p_value
    # the child's gain counted against the parent: the parent against the child loses
    assert not move_test(child, _result("parent", parent_val, parent_cv), DEFAULT_ALPHA, 1).improves


def test_too_few_maneuvers_give_no_p_value():
    parent = _result("parent", [1.0, 2.0])
    child = _result("child", [0.5, 1.1])
    t = move_test(parent, child, DEFAULT_ALPHA, 1)
    assert t.n_maneuvers == 2 and np.isnan(t.p_value) and np.isnan(t.gain_se)
    assert "2 maneuvers" in t.reason and not t.improves
    assert t.to_dict()["p_value"] is None and t.to_dict()["reason"]


def test_bonferroni_over_the_moves_of_a_step():
    parent = _result("parent", [1.0] * 6, [1.0] * 6)
    gains = np.array([0.10, -0.04, 0.12, 0.02, 0.08, -0.02, 0.09, 0.01, 0.05, 0.07, 0.11, 0.03])
    child = _result("child", 1 - gains[6:], 1 - gains[:6])
    one = move_test(parent, child, DEFAULT_ALPHA, 1)
    many = move_test(parent, child, DEFAULT_ALPHA, 40)
    assert one.p_value == many.p_value and DEFAULT_ALPHA / 40 < one.p_value < DEFAULT_ALPHA
    assert one.threshold == DEFAULT_ALPHA and many.threshold == pytest.approx(DEFAULT_ALPHA / 40)
    assert one.improves and not many.improves
    # a failed fit: no test, and why
    failed = CandidateResult.failure(name="f", grid="g", coefficient="CD", lift=None, error="boom", seconds=0.0)
    t = move_test(parent, failed, DEFAULT_ALPHA, 4)
    assert np.isnan(t.p_value) and t.reason == "a fit failed" and not t.improves


def test_a_nested_move_needs_its_wald_test_and_a_lower_pooled_mse_not_a_positive_relative_gain():
    # four small maneuvers a little worse, one large one much better: the mean relative gain is negative, the
    # pooled held-out MSE (what the search compares) falls by 30 %
    parent = _result("parent", [1.0, 1.0, 1.0, 1.0, 10.0])
    child = _result("child", [1.2, 1.2, 1.2, 1.2, 5.0], n=4)
    t = move_test(parent, child, DEFAULT_ALPHA, 1)
    assert t.gain == pytest.approx(-0.06) and t.pooled_gain == pytest.approx(1 - 9.8 / 14)
    assert t.kind == "paired" and not t.improves        # a non-nested move: the relative gain decides
    wald = dataclasses.replace(t, wald_p_value=1e-6)
    assert wald.kind == "wald" and wald.improves          # nested: its Wald test and the pooled gain
    assert not dataclasses.replace(wald, wald_p_value=0.5).improves
    # a nested move that predicts worse pooled is never adopted, however small its Wald p-value
    worse = move_test(parent, _result("child", [0.5, 0.5, 0.5, 0.5, 13.0], n=4), DEFAULT_ALPHA, 1)
    assert worse.gain > 0 and worse.pooled_gain < 0
    assert not dataclasses.replace(worse, wald_p_value=1e-9).improves
    assert wald.to_dict()["pooled_gain"] == pytest.approx(0.3)


def _node(name, validation, cv, n, reasons=(), move=None, parent=None, status="improves", test=None):
    from structsearch.discovery.explore import Node
    return Node(find_candidate("CD-I"), _result(name, validation, cv, n=n), move=move, parent=parent,
                anchor=parent, reasons=tuple(reasons), status=status, test=test)


def test_choose_prefers_admissible_structures_when_asked_and_then_the_fewest_parameters_within_one_se():
    from structsearch.discovery.explore import choose
    best = _node("best", [1.0] * 5, [1.0] * 5, 6, reasons=("t-test accepts 0 at 5%: p5",))
    near = _node("near", [1.001] * 4 + [1.002], [1.0] * 5, 4)
    worse = _node("worse", [1.5] * 5, [1.6] * 5, 3)
    assert choose([best, near, worse]) is near                      # fewest parameters within one SE
    assert choose([best, worse]) is best
    assert choose([best, worse], admissible_first=True) is worse    # the ranking: admissible ones first
    assert choose([best], admissible_first=True) is best            # none admissible: the best still


def test_a_library_effect_within_one_se_of_the_best_passing_move_is_adopted_in_its_place():
    from structsearch.discovery.explore import _nested_first
    from structsearch.discovery.moves import Move
    start = _node("start", [1.0] * 5, [1.0] * 5, 3, status="start")
    term = Move("add", "add CL_Xde_w = X_w*de", ("CL_Xde_w",))
    effect = Move("effect", "elevator", ("CL_de",), effect="elevator")
    best = _node("best", [0.90] * 4 + [0.91], [0.9] * 5, 4, move=term, parent=start)
    best = dataclasses.replace(best, test=move_test(start.result, best.result, DEFAULT_ALPHA, 2))
    peer = _node("peer", [0.905] * 4 + [0.9], [0.9] * 5, 4, move=effect, parent=start, status="rejected")
    peer = dataclasses.replace(peer, test=dataclasses.replace(move_test(start.result, peer.result, DEFAULT_ALPHA, 2),
                                                              wald_p_value=0.2))
    assert not peer.test.improves
    first, *rest = _nested_first([best], [best, peer], DEFAULT_ALPHA)
    assert first.candidate is peer.candidate and first.status == "improves" and rest == [best]
    assert first.test.stands_for == best.move.name and first.test.to_dict()["stands_for"] == best.move.name
    # nothing passes: nothing is adopted, whatever the effect's standing
    assert _nested_first([], [peer], DEFAULT_ALPHA) == []
    # an effect that does not lower the validation MSE does not stand for the best
    worse = dataclasses.replace(peer, result=_result("peer", [1.01] * 5, [0.9] * 5, n=4))
    assert _nested_first([best], [best, worse], DEFAULT_ALPHA)[0] is best


def test_of_two_library_effects_the_data_cannot_tell_apart_the_one_with_fewer_parameters_is_adopted():
    from structsearch.discovery.explore import _nested_first
    from structsearch.discovery.moves import Move
    start = _node("start", [1.0] * 5, [1.0] * 5, 3, status="start")
    wide = Move("effect", "elevator_effectiveness_loss", ("CL_Xde_ss", "CL_Xde_w"),
                effect="elevator_effectiveness_loss")
    narrow = Move("effect", "elevator", ("CL_de",), effect="elevator")
    best = _node("best", [0.90] * 4 + [0.91], [0.9] * 5, 5, move=wide, parent=start)
    best = dataclasses.replace(best, test=move_test(start.result, best.result, DEFAULT_ALPHA, 2))
    near = _node("near", [0.902] * 4 + [0.908], [0.9] * 5, 4, move=narrow, parent=start)
    near = dataclasses.replace(near, test=move_test(start.result, near.result, DEFAULT_ALPHA, 2))
    assert best.mse <= near.mse and move_test(best.result, near.result, DEFAULT_ALPHA, 1).within_one_se
    first, *rest = _nested_first([best, near], [best, near], DEFAULT_ALPHA)
    assert first.candidate is near.candidate and rest == [best]
    # not within one standard error of the best: the best is adopted, however many parameters it adds
    far = dataclasses.replace(near, result=_result("far", [0.99] * 5, [0.99] * 5, n=4))
    assert not move_test(best.result, far.result, DEFAULT_ALPHA, 1).within_one_se
    assert _nested_first([best, far], [best, far], DEFAULT_ALPHA)[0] is best


def test_a_move_that_adds_a_separation_state_is_judged_out_of_sample_not_by_its_wald_test(monkeypatch):
    # with the new state's K term at zero its a1 and a_star are not identified (Davies' problem): the Wald test's
    # reference fails, so its tiny p-value must not adopt the move; an added term on the same states is nested
    import structsearch.discovery.explore as ex
    from structsearch.discovery.moves import Move
    seen = {}

    def spy(parent, child, alpha, n_moves, new_parameters=(), statistics=True):
        seen["nested"] = tuple(new_parameters)
        return move_test(parent, child, alpha, n_moves)
    monkeypatch.setattr(ex, "move_test", spy)
    one = dataclasses.replace(find_candidate("CL-II"), name="one state")
    two = dataclasses.replace(one, name="two states", states=one.states + (("w2", "S"),),
                              regressors=one.regressors + (("CL_KL_w2", "K_L(X_w2)"),))
    assert ex.adds_state(one, two) and not ex.adds_state(two, one) and not ex.adds_state(one, one)
    parent = dataclasses.replace(_node("parent", [1.0] * 5, [1.0] * 5, 3, status="start"), candidate=one)
    state = Move("add state", "add state X_w2", ("a1_w2", "a_star_w2", "CL_KL_w2"))
    child = dataclasses.replace(_node("child", [0.9] * 5, [0.9] * 5, 6, move=state, parent=parent), candidate=two)
    ex._verdict(child, parent, 3, DEFAULT_ALPHA)
    assert seen["nested"] == ()
    term = Move("add", "add CL_de = de", ("CL_de",))
    plus = dataclasses.replace(one, regressors=one.regressors + (("CL_de", "de"),))
    child = dataclasses.replace(_node("child", [0.9] * 5, [0.9] * 5, 4, move=term, parent=parent), candidate=plus)
    ex._verdict(child, parent, 3, DEFAULT_ALPHA)
    assert seen["nested"] == ("CL_de",)


def test_no_look_ahead_from_a_structure_at_the_floor_of_its_own_residual(monkeypatch, tmp_path):
    # every replacement predicts a little better without passing its test: a look-ahead, unless the structure's
    # own residual holds nothing a library-free model predicts (then no pair of moves can pay)
    import structsearch.discovery.explore as ex
    start = find_candidate("CD-IXr")

    def fake_fits(candidates, *args, **kw):
        return [_result(c.name, [1.0] * 5, [1.0] * 5, n=len(c.regressors)) if c is start else
                _result(c.name, [0.99, 1.0, 0.98, 1.01, 0.995], [0.99, 1.0, 0.98, 1.01, 0.995], n=len(c.regressors))
                for c in candidates]
    from types import SimpleNamespace

    from conftest import fitter_for
    from structsearch.fitting.fitter import Fitter
    monkeypatch.setattr(Fitter, "fit", lambda self, candidates, donors=(): fake_fits(candidates))
    lifts = {"CL-VI": SimpleNamespace(candidate=find_candidate("CL-VI"))}
    run = dict(fitter=fitter_for(None, tmp_path, lifts=lifts), library=_library("CD"), beam=1,
               max_steps=2, kinds=("replace",), simplify=False)
    free = ex.explore(start, **run)
    assert [n.status for n in free.steps[0].beam] == ["look-ahead"] and len(free.steps) == 2
    assert free.stop == ex.Stop.LOOK_AHEAD_LED_NOWHERE and "floor" not in free.stopped
    asked = []
    gated = ex.explore(start, **run, at_floor=lambda n: asked.append(n.candidate.name) or True)
    assert len(gated.steps) == 1 and not gated.steps[0].beam and asked == [start.name]
    # the gate is the stop's reason only where it decided: look-aheads there were, and it closed them
    assert gated.stop == ex.Stop.OWN_FLOOR and "at the floor of its own residual" in gated.stopped
    ungated = ex.explore(start, **{**run, "max_steps": 1}, at_floor=lambda n: False)
    assert ungated.steps[0].beam[0].status == "look-ahead"
    assert ungated.stop == ex.Stop.MAX_STEPS and "floor" not in ungated.stopped   # one step, taken: the budget


def test_a_fit_without_folds_is_compared_on_validation_only():
    parent = _result("parent", [1.0, 2.0, 3.0, 2.0], PARENT_CV)
    child = _result("child", [0.8, 1.6, 2.5, 1.5])    # no cross-validation
    t = move_test(parent, child, DEFAULT_ALPHA, 1)
    assert t.basis == "validation" and t.n_maneuvers == 4


# ----- spec files -------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["CL-I", "CL-VI", "CD-I", "CD-IXr", "Cm-XXXIIIr", "hand-made"])
def test_spec_text_round_trips(tmp_path, name):
    if name == "hand-made":
        c = Candidate('CL-I + add "q" \\ [x] = 1', "discover", "CL",
                      (("CL0", "1"), ("CL_KL", "K_L(X)"), ("CL_qstar", "qstar")), (("", "Q"),), None,
                      'with "quotes", a backslash \\ and\na new line', (("a_star", (0.05, 0.3)),))
    else:
        c = find_candidate(name)
    path = tmp_path / "spec.toml"
    path.write_text(spec_text(c, note='found "here"'), encoding="utf-8")
    back = resolve_candidate(str(path), c.coefficient)
    assert back == c
    # the drag and pitch structures take their states from the lift model they name
    assert ("states =" in path.read_text()) == (c.lift is None and bool(c.states))


def test_spec_text_of_a_discovered_child_round_trips(tmp_path):
    parent = find_candidate("CL-VI")
    for move, child in generate(parent, _library("CL"), kinds=("add state", "state kind", "remove state")):
        path = tmp_path / "spec.toml"
        path.write_text(spec_text(child))
        assert resolve_candidate(str(path)) == child, move


# ----- the search -------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def drag_search(tmp_path_factory):
    """A short search for drag on a small clean campaign, from the thesis' final drag model without C_L^2 (fed
    the fitted CL-VI), with every call of the runner recorded."""
    from structsearch.diagnosis.withheld import baseline_without
    from structsearch.discovery.explore import explore
    from structsearch.discovery.judge import judge_for
    from structsearch.fitting.candidate_fit import fit_staged
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.options import FitOptions
    from structsearch.flight.flighttest import build_campaign
    from structsearch.fitting import runner
    campaign = build_campaign(seed=5, scale=0.1, slow_errors=0.0)
    options = FitOptions(n_starts=1, cv_method="one-step")
    train, val = campaign.split("train"), campaign.split("validation")
    lift = fit_staged(find_candidate("CL-VI"), train, val, None, options)
    assert not lift.failed
    start = baseline_without("induced_drag")
    assert start.lift == "CL-VI" and "CL**2" not in dict(start.regressors).values()
    calls = []
    real_run = runner.run

    def recording_run(candidates, *args, **kw):
        calls.append([(structure_key(c), kw["options"].scores_only) for c in candidates])
        return real_run(candidates, *args, **kw)

    mp = pytest.MonkeyPatch()
    mp.setattr(runner, "run", recording_run)
    try:
        fitter = fitter_for(campaign, tmp_path_factory.mktemp("search"), options,
                            lifts={"CL-VI": LiftFit(find_candidate("CL-VI"), lift)})
        found = explore(start, fitter, library_for("CD", train), beam=2, max_steps=2, judge=judge_for(campaign))
    finally:
        mp.undo()
    return found, calls


def test_the_search_adopts_only_moves_that_pass_their_test(drag_search):
    found, _ = drag_search
    path = found.path
    assert path, "the withheld C_L^2 term is found"
    assert path[0].move.effect == "induced_drag" and path[0].status == "improves"
    for node in path:
        assert node.status in ("improves", "simplifies", "look-ahead", "repairs"), node.status
        anchor = node.anchor
        assert anchor is not None and anchor in node.path()
        if node.status == "improves":
            assert node.result.validation.mse < anchor.result.validation.mse
            if node.test.stands_for:   # a library effect within one SE of a move whose test passed
                passed = [t for s in found.steps for t in s.tried if t.move.name == node.test.stands_for
                          and t.parent is node.parent]
                assert passed and passed[0].test.improves and node.move.effect
            else:
                assert node.test.improves and node.test.p_value is not None
                assert node.test.decisive_p_value < node.test.threshold <= DEFAULT_ALPHA
        elif node.status == "simplifies":
            assert node.test.within_one_se and node.n_params <= anchor.n_params
    # the structure the search ends with was adopted (the start, or one a step kept)
    kept = [found.start] + [n for s in found.steps for n in s.beam if n.status in ("improves", "simplifies",
                                                                                 "repairs")]
    assert any(found.final is n for n in kept)
    assert found.final.path()[0] is found.start


def test_the_search_fits_every_structure_once(drag_search):
    found, calls = drag_search
    tried = [n for s in found.steps for n in s.tried]
    keys = [structure_key(n.candidate) for n in tried] + [structure_key(found.start.candidate)]
    assert len(set(keys)) == len(keys)
    # every structure goes to the runner once for its screening and at most once for its full fit
    sent = [k for call in calls for k in call]
    assert len(set(sent)) == len(sent)
    assert {k for k, screened in sent if screened} == {structure_key(n.candidate) for n in tried}
    assert found.n_fitted == len(tried) + 1
    # the nodes a step keeps are among those it tried, each judged against a structure adopted before it
    for step in found.steps:
        assert all(any(b is t for t in step.tried) for b in step.beam)


def test_a_structure_the_search_ends_on_that_is_not_admissible_is_repaired(tmp_path):
    """No move of the search applies (a lift move without another lift model), so the start is where it ends:
    Cm-XXXIIIr with two superfluous terms (alpha, X_ss), correlated with its own and accepted at zero, is
    repaired by removals until it is admissible, each repair removing a reason (or a parameter within one standard
    error), the repairs that keep the fit first."""
    from structsearch.discovery.explore import REPAIR_KINDS, explore
    from structsearch.discovery.judge import judge_for
    from structsearch.fitting.candidate_fit import fit_staged
    from structsearch.fitting.lift_fit import LiftFit
    from structsearch.fitting.options import FitOptions
    from structsearch.flight.flighttest import build_campaign
    campaign = build_campaign(seed=5, scale=0.1, slow_errors=0.0)
    options = FitOptions(n_starts=1, cv_method="one-step")
    train, val = campaign.split("train"), campaign.split("validation")
    lift = LiftFit(find_candidate("CL-VI"), fit_staged(find_candidate("CL-VI"), train, val, None, options))
    base = find_candidate("Cm-XXXIIIr")
    start = dataclasses.replace(base, name="Cm-XXXIIIr + alpha + X_ss",
                                regressors=base.regressors + (("Cm_alpha", "alpha"), ("Cm_X_ss", "X_ss")))
    fitter = fitter_for(campaign, tmp_path, options, lifts={"CL-VI": lift})
    found = explore(start, fitter, library_for("Cm", train), kinds=("lift",), max_steps=6, judge=judge_for(campaign))
    assert not found.start.admissible and found.final.admissible
    repairs = found.path
    assert repairs and all(n.status == "repairs" and n.move.kind in REPAIR_KINDS for n in repairs)
    for node in repairs:
        assert len(node.reasons) < len(node.parent.reasons) or (
            len(node.reasons) == len(node.parent.reasons) and node.n_params < node.parent.n_params
            and node.test.within_one_se)
        assert any(node is b for s in found.steps for b in s.beam)
    # without simplify (a diagnosis) nothing is repaired
    kept = explore(start, fitter, library_for("Cm", train), kinds=("lift",), max_steps=4, judge=judge_for(campaign),
                   simplify=False)
    assert kept.final is kept.start and len(kept.steps) == 1



def test_with_nothing_admissible_the_final_choice_stays_within_the_answers_tolerance_of_the_best_fit():
    """The fewest reasons against a structure decide only among those that fit within 25 % of the best adopted one:
    a start with one flaw that fits 50 % worse is not chosen over a structure with two flaws that fits best."""
    from structsearch.discovery.explore import choose
    best = _node("best", [1.0] * 5, [1.0] * 5, 6, reasons=("t-test accepts 0 at 5%: p5", "p4 at its upper bound"))
    start = _node("start", [1.5] * 5, [1.6] * 5, 1, reasons=("t-test accepts 0 at 5%: p0",))
    close = _node("close", [1.2] * 5, [1.2] * 5, 4, reasons=("t-test accepts 0 at 5%: p3",))
    assert choose([best, start], admissible_first=True) is best
    assert choose([best, start, close], admissible_first=True) is close
