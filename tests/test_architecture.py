"""The house rules: no import cycles, one source of truth for the final models, typed candidate results
that survive the cache, and a wheel that works outside the checkout."""
import json
import math
import os
import subprocess
import sys
import venv
from pathlib import Path

import grimp
import numpy as np
import pytest
from conftest import stated_result
import sympy as sp

from structsearch.engine.regressors import declare
from structsearch.engine.scores import ManeuverScores, R2Summary, weighted_mean_se
from structsearch.flight import reference
from structsearch.fitting.candidate_result import CandidateResult, SplitScores
from structsearch.fitting.specs import find_candidate

ROOT = Path(__file__).resolve().parent.parent


def _cycles(graph) -> list[list[str]]:
    """Every strongly connected group of more than one module (Tarjan)."""
    index, low, stack, on_stack, groups = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.find_modules_directly_imported_by(v):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                groups.append(sorted(group))

    for m in sorted(graph.modules):
        if m not in index:
            visit(m)
    return groups


def test_no_import_cycles_between_modules():
    # imports made for type checkers alone (under TYPE_CHECKING) never run: a cycle through one is no cycle
    graph = grimp.build_graph("structsearch", exclude_type_checking_imports=True)
    assert len(graph.modules) > 40  # the whole package was read
    assert _cycles(graph) == []


def test_cycle_finder_sees_a_cycle():
    class Graph:
        modules = {"a", "b", "c"}
        edges = {"a": {"b"}, "b": {"a"}, "c": {"a"}}

        def find_modules_directly_imported_by(self, m):
            return self.edges[m]

    assert _cycles(Graph()) == [["a", "b"]]


@pytest.mark.parametrize("coefficient,declared", [
    ("CL", reference.final_lift_model()),
    ("CD", reference.final_drag_model()),
    ("Cm", reference.final_pitch_model()),
    ("CL-vi", reference.van_ingen_lift_model()),
])
def test_python_declarations_of_the_final_models_equal_the_grids(coefficient, declared):
    names = reference.VAN_INGEN_MODEL_NAMES if coefficient.endswith("-vi") else reference.FINAL_MODEL_NAMES
    candidate = find_candidate(names[coefficient.split("-")[0]])
    assert declared.coefficient == candidate.coefficient
    assert {s.name: s.kind for s in declared.states} == dict(candidate.states)
    symbols = [s.symbol for s in declared.states]
    from_grid = {name: declare(name, text, states=symbols).expr for name, text in candidate.regressors}
    in_code = {r.name: r.expr for r in declared.regressors}
    assert from_grid.keys() == in_code.keys()
    for name in in_code:
        assert sp.simplify(from_grid[name] - in_code[name]) == 0, name
    if candidate.lift:
        assert candidate.lift == reference.FINAL_MODEL_NAMES["CL"]


def _result(error=None) -> CandidateResult:
    scores = SplitScores(0.5, (0.25, 0.75), (10, 10), R2Summary(0.9, float("nan"), 0.95), 0.1, None)
    if error:
        return CandidateResult.failure(name="X", grid="g", coefficient="CL", lift=None, error=error, seconds=1.5)
    return stated_result("CD-I", "drag", "CD", "CL-VI", 2.0, names=("a", "b"), nonlinear_names=("a",),
                           params={"a": 1.0, "b": -2.0}, stderr={"a": 0.1, "b": float("nan")},
                           p_values={"a": 0.001, "b": 0.2}, at_bound={"a": "lower"},
                           high_correlations=(("a", "b", 0.95),), correlation=((1.0, 0.95), (0.95, 1.0)),
                           n_starts=4, n_reached_best=3, aic=-10.0, bic=-8.0, max_lag=12, converged=False,
                           message="max_nfev reached", nfev=200, train=scores, validation=scores, rank=2,
                           within_noise=True, gap=0.01, gap_se=0.02)


