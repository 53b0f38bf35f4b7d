"""Result serialisation, the fit report, flags, and the command line end to end."""
import json
import subprocess
import sys

import numpy as np
import pytest

from structsearch import fit_report
from structsearch.reporting.fit_report import FORMATS
from structsearch.engine.stallmodel import StallModel


@pytest.fixture(scope="module")
def flagged_fit(noise_free_lift):
    """tau2 truly zero (ends on its lower bound) and two nearly collinear regressors."""
    _, data = noise_free_lift
    from structsearch.flight.synthetic import with_coefficient
    model = StallModel.declare("flags", "CL", states={"": "Q"},
                               regressors={"c0": "1", "kl": "K_L(X)", "a": "alpha", "b": "alpha + 0.02*de"})
    truth = {"tau2": 0.0, "a1": 30.0, "a_star": 0.22, "c0": 0.2, "kl": 2.0, "a": 1.0, "b": 1.0}
    noisy = with_coefficient(data, model, truth, noise_sigma=0.01, noise_phi=0.5, seed=4)
    return model.fit(noisy, start={"tau2": 0.05})


def test_flags(flagged_fit):
    assert flagged_fit.at_bound == {"tau2": "lower"}
    pairs = {frozenset(p[:2]) for p in flagged_fit.high_correlations}
    assert frozenset({"a", "b"}) in pairs
    assert all(abs(p[2]) > 0.9 for p in flagged_fit.high_correlations)


@pytest.mark.parametrize("fmt", FORMATS)
def test_fit_report_formats(flagged_fit, fmt):
    text = fit_report(flagged_fit, fmt)
    for name in flagged_fit.names:
        assert (name.replace("_", "\\_") if fmt == "latex" else name) in text
    if fmt == "latex":
        assert "\\begin{tabular}" in text
    if fmt == "html":
        assert "<table>" in text
    if fmt == "text":
        assert "at lower bound" in text and "|rho| > 0.9" in text and "t-test accepts 0" in text


def test_the_parameter_table_gives_each_reference_dof_and_flags_few_maneuvers(flagged_fit):
    """Issue 30: the t reference's degrees of freedom beside each standard deviation, and a flag where it is
    below FEW_DOF (the few maneuvers behind it make the standard deviation itself uncertain)."""
    import dataclasses
    from structsearch.engine.summary import FEW_DOF, PARAMETER_HEADERS, parameter_rows, parameter_table
    rows = {r[0]: r for r in parameter_rows(flagged_fit)}
    for name, dof in flagged_fit.reference_dof.items():
        assert rows[name][PARAMETER_HEADERS.index("ref. dof")] == pytest.approx(dof)
    assert "ref. dof" in parameter_table(flagged_fit, "md")
    few = dataclasses.replace(flagged_fit.estimates, stated={**flagged_fit.estimates.stated,
                                                             "reference_dof": {**flagged_fit.reference_dof, "c0": 2.0}})
    fit = dataclasses.replace(flagged_fit, estimates=few)
    flags = {r[0]: r[-1] for r in parameter_rows(fit)}
    assert "few maneuvers (t dof 2.0)" in flags["c0"]
    assert not any("few maneuvers" in f for n, f in flags.items() if fit.reference_dof[n] >= FEW_DOF)


def test_result_is_immutable_and_serialises(flagged_fit):
    with pytest.raises(AttributeError):
        flagged_fit.model = "other"
    d = json.loads(json.dumps(flagged_fit.to_dict()))
    assert d["params"].keys() == d["stderr"].keys() == set(flagged_fit.names)
    assert d["at_bound"] == {"tau2": "lower"}
    assert d["r2_maneuvers"]["min"] <= d["r2_maneuvers"]["mean"] <= d["r2_maneuvers"]["max"]
    assert len(d["mse_maneuvers"]) == 6


def test_per_maneuver_statistics(noise_free_lift):
    model, data = noise_free_lift
    from structsearch.flight.synthetic import with_coefficient
    from structsearch.flight.reference import FINAL_LIFT
    noisy = with_coefficient(data, model, FINAL_LIFT, noise_sigma=0.02, seed=9)
    r = model.fit(noisy)
    manual = []
    for sl in noisy.segment_slices():
        y, res = noisy["CL"][sl], r.residuals[sl]
        manual.append(1 - res @ res / np.sum((y - y.mean()) ** 2))
    assert np.allclose(r.r2_segments, manual)
    assert r.r2_summary["min"] == pytest.approx(min(manual))
    assert r.mse == pytest.approx(np.mean(r.residuals ** 2))


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "structsearch", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=600)


