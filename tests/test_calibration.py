"""Calibration: the coverage arithmetic on constructed draws, and a small end-to-end run (CI version)."""
import json
import subprocess
import sys

import numpy as np
import pytest

from structsearch.experiments.calibration import TRUTH, CampaignDraw, summarise
from structsearch.flight.reference import FINAL_MODEL_NAMES


def _draws(offsets_in_sd, sd=0.01, p_values=(0.5, 0.005, 0.2), dof=None):
    """Campaigns whose every estimate is truth + offset * sd, reported with standard deviation sd
    (and t reference ``dof`` when given)."""
    out = []
    for i, off in enumerate(offsets_in_sd):
        est = {FINAL_MODEL_NAMES[c]: {p: v + off * sd for p, v in TRUTH[c].items()} for c in TRUTH}
        sds = {"white": {FINAL_MODEL_NAMES[c]: {p: sd for p in TRUTH[c]} for c in TRUTH}}
        gap = {"white": dict(zip(FINAL_MODEL_NAMES.values(), p_values))}
        dofs = {} if dof is None else {"white": {FINAL_MODEL_NAMES[c]: {p: dof for p in TRUTH[c]} for c in TRUTH}}
        out.append(CampaignDraw(seed=i, samples=100, estimates=est, stderr=sds, gap_p=gap, dof=dofs))
    return out


def test_coverage_ratio_and_rejections_from_known_draws():
    offsets = [0.0, 0.5, -1.5, 2.5, -3.0]          # inside 95 %: 0, 0.5, -1.5 -> 3 of 5
    cal = summarise(_draws(offsets), scale=0.1)
    kind = cal.kinds[0]
    assert {p.parameter for p in kind.parameters} == {p for c in TRUTH for p in TRUTH[c]}
    for p in kind.parameters:
        assert p.coverage95 == pytest.approx(3 / 5)
        assert p.coverage68 == pytest.approx(2 / 5)   # |offset| <= 0.9945: 0 and 0.5
        assert p.mc_sd == pytest.approx(0.01 * np.std(offsets, ddof=1))
        assert p.ratio == pytest.approx(1 / np.std(offsets, ddof=1))
        assert p.bias_in_sd == pytest.approx(np.mean(offsets) / np.std(offsets, ddof=1))
    assert kind.rejections == 5 and kind.gap_tests == 15 and kind.rejection_rate == pytest.approx(1 / 3)
    assert not kind.meets_goals


def test_intervals_use_the_student_t_of_the_reported_dof():
    """t(4): 97.5 % quantile 2.776, 84.1 % quantile 1.134 -> offsets 2.5 and -1.5 move inside."""
    offsets = [0.0, 0.5, -1.5, 2.5, -3.0]
    kind = summarise(_draws(offsets, dof=4), scale=0.1).kinds[0]
    assert all(p.coverage95 == pytest.approx(4 / 5) and p.coverage68 == pytest.approx(2 / 5)
               for p in kind.parameters)


def test_missing_standard_deviation_is_left_out_and_counted():
    draws = _draws([0.0, 0.1, -0.2])
    name = FINAL_MODEL_NAMES["CL"]
    draws[0].stderr["white"][name]["tau1_ss"] = float("nan")
    row = next(p for p in summarise(draws, 0.1).kinds[0].parameters if p.parameter == "tau1_ss")
    assert row.n == 2 and row.coverage95 == 1.0


