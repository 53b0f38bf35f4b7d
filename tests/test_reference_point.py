"""C_m about a fixed reference point, moved to the recorded cg by the known transfer (docs/interfaces.md 7.5,
docs/guide/moment-reference.md)."""
import dataclasses
import json

import numpy as np
import pytest

from structsearch.data.campaign import read_campaign, with_reference_point
from structsearch.data.errors import DataError, DeclarationError
from structsearch.data.flightdata import from_segments
from structsearch.data.moment_transfer import TRANSFER_EXPRESSION, TRANSFER_NAME
from structsearch.engine.stallmodel import StallModel
from structsearch.fitting.candidates import Candidate
from structsearch.fitting.options import FitOptions
from structsearch.fitting.runner import cache_path, campaign_fingerprint, same_model_fitted
from structsearch.fitting.specs import find_candidate, load_grid

CBAR = 2.013


def _moment_about(station, force_station, alpha, lift, drag, couple):
    """Pitching moment (nose up) about body station ``station`` of a lift and drag acting at ``force_station`` plus
    a pure couple, from the force vector: body axes x forward, y right, z down, a station grows aft (its body x is
    -station), the airflow comes along (cos alpha, 0, sin alpha)."""
    flow = np.array([np.cos(alpha), 0.0, np.sin(alpha)])
    force = -drag * flow + lift * np.array([np.sin(alpha), 0.0, -np.cos(alpha)])
    arm = np.array([-(force_station - station), 0.0, 0.0])
    return couple + np.cross(arm, force)[1]


def _transfer_on(alpha, cl, cd, x_cg, x_ref):
    data = from_segments([{"t": np.arange(len(alpha)) * 0.01, "alpha": alpha, "CL": cl, "CD": cd, "x_cg": x_cg,
                           "Cm": np.zeros(len(alpha))}],
                         constants={"cbar": CBAR, "S": 30.0, "b": 15.75, "reference_point": x_ref})
    model = StallModel.declare("about the point", "Cm", {"Cm0": "1"}, offset=(TRANSFER_NAME, TRANSFER_EXPRESSION))
    return model.offset_value(data)


def test_transfer_is_the_moment_of_the_forces_about_two_points():
    """The known term equals the difference of the moments about the recorded cg and the reference point, computed
    from the force vectors by hand: lift and drag at a station that is neither, plus a pure couple."""
    rng = np.random.default_rng(4)
    n, qs = 50, 0.5 * 1.0 * 80.0 ** 2 * 30.0
    alpha = rng.uniform(-0.1, 0.5, n)
    lift, drag, couple = qs * rng.uniform(-0.3, 1.5, n), qs * rng.uniform(0.01, 0.4, n), qs * CBAR * rng.normal(0, .1, n)
    x_cg, x_ref, x_force = 7.0 + 0.3 * rng.random(n), 7.14, 7.0 + rng.normal(0.0, 0.5, n)
    about_cg = np.array([_moment_about(x_cg[i], x_force[i], alpha[i], lift[i], drag[i], couple[i]) for i in range(n)])
    about_ref = np.array([_moment_about(x_ref, x_force[i], alpha[i], lift[i], drag[i], couple[i]) for i in range(n)])
    expected = (about_cg - about_ref) / (qs * CBAR)
    got = _transfer_on(alpha, lift / qs, drag / qs, x_cg, x_ref)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
    # an aft cg (larger station) with positive lift pitches the nose up: the sign convention of the stations
    assert np.all(_transfer_on(np.zeros(3), np.ones(3), np.zeros(3), np.full(3, 7.2), 7.1) > 0)


def test_simulator_truth_with_the_transfer_moves_its_moment_by_it():
    """The "transfer" truth (simulate --cg-moment transfer): two cgs, everything else equal, differ in C_m by the
    hand-computed transfer of its own C_L and C_D; the thesis' truth does not (its cg term has the other sign)."""
    from structsearch.flight.aero import truth_model
    from structsearch.flight.aircraft import CITATION
    n = 20
    alpha = np.linspace(0.0, 0.35, n)
    values = {"alpha": alpha, "q": np.zeros(n), "V": np.full(n, 85.0), "de": np.full(n, -0.05), "CT": np.full(n, .05),
              "cbar": CITATION.cbar, "S": CITATION.S, "b": CITATION.b, "h": np.full(n, 5000.0),
              "X_ss": np.linspace(1.0, 0.2, n), "X_w": np.linspace(1.0, 0.8, n)}
    for cg_moment, sign in (("transfer", 1.0), ("thesis", -1.0)):
        truth = truth_model(cg_moment=cg_moment)
        cl, cd, cm_fwd = truth.coefficients(dict(values, x_cg=np.full(n, 7.05)))
        _, _, cm_aft = truth.coefficients(dict(values, x_cg=np.full(n, 7.25)))
        handmade = (cl * np.cos(alpha) + cd * np.sin(alpha)) * 0.2 / CITATION.cbar
        if cg_moment == "transfer":
            np.testing.assert_allclose(cm_aft - cm_fwd, handmade, rtol=1e-10, atol=1e-13)
        assert np.sign(np.mean(cm_aft - cm_fwd)) == sign
    # at the reference point the transfer truth is the thesis' model
    at_ref = dict(values, x_cg=np.full(n, CITATION.reference_point))
    np.testing.assert_allclose(truth_model(cg_moment="transfer").coefficients(at_ref)[2],
                               truth_model().coefficients(at_ref)[2], rtol=1e-10, atol=1e-13)


