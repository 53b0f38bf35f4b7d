"""The study's tables in Markdown, LaTeX and CSV (each opening with the command that made it) and its box plots
(issue 16). Numbers come from :class:`structsearch.thesis_study.study.Study`."""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
from tabulate import tabulate

from ..data.atomic import write_text
from ..thesis_study.comparison import COMPARED, comparison_rows
from ..thesis_study.dynamic_stalls import THESIS_TAU_CORRELATION
from ..thesis_study.legacy import LEGACY, SNLS
from ..thesis_study.study import FINAL, VAN_INGEN_PUBLISHED, VAN_INGEN_REFITTED, Study

FORMATS = ("md", "tex", "csv")


def _fmt(x, spec=".4g") -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "n/a"
    return format(x, spec) if isinstance(x, (float, np.floating)) else str(x)


def write_table(out: Path, stem: str, title: str, headers, rows, command: str, note: str = "",
                spec: str = ".4g") -> list[Path]:
    """One table as ``stem.md``, ``stem.tex`` and ``stem.csv`` (full precision) under ``out``."""
    text_rows = [[_fmt(x, spec) for x in row] for row in rows]
    md = f"# {title}\n\nCommand: `{command}`\n\n" + (note + "\n\n" if note else "") + tabulate(
        text_rows, headers, tablefmt="github", disable_numparse=True) + "\n"
    tex = f"% {title}\n% command: {command}\n" + tabulate(text_rows, headers, tablefmt="latex_booktabs",
                                                             disable_numparse=True) + "\n"
    buffer = io.StringIO()
    buffer.write(f"# command: {command}\n")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(headers)
    writer.writerows([["" if (isinstance(x, float) and not np.isfinite(x)) else x for x in row] for row in rows])
    return [write_text(out / f"{stem}.md", md), write_text(out / f"{stem}.tex", tex),
            write_text(out / f"{stem}.csv", buffer.getvalue())]


def _comparison(study: Study, out: Path, command: str, reference: str, stem: str, title: str) -> list[Path]:
    rows = [[r["coefficient"], r["split"], r["mse"], r["reference_mse"], r["difference_pct"], r["r2_mean"],
             r["r2_min"], r["r2_max"], r["reference_r2_mean"], r["reference_r2_min"], r["reference_r2_max"]]
            for r in comparison_rows(list(study.scores), FINAL, reference)]
    headers = ["coefficient", "split", "MSE final", f"MSE {reference}", "% difference", "R2 mean", "R2 min",
               "R2 max", "R2 mean ref.", "R2 min ref.", "R2 max ref."]
    models = ", ".join(f"{c} {n}" for c, n in study.models[FINAL].items())
    refs = ", ".join(f"{c} {n}" for c, n in study.models[reference].items())
    note = (f"Final models: {models}. {reference}: {refs}. R^2 per maneuver (mean, min, max); % difference of "
            "the MSE against the reference. C_X and C_Z from each set's C_L and C_D at the measured alpha.")
    return write_table(out, stem, title, headers, rows, command, note)


def _estimators(study: Study, out: Path, command: str) -> list[Path]:
    e = study.estimators
    rows = [[r["coefficient"], r["split"], r["reference_mse"], r["mse"], r["difference_pct"]]
            for r in comparison_rows(list(e.scores), SNLS, LEGACY)]
    structures = ", ".join(f"{c} {n}" for c, n in e.names.items())
    note = (f"Structures: {structures}. The lift model estimated both ways from the same {e.n_starts} start points "
            f"(the declared start and scrambled Sobol points): legacy, per training maneuver with every parameter "
            f"free, the best start kept, the separation parameters averaged, the linear ones re-estimated by OLS on "
            f"all training maneuvers ({e.legacy.seconds:.1f} s); SNLS on all training maneuvers at once "
            f"({e.snls_seconds:.1f} s; the solver alone, like the legacy one). Drag and pitch by OLS on each lift "
            "fit's separation states. % difference: SNLS against legacy (thesis Table 7: C_L -36 % in training).")
    written = write_table(out, "legacy_vs_snls", "The legacy estimator against SNLS (thesis Table 7)",
                          ["coefficient", "split", "MSE legacy", "MSE SNLS", "% difference"], rows, command, note)
    names = list(e.snls_params)
    written += write_table(out, "legacy_vs_snls_parameters", f"{e.names['CL']}'s parameters, legacy and SNLS",
                           ["parameter", "legacy", "SNLS"],
                           [[n, e.legacy.params.get(n, float("nan")), e.snls_params[n]] for n in names], command)
    return written