@pytest.mark.parametrize("error", [None, "FitError: boom"])
def test_candidate_result_survives_the_cache_as_json(error):
    r = _result(error)
    text = json.dumps(r.to_json(), allow_nan=False)  # the cache holds strict JSON: no NaN
    back = CandidateResult.from_json(json.loads(text))
    if error:
        assert back == r
        return
    assert back.validation.r2.mean == r.validation.r2.mean and math.isnan(back.validation.r2.min)
    assert back.estimates.params == r.estimates.params and back.optimizer.converged is False and back.optimizer.message == "max_nfev reached"
    assert back.estimates.high_correlations == r.estimates.high_correlations and back.insignificant == ("b",)
    np.testing.assert_array_equal(back.estimates.correlation, [[1.0, 0.95], [0.95, 1.0]])


def test_a_cache_entry_of_another_layout_is_refused():
    doc = _result().to_json()
    doc["layout"] = 0
    with pytest.raises(ValueError, match="layout"):
        CandidateResult.from_json(doc)


def test_maneuver_scores_against_direct_formulas():
    rng = np.random.default_rng(7)
    y = rng.standard_normal(30)
    r = 0.3 * rng.standard_normal(30)
    slices = [slice(0, 10), slice(10, 25), slice(25, 30)]
    s = ManeuverScores.of(y, r, slices)
    for k, sl in enumerate(slices):
        assert s.mse[k] == pytest.approx(np.mean(r[sl] ** 2))
        assert s.r2[k] == pytest.approx(1 - np.sum(r[sl] ** 2) / np.sum((y[sl] - y[sl].mean()) ** 2))
    assert s.pooled_mse == pytest.approx(np.mean(r ** 2))
    constant = ManeuverScores.of(np.ones(10), np.zeros(10), [slice(0, 10)])
    assert math.isnan(constant.r2[0]) and math.isnan(constant.r2_summary().mean)


def test_weighted_mean_and_standard_error():
    mean, se = weighted_mean_se(np.array([1.0, 3.0]), np.array([1.0, 3.0]))
    assert mean == pytest.approx(2.5)
    # equal weights: the textbook standard error of a mean, s / sqrt(n)
    x = np.random.default_rng(2).standard_normal(12)
    mean, se = weighted_mean_se(x, np.full(12, 7.0))
    assert mean == pytest.approx(x.mean()) and se == pytest.approx(x.std(ddof=1) / np.sqrt(12))
    assert math.isnan(weighted_mean_se(np.array([2.0]), np.array([5.0]))[1])  # one maneuver: no spread


def _third_party_imports() -> tuple[set[str], set[str]]:
    """Top-level names the package imports from outside itself and the standard library: (at module
    level, anywhere)."""
    import ast
    module_level, anywhere = set(), set()
    for path in (ROOT / "structsearch").rglob("*.py"):
        tree = ast.parse(path.read_text())
        top = set(map(id, tree.body))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name.split(".")[0] for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module.split(".")[0]]
            else:
                continue
            names = [n for n in names if n != "structsearch" and n not in sys.stdlib_module_names]
            anywhere.update(names)
            if id(node) in top:
                module_level.update(names)
    return module_level, anywhere


def _requirement_name(text: str) -> tuple[str, str | None]:
    """(distribution, extra or None) of a Requires-Dist line."""
    import re
    name = re.match(r"[A-Za-z0-9_.-]+", text).group(0).lower().replace("_", "-")
    extra = re.search(r"extra\s*==\s*['\"]([^'\"]+)", text)
    return name, extra.group(1) if extra else None


