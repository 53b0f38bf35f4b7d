"""Equivalences: a library term that is, to first order, also the signature of an anomaly (a vane lag: alpha_dot)."""
import dataclasses

import numpy as np
import pytest

from structsearch.data.flightdata import single_segment
from structsearch.diagnosis.equivalence import Equivalence, equivalences, slope
from structsearch.diagnosis.withheld import outside_right
from structsearch.discovery import effects as fx
from structsearch.discovery.equivalents import ALPHA_DOT_TERM, VANE_LAG, Signature, vane_lag_from_alpha_dot
from structsearch.fitting.candidates import Candidate
from structsearch.flight.anomalies import ANOMALIES

CBAR = 2.013


def test_every_declared_equivalent_names_an_anomaly_and_a_term_of_its_effect():
    declared = [(e, q) for e in fx.LIBRARY.values() for q in e.equivalents]
    assert [(e.name, q.anomaly) for e, q in declared] == [("alpha_dot", "vane_lag")]
    for e, q in declared:
        assert q.anomaly in ANOMALIES and q.unit and q.derivation
        added = dict(e.apply(Candidate("probe", "", "CL", (("CL0", "1"),))).regressors)
        assert q.term in added.values()
    assert fx.equivalents_of("alpha_dot * cbar / V") == [("alpha_dot", VANE_LAG)]
    assert fx.equivalents_of("qstar") == []


def test_vane_lag_conversion_at_one_airspeed_is_the_coefficient_ratio():
    # C_alphadot alpha_dot cbar/V = tau C_alpha alpha_dot  =>  tau = C_alphadot / C_alpha * cbar / V
    rng = np.random.default_rng(0)
    n, v, c_alpha, tau = 500, 70.0, 4.0, 0.3
    s = Signature(rng.normal(0, 0.05, n), np.full(n, v), CBAR, np.full(n, c_alpha))
    assert vane_lag_from_alpha_dot(tau * c_alpha * v / CBAR, s) == pytest.approx(tau, rel=1e-12)
    assert vane_lag_from_alpha_dot(-tau * c_alpha * v / CBAR, s) == pytest.approx(-tau, rel=1e-12)  # a lead
    flat = dataclasses.replace(s, slope=np.zeros(n))
    assert np.isnan(vane_lag_from_alpha_dot(1.0, flat))


def test_vane_lag_conversion_recovers_a_lag_from_a_lagged_signal():
    """The first-order derivation checked on a lagged signal: C = C_alpha alpha read through a vane lag tau,
    the alpha_dot term fitted by least squares to what the model misses, converted back."""
    rng = np.random.default_rng(1)
    dt, tau, c_alpha = 0.01, 0.38, 4.2
    t = np.arange(0, 60, dt)
    alpha = 0.1 + 0.04 * np.sin(0.6 * t) + 0.02 * np.sin(1.3 * t + 1.0)
    measured = np.empty_like(alpha)       # alpha_meas + tau d(alpha_meas)/dt = alpha, exact for linear input
    measured[0] = alpha[0]
    k = np.exp(-dt / tau)
    for i in range(1, len(t)):
        measured[i] = k * measured[i - 1] + (1 - k) * 0.5 * (alpha[i] + alpha[i - 1])
    keep = t > 5 * tau                    # past the start transient
    v = 60 + 20 * rng.random(len(t))      # airspeed varies: the least squares weighs it
    rate = np.gradient(measured, dt)
    missed = c_alpha * (alpha - measured)
    x = rate * CBAR / v
    coefficient = float(x[keep] @ missed[keep] / (x[keep] @ x[keep]))
    s = Signature(rate[keep], v[keep], CBAR, np.full(keep.sum(), c_alpha))
    assert vane_lag_from_alpha_dot(coefficient, s) == pytest.approx(tau, rel=0.02)


def _data(n=400, seed=2):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    alpha = 0.1 + 0.05 * np.sin(0.5 * t)
    return single_segment({"t": t, "alpha": alpha, "alpha_dot": 0.025 * np.cos(0.5 * t),
                           "V": 60 + 10 * rng.random(n), "q": np.zeros(n), "de": np.zeros(n),
                           "CL": np.zeros(n), "CD": np.zeros(n), "Cm": np.zeros(n)}, constants={"cbar": CBAR})