def test_a_known_offset_fits_as_if_applied_to_the_data(small_campaign):
    """Fitting C_m with the transfer as a known term gives the estimates of fitting (C_m - transfer) without it, and
    the same residuals: scores stay comparable with models about the cg."""
    from structsearch.flight.reference import FINAL_LIFT
    rng = np.random.default_rng(2)
    cols = dict(small_campaign.columns)
    n = small_campaign.n_samples
    cols.update(CL=0.1 + 5.0 * cols["alpha"], CD=0.03 + cols["alpha"] ** 2, x_cg=7.0 + 0.2 * rng.random(n))
    cols["Cm"] = 0.02 - 0.3 * cols["CL"] + 0.5 * (cols["x_cg"] - 7.1) / CBAR * cols["CL"] + rng.normal(0, .01, n)
    data = small_campaign.with_columns(cols)
    data = dataclasses.replace(data, constants={**data.constants, "reference_point": 7.1})
    regs = {"Cm0": "1", "Cm_CL": "CL", "Cm_1mX": "(1 - X)*CL"}
    fixed = {k: FINAL_LIFT[k + "_ss"] for k in ("tau1", "tau2", "a1", "a_star")}
    about = StallModel.declare("about", "Cm", regs, states={"": "U"}, fixed=fixed,
                               offset=(TRANSFER_NAME, TRANSFER_EXPRESSION))
    plain = StallModel.declare("plain", "Cm", regs, states={"": "U"}, fixed=fixed)
    moved = data.with_columns({**data.columns, "Cm": data["Cm"] - about.offset_value(data)})
    a, p = about.fit(data, covariance="white"), plain.fit(moved, covariance="white")
    assert a.params == pytest.approx(p.params, rel=1e-9, abs=1e-12)
    np.testing.assert_allclose(data["Cm"] - about.predict(data, a.params), moved["Cm"] - plain.predict(moved, p.params),
                               atol=1e-12)
    assert "Cm = Cm_transfer + Cm0" in a.equations.text[0]
    assert any(TRANSFER_EXPRESSION in line for line in a.equations.text)


# ----- declarations -----------------------------------------------------------------------------------------
def test_the_shipped_grid_has_the_final_model_about_the_fixed_point():
    pitch = load_grid("pitch")
    fixed, final = pitch["Cm-XXXIIIf"], pitch["Cm-XXXIIIr"]
    assert fixed.moment_reference == "fixed" and final.moment_reference == "cg"
    assert dict(fixed.regressors) == {k: v for k, v in final.regressors if k != "Cm_xcgCL"}
    assert Candidate.from_dict(fixed.to_dict()) == fixed
    assert "moment_reference" not in final.to_dict()   # a cg candidate's dict (its cache key) is unchanged


def test_a_spec_entry_declares_its_reference(tmp_path):
    from structsearch.discovery.spec_file import spec_text
    spec = tmp_path / "mine.toml"
    spec.write_text('name = "mine"\ncoefficient = "Cm"\nlift = "CL-VI"\n[[entry]]\nname = "Cm-mine"\n'
                    'regressors = { Cm0 = "1", Cm_CL = "CL" }\nmoment_reference = "fixed"\n')
    c = load_grid(str(spec))["Cm-mine"]
    assert c.moment_reference == "fixed"
    again = tmp_path / "again.toml"
    again.write_text(spec_text(c))
    assert load_grid(str(again))["Cm-mine"] == c     # discover's and the refinement's spec files keep it
    spec.write_text(spec.read_text().replace('"fixed"', '"nose"'))
    with pytest.raises(DeclarationError, match=r"mine.toml \[\[entry\]\] #1: moment_reference must be one of"):
        load_grid(str(spec))
    lift = tmp_path / "lift.toml"
    lift.write_text('name = "l"\ncoefficient = "CL"\n[[entry]]\nname = "CL-x"\nregressors = { CL0 = "1" }\n'
                    'moment_reference = "fixed"\n')
    with pytest.raises(DeclarationError, match="this grid models CL"):
        load_grid(str(lift))