@pytest.mark.slow
def test_the_wheel_works_outside_the_checkout(tmp_path):
    """Build the wheel, install it into a fresh virtual environment and fit a small campaign from elsewhere.

    The wheel's metadata must declare every distribution the package imports: those imported at module
    level as dependencies, the others (imported where an optional feature needs them) at least in an
    extra. The fresh environment then borrows those distributions from this one (a path entry after its
    own site-packages) rather than installing them again from the registry (20 s of unpacking wheels)."""
    import zipfile
    from importlib.metadata import packages_distributions
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(ROOT)],
                   check=True, cwd=tmp_path)
    wheel = next(dist.glob("structsearch-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        meta = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        lines = archive.read(meta).decode().splitlines()
    declared = [_requirement_name(line.split(":", 1)[1].strip()) for line in lines
                if line.startswith("Requires-Dist:")]
    required = {name for name, extra in declared if extra is None}
    optional = {name for name, extra in declared if extra is not None}
    distributions = {k: {d.lower().replace("_", "-") for d in v} for k, v in packages_distributions().items()}
    # the borrowed distributions must satisfy the wheel's version constraints
    from importlib.metadata import version
    from packaging.requirements import Requirement
    for line in lines:
        if line.startswith("Requires-Dist:") and "extra ==" not in line:
            req = Requirement(line.split(":", 1)[1].strip())
            if req.marker is not None and not req.marker.evaluate():
                continue  # not for this interpreter
            assert req.specifier.contains(version(req.name), prereleases=True), (str(req), version(req.name))
    module_level, anywhere = _third_party_imports()
    assert {"numpy", "scipy", "sympy"} <= module_level  # the scan sees imports
    for name in sorted(anywhere):
        provided_by = distributions.get(name, set())
        assert provided_by, f"the package imports {name!r}, which no installed distribution provides"
        needed = required if name in module_level else required | optional
        assert provided_by & needed, f"the package imports {name!r} ({', '.join(provided_by)}), which the " \
                                     f"wheel does not declare{'' if name in module_level else ' in an extra'}"

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    python = env_dir / "bin" / "python"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps", str(wheel)],
                   check=True, cwd=tmp_path)
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          check=True, capture_output=True, text=True).stdout.strip()
    # a path line adds this environment's site-packages without running its .pth files (the checkout's
    # editable install among them)
    import sysconfig
    here = sysconfig.get_paths()["purelib"]   # where this environment's packages live
    Path(site, "zz_borrowed_dependencies.pth").write_text(here + "\n")
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    where = subprocess.run([str(python), "-c", "import structsearch, sys; print(structsearch.__file__)"],
                           check=True, cwd=tmp_path, env=clean, capture_output=True, text=True).stdout
    assert str(env_dir) in where and str(ROOT) not in where
    exe = env_dir / "bin" / "structsearch"
    subprocess.run([str(exe), "simulate", "--out", "camp", "--scale", "0.05", "--seed", "3"], check=True,
                   cwd=tmp_path, env=clean, capture_output=True)
    fit = subprocess.run([str(exe), "fit", "--data", "camp", "--model", "CD-IXr", "--out", "fit", "--starts", "1"],
                         cwd=tmp_path, env=clean, capture_output=True, text=True)
    assert fit.returncode == 0, fit.stderr
    doc = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert doc["model"] == "CD-IXr" and doc["lift"]["model"] == "CL-VI"
    assert doc["params"].keys() == doc["stderr"].keys() and isinstance(doc["converged"], bool)


# ----- one result vocabulary (issue 27): a candidate's result composes the fit's estimates ------------
def _fitted_candidate():
    from structsearch import SeparableModel
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 4.0, 240)
    y = 2.0 * np.exp(-1.3 * x) + 0.5 + 0.01 * rng.standard_normal(len(x))
    fit = SeparableModel({"b1": "exp(-b2*x)", "b0": "1"}, variables=["x"]).fit(
        {"x": x}, y, start={"b2": 1.0}, bounds={"b2": (0.1, 5.0)}, covariance="hac-maneuver",
        segments=[60, 120, 180])
    scores = SplitScores(fit.mse, tuple(fit.mse_segments.values()), tuple(map(int, fit.segments.counts)),
                         fit.segments.r2_summary())
    return fit, CandidateResult.from_fit(name="E", grid="g", coefficient="y", lift=None, result=fit, train=scores,
                                         validation=scores, seconds=0.5)