@pytest.mark.slow
def test_calibration_command_end_to_end(tmp_path):
    """The CI version: two scaled campaigns, every covariance kind, strict JSON and the markdown."""
    out = subprocess.run([sys.executable, "-m", "structsearch", "bench", "--calibration", "--campaigns", "2",
                          "--scale", "0.05", "--jobs", "2", "--out", str(tmp_path)],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    doc = json.loads((tmp_path / "calibration.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert set(doc["kinds"]) == {"colored", "white", "hac", "hac-qs", "hac-maneuver", "cluster"}
    for name, kind in doc["kinds"].items():
        assert kind["gap_tests"] + kind["gap_tests_not_estimable"] == 6
        rows = kind["parameters"]
        assert len(rows) == sum(len(t) for t in TRUTH.values())
        if name == "cluster":
            # four training maneuvers, up to 11 parameters: not estimable, reported as null (never 0)
            assert all(r["n"] == 0 and r["reported_sd"] is None for r in rows)
            assert kind["pooled_coverage95"] is None
        else:  # every final-model parameter got a positive standard deviation in both campaigns
            assert all(r["n"] == 2 and r["reported_sd"] > 0 for r in rows)
    text = (tmp_path / "calibration.md").read_text()
    assert "bench --calibration --campaigns 2 --scale 0.05" in text and "## cluster" in text
    # the static curves' bands against the truth (issue 29): a coverage per coefficient, from both campaigns
    for coef in ("CL", "CD", "Cm"):
        band = doc["bands"][coef]
        assert 0.0 <= band["campaign_min"] <= band["coverage95"] <= band["campaign_max"] <= 1.0
        assert band["mean_half_width"] > 0
    assert "Static curves: 95 % confidence bands against the truth" in text
    # the joint fit's parameters (issue 29): every final-model parameter once, the shared ones from the joint fit
    joint = {r["parameter"]: r for r in doc["joint"]}
    assert set(joint) == {p for c in TRUTH for p in TRUTH[c]} and all(r["n"] == 2 for r in joint.values())
    assert "## Joint fit of the three final models" in text
    assert "best calibrated" in out.stdout
    # issue 30: held-out seeds by default, the default-start fits apart, the interface's per-parameter names
    assert doc["seeds"]["held_out"] is True and doc["seeds"]["values"] == [2000, 2001]
    start = doc["default_start"]
    assert start["covariance"] == "hac-maneuver" and len(start["parameters"]) == sum(len(t) for t in TRUTH.values())
    assert all(r["n"] == 2 and r["sd_ratio"] == r["ratio"] and r["coverage_95"] == r["coverage95"]
               for r in start["parameters"])
    assert "## From the default start" in text and "held out: disjoint from the seeds 1000-1049" in text


def test_held_out_seeds_are_disjoint_from_the_tuning_seeds():
    from structsearch.experiments.calibration import HELD_OUT_FIRST, TUNING_SEEDS, held_out
    assert held_out(range(HELD_OUT_FIRST, HELD_OUT_FIRST + 50))
    assert not held_out([TUNING_SEEDS[-1], TUNING_SEEDS[-1] + 1])


def test_default_start_rows_calibrate_like_the_truth_start_ones():
    """The default-start fits' rows use the same arithmetic as the truth-start ones (3 of 5 inside at 95 %)."""
    from structsearch.experiments.calibration import default_start_rows
    offsets = [0.0, 0.5, -1.5, 2.5, -3.0]
    draws = [CampaignDraw(d.seed, d.samples, d.estimates, d.stderr, d.gap_p, d.dof,
                          default_estimates=d.estimates, default_stderr=d.stderr["white"],
                          default_dof={m: {} for m in d.estimates}, other_basin=("CL-VI",) if i == 0 else ())
             for i, d in enumerate(_draws(offsets))]
    rows = default_start_rows(draws)
    assert len(rows) == sum(len(t) for t in TRUTH.values())
    assert all(p.coverage95 == pytest.approx(3 / 5) and p.coverage68 == pytest.approx(2 / 5) for p in rows)
    assert default_start_rows(_draws(offsets)) == ()


def test_band_coverage_pools_the_points_of_every_campaign():
    draws = _draws([0.0, 0.1])
    draws = [CampaignDraw(d.seed, d.samples, d.estimates, d.stderr, d.gap_p, d.dof,
                          band_hits={"CL": hits, "CD": (True,) * 4, "Cm": (False,) * 4},
                          band_widths={"CL": 0.1, "CD": 0.01, "Cm": 0.02})
             for d, hits in zip(draws, [(True, True, True, False), (True, False, False, False)])]
    cal = summarise(draws, 0.1)
    assert cal.band_coverage == {"CL": pytest.approx(4 / 8), "CD": 1.0, "Cm": 0.0}
    assert cal.band_campaign_coverage["CL"] == (0.25, 0.75)
    # no draw with bands (the default covariance was not among the kinds): NaN, never 0
    assert all(np.isnan(v) for v in summarise(_draws([0.0, 0.1]), 0.1).band_coverage.values())


def test_a_parameters_coverage_is_judged_against_its_binomial_monte_carlo_error():
    """Of 20 campaigns, 95 % intervals cover the truth at least 15 times but for a 0.1 % chance
    (P(count <= 14) = 3.3e-4, P(count <= 15) = 2.6e-3): 20 of 20 and 15 of 20 pass, 14 of 20 fails."""
    from structsearch.experiments.calibration import ParameterCalibration
    from scipy import stats
    assert stats.binom.cdf(14, 20, 0.95) < 0.001 < stats.binom.cdf(15, 20, 0.95)

    def row(covered):
        return ParameterCalibration("m", "p", 0.0, 0.0, 1.0, 1.0, 0.7, covered / 20, 20)
    assert [row(c).binomial_floor95 for c in (20, 15, 14)] == [15, 15, 15]
    assert [row(c).coverage95_consistent for c in (20, 15, 14)] == [True, True, False]


def test_a_kind_meets_its_goals_only_with_every_parameter_within_its_binomial_error():
    # 20 campaigns, offsets inside the 95 % interval (|z| < 1.96) in all but k of them
    def kind(k):
        offsets = [0.3 * ((-1) ** i) for i in range(20 - k)] + [3.0] * k
        return summarise(_draws(offsets), scale=0.1).kinds[0]
    assert all(p.covered95 == 20 for p in kind(0).parameters) and not kind(0).below_binomial
    assert all(p.covered95 == 14 for p in kind(6).parameters)
    assert len(kind(6).below_binomial) == len(kind(6).parameters) and not kind(6).meets_goals


def _committed_calibration(folder: str):
    """A committed calibration of the transfer truth on held-out seeds: (the document, its hac-maneuver kind, its
    rows by "model parameter", Cm-XXXIIIf's Cm_CL row, the worst-covered row); no count below its binomial floor."""
    import json
    from pathlib import Path
    doc = json.loads((Path(__file__).resolve().parents[1] / "results" / folder / "calibration.json").read_text())
    assert doc["cg_moment"] == "transfer" and doc["seeds"]["held_out"]
    kind = doc["kinds"]["hac-maneuver"]
    rows = {f"{p['model']} {p['parameter']}": p for p in kind["parameters"]}
    assert kind["below_binomial_floor"] == [] and all(p["coverage95_consistent"] for p in rows.values())
    return doc, kind, rows, rows["Cm-XXXIIIf Cm_CL"], min(rows.values(), key=lambda p: p["coverage95"])


def test_the_calibration_the_guide_quotes_is_the_committed_one():
    """The flight-effect calibration the guides quote is a committed results file made by the command they
    name, with its flight effects; every quoted figure is read from it, and each parameter's count is judged
    against its binomial Monte Carlo error."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    doc, kind, rows, cm_cl, worst = _committed_calibration("calibration_cg_transfer")
    assert doc["flight_effects"] == ["x_cg"] and doc["scale"] == 1.0 and len(doc["seeds"]["values"]) == 20
    assert len(rows) == 25 and all(p["binomial_floor95"] == 15 for p in rows.values())
    guide = (root / "docs" / "guide" / "flight-effects.md").read_text()
    pooled = f"{kind['pooled_coverage95']:.3f}"
    assert f"pooled (25 parameters)   {pooled}" in guide
    assert f"{cm_cl['coverage95']:.2f} ({cm_cl['covered95']}/20; sd ratio {cm_cl['sd_ratio']:.2f})" in guide
    assert f"{worst['coverage95']:.2f} ({worst['covered95']}/20, {worst['model']} {worst['parameter']})" in guide
    rejected = round(kind["gap_test_rejection_rate"] * kind["gap_tests"])
    missing = f" ({kind['gap_tests_not_estimable']} not estimable)" if kind["gap_tests_not_estimable"] else ""
    assert f"gap test rejections      {rejected}/{kind['gap_tests']}{missing} " in guide
    assert f"pool at {pooled}" in (root / "docs" / "guide" / "moment-reference.md").read_text()


def test_the_calibration_without_the_effect_the_guide_quotes_is_committed_too():
    """The guide's "without" column: the same truth flown without --flight-effects at scale 0.5, 8 held-out
    campaigns, committed as results/calibration_cg_transfer_without; its quoted figures are read from it."""
    from pathlib import Path
    root = Path(__file__).resolve().parents[1]
    doc, kind, rows, cm_cl, worst = _committed_calibration("calibration_cg_transfer_without")
    assert doc.get("flight_effects", []) == [] and doc["scale"] == 0.5
    assert doc["seeds"]["values"] == list(range(2000, 2008))
    guide = (root / "docs" / "guide" / "flight-effects.md").read_text()
    assert f"{cm_cl['coverage95']:.2f} ({cm_cl['covered95']}/8; sd ratio {cm_cl['sd_ratio']:.2f})" in guide
    assert f"{worst['coverage95']:.2f} ± 0.15 ({worst['model']} {worst['parameter']}) to 1.00" in guide
    assert f"{kind['pooled_coverage95']:.3f} ± 0.013" in guide
    rejected = round(kind["gap_test_rejection_rate"] * kind["gap_tests"])
    assert guide.count(f"{rejected}/{kind['gap_tests']}\n") == 1
    pitch = [p["coverage95"] for key, p in rows.items() if key.startswith("Cm-XXXIIIf")]
    assert f"{min(pitch):.2f}-{max(pitch):.2f}" in guide


def test_a_parameter_no_campaign_estimated_has_no_count_not_zero():
    from structsearch.experiments.calibration import ParameterCalibration
    p = ParameterCalibration("m", "p", 0.0, 0.0, 1.0, float("nan"), float("nan"), float("nan"), 0)
    assert p.covered95 is None and p.binomial_floor95 is None and p.coverage95_consistent is None