def test_moves_and_stages_keep_the_reference():
    """A structure search's children, a refinement's and a fit's quasi-steady stage take C_m about the same point."""
    from structsearch.discovery.effects import applicable
    from structsearch.discovery.moves import _child
    from structsearch.fitting.staging import demoted
    from structsearch.grid_search.refinement import _refined
    c = find_candidate("Cm-XXXIIIf")
    assert demoted(c, "Q").moment_reference == "fixed"
    assert _child(c, "fewer", c.regressors[:-1]).moment_reference == "fixed"
    assert _refined(c, ["Cm_CT"], "r").moment_reference == "fixed"
    moved = [e.apply(c) for e in applicable(c)]
    assert moved and all(m.moment_reference == "fixed" for m in moved)


# ----- the manifest key and the option ------------------------------------------------------------------------
def _campaign_dir(path, aircraft_lines: str, x_cg: float = 7.1):
    t = np.arange(0, 4, 0.01)
    path.mkdir()
    for name in ("m1", "m2"):
        cols = {"t": t, "alpha": 0.1 + 0.05 * np.sin(t), "q": 0.05 * np.cos(t), "V": 80 + 0 * t, "de": 0 * t,
                "CL": 0.5 + 0 * t, "CD": 0.05 + 0 * t, "Cm": 0 * t, "x_cg": x_cg + 0 * t}
        np.savetxt(path / f"{name}.csv", np.column_stack(list(cols.values())), delimiter=",",
                   header=",".join(cols), comments="")
    (path / "campaign.toml").write_text(
        f'name = "t"\n[aircraft]\nS = 30.0\ncbar = {CBAR}\nb = 15.75\n{aircraft_lines}\n'
        '[[maneuver]]\nid = "m1"\nfile = "m1.csv"\nkind = "quasi-steady"\nsplit = "train"\n'
        '[[maneuver]]\nid = "m2"\nfile = "m2.csv"\nkind = "quasi-steady"\nsplit = "validation"\n')
    return path


@pytest.mark.parametrize("lines,x_cg,message", [
    ("reference_point = nan", 7.1, "reference_point must be a finite number"),
    ('reference_point = "7.1"', 7.1, "reference_point must be a finite number"),
    ("reference_point = true", 7.1, "reference_point must be a finite number"),
    ("x_cg_range = [7.0, 7.3]\nreference_point = 281.25", 7.1, "chords from the cg envelope"),
    ("reference_point = 281.25\nx_cg_range = [7.0, 7.3]", 7.1, "chords from the cg envelope"),
    ("reference_point = 5000.0", 7.1, "not a body station"),
    ("reference_point = 7.14", 281.0, "chords from a recorded x_cg"),
])
def test_bad_reference_points_are_one_error_naming_file_and_key(tmp_path, lines, x_cg, message):
    directory = _campaign_dir(tmp_path / "c", lines, x_cg)
    with pytest.raises(DataError, match=message) as err:
        read_campaign(directory)
    assert "campaign.toml" in str(err.value) and "'reference_point'" in str(err.value)


def test_the_option_replaces_the_manifest_point(tmp_path):
    campaign = read_campaign(_campaign_dir(tmp_path / "c", "x_cg_range = [7.0, 7.3]\nreference_point = 7.14"))
    assert campaign.data.constants["reference_point"] == 7.14
    moved = with_reference_point(campaign, 7.2)
    assert moved.aircraft["reference_point"] == moved.data.constants["reference_point"] == 7.2
    with pytest.raises(DataError, match=r"--reference-point.*chords from the cg envelope"):
        with_reference_point(campaign, 281.0)


# ----- the cache ----------------------------------------------------------------------------------------------
def test_a_cg_fit_is_never_served_for_a_fixed_point_fit(tmp_path):
    """The candidate's reference is in its cache key, the reference point in the data key; a fixed-point candidate
    is no twin of the same structure about the cg."""
    campaign = read_campaign(_campaign_dir(tmp_path / "c", "x_cg_range = [7.0, 7.3]\nreference_point = 7.14"))
    cg = find_candidate("Cm-XXXIIIr")
    fixed = cg.with_moment_reference("fixed")
    key = campaign_fingerprint(campaign)
    assert cache_path(tmp_path, cg, key, None, FitOptions()) != cache_path(tmp_path, fixed, key, None, FitOptions())
    assert key != campaign_fingerprint(with_reference_point(campaign, 7.2))
    assert same_model_fitted([fixed], [(cg, _fitted_stub())]) == {}
    assert same_model_fitted([cg], [(cg, _fitted_stub())]) != {}


def _fitted_stub():
    class Fitted:
        failed = False
    return Fitted()