def test_a_candidate_result_keeps_the_fits_estimates_and_covariance():
    fit, cand = _fitted_candidate()
    assert cand.estimates is fit.estimates and cand.optimizer.converged is fit.converged
    for name in ("names", "nonlinear_names", "params", "stderr", "p_values", "at_bound", "reference_dof",
                 "not_identifiable", "significant", "condition_number", "significance", "max_lag"):
        assert getattr(cand.estimates, name) == getattr(fit, name), name
    assert cand.n_params == fit.n_params and cand.identifiable == fit.identifiable
    np.testing.assert_array_equal(cand.cov_params().to_numpy(), fit.covariance)
    assert cand.wald_test(["b0", "b1"]) == fit.wald_test(["b0", "b1"])
    assert cand.conf_int().equals(fit.conf_int())
    from structsearch.reporting.fit_report import fit_report
    assert "covariance" in fit_report(cand) and fit_report(cand, "html") == cand.summary().as_html()
    assert fit_report(cand, "csv") == fit_report(fit, "csv")


def test_a_candidate_results_json_round_trip_is_exact():
    _, cand = _fitted_candidate()
    back = CandidateResult.from_json(json.loads(json.dumps(cand.to_json(), allow_nan=False)))
    assert back == cand
    np.testing.assert_array_equal(back.estimates.covariance, cand.estimates.covariance)
    np.testing.assert_array_equal(back.estimates.white_covariance, cand.estimates.white_covariance)
    np.testing.assert_array_equal(back.estimates.effective_maneuvers, cand.estimates.effective_maneuvers)
    assert back.estimates.p_values == cand.estimates.p_values and back.estimates.stderr == cand.estimates.stderr
    assert back.to_json() == cand.to_json()


def test_a_failed_candidate_has_no_statistics():
    failed = _result("FitError: boom")
    assert failed.estimates is None and failed.n_params == 0 and failed.identifiable is None
    with pytest.raises(ValueError, match="no estimates: FitError: boom"):
        failed.wald_test(["a"])


def test_replacing_a_fit_results_covariance_replaces_its_statistics():
    import dataclasses
    fit, _ = _fitted_candidate()
    doubled = dataclasses.replace(fit, covariance=4.0 * fit.covariance, covariance_kind="white")
    assert doubled.covariance_kind == "white" and fit.covariance_kind == "hac-maneuver"
    assert doubled.stderr["b2"] == pytest.approx(2.0 * fit.stderr["b2"], rel=1e-12)
    assert doubled.params == fit.params and doubled.rss == fit.rss
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'"):
        dataclasses.replace(fit, colour="red")


def test_a_wald_test_of_a_parameter_that_is_not_identifiable_is_nan_with_the_reason():
    import dataclasses
    fit, _ = _fitted_candidate()
    cov = fit.covariance.copy()
    cov[0, :] = cov[:, 0] = np.nan
    broken = dataclasses.replace(fit, covariance=cov, unidentifiable={"b2": "for the test"})
    test = broken.wald_test(["b2", "b0"])
    assert np.isnan(test.p_value) and test.reason == "b2 is not identifiable: for the test"
    assert not np.isnan(broken.wald_test(["b0"]).p_value)
    assert broken.conf_int().loc["b2"].isna().all() and not broken.conf_int().loc["b0"].isna().any()