def _joint(study: Study, out: Path, command: str) -> list[Path]:
    j = study.joint
    rows = [[s.coefficient, s.structure, s.sequential_validation, s.joint_validation,
             100.0 * (s.joint_validation / s.sequential_validation - 1.0), s.sequential_train, s.joint_train]
            for s in j.scores]
    seq_rho, joint_rho = j.tau_correlation
    note = (f"{' + '.join(j.structures)} fitted jointly: one separable problem in which the three coefficients share "
            f"the separation parameters, each its own linear block, weighted by its inverse residual variance "
            f"(settled after {j.iterations} iterations{'' if j.weights_settled else ': NOT settled'}"
            f"{'' if j.converged else '; the optimizer did NOT converge'}). Sequential: the lift model alone, then "
            f"drag and pitch on its states. rho(tau1_ss, tau2_ss) {_fmt(seq_rho, '+.2f')} (lift only) -> "
            f"{_fmt(joint_rho, '+.2f')} (joint), with the {j.covariance} covariance of each fit.")
    written = write_table(out, "joint_vs_sequential", "The final models fitted jointly against sequentially (MSE)",
                          ["coefficient", "structure", "MSE val. sequential", "MSE val. joint", "% difference",
                           "MSE train sequential", "MSE train joint"], rows, command, note)
    rows = [[p.coefficient, p.name, p.sequential, p.sequential_sd, p.joint, p.joint_sd,
             p.joint_sd / p.sequential_sd if p.sequential_sd > 0 else float("nan")] for p in j.parameters]
    note = ("Standard deviations with each fit's covariance: the lift-only fit's own; drag and pitch sequential: "
            "two-step on the lift-only model (its estimation error included); joint: the stacked problem's. A shared "
            "separation parameter is listed under the lift model. Drag and pitch read the lift model's C_L in both; "
            "the joint covariance treats that C_L as data (the weight iteration updates it), the two-step one "
            "carries its error.")
    written += write_table(out, "joint_vs_sequential_parameters", "Parameters of the final models, joint and "
                           "sequential", ["coefficient", "parameter", "sequential", "sd sequential", "joint", "sd joint",
                                          "sd joint / sequential"], rows, command, note)
    return written


def _dynamic_stalls(study: Study, out: Path, command: str) -> list[Path]:
    """The lift model with and without the dynamic stalls, and its parameter correlations each way."""
    d = study.dynamic_stalls
    q, f = d.quasi_steady, d.full
    rows = []
    for name in f.names:
        i = f.names.index(name)
        j = q.names.index(name) if name in q.names else None
        rows.append([name] + ([q.estimate[j], q.sd[j], q.p_value[j]] if j is not None else [np.nan] * 3)
                    + [f.estimate[i], f.sd[i], f.p_value[i]])
    note = (f"{d.model} on the {len(q.maneuvers)} quasi-steady training stalls and on all {len(f.maneuvers)} "
            "training maneuvers. Called out: " + "; ".join(
                f"rho({a}, {b}) {_fmt(rq, '+.2f')} -> {_fmt(rf, '+.2f')}" for a, b, rq, rf in d.called_out())
            + f". The thesis (Tables 10.2-10.3) reports |rho(tau1_ss, tau2_ss)| "
            f"{THESIS_TAU_CORRELATION['quasi-steady only']} -> {THESIS_TAU_CORRELATION['full training set']}; here "
            f"{abs(d.quasi_steady.rho('tau1_ss', 'tau2_ss')):.2f} -> {abs(d.full.rho('tau1_ss', 'tau2_ss')):.2f}"
            + (": the other maneuvers tell the lag from the delay. " if abs(d.full.rho('tau1_ss', 'tau2_ss'))
               < abs(d.quasi_steady.rho('tau1_ss', 'tau2_ss')) else ": the other maneuvers do not decorrelate them. ")
            + "The level depends on the campaign (on a simulated one, on its noise and slow errors) and on the "
            "covariance estimator (here the fit's default).")
    written = write_table(out, "dynamic_stalls", "The lift model with and without the dynamic stalls (thesis "
                           "Tables 10.1-10.3)", ["parameter", "estimate (QS only)", "sd (QS only)", "p (QS only)",
                                                 "estimate (full)", "sd (full)", "p (full)"], rows, command, note)
    for ident, stem in ((q, "correlation_quasi_steady"), (f, "correlation_full")):
        written += write_table(out, stem, f"Parameter correlations of {d.model}, {ident.label}",
                               ["parameter"] + list(ident.names),
                               [[n] + list(row) for n, row in zip(ident.names, ident.correlation)], command)
    return written


