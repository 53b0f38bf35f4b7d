"""Issue 27: the benchmark's and the study's typed results serialise with ``to_dict()`` into plain JSON, key
for key what the command writes (``withheld_benchmark.json``) or what the study holds."""
import json
import math

import pytest

from structsearch.diagnosis.withheld import (NOT_EXPRESSIBLE, AnomalyRow, BenchmarkResult, NullRow, WithheldRow,
                                             markdown)
from structsearch.reporting.diagnosis_doc import benchmark_console_line
from structsearch.thesis_study.comparison import CoefficientScores
from structsearch.thesis_study.derived import Collinearity, DerivedQuantity
from structsearch.thesis_study.dynamic_stalls import DynamicStallStudy, Identification
from structsearch.thesis_study.legacy import EstimatorComparison, LegacyFit
from structsearch.thesis_study.search_tables import ThesisTable
from structsearch.thesis_study.study import Study

# withheld_benchmark.json's keys as the benchmark wrote them before the rows were typed
WITHHELD_KEYS = ["effect", "coefficient", "baseline", "ranked_first", "first", "shrink", "closes_half", "truth_share",
                 "top_phase", "top_alpha_band", "truth_phase", "truth_alpha_band", "truth_mse", "located",
                 "gap_p_value", "explained", "state_alpha_rms", "state_alpha_rms_after", "seconds"]
ANOMALY_KEYS = ["anomaly", "coefficient", "baseline", "description", "signal", "detected", "top_phase",
                "top_alpha_band", "truth_phase", "truth_alpha_band", "truth_mse", "located", "adopted",
                "closed_by_library", "explained", "false_claim", "unexplained_share", "first_signal", "says",
                "first_signal_remaining", "signal_first", "gap_p_value", "equivalence", "equivalent_value",
                "injected_value", "right", "seconds"]
NULL_KEYS = ["seed", "model", "explained", "gap_p_value", "alarm_test", "alarm_combined", "seconds", "adopted"]


def _benchmark():
    rows = (WithheldRow("elevator", "CL", "CL-VI - elevator", True, "elevator", 0.9, True, 0.95, "attached",
                        "0.04-0.08", "attached", "0.04-0.08", 1e-6, True, 1e-9, True, 0.01, 0.005, 3.0),
            WithheldRow("thrust", "CD", "CD-IXr - thrust", False, "induced_drag", None, False, None, None, None,
                        "stalled", "0.20-0.24", 2e-7, False, None, False, None, None, 2.0))
    outside = (AnomalyRow("vane_lag", "Cm", "Cm-XXXIIIr", "A lag.", "alpha_dot", True, "reattaching", "0.16-0.20",
                          "reattaching", "0.16-0.20", 1e-7, True, "Cm-XXXIIIr", float("nan"), False, False, 0.8,
                          "alpha_dot", "80% of the gap ...", "alpha_dot", True, 1e-4, None, None, 0.4, True, 5.0),)
    null = (NullRow(0, "CL-VI", True, 0.3, False, False, 1.0), NullRow(0, "CD-IXr", False, None, None, True, 1.0))
    return BenchmarkResult(0, 0.1, rows, outside, null, NOT_EXPRESSIBLE, 12.0)


def test_benchmark_to_dict_keeps_the_keys_of_withheld_benchmark_json():
    res = _benchmark()
    doc = json.loads(json.dumps(res.to_dict(), indent=2, default=float))
    assert list(doc) == ["seed", "scale", "rows", "outside", "null", "not_expressible", "seconds"]
    assert [list(r) for r in doc["rows"]] == [WITHHELD_KEYS] * 2
    assert list(doc["outside"][0]) == ANOMALY_KEYS and math.isnan(doc["outside"][0]["closed_by_library"])
    assert [list(r) for r in doc["null"]] == [NULL_KEYS] * 2 and doc["null"][1]["alarm_test"] is None
    assert doc["not_expressible"] == NOT_EXPRESSIBLE
    # the summary line and the page count the same rows
    assert benchmark_console_line(res, "out/withheld_benchmark.md") == (
        "withheld effect ranked first 1/2; out-of-library effects right (located, not falsely explained and their "
        "signal first, or explained with the equivalence named) 1/1; false alarms 1/2 (Wald test alone 0); wrote out/withheld_benchmark.md")
    page = markdown(res, "cmd")
    assert "Ranked first: **1/2**" in page and "by the combined rule: **1/2**" in page and "| n/a" in page


def _identification(label):
    return Identification(label, ("m1", "m2"), ("tau1_ss", "tau2_ss"), (1.0, 2.0), (0.1, float("nan")),
                          (1e-3, 0.5), ((1.0, 0.7), (0.7, 1.0)))


def test_study_to_dict_is_plain_json():
    scores = (CoefficientScores("final", "CL", "train", 1e-4, (0.9, 0.8), ("m1", "m2")),)
    legacy = LegacyFit("CL-I", {"a": 1.0}, ({"a": 0.9}, {"a": 1.1}), 4, 2.5)
    study = Study({"final": {"CL": "CL-VI"}}, scores,
                  DynamicStallStudy("CL-VI", _identification("quasi-steady only"), _identification("full training set")),
                  ("S", "Q", "U"), ((1.0, 2.0, 3.0),) * 3, (DerivedQuantity("tau1_ss*", 5.0, "-", "chords"),),
                  Collinearity((("alpha", "de", 0.8),), (("CL0", 1.0),), 12.0),
                  EstimatorComparison({"CL": "CL-I"}, legacy, {"a": 1.0}, 0.5, 4, scores),
                  (ThesisTable("lift", "CL", "CL-I", ("model", "MSE"), (("CL-I", 1e-4),)),))
    doc = study.to_dict()
    text = json.dumps(doc)   # no default: a numpy value or a tuple key would raise here
    assert math.isnan(json.loads(text)["dynamic_stalls"]["full"]["sd"][1])
    assert list(doc) == ["models", "scores", "dynamic_stalls", "separation", "derived", "collinearity", "estimators",
                         "search_tables", "joint"]
    assert doc["joint"] is None       # a study built without the joint comparison says so
    assert doc["scores"][0]["r2_mean"] == scores[0].r2_mean == pytest.approx(0.85)
    assert doc["dynamic_stalls"]["called_out"][0] == {"a": "tau1_ss", "b": "tau2_ss", "rho_quasi_steady": 0.7,
                                                      "rho_full": 0.7}
    assert doc["separation"]["training_mse"][2] == [1.0, 2.0, 3.0]
    assert doc["collinearity"]["vif"] == [{"regressor": "CL0", "vif": 1.0}]
    assert doc["estimators"]["legacy"]["per_maneuver"] == [{"a": 0.9}, {"a": 1.1}]
    assert doc["search_tables"][0]["rows"] == [["CL-I", 1e-4]]