def test_ci_runs_exactly_the_readme_test_command():
    """CI (``.ci/run``) must call the test command the README gives, character for character, first; what it adds
    after it is the simulated second machine (``.ci/another_machine``), which the README names."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    readme = (root / "README.md").read_text()
    # the first command after "Tests:" (past the block's test marker and its fence; a console prompt dropped)
    tests = next(line.strip().removeprefix("$ ") for line in readme.split("\nTests:\n", 1)[1].splitlines()
                 if line.strip() and not line.strip().startswith(("<!--", "```")))
    assert "pytest" in tests and "lint-imports" in tests
    ci = [line.strip() for line in (root / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.lstrip().startswith(("#", "set ", "cd "))]
    assert ci == [tests, "bash .ci/another_machine"]
    assert ".ci/another_machine" in readme


def test_rooms_stay_small_and_the_api_takes_one_settings_value():
    """No function over 60 lines, no module over 450, no API function with more than 8 keyword options besides
    its settings value (the house's limits: a function or module past them is split, an API option past them
    belongs in structsearch.Settings)."""
    import ast
    package = ROOT / "structsearch"
    long_functions, long_modules, wide = [], [], []
    for path in sorted(package.rglob("*.py")):
        text = path.read_text()
        if len(text.splitlines()) > 450:
            long_modules.append(str(path.relative_to(ROOT)))
        tree = ast.parse(text)
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= 60:
                long_functions.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name}")
        if path.parent.name == "api":
            for node in tree.body:
                if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
                    options = [a.arg for a in node.args.kwonlyargs if a.arg != "settings"]
                    if len(options) > 8:
                        wide.append(f"{node.name}: {len(options)}")
    assert long_functions == [] and long_modules == [] and wide == [], (long_functions, long_modules, wide)


def test_coefficients_are_named_once_in_their_registry():
    """What a coefficient is (its grid, JSBSim axis, whether it is a moment or owns the separation states) is
    read from structsearch.data.coefficients: no module spells the three names as a tuple of its own."""
    from structsearch.data.coefficients import coefficient
    from structsearch.data.errors import DeclarationError
    with pytest.raises(DeclarationError, match="'CZ' is not one of CL, CD, Cm, CY, Cl, Cn"):
        coefficient("CZ")
    spelled = [str(p.relative_to(ROOT)) for p in sorted((ROOT / "structsearch").rglob("*.py"))
               if '("CL", "CD", "Cm")' in p.read_text() and p.name != "coefficients.py"]
    assert spelled == []


def test_the_engine_asks_a_problem_what_it_declares_and_probes_nothing():
    """The solver and the statistics use only what SeparableProblem declares (its capabilities have defaults):
    no ``hasattr`` probe of a problem in the engine."""
    import ast
    probes = []
    for path in sorted((ROOT / "structsearch" / "engine").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "hasattr":
                probes.append(f"{path.relative_to(ROOT)}:{node.lineno}")
            # getattr(problem, "capability", default): a probe too (the protocol's defaults answer instead)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr" \
                    and len(node.args) == 3 and "problem" in ast.unparse(node.args[0]):
                probes.append(f"{path.relative_to(ROOT)}:{node.lineno}")
    assert probes == []


def test_a_problem_that_declares_only_evaluate_is_fitted_with_the_protocols_defaults():
    """A user's problem subclasses SeparableProblem and writes ``evaluate`` alone: fit_problem reads the
    defaults (nothing unidentifiable beyond the Jacobian's rank, one Jacobian block, the plain residual, no
    inputs to name). The fit of y = c exp(-k x) recovers k and c to within their noise."""
    from structsearch.engine.fit import fit_problem
    from structsearch.engine.snls import Evaluation, SeparableProblem

    class Decay(SeparableProblem):
        nonlinear_names, linear_names = ("k",), ("c",)

        def __init__(self, x):
            self.x = x

        def evaluate(self, theta):
            e = np.exp(-theta[0] * self.x)[:, None]
            return Evaluation(e, -self.x[:, None] * e, np.array([0]), np.array([0]))

    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 4.0, 200)
    y = 2.0 * np.exp(-0.7 * x) + 0.01 * rng.standard_normal(x.size)
    fit = fit_problem(Decay(x), y, boundaries=np.array([0, x.size]), segment_names=["all"], start=[0.3],
                      lower=[0.0], upper=[5.0], covariance="white")
    k, c = fit.params["k"], fit.params["c"]
    sk, sc = fit.stderr["k"], fit.stderr["c"]
    # 4 standard errors: a miss of that size has probability below 1e-4 under the fit's own covariance
    assert abs(k - 0.7) < 4 * sk and abs(c - 2.0) < 4 * sc and 0 < sk < 0.01