def write(study: Study, out: Path, command: str, figures: bool = True) -> list[Path]:
    out = Path(out)
    written = _estimators(study, out, command)
    if study.joint is not None:
        written += _joint(study, out, command)
    written += _comparison(study, out, command, VAN_INGEN_REFITTED, "final_vs_van_ingen",
                          "Final models against Van Ingen's structures refitted (thesis Tables 17 and 11.1)")
    written += _comparison(study, out, command, VAN_INGEN_PUBLISHED, "final_vs_van_ingen_published",
                           "Final lift model against Van Ingen's lift model as published (thesis Table 11.1, "
                           "C_L only: only its lift values are published)")
    written += _dynamic_stalls(study, out, command)
    kinds = study.separation_kinds
    written += write_table(out, "separation_matrix", "Separation kinds: training MSE of C_L (thesis Table 8)",
                           ["X_ss \\ X_w"] + list(kinds),
                           [[k] + list(row) for k, row in zip(kinds, study.separation_mse)], command,
                           "Rows: the stall-strip state's kind; columns: the wing state's (S static, Q "
                           "quasi-steady, U unsteady).", spec=".6g")
    written += write_table(out, "derived", f"Derived quantities of {study.models[FINAL]['CL']}",
                           ["quantity", "value", "unit", "meaning"],
                           [[x.name, x.value, x.unit, x.meaning] for x in study.derived], command)
    c = study.collinearity
    rows = [[f"corr({a}, {b})", v] for a, b, v in c.correlations]
    rows += [[f"VIF {name}", v] for name, v in c.vif]
    rows += [["condition number (scaled)", c.condition_number]]
    written += write_table(out, "collinearity", f"Collinearity of {study.models[FINAL]['CL']}'s regressors in the "
                           "training data", ["measure", "value"], rows, command,
                           "Pairs of data columns strongly correlated make derivatives on both trade off "
                           "(thesis chapter 11: alpha with delta_e in trimmed flight, q with alpha_dot when the "
                           "flight path hardly turns); the VIFs are those of this model's own regressors, and one "
                           "above 10 names a regressor the data pin poorly.")
    for t in study.search_tables:
        written += write_table(out, f"{t.grid}_thesis", f"The {t.grid} grid in the thesis' layout (Tables 9, 10, 20)",
                               list(t.headers), [list(r) for r in t.rows], command,
                               "A star marks a regressor the candidate holds; X columns give each separation "
                               "state's kind (S static, Q quasi-steady, U unsteady); % to the reference: training "
                               f"MSE against {t.reference} refitted. C_X and C_Z (lift and drag) combine the "
                               "candidate's coefficient with the other one as measured, as the search tables do "
                               "(final_vs_van_ingen combines both models' predictions). Coefficients and MSEs are "
                               "dimensionless.")
    if figures:
        from . import figures as fg
        fg.require()
        r2 = {(s.model, s.coefficient, s.split): s.r2 for s in study.scores}
        models = [FINAL, VAN_INGEN_REFITTED, VAN_INGEN_PUBLISHED]
        written.append(fg.save(fg.r2_boxes(r2, COMPARED, models), out / "r2_boxes.png"))
    return written