@pytest.mark.slow
def test_fixed_and_cg_fits_of_one_structure_differ_in_one_cache(simulated_campaign, tmp_path):
    """Fitted through one cache, the structure about the cg and about the fixed point are two fits: their cg term
    differs by the transfer (about 1: C_N/C_L), every other estimate nearly equal."""
    from structsearch.fitting.fitter import Fitter, RunConfig
    from structsearch.fitting.lift_fit import LiftFit
    campaign = simulated_campaign(0, 0.05)
    fitter = Fitter(RunConfig(campaign, tmp_path, FitOptions(n_starts=1, cv_folds=0)))
    lift_c = find_candidate("CL-VI")
    fitter = fitter.with_lifts({"CL-VI": LiftFit(lift_c, fitter.fit_one(lift_c))})
    cg = find_candidate("Cm-XXXIIIr")
    r_cg, r_fixed = fitter.fit([cg, cg.with_moment_reference("fixed")])
    assert len(list((tmp_path / "cache" / "pitch").glob("Cm-XXXIIIr-*.json"))) == 2
    shift = r_fixed.estimates.params["Cm_xcgCL"] - r_cg.estimates.params["Cm_xcgCL"]
    assert shift == pytest.approx(-1.0, abs=0.05)
    assert r_fixed.mse_train == pytest.approx(r_cg.mse_train, rel=0.02)
    assert any("Cm_transfer" in line for line in r_fixed.equations.text)


# ----- the comparison -----------------------------------------------------------------------------------------
def test_without_a_cg_term_within_noise_where_the_truth_is_a_transfer(simulated_campaign):
    """A default-band campaign whose truth moves C_m to the cg by the transfer alone: Cm-XXXIIIr's cg term is
    not needed, the fixed-point structure is within noise of it on the validation maneuvers."""
    from structsearch.experiments.reference_point import compare_references
    out = compare_references(simulated_campaign(0, 0.1, cg_moment="transfer"), options=FitOptions(n_starts=1))
    assert out.validation.fixed_within_noise, out


def test_the_thesis_truth_has_a_cg_term_that_is_no_transfer(simulated_campaign):
    """The default truth's cg term is the thesis' Cm_xcgCL = -0.96 (a transfer is +1 times C_N): without a cg term
    the fixed-point structure misses the rest, -1.96 x_cg/cbar C_L, and is worse on the validation maneuvers."""
    from structsearch.experiments.reference_point import compare_references
    out = compare_references(simulated_campaign(0, 0.1), options=FitOptions(n_starts=1))
    assert not out.validation.fixed_within_noise and out.validation.mean > 0.1, out


def test_a_wide_cg_spread_shows_the_cg_term_is_the_transfer(simulated_campaign):
    """Loadings 0.24 m apart and a truth that is the transfer: Cm-XXXIIIr's own cg term estimates the transfer
    (Cm_xcgCL about 1, C_N/C_L), and the fixed-point structure, which knows it, is within noise of it."""
    from structsearch.experiments.reference_point import compare_references
    out = compare_references(simulated_campaign(0, 0.1, cg_spread=0.24, cg_moment="transfer"),
                             options=FitOptions(n_starts=1))
    value, sd = out.estimates["Cm-XXXIIIr Cm_xcgCL"]
    assert abs(value - 1.0) < max(3 * sd, 0.1) and out.validation.fixed_within_noise, out


# ----- the command line ---------------------------------------------------------------------------------------
def test_cli_refuses_a_reference_point_off_the_aircraft(run_cli, tmp_path):
    data = _campaign_dir(tmp_path / "c", "x_cg_range = [7.0, 7.3]\nreference_point = 7.14")
    proc = run_cli("fit", "--data", data, "--model", "Cm-XXXIIIf", "--reference-point", "281.25",
                   "--out", tmp_path / "o")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1
    assert "reference_point" in proc.stderr and "--reference-point" in proc.stderr


@pytest.mark.slow
def test_cli_fits_about_the_point_the_command_line_names(run_cli, tmp_path):
    data, out = tmp_path / "c", tmp_path / "o"
    proc = run_cli("simulate", "--out", data, "--scale", "0.05", "--cg-spread", "0.2", "--cg-moment", "transfer")
    assert proc.returncode == 0, proc.stderr
    assert "cg_spread = 0.2" in (data / "campaign.toml").read_text()
    proc = run_cli("fit", "--data", data, "--model", "Cm-XXXIIIr", "--moment-reference", "fixed",
                   "--reference-point", "7.2", "--starts", "1", "--out", out)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((out / "fit.json").read_text())
    assert doc["moment_reference"]["about"] == "fixed" and doc["moment_reference"]["reference_point"] == 7.2
    assert doc["equations"]["text"][0].startswith("Cm = Cm_transfer + ")
