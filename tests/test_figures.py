"""The campaign report: figures exist and carry content, derived curves match the thesis' equations."""
import base64
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import fitter_for

from structsearch.reporting import figure_data as rd
from structsearch.data.campaign import read_campaign, write_campaign
from structsearch.flight.flighttest import build_campaign
from structsearch.fitting.options import FitOptions
from structsearch.flight.reference import FINAL_MODEL_NAMES
from structsearch.engine.separation import static_separation

from test_report_cli import run_cli

pytest.importorskip("matplotlib")

FIGURES = ("separation_static", "lift_static", "drag_polar", "pitch_static", "centre_of_pressure",
           "elevator_effectiveness", "time_traces", "hysteresis", "correlations", "gap_breakdown",
           "forward_simulation")


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    path = tmp_path_factory.mktemp("campaign") / "c"
    write_campaign(build_campaign(seed=3, scale=0.05), path)
    return read_campaign(path)


@pytest.fixture(scope="module")
def report_run(small, tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    # the thesis' final structures named (no search ranking: the report would run the search first)
    proc = run_cli("report", "--data", str(small.directory), "--out", str(out), "--starts", "2", "--quiet",
                   *(arg for name in FINAL_MODEL_NAMES.values() for arg in ("--model", name)))
    return proc, out


@pytest.fixture(scope="module")
def model_set(small, report_run):
    # the report's cache serves these fits
    from structsearch.thesis_study.model_set import fit_model_set
    return fit_model_set("identified", FINAL_MODEL_NAMES, fitter_for(small, report_run[1], FitOptions(n_starts=2)))


@pytest.mark.slow
def test_report_writes_every_figure_with_content(report_run):
    from matplotlib.image import imread
    proc, out = report_run
    assert proc.returncode == 0, proc.stderr
    assert "report.html" in proc.stdout
    for name in FIGURES:
        path = out / "figures" / f"{name}.png"
        assert path.exists(), name
        assert path.stat().st_size > 15_000, name
        image = imread(path)[..., :3]
        # more than a blank canvas with axes: many distinct colours, and not mostly white
        distinct = len(np.unique((image * 255).astype(np.uint8).reshape(-1, 3), axis=0))
        assert distinct > 200, (name, distinct)
        assert np.mean(image < 0.95) > 0.03, name


def test_html_is_self_contained_with_captions(report_run):
    _, out = report_run
    page = (out / "report.html").read_text()
    images = re.findall(r"<img src='data:image/png;base64,([A-Za-z0-9+/=]+)'", page)
    assert len(images) == len(FIGURES)
    assert all(base64.b64decode(i)[:8] == b"\x89PNG\r\n\x1a\n" for i in images)
    assert page.count("<figcaption>") == len(FIGURES)
    assert "http://" not in page and "https://" not in page
    # the final structures named on the command line, and the page says so
    assert "CL-VI" in page and "Cm-XXXIIIr" in page and "named on the command line" in page
    assert "<table>" in page
    # the static curves carry their bands, and the captions say which (issue 29)
    assert page.count("95 % confidence band (where the true static curve lies") == 2


def test_centre_of_pressure_and_elevator_effectiveness_follow_eqs_32_33(model_set, small):
    ref = rd.reference(small.split("train"))
    alpha = np.linspace(0.0, 0.4, 41)
    got = rd.derived_pitch(model_set, alpha, ref)
    p = model_set.aero.params
    x_ss = static_separation(alpha, p["a1_ss"], p["a_star_ss"])
    x_w = static_separation(alpha, p["a1_w"], p["a_star_w"])
    l_cp = -(p["Cm_CL"] + p["Cm_1mX_ssCL"] * (1 - x_ss) + p["Cm_1mX_wCL"] * (1 - x_w)
             + p["Cm_xcgCL"] * ref.x_cg / ref.constants["cbar"])
    np.testing.assert_allclose(got["l_cp"], l_cp, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(got["x_cp"], ref.x_cg + l_cp * ref.constants["cbar"], rtol=1e-12)
    np.testing.assert_allclose(got["Cm_de"], p["Cm_de"] + p["Cm_Xde_ss"] * x_ss, rtol=1e-10, atol=1e-12)


def test_static_lift_curve_is_eq_34_at_equilibrium(model_set, small):
    ref = rd.reference(small.split("train"))
    alpha = np.linspace(0.0, 0.4, 41)
    p = model_set.aero.params
    kl = lambda x: ((1 + np.sqrt(x)) / 2) ** 2 * alpha  # noqa: E731
    expected = (p["CL0"] + p["CL_KL_ss"] * kl(static_separation(alpha, p["a1_ss"], p["a_star_ss"]))
                + p["CL_KL_w"] * kl(static_separation(alpha, p["a1_w"], p["a_star_w"])))
    np.testing.assert_allclose(rd.static_coefficients(model_set, alpha, ref)["CL"], expected, rtol=1e-12)


def test_stall_stages_invert_the_separation_curve(model_set):
    curves = rd.separation_curves(model_set, np.linspace(0, 0.4, 5))
    for c in curves.values():
        for (label, level), a in zip(rd.STAGES, c["stages"].values()):
            assert static_separation(np.array([a]), c["a1"], c["a_star"])[0] == pytest.approx(level, abs=1e-12)


def test_corrected_points_scatter_around_the_static_curve(model_set, small):
    """Partial residuals: subtracting the static curve leaves the model's residuals (mean ~ 0)."""
    ref = rd.reference(small.split("train"))
    pts = rd.partial_points(model_set, small.data, ref, max_points=3000)
    static = rd.static_coefficients(model_set, pts["alpha"], ref)
    for coef in rd.LONGITUDINAL:
        off = pts[coef] - static[coef]
        spread = np.std(small.data[coef])
        assert abs(np.mean(off)) < 0.05 * spread, coef


def test_gap_cells_are_per_maneuver_band_mse(small):
    val = small.split("validation")
    rng = np.random.default_rng(5)
    residual = rng.normal(size=val.n_samples)
    bands = rd.alpha_bands(val["alpha"])
    cells = rd.gap_cells(residual, val, bands)
    sl = val.segment_slices()[0]
    a = val["alpha"][sl]
    for j in range(len(bands) - 1):
        inside = (a >= bands[j]) & (a < bands[j + 1])
        if inside.any():
            assert cells[0, j] == pytest.approx(np.mean(residual[sl][inside] ** 2))
        else:
            assert np.isnan(cells[0, j])


def test_core_imports_without_matplotlib():
    code = ("import sys; sys.modules['matplotlib'] = None\n"
            "import structsearch, structsearch.cli, structsearch.reporting.page as cr, structsearch.reporting.figures as f\n"
            "assert f.plt is None\n"
            "from structsearch.data.errors import StructSearchError\n"
            "try:\n    f.require()\nexcept StructSearchError as e:\n    print(e)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "structsearch[figures]" in proc.stdout


def test_report_models_come_from_the_ranking_or_the_command_line(tmp_path):
    """Issue 43: a refined winner is shown as itself (read back from refined_<grid>.toml), never swapped for the
    thesis' final structures; a drag or pitch winner on another lift model keeps it."""
    from structsearch.reporting.choice import chosen_models
    from structsearch.reporting.refined import write_refined
    from structsearch.grid_search.refinement import _refined
    from structsearch.fitting.specs import find_candidate
    choice = chosen_models(tmp_path)
    assert choice.names == FINAL_MODEL_NAMES and "final structures" in choice.notes[0]
    (tmp_path / "ranking.csv").write_text("grid,model,rank\nlift,CL-VI,1\ndrag,CD-IX,1\npitch,Cm-XXXIr-auto,1\n"
                                          "pitch,Cm-XXXI,2\n")
    with pytest.raises(Exception, match="refined_<grid>.toml"):
        chosen_models(tmp_path)
    refined = _refined(find_candidate("Cm-XXXI"), ["Cm_qstar"], "r-auto")
    write_refined(tmp_path, {"pitch": [refined]})
    choice = chosen_models(tmp_path)
    assert {k: c.name for k, c in choice.winners.items()} == {"CL": "CL-VI", "CD": "CD-IX", "Cm": "Cm-XXXIr-auto"}
    assert choice.winners["Cm"] == refined and choice.shown == choice.winners
    assert chosen_models(tmp_path, ("Cm-XXXI",)).names == {"CL": "CL-VI", "CD": "CD-IX", "Cm": "Cm-XXXI"}
    (tmp_path / "ranking.csv").write_text("grid,model,rank\nlift,CL-II,1\ndrag,CD-IX,1\npitch,Cm-XXXIr-auto,1\n")
    choice = chosen_models(tmp_path)
    assert choice.winners["CL"].name == "CL-II" and choice.shown["CL"].name == "CL-VI"
    assert choice.winners["CD"].name == "CD-IX" and choice.lifts["Cm"].name == "CL-VI"
    assert any("takes its separation states from CL-VI" in n for n in choice.notes)


def test_a_ranking_without_its_columns_is_one_clear_error(small, tmp_path):
    (tmp_path / "ranking.csv").write_text("grid,name\nlift,CL-VI\n")
    proc = run_cli("report", "--data", str(small.directory), "--out", str(tmp_path), "--quiet")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert "ranking.csv" in proc.stderr and "'model'" in proc.stderr and "row 1" in proc.stderr


def test_a_move_that_changes_little_is_said_to_in_the_gap_figure():
    """Issue 31: gap_breakdown.png drew two identical panels when the effect changed little; its third panel
    is the change, whose title says when the maps look alike."""
    from structsearch.reporting.figures import LITTLE_CHANGE, gap_change_words
    before = np.array([[1.0, 2.0], [np.nan, 4.0]])
    assert "look alike" in gap_change_words(before, before * (1 - LITTLE_CHANGE / 10))
    words = gap_change_words(before, before * 0.5)
    assert "look alike" not in words and "-50%" in words


def test_a_comparison_curve_away_from_every_point_is_explained_in_the_figure():
    """Issue 31: in pitch_static.png the refitted Cm-I lay above every measured point with the reason only in the
    caption; the figure now says why."""
    from structsearch.reporting.page import offset_note
    alpha = np.linspace(0.0, 0.4, 50)
    points = {"alpha": np.linspace(0.05, 0.35, 200)}
    points["Cm"] = -0.5 * points["alpha"]
    above = offset_note("Cm", alpha, {"Cm": -0.5 * alpha + 0.03}, points, "Cm-XXXIIIr", "Cm-I")
    assert above.startswith("Cm-I lies above 100% of the points") and "delta_e follows alpha" in above
    assert offset_note("Cm", alpha, {"Cm": -0.5 * alpha - 0.03}, points, "M", "V").startswith("V lies below")
    wiggle = {"alpha": points["alpha"], "Cm": points["Cm"] + 0.01 * np.sin(40 * points["alpha"])}
    assert offset_note("Cm", alpha, {"Cm": -0.5 * alpha}, wiggle, "M", "V") is None
    assert offset_note("Cm", alpha, None, points, "M", "V") is None
