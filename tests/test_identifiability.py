"""Identifiability on a simulated campaign (scaled down for CI): CL-VI recovers the truth."""
import pytest

from structsearch.flight.flighttest import build_campaign
from structsearch.flight.reference import FINAL_LIFT, final_lift_model

KINDS = ("quasi-steady", "dynamic", "deep-dynamic")


@pytest.fixture(scope="module")
def campaign():
    # information content without the slow reconstruction errors: with them the estimated correlation
    # itself scatters (tau1-tau2 on the whole campaign -0.11 and -0.35 for seeds 0 and 1 at this scale)
    return build_campaign(seed=0, scale=0.5, slow_errors=0.0)


@pytest.fixture(scope="module")
def fits(campaign):
    model = final_lift_model()
    train = [i for i, m in enumerate(campaign.maneuvers) if m.split == "train" and m.kind in KINDS]
    quasi = [i for i in train if campaign.maneuvers[i].kind == "quasi-steady"]
    return (model.fit(campaign.data.select(train), n_starts=2, n_jobs=2),
            model.fit(campaign.data.select(quasi), n_starts=2, n_jobs=2))


def _tau_correlation(result):
    i, j = result.names.index("tau1_ss"), result.names.index("tau2_ss")
    return result.correlation[i, j]


def test_every_truth_parameter_within_three_sigma(fits):
    full, _ = fits
    for name, truth in FINAL_LIFT.items():
        assert abs(full.params[name] - truth) < 3 * full.stderr[name], name


def test_dynamic_stalls_decorrelate_tau1_and_tau2(fits):
    full, quasi = fits
    assert abs(_tau_correlation(quasi)) > 0.6
    assert abs(_tau_correlation(full)) < abs(_tau_correlation(quasi)) - 0.3
    assert full.stderr["tau1_ss"] < 0.5 * quasi.stderr["tau1_ss"]


def test_the_study_table_reports_the_decorrelation(campaign):
    """Issue 16 (replacing issue 3's strict xfail on |rho| < 0.3): the study's Tables 10.1-10.3 counterpart,
    on the same maneuvers, shows the dynamic stalls cutting |rho(tau1_ss, tau2_ss)| by at least 0.3; the
    thesis' 0.06 is not what this simulated plan gives (docs/guide/study.md)."""
    from structsearch.fitting.options import FitOptions
    from structsearch.thesis_study.dynamic_stalls import dynamic_stall_study
    study = dynamic_stall_study(campaign, options=FitOptions(n_starts=2))
    (a, b, quasi, full), _ = study.called_out()
    assert (a, b) == ("tau1_ss", "tau2_ss")
    assert abs(full) <= abs(quasi) - 0.3, (quasi, full)
    i = study.full.names.index("tau1_ss")
    assert study.full.sd[i] < study.quasi_steady.sd[study.quasi_steady.names.index("tau1_ss")]


def test_dynamic_stalls_alone_separate_lag_from_delay(campaign):
    """The dynamic stalls carry the information that tells tau1 from tau2 (what issue 3's 0.3 asks of the
    whole campaign holds for them alone; the quasi-steady stalls outweigh them in the Table-4 mix)."""
    model = final_lift_model()
    dynamic = [i for i, m in enumerate(campaign.maneuvers) if m.kind == "dynamic"]
    start = {k: FINAL_LIFT[k] for k in model.nonlinear_names}
    result = model.fit(campaign.data.select(dynamic), start=start)
    assert abs(_tau_correlation(result)) < 0.3
