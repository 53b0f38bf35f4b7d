"""Every table structsearch prints or writes, rendered one way (text, Markdown, LaTeX, HTML, CSV).

Parameter and correlation tables accept anything that reads like a fit: a
:class:`~structsearch.engine.results.FitResult` or a search's
:class:`~structsearch.fitting.candidate_result.CandidateResult` (``names``,
``nonlinear_names``, ``params``, ``stderr``, ``p_values``, ``significant``,
``at_bound``, ``high_correlations``, ``correlation``).
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..data.atomic import write_text
from ..data.manifest import begin_set, finish_set
from ..engine.estimates import HIGH_CORRELATION
# one renderer for every table of a fit (engine.summary), re-exported here for the report's callers
from ..engine.summary import (CSV_DIGITS, FORMATS, PARAMETER_HEADERS, TABLEFMT,  # noqa: F401
                              csv_value, parameter_flags, parameter_rows, parameter_table, render_table)
from ..engine.summary import with_newline as _with_newline
from ..fitting.candidate_result import CandidateResult, Placement
from ..fitting.candidates import Candidate
from ..grid_search.ranking import gap_reference


def correlation_table(fit, fmt: str = "text") -> str:
    """Parameter correlation matrix (thesis Tables 12, 14, 16); |rho| above the flag level marked *."""
    names = list(fit.names)
    matrix = np.asarray(fit.correlation, float)
    if fmt == "csv":
        return render_table([[n] + [f"{v:.4f}" for v in row] for n, row in zip(names, matrix)], [""] + names, fmt)
    body = [[n] + [f"{v:+.2f}" + ("*" if i != j and abs(v) > HIGH_CORRELATION else "") for j, v in enumerate(row)]
            for i, (n, row) in enumerate(zip(names, matrix))]
    return _with_newline(render_table(body, [""] + names, fmt, numparse=False), fmt)


# ----- the ranking of a grid ----------------------------------------------------------------
# (ranking.csv field, table header); ranking.csv also carries "grid", "message" and "error".
COLUMNS = [("rank", "rank"), ("model", "model"), ("admissible", "admissible"), ("lift", "lift model"),
           ("n_params", "parameters"),
           ("mse_train", "MSE train"), ("mse_cv", "MSE CV"), ("mse_validation", "MSE validation"),
           ("mse_cx_validation", "MSE C_X val."), ("mse_cz_validation", "MSE C_Z val."),
           ("r2_validation_mean", "R2 val. mean"), ("r2_validation_min", "R2 val. min"),
           ("r2_validation_max", "R2 val. max"), ("r2_validation_pooled", "R2 val. pooled"), ("aic", "AIC"), ("n_insignificant", "t-test accepts 0"),
           ("n_high_corr", f"|rho| > {HIGH_CORRELATION}"), ("within_noise", "within noise of best"),
           ("gap", "gap to best"), ("gap_se", "gap s.e."),
           ("converged", "converged"), ("nfev", "evaluations"), ("identifiable", "identifiable"),
           ("condition_number", "cond. (scaled J)")]
RANKING_FIELDS = ["grid", "model", "rank", "mse_train", "mse_validation", "n_params", "lift", "mse_cx_validation",
                  "mse_cz_validation", "r2_validation_mean", "r2_validation_min", "r2_validation_max", "aic",
                  "n_insignificant", "n_high_corr", "within_noise", "converged", "nfev", "message", "identifiable",
                  "condition_number", "not_identifiable", "error", "admissible", "reasons", "mse_cv", "cv_folds",
                  "gap", "gap_se", "r2_validation_pooled", "cv_scheme", "cv_note", "origin"]


def table_row(s: CandidateResult) -> dict:
    """One candidate as the fields of ``ranking.csv`` (None where there is no value)."""
    p = s.placement or Placement()
    row = {"grid": s.grid, "model": s.name, "rank": p.rank, "lift": s.lift or "-", "error": s.error,
           "admissible": p.admissible, "reasons": "; ".join(p.reasons), "origin": p.origin}
    if not s.failed:
        v = s.validation
        row.update({"n_params": s.n_params, "mse_train": s.mse_train, "mse_validation": s.mse_validation,
                    "mse_cx_validation": v.mse_cx, "mse_cz_validation": v.mse_cz,
                    # no maneuver with an R^2 (constant signal): empty, not "nan"
                    **{f"r2_validation_{k}": (x if math.isfinite(x) else None) for k, x in v.r2.as_dict().items()},
                    "aic": s.aic, "n_insignificant": len(s.insignificant), "n_high_corr": len(s.estimates.high_correlations),
                    "within_noise": p.within_noise, "converged": s.optimizer.converged, "nfev": s.optimizer.nfev,
                    "mse_cv": s.cv.mse if s.cv is not None else None, "cv_folds": s.cv_folds,
                    # how the folds were formed, or why there is no mse_cv (structsearch.fitting.folds)
                    "cv_scheme": s.cv_scheme or None, "cv_note": s.cv_note or None,
                    "gap": p.gap, "gap_se": p.gap_se if p.gap_se is not None and math.isfinite(p.gap_se) else "n/a",
                    "message": s.optimizer.message, "identifiable": s.identifiable, "condition_number": s.estimates.condition_number,
                    # a fit that did not converge withholds every parameter's statistics for one reason: said once
                    "not_identifiable": (f"every parameter: {s.estimates.withheld}" if s.estimates.withheld else
                                         "; ".join(f"{k}: {v}" for k, v in s.estimates.not_identifiable.items()))})
    return row


def signed_percent(x: float, sign: bool = True) -> str:
    """A relative change as a percentage (signed unless ``sign`` is false) that never reads "-0.0%": below 0.1%
    at two significant digits; "n/a" for NaN; a change below 1e-9 is rounding of zero (a gap of 1e-17): "0%"."""
    if x != x:
        return "n/a"
    if abs(x) < 1e-9:
        return "0%"
    plus = "+" if sign else ""
    return f"{100 * x:{plus}.2g}%" if abs(x) < 1e-3 else f"{x:{plus}.1%}"


def _cell(v):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "-" if math.isnan(v) else f"{v:.4g}"
    return v


def grid_table(ranked: list[CandidateResult], fmt: str) -> str:
    """A grid's ranking (thesis Tables 8, 9, 10, 20): one row per candidate, best first; why a candidate
    is not admissible in the last column."""
    headers = [h for _, h in COLUMNS] + ["not admissible because"]
    body = []
    for s in ranked:
        row = table_row(s)
        if fmt != "csv":   # a person reads the gaps as the console prints them: +10.7%; the CSV keeps fractions
            row.update({k: signed_percent(row[k], sign=k == "gap") for k in ("gap", "gap_se")
                        if isinstance(row.get(k), float)})
        body.append([_cell(row.get(k)) for k, _ in COLUMNS] + [row["reasons"]])
    table = _with_newline(render_table(body, headers, fmt), fmt)
    note = gap_note(ranked)
    if fmt in ("md", "markdown") and note:
        return table + "\n" + note + "\n"
    if fmt in ("tex", "latex") and note:
        return table + "% " + note + "\n"
    return table


def gap_note(ranked: list[CandidateResult]) -> str:
    """What "gap to best" and "within noise of best" are measured against (the same for every row)."""
    reference = gap_reference(ranked)
    if reference is None:
        return ""
    against = ("the best-fitting admissible candidate" if reference.placement.admissible else
               "the best-fitting candidate (none is admissible)")
    return (f"Gap to best: each candidate's mean per-maneuver relative excess of held-out MSE over {against}, "
            f"{reference.name}; within noise of best: a gap below its standard error (or 1 %). "
            "Rejected candidates are measured against the same candidate, so none looks tied with the winner "
            "only because it is tied with the best of the rejected.")


def ranking_csv(ranked_by_grid: dict[str, list[CandidateResult]]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(RANKING_FIELDS)
    for ranked in ranked_by_grid.values():
        for s in ranked:
            row = table_row(s)
            w.writerow(["" if row.get(f) is None else csv_value(row[f]) for f in RANKING_FIELDS])
    return buf.getvalue()


def thesis_stderr_rows(ranked_by_grid: dict[str, list[CandidateResult]]) -> list[list]:
    """The thesis' final models as identified here next to thesis Tables 11, 13 and 15: estimate and
    standard deviation, and the ratio of the standard deviations (the simulator's realism check)."""
    from ..flight.reference import FINAL_DRAG, FINAL_LIFT, FINAL_MODEL_NAMES, FINAL_PITCH, THESIS_STDERR
    truth = {**FINAL_LIFT, **FINAL_DRAG, **FINAL_PITCH}
    rows = []
    for name in FINAL_MODEL_NAMES.values():
        fit = next((s for ranked in ranked_by_grid.values() for s in ranked
                    if s.name == name and not s.failed), None)
        if fit is None:
            continue
        for p in fit.estimates.names:
            sd = fit.estimates.stderr.get(p, float("nan"))
            ratio = sd / THESIS_STDERR[p] if p in THESIS_STDERR and sd > 0 else float("nan")
            within = "n/a (not estimable)" if math.isnan(ratio) else "yes" if 0.5 <= ratio <= 2.0 else "no"
            rows.append([name, p, truth.get(p, float("nan")), fit.estimates.params[p], THESIS_STDERR.get(p, float("nan")),
                         sd, ratio, within])
    return rows


THESIS_STDERR_HEADERS = ["model", "parameter", "thesis estimate", "estimate", "thesis std. dev.", "std. dev.",
                         "std. dev. / thesis", "within a factor of 2"]


def write_tables(ranked_by_grid: dict[str, list[CandidateResult]], out: Path,
                 thesis_fits: dict[str, list[CandidateResult]] | None = None,
                 refined: Mapping[str, Sequence[Candidate]] | None = None) -> list[Path]:
    """``ranking.csv`` plus, per grid, the ranking (thesis Tables 8, 9, 10, 20) and the best candidate's
    parameters (Tables 11, 13, 15) and correlation matrix (Tables 12, 14, 16) in md/tex/csv; given
    the final models fitted with the thesis' covariance estimator, ``thesis_stderr``; and the structures the
    refinement reached (grid -> candidates), as ``refined_<grid>.toml`` (:mod:`structsearch.reporting.refined`)."""
    from .refined import write_refined
    out = Path(out)
    begin_set(out, "search")   # a run killed among these files leaves them marked incomplete
    written = [write_text(out / "ranking.csv", ranking_csv(ranked_by_grid))]
    written += write_refined(out, refined or {})
    for grid, ranked in ranked_by_grid.items():
        safe = "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in grid)
        best = next((s for s in ranked if not s.failed), None)
        for fmt in ("md", "tex", "csv"):
            written.append(write_text(out / f"{safe}.{fmt}", grid_table(ranked, fmt)))
            if best is not None:
                written.append(write_text(out / f"{safe}_best_parameters.{fmt}", parameter_table(best.estimates, fmt)))
                written.append(write_text(out / f"{safe}_best_correlation.{fmt}", correlation_table(best.estimates, fmt)))
    rows = thesis_stderr_rows(thesis_fits) if thesis_fits else []
    if rows:
        for fmt in ("md", "csv"):
            written.append(write_text(out / f"thesis_stderr.{fmt}",
                                      render_table(rows, THESIS_STDERR_HEADERS, fmt, floatfmt=".4g")))
    finish_set(out, "search", written)
    return written
