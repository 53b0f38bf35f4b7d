import functools
import os
import shutil
import subprocess
import sys

# one BLAS thread, as the CLI uses; keeps timings of the suite stable on small machines
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from structsearch.flight.reference import FINAL_LIFT, final_lift_model  # noqa: E402
from structsearch.flight.synthetic import campaign, with_coefficient  # noqa: E402


def pytest_configure(config):
    # `-m "not slow"` leaves out the end-to-end runs of whole commands on simulated campaigns (the README's
    # test command runs everything)
    config.addinivalue_line("markers", "slow: a heavy end-to-end run (a whole command on a simulated campaign)")


def run_cli(*args, cwd=None, timeout=600, extra=()):
    """``structsearch ARGS`` in a fresh interpreter (as a user runs it): the completed process."""
    return subprocess.run([sys.executable, *extra, "-m", "structsearch", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout)


@pytest.fixture(name="run_cli", scope="session")
def run_cli_fixture():
    """:func:`run_cli` for tests that take it as a fixture."""
    return run_cli


@functools.lru_cache(maxsize=8)
def _simulated(seed: int, scale: float, options: tuple):
    from structsearch.flight.flighttest import build_campaign
    return build_campaign(seed=seed, scale=scale, **dict(options))


@pytest.fixture(scope="session")
def simulated_campaign():
    """``simulated_campaign(seed, scale, **build_campaign options)``: a seeded simulated campaign, flown once
    per test process and shared (campaigns are immutable: their columns are read-only)."""
    def make(seed: int = 0, scale: float = 0.05, **options):
        return _simulated(seed, scale, tuple(sorted((k, tuple(v) if isinstance(v, list) else v)
                                                    for k, v in options.items())))
    return make


@pytest.fixture(scope="session")
def campaign_on_disk(tmp_path_factory, simulated_campaign):
    """``campaign_on_disk(seed, scale, **options)``: the same campaign written once per test process to a
    directory and read back (the command line's view of it: ``campaign.directory``)."""
    from structsearch.data.campaign import read_campaign, write_campaign
    written = {}

    def make(seed: int = 0, scale: float = 0.05, **options):
        key = (seed, scale, tuple(sorted(options.items())))
        if key not in written:
            path = tmp_path_factory.mktemp("campaign") / "c"
            write_campaign(simulated_campaign(seed, scale, **options), path)
            written[key] = read_campaign(path)
        return written[key]
    return make


@pytest.fixture(scope="session")
def small_campaign():
    """Six 30 s maneuvers at 100 Hz (quasi-steady, dynamic, deep dynamic)."""
    return campaign({"quasi-steady": 2, "dynamic": 2, "deep-dynamic": 2}, duration=30.0, seed=11)


@pytest.fixture(scope="session")
def noise_free_lift(small_campaign):
    model = final_lift_model()
    return model, with_coefficient(small_campaign, model, FINAL_LIFT)


def central_difference(fun, x, rel=1e-6):
    """Central finite differences of a vector function, one column per parameter."""
    x = np.asarray(x, float)
    cols = []
    for i in range(len(x)):
        h = rel * max(abs(x[i]), 1e-3)
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        cols.append((fun(xp) - fun(xm)) / (2 * h))
    return np.column_stack(cols)


def assert_matches_finite_difference(jacobian, fun, x, rel=1e-5, safety=10.0):
    """An analytic Jacobian against central differences, with a tolerance the differences give themselves.

    Central differences at steps h and h/2 (D1, D2) are extrapolated (4 D2 - D1) / 3 (Richardson); the
    truncation error of D2 is about |D1 - D2| / 3 and its rounding error about 100 eps max|f| / h. The analytic
    Jacobian must lie within ``safety`` times their sum of the extrapolation (plus 1e-12 of each column's
    scale): a bound that follows the curvature and the size of each element, so it holds on any processor
    and BLAS kernel, and still fails a wrong derivative (an error larger than the differences' own)."""
    x = np.asarray(x, float)
    jacobian = np.asarray(jacobian, float)
    d1 = central_difference(fun, x, rel)
    d2 = central_difference(fun, x, rel / 2)
    # rounding: a model's values carry up to 100 eps of its largest value (separation states are integrated
    # sample by sample; measured 2e-14 on a static lift curve of size 1), and a difference divides that by h
    f = float(np.abs(np.asarray(fun(x), float)).max())
    h2 = (rel / 2) * np.maximum(np.abs(x), 1e-3)
    rounding = 100 * np.finfo(float).eps * f / h2
    extrapolated = (4 * d2 - d1) / 3
    scale = np.abs(extrapolated).max(axis=0)
    bound = safety * (np.abs(d1 - d2) / 3 + rounding) + 1e-12 * scale + 1e-300
    bad = np.abs(jacobian - extrapolated) > bound
    if np.any(bad):
        i, j = np.argwhere(bad)[0]
        raise AssertionError(f"{bad.sum()} elements off; first at row {i}, column {j}: analytic {jacobian[i, j]!r}"
                             f", finite difference {extrapolated[i, j]!r}, bound {bound[i, j]!r}")


def fitter_for(campaign, cache_dir, options=None, n_jobs: int = 1, lifts=None, progress=None, trace=None):
    """A :class:`~structsearch.fitting.fitter.Fitter` on ``campaign`` caching in ``cache_dir`` (what a command's
    API function makes from its settings)."""
    from structsearch.fitting.fitter import Fitter, RunConfig
    from structsearch.fitting.options import FitOptions
    config = RunConfig(campaign, cache_dir, options or FitOptions(), n_jobs, "loky", progress, trace)
    return Fitter(config, dict(lifts or {}))


# ----- results built from stated statistics (the tests' factory; a fit makes them otherwise) -----------------
STATED_KEYWORDS = ("names", "nonlinear_names", "params", "stderr", "p_values", "at_bound", "high_correlations",
                   "correlation", "significance", "reference_dof", "max_lag", "not_identifiable", "condition_number")


def stated_result(*args, **fields):
    """A CandidateResult whose estimates are the statistics given (``names``, ``params``, ``stderr``, ...;
    :data:`STATED_KEYWORDS`), amending ``estimates`` when one is given (``params=None``: no fit), and whose
    placement in a ranking is the one given (``rank``, ``admissible``, ...)."""
    from structsearch.fitting.candidate_result import CandidateResult, OptimizerReport, Placement
    placing = {k: fields.pop(k) for k in ("admissible", "reasons", "rank", "within_noise", "gap", "gap_se")
               if k in fields}
    if placing:
        fields["placement"] = Placement(**placing)
    optimizer = {k: fields.pop(k) for k in ("converged", "message", "nfev", "n_starts", "n_reached_best")
                 if k in fields}
    if optimizer:
        fields["optimizer"] = OptimizerReport(**optimizer)
    stated = {k: fields.pop(k) for k in STATED_KEYWORDS if k in fields}
    if stated:
        fields["estimates"] = (None if "params" in stated and stated["params"] is None
                               else _restated(fields.get("estimates"), stated, fields.get("train")))
    return CandidateResult(*args, **fields)


def _restated(base, stated: dict, train):
    """``base`` (or, without one, estimates of the stated parameters alone) with the ``stated`` statistics.
    Without a fit to derive them from, a covariance is rebuilt from stated correlations and standard
    deviations (NaN where either is missing) and the box is unknown (NaN)."""
    old = base.params if base is not None else {}
    params = stated.get("params", old) or {}
    names = tuple(stated.get("names", base.names if base is not None else tuple(params)))
    nonlinear = tuple(stated.get("nonlinear_names", base.nonlinear_names if base is not None else ()))
    linear = tuple(n for n in names if n not in nonlinear)
    ordered = nonlinear + linear
    p = len(ordered)
    same = base is not None and base.names == ordered
    carried = dict(base.stated) if same else {}
    carried.update({k: v for k, v in stated.items() if k in ("stderr", "p_values", "at_bound", "high_correlations",
                                                             "correlation", "not_identifiable", "reference_dof")})
    if base is None:  # a result built by hand names what it cannot identify (nothing, unless it says so)
        carried.setdefault("not_identifiable", {})
    if "high_correlations" in carried:
        carried["high_correlations"] = [tuple(pair) for pair in carried["high_correlations"]]
    if same and not ({"stderr", "correlation"} & set(stated)):
        covariance = base.covariance
    else:
        sd = np.array([(carried.get("stderr") or (base.stderr if same else {})).get(n, np.nan) for n in ordered],
                      float)
        corr = (np.asarray(carried["correlation"], float).reshape(p, p) if len(carried.get("correlation", ())) else
                base.correlation if same else np.where(np.eye(p, dtype=bool), 1.0, np.nan))
        covariance = corr * np.outer(sd, sd)
    box = (base.lower, base.upper) if base is not None and base.nonlinear_names == nonlinear else \
        (np.full(len(nonlinear), np.nan), np.full(len(nonlinear), np.nan))
    from structsearch.engine.estimates import ParameterEstimates
    return ParameterEstimates(
        nonlinear_names=nonlinear, linear_names=linear,
        values=np.array([params.get(n, np.nan) for n in ordered], float), lower=box[0], upper=box[1],
        covariance=covariance, covariance_kind=base.covariance_kind if base is not None else "white",
        n_samples=(base.n_samples if base is not None else int(sum(train.n_maneuvers)) if train is not None else 0),
        n_maneuvers=(base.n_maneuvers if base is not None else len(train.n_maneuvers) if train is not None else 0),
        white_covariance=base.white_covariance if same else None,
        max_lag=stated.get("max_lag", base.max_lag if base is not None else None),
        bandwidth=base.bandwidth if base is not None else None,
        effective_maneuvers=base.effective_maneuvers if same else None,
        significance=stated.get("significance", base.significance if base is not None else 0.05),
        unidentifiable=dict(base.unidentifiable) if same else {},
        condition_number=_nan(stated.get("condition_number",
                                                 base.condition_number if base is not None else None)),
        generated_regressors=base.generated_regressors if base is not None else None, stated=carried,
        units=dict(base.units) if base is not None else {},
        n_flights=base.n_flights if base is not None else None)


def _nan(v) -> float:
    return float("nan") if v is None else float(v)


@pytest.fixture
def campaign_dir(campaign_on_disk, tmp_path):
    """A copy of a small written campaign, free to spoil (the hostile-input tests alter its files)."""
    source = campaign_on_disk(seed=1, scale=0.05, slow_errors=0.0).directory
    target = tmp_path / "campaign"
    shutil.copytree(source, target)
    return target