@pytest.mark.slow
def test_bench_command_end_to_end(tmp_path):
    proc = run_cli("bench", "--samples", "6000", "--repeats", "1", "--starts", "2", "--jobs", "1", "--no-search",
                   "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    fig = json.loads((tmp_path / "bench.json").read_text())
    assert fig["random_starts"]["n"] == 2
    for method in ("snls", "prototype", "full", "fd"):  # every method measured alike
        assert fig["one_start"][method]["nfev"] > 0 and 0 <= fig["random_starts"][method]["success"] <= 2
        assert fig["memory_by_method"][method][0]["peak_mb"] > 0
    assert fig["memory"][1]["samples"] == 2 * fig["memory"][0]["samples"]
    # the prototype reaches the same answer as SNLS from the default start (it is a correct baseline)
    assert fig["one_start"]["prototype"]["rss"] == pytest.approx(fig["one_start"]["snls"]["rss"], rel=1e-6)
    md = (tmp_path / "bench.md").read_text()
    assert "Like for like" in md and "prototype" in md
    assert not list(tmp_path.glob(".bench*"))  # no temporary files left behind


def test_cli_rejects_unknown_command():
    proc = run_cli("frobnicate")
    assert proc.returncode != 0 and "invalid choice" in proc.stderr


def test_simulate_command_end_to_end(tmp_path):
    out = tmp_path / "camp"
    proc = run_cli("simulate", "--out", str(out), "--seed", "2", "--scale", "0.05", "--withhold", "induced_drag")
    assert proc.returncode == 0, proc.stderr
    assert "6 maneuvers" in proc.stdout
    from structsearch.data.campaign import read_campaign
    campaign = read_campaign(out)
    assert {m.split for m in campaign.maneuvers} == {"train", "validation"}
    assert 'withheld = "induced_drag"' in (out / "campaign.toml").read_text()
    for col in ("t", "alpha", "q", "V", "de", "CL", "CD", "Cm", "alpha_dot", "CT", "x_cg", "theta", "h",
                "CX", "CZ"):
        assert col in campaign.data


def test_simulate_rejects_effects_outside_the_final_model(tmp_path):
    proc = run_cli("simulate", "--out", str(tmp_path / "x"), "--withhold", "alpha_dot")
    assert proc.returncode != 0 and "invalid choice: 'alpha_dot'" in proc.stderr
    assert not (tmp_path / "x").exists()


def test_a_variance_that_is_not_positive_is_named_and_never_clipped(flagged_fit):
    """A covariance with a negative diagonal entry (an indefinite estimate) gives NaN, a reason and a flag."""
    import dataclasses
    import math
    cov = flagged_fit.covariance.copy()
    name = flagged_fit.names[-1]
    cov[-1, -1] = -abs(cov[-1, -1]) - 1e-12
    broken = dataclasses.replace(flagged_fit, covariance=cov)
    assert math.isnan(broken.stderr[name]) and math.isnan(broken.p_values[name]) and math.isnan(broken.t_values[name])
    assert list(broken.not_identifiable) == [name] and "negative" in broken.not_identifiable[name]
    assert not broken.identifiable and flagged_fit.identifiable
    assert all(math.isnan(broken.correlation[-1, j]) for j in range(len(broken.names) - 1))
    row = next(line for line in fit_report(broken, "markdown").splitlines() if line.startswith(f"| {name} "))
    assert "not identifiable" in row
    doc = broken.to_dict()
    assert doc["identifiable"] is False and name in doc["not_identifiable"]


def test_condition_number_of_the_scaled_jacobian():
    from structsearch.engine.statistics import scaled_condition_number
    rng = np.random.default_rng(3)
    jac = rng.standard_normal((200, 3)) * [1e-4, 1.0, 1e5]
    jac[:, 2] += 1e5 * 0.999 * jac[:, 1]  # nearly collinear columns
    unit = jac / np.linalg.norm(jac, axis=0)
    assert scaled_condition_number(jac) == pytest.approx(np.linalg.cond(unit), rel=1e-8)
    jac[:, 0] = 0.0
    assert scaled_condition_number(jac) == float("inf")


@pytest.mark.slow
def test_report_renders_for_a_campaign_without_x_cg(tmp_path):
    """Issue 12 items 4 and 6: the transport's campaign has no x_cg column and no cg envelope -> the pitch
    model that needs x_cg is replaced by one that does not, the centre of pressure is left out with a note,
    and neither an x_cg nor an envelope is printed."""
    data = tmp_path / "c"
    proc = run_cli("simulate", "--aircraft", "transport", "--scale", "0.05", "--seed", "3", "--out", str(data))
    assert proc.returncode == 0, proc.stderr
    assert "x_cg" not in (data / "campaign.toml").read_text() and "x_cg" not in (data / "m01.csv").open().readline()
    proc = run_cli("report", "--data", str(data), "--out", str(tmp_path / "r"), "--diagnose", "none",
                   "--starts", "1", "--model", "Cm-XXXIIIr")
    assert proc.returncode == 0, proc.stderr
    page = (tmp_path / "r" / "report.html").read_text()
    assert "Cm-XXXIIIr needs x_cg, which the campaign does not have" in page
    assert "cannot be placed" in page and "centre_of_pressure.png" not in page
    assert "x_cg = " not in page and "envelope" not in page