def test_equivalences_of_an_added_alpha_dot_term():
    data = _data()
    base = Candidate("lin", "test", "CL", (("CL0", "1"), ("CL_alpha", "alpha"), ("CL_qstar", "qstar")))
    added = fx.LIBRARY["alpha_dot"].apply(base)
    v_mean = 65.0
    params = {"CL0": 0.2, "CL_alpha": 4.0, "CL_qstar": 8.0, "CL_alphadot": 0.4 * 4.0 * v_mean / CBAR}
    assert slope(added, params, data) == pytest.approx(np.full(data.n_samples, 4.0), rel=1e-6)
    (eq,) = equivalences(base, added, params, data)
    assert (eq.effect, eq.term, eq.anomaly, eq.unit, eq.dropped) == ("alpha_dot", "CL_alphadot", "vane_lag", "s", ())
    assert eq.value == pytest.approx(0.4, rel=0.02)    # V between 60 and 70 m/s, against the 65 m/s put in
    assert eq.words().startswith("also the signature of a vane lag of about 0.4 s (CL_alphadot = ")
    assert Equivalence.from_dict(eq.to_dict()) == eq
    # a term the baseline had is not read; a replaced term is named beside the conversion
    assert equivalences(added, added, params, data) == ()
    swapped = Candidate("swap", "test", "CL", (("CL0", "1"), ("CL_alpha", "alpha"), ("CL_alphadot", ALPHA_DOT_TERM)))
    (eq,) = equivalences(base, swapped, params, data)
    assert eq.dropped == ("CL_qstar",) and "it replaced CL_qstar" in eq.words()


def test_the_benchmark_counts_explained_with_the_equivalence_named_as_right():
    # explained by library terms: right only with the equivalence named and at least half of the gap closed
    assert outside_right(True, True, located=False, false_claim=False, signal_first=False)
    assert not outside_right(True, False, located=True, false_claim=False, signal_first=True)
    assert not outside_right(True, True, located=True, false_claim=True, signal_first=True)
    # not explained: located, not falsely explained, the signal first (as before)
    assert outside_right(False, False, located=True, false_claim=False, signal_first=True)
    assert not outside_right(False, False, located=False, false_claim=False, signal_first=True)


def test_on_a_simulated_vane_lag_campaign_the_term_carries_part_of_the_lag():
    """A campaign flown with a known vane lag (pitch_rate withheld from the truth and the baseline, so that q*
    cannot take the lag up), the final lift structure without q* plus the alpha_dot term fitted: the conversion
    is positive, grows with the lag and stays below it, because the stall strip's time constants tau1 and tau2
    take up most of the lag (a lag of the state is a lag of alpha there); the equivalence says it is partial.
    Measured (seed 4, scale 0.05, no slow errors): 0.033 s of 0.25 s, 0.080 s of 0.4 s."""
    from structsearch.data.campaign import Maneuver, make_campaign
    from structsearch.diagnosis.withheld import baseline_without
    from structsearch.fitting.candidate_fit import fit_candidate
    from structsearch.fitting.options import FitOptions
    from structsearch.flight.aero import truth_model
    from structsearch.flight.aircraft import CITATION
    from structsearch.flight.flighttest import scaled_plan, simulate_campaign, thesis_plan
    base = baseline_without("pitch_rate")
    model = fx.LIBRARY["alpha_dot"].apply(base)
    plan = scaled_plan(thesis_plan(), 0.05)
    found = []
    for tau in (0.25, 0.4):
        lag = dataclasses.replace(ANOMALIES["vane_lag"], vane_lag_s=tau)
        segments = simulate_campaign(plan, truth_model(["pitch_rate"]), 4, slow_errors=0.0, anomaly=lag)
        c = make_campaign(f"vane lag {tau}", CITATION.manifest(5500.0),
                          [Maneuver(p.id, f"{p.id}.csv", p.kind, p.split) for p in plan], segments,
                          {"withheld": "pitch_rate", "anomaly": "vane_lag"})
        train, val = c.split("train"), c.split("validation")
        r = fit_candidate(model, train, val, None, FitOptions(n_starts=1))
        (eq,) = equivalences(base, model, r.estimates.params, train)
        assert eq.anomaly == "vane_lag" and eq.partial and "only the part the term carries" in eq.words()
        found.append(eq.value)
    assert 0 < found[0] < found[1] < 0.4 and found[1] < 0.25
